"""The farm end to end: a coordinator and worker processes over real ZeroMQ sockets, jobs
submitted over real HTTP, frames compared with the standalone brute-force render."""
import json
import re
import signal
import time

import pytest

from farm_harness import LocalFarm, compare, render_reference, small_scene
from tcfarm.client import ApiError


def counter(metrics, name):
    """The value of an unlabelled metric; fails when the coordinator does not export it."""
    match = re.search(rf"^{re.escape(name)} (\S+)$", metrics, re.M)
    assert match, f"{name} is not exported"
    return float(match.group(1))


def holds_tasks(farm, worker_name):
    """True when the farm's last snapshot shows the worker holding tasks with more queued."""
    workers = farm.client.workers()
    held = [w["in_flight"] for w in workers["workers"] if w["name"] == worker_name]
    return workers["queued_tasks"] > 0 and held and held[0] > 0


def kill_the_first_worker_while_it_holds_tasks(farm, job):
    """SIGKILL for worker test-0 once it holds tasks with more queued: it dies owing pixels."""
    deadline = time.monotonic() + 120
    while not holds_tasks(farm, "test-0"):
        state = farm.client.job(job["id"])["state"]
        assert state in ("queued", "running"), f"the job ended ({state}) before a worker held tasks"
        assert time.monotonic() < deadline, "no worker held tasks"
        time.sleep(0.01)
    farm.workers[0].send_signal(signal.SIGKILL)


@pytest.fixture(scope="module")
def twelve_spheres(scenes_dir):
    return small_scene(scenes_dir / "paper_b_twelve_spheres.json")


@pytest.fixture(scope="module")
def reference(twelve_spheres, tmp_path_factory):
    return render_reference(twelve_spheres, tmp_path_factory.mktemp("reference"))


@pytest.fixture
def farm(tmp_path):
    with LocalFarm(tmp_path, workers=2) as farm:
        farm.wait_for_workers(2)
        yield farm


def test_bin_width_two_is_bit_identical_to_brute_force(farm, twelve_spheres, reference):
    job = farm.run_job(twelve_spheres, strategy="search", bin_width=2)
    assert job["traced_pixel_ratio"] == 1.0
    error = compare(reference, farm.store / str(job["id"]))
    assert error["frames"] == 21
    assert error["differing_pixels"] == 0


def test_bin_width_ten_traces_fewer_pixels_and_reports_its_error(farm, twelve_spheres,
                                                                 reference):
    job = farm.run_job(twelve_spheres, strategy="search", bin_width=10)
    assert job["traced_pixel_ratio"] < 0.8
    assert job["pixels_traced"] + job["pixels_copied"] == 21 * 160 * 120
    metrics = farm.metrics()
    for name in ("pixels_traced", "pixels_copied"):
        counted = re.search(rf"^tcfarm_{name}_total (\S+)$", metrics, re.M).group(1)
        assert float(counted) == job[name], (name, counted)
    assert min(job["traced_per_frame"]) >= 0
    error = compare(reference, farm.store / str(job["id"]))
    # The paper's flaw: copies between equal bin ends can be wrong, but few.
    assert error["differing_share"] < 0.05
    print(f"n=10: traced ratio {job['traced_pixel_ratio']:.3f}, "
          f"pixels differing {error['differing_pixels']} ({100 * error['differing_share']:.3f} %)")


def test_a_worker_killed_mid_job_loses_no_pixel(tmp_path, twelve_spheres):
    # Four times the pixels of the module's scene, so the job lasts long enough on a busy
    # machine for a worker to be caught holding tasks.
    scene = json.loads(json.dumps(twelve_spheres))
    scene["render"].update(width=320, height=240)
    (tmp_path / "farm").mkdir()
    reference = render_reference(scene, tmp_path / "reference")
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        job = farm.client.submit(scene, strategy="brute")
        kill_the_first_worker_while_it_holds_tasks(farm, job)
        job = farm.client.wait(job["id"], timeout=300)
        assert job["state"] == "completed", job
        error = compare(reference, farm.store / str(job["id"]))
        assert error["differing_pixels"] == 0
        assert counter(farm.metrics(), "tcfarm_tasks_requeued_total") > 0


def test_a_worker_killed_mid_exact_segment_leaves_the_output_bit_identical(tmp_path, scenes_dir):
    # exact spreads each frame's pixel set over both workers and each task returns the
    # horizons later frames are planned from: a worker killed holding such tasks must cost
    # no pixel and no horizon. Full size and four samples a pixel, so the segment outlasts
    # the farm's notice that a worker holds tasks (one sample: over in half a second).
    scene = json.loads((scenes_dir / "paper_b_twelve_spheres.json").read_text())
    scene["render"]["samples_per_pixel"] = 4
    (tmp_path / "farm").mkdir()
    reference = render_reference(scene, tmp_path / "reference")
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        job = farm.client.submit(scene, strategy="exact", bin_width=60)
        kill_the_first_worker_while_it_holds_tasks(farm, job)
        job = farm.client.wait(job["id"], timeout=300)
        assert job["state"] == "completed", job
        assert counter(farm.metrics(), "tcfarm_tasks_requeued_total") > 0
        assert job["traced_pixel_ratio"] < 0.5  # it still copied most pixels
        error = compare(reference, farm.store / str(job["id"]))
        assert error["frames"] == 60
        assert error["differing_pixels"] == 0, error


def test_frames_that_finish_ahead_wait_on_disk_when_memory_is_short(tmp_path, twelve_spheres,
                                                                    farm):
    # The paper's search releases a frame once it is whole, so frames reach the coherence
    # analysis out of order. With no memory for them, they wait on disk: same record,
    # same change masks, nothing left behind.
    # Bins of five frames make that certain, not a race between bins: the search traces
    # the middle frame, then frames 1 and 3 of the bin in separate tasks, and whichever
    # comes back first is whole while frame 0 is still read by its bin.
    (tmp_path / "short").mkdir()
    with LocalFarm(tmp_path / "short", workers=2,
                   coordinator_args=("--pending-frame-memory", "0")) as short:
        short.wait_for_workers(2)
        spilled = short.run_job(twelve_spheres, strategy="search", bin_width=5)
        spilled_masks = {p.name: p.read_bytes()
                         for p in (short.store / str(spilled["id"])).glob("change_*.png")}
        assert not (short.store / str(spilled["id"]) / ".pending").exists()
    held = farm.run_job(twelve_spheres, strategy="search", bin_width=5)
    assert spilled["stats"]["frames_waited_on_disk"] > 0
    assert held["stats"]["frames_waited_on_disk"] == 0
    assert spilled["stats"]["coherence"] == held["stats"]["coherence"]
    held_masks = {p.name: p.read_bytes()
                  for p in (farm.store / str(held["id"])).glob("change_*.png")}
    assert len(spilled_masks) == 21 and spilled_masks == held_masks


def test_a_coordinator_short_of_memory_works_on_fewer_bins_at_once(tmp_path, twelve_spheres,
                                                                   farm):
    # 160x120 frames take 225 KiB; 5 MiB for the farm's jobs (none of it for frames ahead
    # of their turn) holds one bin of 4 frames at a time with what the farm keeps, not
    # four. The frames are the same either way.
    (tmp_path / "short").mkdir()
    with LocalFarm(tmp_path / "short", workers=2,
                   coordinator_args=("--farm-memory", "5", "--pending-frame-memory", "0")) as short:
        short.wait_for_workers(2)
        narrow = short.run_job(twelve_spheres, strategy="search", bin_width=4)
        wide = farm.run_job(twelve_spheres, strategy="search", bin_width=4)
        assert (narrow["stats"]["live_bins"], wide["stats"]["live_bins"]) == (1, 4)
        assert compare(farm.store / str(wide["id"]),
                       short.store / str(narrow["id"]))["differing_pixels"] == 0
        with pytest.raises(ApiError) as refused:
            short.client.submit(twelve_spheres, strategy="search", bin_width=20)
        assert refused.value.status == 413 and refused.value.code == "job_too_large"


# 8 million triangles: a worker takes seconds to build them, longer than this coordinator
# waits for a silent worker. Built off the worker's loop, it goes on answering heartbeats.
LARGE_TERRAIN = {
    "camera": {"position": [0, 30, 60], "look_at": [0, 0, 0]},
    "lights": [{"type": "directional", "direction": [-1, -2, -1], "intensity": [1, 1, 1]}],
    "shapes": [{"type": "terrain", "origin": [-50, -2, -50], "size": [100, 100], "height": 8,
                "cells": [2000, 2000], "seed": 7}],
    "render": {"width": 16, "height": 12, "frames": {"start": 0, "count": 1}},
}


def test_a_worker_building_a_large_scene_is_not_taken_for_dead(tmp_path):
    with LocalFarm(tmp_path, workers=1, coordinator_args=("--worker-timeout", "1500")) as farm:
        farm.wait_for_workers(1)
        job = farm.run_job(LARGE_TERRAIN, strategy="brute", timeout=600)
        assert job["state"] == "completed", job
        assert counter(farm.metrics(), "tcfarm_tasks_requeued_total") == 0
        assert "reconnecting" not in farm.worker_log(0).read_text()


def test_the_farm_keeps_answering_while_large_frames_are_encoded(tmp_path):
    # A still terrain: exact traces frame 0 and finishes the 11 others at once as copies.
    # Each 2048x1536 frame takes most of a second to encode through one writer thread at
    # zip level 9: a coordinator that waited for its writer would be silent for seconds.
    # Each side gives up on a peer silent for 1.5 s (heartbeats every 300 ms). The
    # coordinator hands frames to its writer as it has room, so it goes on answering.
    scene = {"camera": {"position": [0, 20, 60], "look_at": [0, 0, 0]},
             "lights": [{"type": "directional", "direction": [-1, -2, -1], "intensity": [1, 1, 1]}],
             "shapes": [{"type": "terrain", "origin": [-50, -2, -50], "size": [100, 100],
                         "height": 8, "cells": [200, 200], "seed": 7}],
             "render": {"width": 2048, "height": 1536, "frames": {"start": 0, "count": 12}}}
    with LocalFarm(tmp_path, workers=0, coordinator_args=(
            "--worker-timeout", "1500", "--writer-threads", "1", "--exr-compression", "zip:9")) as farm:
        farm.add_worker("--coordinator-timeout", "1500")
        farm.wait_for_workers(1)
        job = farm.run_job(scene, strategy="exact", bin_width=12, timeout=120)
        assert job["frames"]["done"] == 12 and job["traced_pixel_ratio"] < 0.1
        assert "reconnecting" not in farm.worker_log(0).read_text()


def test_a_stopping_coordinator_says_goodbye_and_its_workers_reconnect_at_once(tmp_path):
    # Each side waits a minute for a silent peer: only the goodbye can tell the worker sooner.
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--worker-timeout", "60000")) as farm:
        worker = farm.add_worker("--coordinator-timeout", "60000")
        farm.wait_for_workers(1)
        farm.coordinator.send_signal(signal.SIGTERM)
        assert farm.coordinator.wait(timeout=10) == 0
        deadline = time.monotonic() + 10
        log = farm.worker_log(0)
        while "said goodbye; reconnecting" not in log.read_text():
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.05)
        assert "silent" not in log.read_text()
        assert worker.poll() is None, "a worker outlives its coordinator, reconnecting"


def test_a_stopping_worker_says_goodbye_and_leaves_the_farm_at_once(tmp_path):
    # The coordinator waits a minute for a silent worker: only the goodbye can tell it sooner.
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--worker-timeout", "60000")) as farm:
        worker = farm.add_worker()
        farm.wait_for_workers(1)
        worker.send_signal(signal.SIGTERM)
        assert worker.wait(timeout=10) == 0, farm.worker_log(0).read_text()
        deadline = time.monotonic() + 10
        while farm.client.workers()["workers"]:
            assert time.monotonic() < deadline, farm.client.workers()
            time.sleep(0.05)


def test_a_bad_scene_fails_the_request_not_the_farm(farm, twelve_spheres):
    bad = dict(twelve_spheres, shapes=[dict(twelve_spheres["shapes"][1], radius=-2)])
    with pytest.raises(ApiError) as error:
        farm.client.submit(bad)
    assert error.value.status == 400
    assert error.value.pointer == "/scene/shapes/0/radius"
    good = farm.client.submit(twelve_spheres, frames={"start": 0, "end": 2}, strategy="brute")
    assert farm.client.wait(good["id"], timeout=40)["state"] == "completed"


def test_hostile_messages_are_dropped_and_counted(farm, twelve_spheres):
    zmq = pytest.importorskip("zmq")
    context = zmq.Context()
    socket = context.socket(zmq.DEALER)
    socket.connect(farm.zmq)
    for message in ([b"garbage"], [b"\x01", b"\x03", b"\xff\xff", b""],
                    [b"\x09", b"\x01", b"", b""], [b"\x01", b"\x02", b"\x80", b"x" * 100]):
        socket.send_multipart(message)
    time.sleep(0.5)
    socket.close(linger=0)
    context.term()
    job = farm.run_job(twelve_spheres, frames={"start": 0, "end": 2}, strategy="brute")
    assert job["state"] == "completed"
    malformed = [line for line in farm.metrics().splitlines()
                 if line.startswith("tcfarm_messages_malformed_total")]
    assert malformed and float(malformed[0].split()[-1]) >= 4
