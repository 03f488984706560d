"""Disk faults and restarts through the real coordinator: a full job database (507, the
process stays up, everything recovers), a full frame store (a failed job whose record
says exactly which frames are on disk), a database that does not belong to its store
(refused at start), and a coordinator killed mid-job that resumes without tracing its
written frames again, with every written frame in its job's event log, and whose local
workers die with it.

A full disk is a real tmpfs of a few MiB mounted for the test (root only; skipped with
the reason when mounting is not permitted)."""
import contextlib
import json
import os
import pathlib
import re
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import (COORDINATOR, ROOT, LocalFarm, compare, render_reference,  # noqa: E402
                          small_scene)
from tcfarm.client import ApiError  # noqa: E402

ONE_SPHERE = ROOT / "tests" / "scenes" / "paper_a_one_sphere.json"
TIMEOUT = 300


@contextlib.contextmanager
def tmpfs(directory, size="4m"):
    """A tmpfs of `size` at `directory`, unmounted afterwards."""
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs to fill a disk needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(directory)],
                             capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"mount -t tmpfs is not permitted here: {mounted.stderr.strip()}")
    try:
        yield directory
    finally:
        subprocess.run(["umount", "-l", str(directory)], check=False)


def fill(directory):
    """Fills the disk of `directory` with a file until it refuses a byte; returns the file."""
    filler = pathlib.Path(directory) / "filler"
    with open(filler, "wb", buffering=0) as f:  # unbuffered: nothing left to fail at close
        for piece in (65536, 4096, 1):
            try:
                while True:
                    f.write(b"\0" * piece)
            except OSError:
                pass
    return filler


def large_scene(spheres=50000):
    """A valid scene whose JSON is about 6 MB: more than the database's write-ahead log
    holds before a checkpoint (1000 pages of 4 KiB), so storing it must take new room."""
    scene = small_scene(ONE_SPHERE, 32, 24, 2)
    scene["shapes"] += [{"type": "sphere", "name": f"pad{i}", "center": [i * 0.001, 500, -400],
                         "radius": 0.01, "material": "ball"} for i in range(spheres)]
    return scene


def wait_until(predicate, timeout=TIMEOUT, what="a condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise TimeoutError(f"timed out waiting for {what}")


def metric(farm, name):
    match = re.search(rf"^{name} (\S+)$", farm.metrics(), re.MULTILINE)
    return float(match.group(1)) if match else None


def start_coordinator(store, *args):
    """A coordinator expected to refuse to start: its exit status and stderr."""
    result = subprocess.run([str(COORDINATOR), "serve", "--http", "127.0.0.1:0", "--zmq", "tcp://127.0.0.1:*",
                             "--store", str(store), "--local-workers", "0", *map(str, args)],
                            capture_output=True, text=True, timeout=60)
    return result.returncode, result.stderr


# ---------------------------------------------------------------------------------------
# 1. The job database's disk is full


def test_full_database_answers_507_keeps_running_and_recovers(tmp_path):
    with tmpfs(tmp_path / "dbdisk", size="16m") as dbdisk, \
            LocalFarm(tmp_path, workers=1, coordinator_args=("--db", dbdisk / "jobs.db")) as farm:
        farm.wait_for_workers(1)
        first = farm.run_job(small_scene(ONE_SPHERE, 64, 48, 6), strategy="brute")
        running = farm.client.submit(small_scene(ONE_SPHERE, 160, 120, 30), strategy="exact", bin_width=30)
        filler = fill(dbdisk)

        with pytest.raises(ApiError) as refused:
            farm.client.submit(large_scene(), strategy="brute")
        print("submit on a full database:", refused.value)
        assert refused.value.status == 507 and refused.value.code == "insufficient_storage"
        assert "job database" in str(refused.value) and "full" in str(refused.value)
        # Reads go on; the process and its farm loop stay up.
        assert farm.client.job(first["id"])["state"] == "completed"
        assert [job["id"] for job in farm.client.jobs()] == [running["id"], first["id"]]
        time.sleep(1.0)  # the loop meets the full disk for a while (records, claims)
        assert farm.coordinator.poll() is None

        filler.unlink()  # room again
        done = farm.client.wait(running["id"], timeout=TIMEOUT)
        assert done["state"] == "completed", done
        assert done["frames"]["done"] == 30 and min(done["traced_per_frame"]) >= 0
        again = farm.client.submit(large_scene(), strategy="brute")
        assert again["id"] == running["id"] + 1  # the refused submit took no id
        farm.client.cancel(again["id"])
        ids = [job["id"] for job in farm.client.jobs()]
        assert ids == [again["id"], running["id"], first["id"]]  # none lost, none twice
        print("job database writes refused and retried:", metric(farm, "tcfarm_job_store_writes_refused_total"))
        assert farm.coordinator.poll() is None


# ---------------------------------------------------------------------------------------
# 2. The frame store's disk is full


def test_full_store_fails_the_job_with_a_record_of_the_frames_on_disk(tmp_path):
    farm_dir = tmp_path / "farm"
    farm_dir.mkdir()
    with tmpfs(farm_dir / "store", size="3m"), \
            LocalFarm(farm_dir, workers=1, coordinator_args=("--db", tmp_path / "jobs.db")) as farm:
        farm.wait_for_workers(1)
        job = farm.client.submit(small_scene(ONE_SPHERE, 320, 240, 60), strategy="brute")
        job = farm.client.wait(job["id"], timeout=TIMEOUT)
        print("store full:", job["error"])
        assert job["state"] == "failed"
        assert re.search(r"frame \d+ \(frame_\d{4}\) could not be written|the mask \S+ could not be written",
                         job["error"]), job["error"]
        folder = farm.store / str(job["id"])
        on_disk = sorted(int(p.stem[6:]) for p in folder.glob("frame_*.exr"))
        recorded = [f for f, traced in enumerate(job["traced_per_frame"]) if traced >= 0]
        print(f"{len(recorded)} of 60 frames recorded, on disk: {on_disk}")
        assert recorded == on_disk  # whole frames only, each recorded
        assert job["frames"]["done"] == len(recorded)
        assert 0 < len(recorded) < 60
        # Nothing half-written is left behind. The frame finisher, which starts on the failed
        # job's frames at once (and fails on the full disk), has a temporary file now and then.
        wait_until(lambda: not list(folder.glob("*.partial*")), timeout=10, what="no temporary file left")
        assert f"{len(recorded)} of 60 frames are written and recorded" in job["error"]
        for frame in recorded:  # their previews made on request, from memory on the full disk
            assert farm.client.frame(job["id"], frame, "png")[:8] == b"\x89PNG\r\n\x1a\n"
        missing = next(f for f in range(60) if f not in recorded)
        with pytest.raises(ApiError) as absent:
            farm.client.frame(job["id"], missing, "png")
        assert absent.value.status == 404
        assert farm.coordinator.poll() is None


# ---------------------------------------------------------------------------------------
# 3. A database and a store that do not belong together


def test_a_database_that_is_not_the_stores_is_refused(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with LocalFarm(tmp_path / "a", workers=1) as farm:
        farm.wait_for_workers(1)
        old = farm.run_job(small_scene(ONE_SPHERE, 32, 24, 2), strategy="brute")
    store_a = tmp_path / "a" / "store"
    old_frame = (store_a / str(old["id"]) / "frame_0000.exr").read_bytes()

    status, stderr = start_coordinator(store_a, "--db", tmp_path / "fresh.db")
    print("fresh database over an old store:", stderr.strip())
    assert status == 1 and "job folders" in stderr and "--adopt-store" in stderr

    with LocalFarm(tmp_path / "b", workers=0):
        pass  # store b gets its identity, and its database records it
    status, stderr = start_coordinator(tmp_path / "b" / "store", "--db", store_a / "jobs.db")
    print("database of store a over store b:", stderr.strip())
    assert status == 1 and "belongs to store" in stderr

    # The way out: a fresh database adopts the store, its ids start above its folders.
    with LocalFarm(tmp_path / "a", workers=1,
                   coordinator_args=("--db", tmp_path / "fresh.db", "--adopt-store")) as farm:
        farm.wait_for_workers(1)
        new = farm.run_job(small_scene(ONE_SPHERE, 32, 24, 2), strategy="brute")
    assert new["id"] > old["id"]
    assert (store_a / str(old["id"]) / "frame_0000.exr").read_bytes() == old_frame


# ---------------------------------------------------------------------------------------
# 4. Killed mid-job, restarted: the job resumes


def bins_in_progress(strategy, bin_width, frames, kept):
    """The frames of the bins (segments) that had some frames written and some not."""
    if strategy == "exact":
        spans = [(s, min(s + bin_width, frames) - 1) for s in range(0, frames, bin_width)]
    else:
        width = 2 if strategy == "brute" else bin_width
        spans = [(s, min(s + width - 1, frames - 1)) for s in range(0, frames - 1, width - 1)]
    partial = [(a, b) for a, b in spans if any(f in kept for f in range(a, b + 1))
               and not all(f in kept for f in range(a, b + 1))]
    return sum(b - a + 1 for a, b in partial)


def kill_at_half(farm, job_id, frames):
    wait_until(lambda: farm.client.job(job_id)["frames"]["done"] >= frames // 2, what="half the frames")
    farm.coordinator.send_signal(signal.SIGKILL)
    farm.coordinator.wait()


def recorded_frames(database, job_id):
    with contextlib.closing(sqlite3.connect(database)) as db:
        rows = db.execute("SELECT frame FROM job_frames WHERE job_id = ?", (job_id,)).fetchall()
        plan = json.loads(db.execute("SELECT plan FROM jobs WHERE id = ?", (job_id,)).fetchone()[0])
    return {row[0] for row in rows}, plan


def frames_told(events):
    """How many frames_written events name each frame, and how many frames were told as
    recovered."""
    times, recovered = {}, 0
    for event in events:
        if event["type"] == "frames_written":
            for first, last in event["ranges"]:
                for frame in range(first, last + 1):
                    times[frame] = times.get(frame, 0) + 1
            recovered += event["count"] if event.get("recovered") else 0
    return {"times": times, "recovered": recovered}


@pytest.mark.parametrize("strategy,bin_width", [("exact", 6), ("search", 6), ("guarded", 6), ("brute", 2)])
def test_a_killed_coordinator_resumes_the_job_without_retracing_written_frames(tmp_path, strategy, bin_width):
    frames, width, height = 36, 240, 180
    scene = small_scene(ONE_SPHERE, width, height, frames)
    # Four samples a pixel: the second half of the job must last longer than noticing the
    # first half and killing the coordinator takes (at one sample a guarded job wrote its
    # last 18 frames within that).
    scene["render"]["samples_per_pixel"] = 4
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.client.submit(scene, strategy=strategy, bin_width=bin_width)
        kill_at_half(farm, job["id"], frames)
    kept, plan = recorded_frames(tmp_path / "store" / "jobs.db", job["id"])
    assert 0 < len(kept) < frames, f"killed with {len(kept)} of {frames} frames written: not mid-job"
    assert plan["strategy"] == strategy
    before = job["submitted_at"]

    with LocalFarm(tmp_path, workers=1) as farm:  # the same store and database
        farm.wait_for_workers(1)
        resumed = farm.client.wait(job["id"], timeout=TIMEOUT)
        assert resumed["state"] == "completed", resumed
        stats = resumed["stats"]
        bound = bins_in_progress(strategy, plan["bin_width"], frames, kept) * width * height
        print(f"{strategy}: killed with {len(kept)} of {frames} frames written; resumed_frames "
              f"{stats['resumed_frames']}, traced again {stats['retraced_pixels']} pixels in "
              f"{stats['retraced_frames']} frames (bound: {bound}, the bins in progress)")
        assert stats["resumed_frames"] == len(kept)
        assert stats["retraced_pixels"] <= bound
        assert resumed["frames"]["done"] == frames
        assert resumed["submitted_at"] == before
        # The event log names every frame once, those the killed coordinator had recorded
        # but not yet told included (told on resume, marked recovered).
        told = frames_told(farm.client.events(job["id"]))
        print(f"{strategy}: {told['recovered']} frames told as recovered on resume")
        assert told["times"] == {frame: 1 for frame in range(frames)}

        if strategy in ("search", "guarded"):
            # Not brute force: the resumed job equals an uninterrupted one, bit for bit.
            uninterrupted = farm.run_job(scene, strategy=strategy, bin_width=bin_width)
            error = compare(farm.store / str(uninterrupted["id"]), farm.store / str(job["id"]))
        else:
            reference = render_reference(scene, tmp_path / "reference")
            error = compare(reference, farm.store / str(job["id"]))
        print(f"{strategy}: {error['differing_pixels']} pixels differ in {error['frames']} frames")
        assert error["frames"] == frames and error["differing_pixels"] == 0


def test_started_at_survives_the_restart(tmp_path):
    frames = 30
    scene = small_scene(ONE_SPHERE, 240, 180, frames)
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.client.submit(scene, strategy="brute")
        wait_until(lambda: farm.client.job(job["id"])["frames"]["done"] >= 2, what="two frames")
        started = farm.client.job(job["id"])["started_at"]
        farm.coordinator.send_signal(signal.SIGKILL)
        farm.coordinator.wait()
    time.sleep(1.1)  # a restart a second later would show as a later started_at
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        resumed = farm.client.wait(job["id"], timeout=TIMEOUT)
    assert resumed["state"] == "completed"
    assert resumed["started_at"] == started


def children_of(pid):
    """The pids of the live processes whose parent is `pid`, from /proc/*/stat."""
    children = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()  # after "pid (comm)"
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            children.append(int(stat.parent.name))
    return children


def alive(pid):
    """Whether the process exists and is not a zombie waiting for its reaper."""
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_local_workers_die_with_a_killed_coordinator(tmp_path):
    """Workers the coordinator started itself do not outlive it, even when it is killed
    with SIGKILL (no goodbye, no cleanup): an orphan would join the next coordinator."""
    with LocalFarm(tmp_path, workers=0, local_workers=2) as farm:
        farm.wait_for_workers(2)
        workers = children_of(farm.coordinator.pid)
        assert len(workers) == 2, f"the coordinator's children: {workers}"
        farm.coordinator.send_signal(signal.SIGKILL)
        farm.coordinator.wait()
        try:
            # A liveness bound, not a speed measure: the kernel kills them as the coordinator dies.
            wait_until(lambda: not any(alive(pid) for pid in workers), timeout=10,
                       what=f"local workers {workers} to die with their coordinator")
        finally:
            for pid in filter(alive, workers):  # orphans left by a failure: not the next test's
                os.kill(pid, signal.SIGKILL)
