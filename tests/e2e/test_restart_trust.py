"""A restart is not evidence. No liar here: one honest worker (a worker process, or the
coordinator's own local worker) and a job of each strategy; the coordinator is killed with
SIGKILL mid-job and a new one started on the same store, with new worker processes (the new
coordinator listens on new ports); with keys, the new worker is the same principal as the
one before. The frames kept from the first run were traced for a
coordinator that is gone, and the checks, disputes and the referee's unseen sample of the
second run meet them: none of that may ban anyone.

What must hold: nobody is banned, the job completes, `exact`, `brute` and `auto` with 0
pixels differing from `tcfarm-worker render`, and `search` and `guarded` with no more than
the same job on a farm never restarted, within a small tolerance. Timeouts are generous
limits, never assertions."""
import signal

import pytest

from farm_harness import LocalFarm, differing_pixels, render_reference, small_scene, wait_until
from tcfarm.client import FINAL_STATES
from test_worker_auth import coordinator_keys, keys, worker_keys  # noqa: F401

WAIT_S = 400
WIDTH, HEIGHT, FRAMES = 160, 120, 30
BIN_WIDTH = 6
# search and guarded: pixels a resumed job may differ by beyond the job never restarted.
TOLERANCE = WIDTH * HEIGHT // 100


@pytest.fixture(scope="module")
def scene(scenes_dir):
    return small_scene(scenes_dir / "paper_b_twelve_spheres.json", width=WIDTH, height=HEIGHT, frames=FRAMES)


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory):
    return render_reference(scene, tmp_path_factory.mktemp("reference"))


def differing(farm, reference, job):
    return differing_pixels(farm, reference, job, FRAMES)


def farm_of(directory, worker, keys):
    """A farm on `directory`'s store with one honest worker: a worker process ("process"), the
    coordinator's own local worker ("local"), or a worker process with a key of its own on a
    farm that authenticates keys ("keyed": the same principal before and after the restart)."""
    if worker == "local":
        return LocalFarm(directory, workers=0, local_workers=1)
    if worker == "keyed":
        farm = LocalFarm(directory, workers=0, coordinator_args=coordinator_keys(keys))
        farm.add_worker(*worker_keys(keys, keys["worker"]))
        return farm
    return LocalFarm(directory, workers=1)


def options_for(strategy):
    return {} if strategy in ("brute", "auto") else {"bin_width": BIN_WIDTH}


def kill_mid_job(farm, job_id):
    """SIGKILL as soon as the job reports a frame done; returns the frames done then."""
    seen = {}

    def some_done():
        job = farm.client.job(job_id)
        seen.update(done=job["frames"]["done"], state=job["state"])
        return job["frames"]["done"] > 0 or job["state"] in FINAL_STATES

    wait_until(some_done, "a frame done", timeout=WAIT_S)
    farm.coordinator.send_signal(signal.SIGKILL)
    farm.coordinator.wait()
    assert seen["state"] not in FINAL_STATES and seen["done"] < FRAMES, f"not mid-job when killed: {seen}"
    return seen["done"]


@pytest.mark.parametrize("strategy,worker", [("exact", "process"), ("brute", "process"), ("search", "process"),
                                             ("guarded", "process"), ("auto", "process"), ("exact", "local"),
                                             ("guarded", "local"), ("exact", "keyed"), ("auto", "keyed")])
def test_a_coordinator_killed_mid_job_and_restarted_bans_nobody_and_completes_the_job(
        strategy, worker, keys, scene, reference, tmp_path):
    with farm_of(tmp_path, worker, keys) as farm:
        farm.wait_for_workers(1, timeout=60)
        job = farm.client.submit(scene, strategy=strategy, **options_for(strategy))
        done = kill_mid_job(farm, job["id"])
    (tmp_path / "coordinator.log").rename(tmp_path / "coordinator-killed.log")

    with farm_of(tmp_path, worker, keys) as farm:  # the same store, new ports, new workers
        farm.wait_for_workers(1, timeout=60)
        resumed = farm.client.wait(job["id"], timeout=WAIT_S)
        stats = resumed["stats"]
        sample = stats["error"]["referee_sample"]
        print(f"{strategy} ({worker} worker): killed with {done} of {FRAMES} frames done; "
              f"{resumed['state']}, resumed_frames {stats.get('resumed_frames')}; referee sample "
              f"sampled {sample['pixels_sampled']}, wrong {sample['pixels_wrong']}, "
              f"caught {sample['workers_caught']}; audit {stats['error'].get('audit')}")
        bans = farm.client.distrusted_workers()
        assert bans == [], f"an honest worker is banned after a restart: {bans}; error {stats['error']}"
        assert resumed["state"] == "completed", resumed
        assert sample["pixels_wrong"] == 0, stats["error"]
        assert stats["resumed_frames"] < FRAMES, stats
        wrong = differing(farm, reference, resumed)
        if strategy in ("search", "guarded"):
            uninterrupted = farm.run_job(scene, strategy=strategy, timeout=WAIT_S, **options_for(strategy))
            bound = differing(farm, reference, uninterrupted)
            print(f"{strategy}: {wrong} pixels differ; {bound} in the same job never restarted")
            assert wrong <= bound + TOLERANCE, stats["error"]
        else:
            print(f"{strategy}: {wrong} pixels differ")
            assert wrong == 0, stats["error"]
        assert farm.client.distrusted_workers() == []
