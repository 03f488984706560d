"""A worker's own /metrics and /healthz, served by `tcfarm-worker serve --metrics`, through
real processes: what it reports must agree with the work the coordinator gave it."""
import re
import shutil
import subprocess
import time

import pytest
import requests

from farm_harness import ROOT, WORKER, LocalFarm, small_scene

SCENE = ROOT / "tests" / "scenes" / "paper_b_twelve_spheres.json"
WIDTH, HEIGHT, FRAMES = 160, 120, 6


def parse_metrics(text):
    """{'name{labels}': value} for every sample line."""
    samples = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            name, value = line.rsplit(" ", 1)
            samples[name] = float(value)
    return samples


def scrape(url):
    response = requests.get(url + "/metrics", timeout=10)
    assert response.status_code == 200
    assert response.headers["Content-Type"].startswith("text/plain")
    return response.text


@pytest.fixture
def farm(tmp_path):
    with LocalFarm(tmp_path, workers=0, worker_threads=2) as farm:
        yield farm


def test_worker_metrics_count_the_work_it_was_given(farm):
    _, url = farm.add_worker_with_metrics()
    farm.wait_for_workers(1)
    scene = small_scene(SCENE, WIDTH, HEIGHT, FRAMES)
    farm.run_job(scene, strategy="brute")

    text = scrape(url)
    worker = parse_metrics(text)
    coordinator = parse_metrics(farm.metrics())
    pixels = WIDTH * HEIGHT * FRAMES
    assert worker["tcfarm_worker_pixels_total"] == pixels
    assert worker["tcfarm_worker_tasks_total"] == coordinator["tcfarm_task_results_total"]
    # One sample per pixel; every camera hit on a Phong sphere or the floor casts a shadow ray
    # toward the one light; nothing in this scene reflects or refracts.
    assert worker['tcfarm_worker_rays_total{type="primary"}'] == pixels
    assert 0 < worker['tcfarm_worker_rays_total{type="shadow"}'] <= pixels
    assert worker['tcfarm_worker_rays_total{type="reflection"}'] == 0
    assert worker['tcfarm_worker_rays_total{type="refraction"}'] == 0
    assert worker["tcfarm_worker_rays_per_second"] > 0
    assert worker["tcfarm_worker_trace_seconds_total"] > 0
    assert worker["tcfarm_worker_trace_cpu_seconds_total"] > 0
    assert worker["tcfarm_worker_coordinator_up"] == 1
    assert worker["tcfarm_worker_threads"] == 2
    # The scene is fetched once; tasks that arrive while it is being fetched wait for it.
    assert worker["tcfarm_worker_scene_cache_misses_total"] == 1
    tasks = worker["tcfarm_worker_tasks_total"]
    assert worker["tcfarm_worker_scene_cache_hits_total"] >= tasks - 3

    # A second job on the same scene is served from the cache.
    farm.run_job(scene, strategy="brute")
    again = parse_metrics(scrape(url))
    assert again["tcfarm_worker_scene_cache_misses_total"] == 1
    assert again["tcfarm_worker_scene_cache_hits_total"] > worker["tcfarm_worker_scene_cache_hits_total"]
    assert again["tcfarm_worker_pixels_total"] == 2 * pixels

    if shutil.which("promtool"):
        check = subprocess.run(["promtool", "check", "metrics"], input=text, text=True,
                               capture_output=True, timeout=30)
        assert check.returncode == 0, check.stdout + check.stderr


def wait_for_health(url, coordinator, timeout=15):
    """The worker's /healthz once it reports the coordinator as `coordinator`."""
    deadline = time.monotonic() + timeout
    while True:
        health = requests.get(url + "/healthz", timeout=10)
        if health.json()["coordinator"] == coordinator or time.monotonic() > deadline:
            return health
        time.sleep(0.1)


def test_worker_health_follows_the_coordinator(farm):
    process, url = farm.add_worker_with_metrics()
    # Connected once the coordinator has said something (its first heartbeat at the latest).
    health = wait_for_health(url, "connected")
    assert health.status_code == 200
    assert health.json() == {"status": "ok", "coordinator": "connected"}
    assert parse_metrics(scrape(url))["tcfarm_worker_coordinator_up"] == 1

    farm.coordinator.terminate()
    farm.coordinator.wait(timeout=10)
    # The worker process itself is fine, still serving, and says what is wrong.
    health = wait_for_health(url, "unreachable")
    assert health.status_code == 200
    assert health.json() == {"status": "ok", "coordinator": "unreachable"}
    assert parse_metrics(scrape(url))["tcfarm_worker_coordinator_up"] == 0
    assert process.poll() is None


@pytest.mark.parametrize("address, problem", [
    ("9100", "expected HOST:PORT"),
    ("127.0.0.1:70000", "port from 0 to 65535"),
    ("127.0.0.1:http", "expected HOST:PORT"),
])
def test_bad_metrics_address_is_refused_clearly(address, problem):
    result = subprocess.run([str(WORKER), "serve", "--metrics", address], capture_output=True,
                            text=True, timeout=10)
    assert result.returncode == 2
    assert re.search(rf"--metrics {re.escape(address)}: .*{re.escape(problem)}", result.stderr), \
        result.stderr


def test_metrics_port_taken_fails_at_start(farm):
    _, url = farm.add_worker_with_metrics()
    port = url.rsplit(":", 1)[1]
    result = subprocess.run([str(WORKER), "serve", "--coordinator", farm.zmq, "--metrics",
                             f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=10)
    assert result.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port}" in result.stderr
