"""A worker told to stop (SIGTERM) while it builds a huge scene stops at once instead of
finishing the build first; a worker whose job is canceled mid-build gives the build up;
and stopping builds changes nothing in what workers render. Real coordinator and worker
processes on loopback."""
import re
import signal
import subprocess
import time

import pytest
import requests

from farm_harness import ROOT, LocalFarm, compare, render_reference, small_scene, wait_until

# Two terrains of 1600 x 1600 cells: 10 million triangles, a few lines of JSON. Building
# their trees takes far longer than the bound below (40 s on two busy cores); parsing the
# scene takes no time, so the build is under way soon after the worker gets the scene.
HUGE_SCENE = {
    "camera": {"position": [0, 20, 60], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [10, 50, 10], "intensity": [500, 500, 500]}],
    "shapes": [{"type": "terrain", "origin": [-50 + 12 * i, -2, -50], "size": [100, 100],
                "height": 8, "cells": [1600, 1600], "seed": i} for i in range(2)],
    "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 1}},
}
# A liveness bound, not a speed figure: without the stop the worker would sit in the build.
EXIT_BOUND_S = 5


def worker_counter(url, name):
    text = requests.get(url + "/metrics", timeout=10).text
    match = re.search(rf"^{re.escape(name)} (\S+)$", text, re.M)
    assert match, f"{name} is not exported"
    return float(match.group(1))


@pytest.fixture
def farm(tmp_path):
    with LocalFarm(tmp_path, workers=0, worker_threads=2) as farm:
        yield farm


def start_huge_build(farm):
    """A worker with metrics, in the middle of building HUGE_SCENE: (process, url, job id)."""
    worker, url = farm.add_worker_with_metrics()
    farm.wait_for_workers(1)
    job = farm.client.submit(HUGE_SCENE, strategy="brute")
    wait_until(lambda: worker_counter(url, "tcfarm_worker_scene_cache_misses_total") >= 1,
               "the worker to ask for the scene", timeout=30)
    wait_until(lambda: worker_counter(url, "tcfarm_worker_scene_builds") == 1,
               "the worker to start building the scene", timeout=30)
    time.sleep(0.5)
    # Still building: nothing traced, nothing failed.
    assert worker_counter(url, "tcfarm_worker_scene_builds") == 1
    assert worker_counter(url, "tcfarm_worker_tasks_total") == 0
    assert worker_counter(url, "tcfarm_worker_scene_errors_total") == 0
    return worker, url, job["id"]


def test_sigterm_stops_a_worker_in_the_middle_of_a_scene_build(farm):
    worker, _, _ = start_huge_build(farm)
    worker.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    try:
        worker.wait(timeout=EXIT_BOUND_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the worker still runs {EXIT_BOUND_S} s after SIGTERM, in the middle of a scene build")
    print(f"worker exited {time.monotonic() - sent:.2f} s after SIGTERM, mid-build")
    assert worker.returncode == 0, farm.worker_log(0).read_text()
    assert farm.metric("tcfarm_task_results_total") == 0


def test_canceling_the_job_stops_the_build_of_its_scene(farm):
    worker, url, job_id = start_huge_build(farm)
    farm.client.cancel(job_id)
    canceled = time.monotonic()
    wait_until(lambda: worker_counter(url, "tcfarm_worker_scene_builds") == 0,
               "the worker to give up the build of the canceled job's scene", timeout=EXIT_BOUND_S)
    print(f"build given up {time.monotonic() - canceled:.2f} s after the cancel")
    assert worker.poll() is None  # the worker lives on
    assert worker_counter(url, "tcfarm_worker_scene_errors_total") == 0  # giving up is no failure
    assert worker_counter(url, "tcfarm_worker_tasks_total") == 0


def test_a_worker_that_can_stop_its_builds_renders_as_the_reference_does(farm, tmp_path):
    farm.add_worker()
    farm.wait_for_workers(1)
    scene = small_scene(ROOT / "tests" / "scenes" / "paper_b_twelve_spheres.json", 96, 72, 4)
    job = farm.run_job(scene, strategy="brute")
    error = compare(render_reference(scene, tmp_path / "reference"), farm.store / str(job["id"]))
    assert error["frames"] == 4
    assert error["differing_pixels"] == 0
