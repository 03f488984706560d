"""The docker-compose cluster, for real: images built from deploy/Dockerfile, a coordinator
and three worker containers finding each other by service name, Prometheus scraping them,
the 12-sphere animation submitted over the published HTTP port, one worker killed mid-job.

Needs root (or sudo) on Debian 12: deploy/ensure-docker installs Docker and Compose from
Debian's packages when missing, starts dockerd, and bootstraps debian:bookworm-slim when no
registry is reachable. Set TCFARM_SKIP_DOCKER=1 to leave this module out on a machine that
cannot run containers."""
import json
import os
import re
import subprocess
import time

import pytest
import requests

from compose_cluster import ComposeCluster, docker, ensure_docker, inspect, remove_stale_projects
from farm_harness import ROOT, Client, compare, render_reference

if os.environ.get("TCFARM_SKIP_DOCKER") == "1":
    pytest.skip("TCFARM_SKIP_DOCKER=1", allow_module_level=True)

SCENE = ROOT / "tests" / "scenes" / "paper_b_twelve_spheres.json"
DASHBOARD = ROOT / "deploy" / "grafana" / "dashboards" / "tcfarm.json"
WORKERS = 3


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    ensure_docker()
    remove_stale_projects()
    cluster = ComposeCluster(tmp_path_factory.mktemp("compose"))
    cluster.build()
    try:
        cluster.up(WORKERS)
        cluster.wait_http(cluster.url + "/healthz")
        cluster.tokens = cluster.api_tokens()
        yield cluster
    finally:
        cluster.down()


@pytest.fixture(scope="module")
def scene():
    return json.loads(SCENE.read_text())


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory):
    return render_reference(scene, tmp_path_factory.mktemp("reference"))


def wait_for(condition, what, timeout=60, interval=0.5):
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what}: not within {timeout} s")
        time.sleep(interval)


def busy_worker_container(client, containers):
    for worker in client.workers()["workers"]:
        if worker["in_flight"] > 0:
            host = worker["name"].rsplit(":", 1)[0]
            for container in containers:
                if container.startswith(host):
                    return container
    return None


@pytest.fixture(scope="module")
def finished_job(cluster, scene, reference, tmp_path_factory):
    """The animation rendered by the cluster while one worker container is killed."""
    client = Client(cluster.url, token=cluster.tokens["admin"])
    wait_for(lambda: len(client.workers()["workers"]) >= WORKERS, f"{WORKERS} workers connected")
    # Listed before the job starts: asking docker takes longer than the job may last.
    containers = cluster.running_containers("worker")
    job = client.submit(scene, strategy="exact")
    # The victim is a worker holding tasks (its name is its container's hostname, the
    # container id's first 12 digits, a colon and its pid): its work must be taken back.
    # Picked as soon as one holds any: on a fast machine the job may be over before long.
    victim = wait_for(lambda: busy_worker_container(client, containers), "a worker holding tasks",
                      timeout=300, interval=0.01)
    assert client.job(job["id"])["state"] == "running", "the job ended before a worker was killed"
    assert docker("kill", "--signal", "KILL", victim).returncode == 0
    job = client.wait(job["id"], timeout=900)
    frames = tmp_path_factory.mktemp("cluster-frames")
    for frame in range(job["frames"]["start"], job["frames"]["end"] + 1):
        (frames / f"frame_{frame:04d}.exr").write_bytes(client.frame(job["id"], frame, "exr"))
    return {"job": job, "frames": frames, "victim": victim, "client": client}


def test_cluster_renders_the_animation_bit_identical_despite_a_killed_worker(
        cluster, finished_job, reference):
    job = finished_job["job"]
    assert job["state"] == "completed", job
    assert job["frames"]["done"] == job["frames"]["count"] == 60
    error = compare(reference, finished_job["frames"])
    assert error["frames"] == 60
    assert error["differing_pixels"] == 0, error
    # The killed worker held tasks: they were taken back and traced elsewhere.
    metrics = requests.get(cluster.url + "/metrics", timeout=10,
                           headers={"Authorization": f"Bearer {cluster.tokens['read']}"}).text
    requeued = float(re.search(r"^tcfarm_tasks_requeued_total (\S+)$", metrics, re.M).group(1))
    assert requeued >= 1
    pixels = job["width"] * job["height"] * job["frames"]["count"]
    assert job["pixels_traced"] + job["pixels_copied"] == pixels, job
    assert job["pixels_traced"] < 0.5 * pixels, job  # exact reuses most pixels


def test_images_run_unprivileged_without_compilers_and_report_healthy(cluster, finished_job):
    containers = cluster.running_containers("coordinator") + cluster.running_containers("worker")
    assert len(containers) >= WORKERS  # the coordinator and the surviving workers
    for container in containers:
        assert docker("exec", container, "id", "-u").stdout.strip() == "10001"
        compilers = docker("exec", container, "sh", "-c", "command -v cc gcc g++ c++ clang")
        assert compilers.stdout.strip() == "", compilers.stdout
    wait_for(lambda: all(inspect(c)["State"].get("Health", {}).get("Status") == "healthy"
                         for c in containers), "every container healthy", timeout=90)


def prometheus_targets(cluster):
    body = requests.get(cluster.prometheus + "/api/v1/targets", timeout=10).json()
    return body["data"]["activeTargets"]


def test_prometheus_scrapes_the_coordinator_and_every_live_worker(cluster, finished_job):
    cluster.wait_http(cluster.prometheus + "/-/ready")
    live_workers = len(cluster.running_containers("worker"))

    def all_targets_up():
        targets = prometheus_targets(cluster)
        jobs = [t["labels"]["job"] for t in targets]
        return (jobs.count("tcfarm-coordinator") == 1 and jobs.count("tcfarm-worker") == live_workers
                and all(t["health"] == "up" for t in targets))
    wait_for(all_targets_up, "coordinator and live workers scraped and up", timeout=90)

    # Prometheus holds the farm's figures from both kinds of target, once scraped after the job.
    def scalar(expr):
        result = cluster.prometheus_query(expr)
        return float(result[0]["value"][1]) if result else 0.0
    job = finished_job["job"]
    wait_for(lambda: scalar("tcfarm_pixels_traced_total") >= job["pixels_traced"],
             "the job's traced pixels in Prometheus", timeout=60)
    wait_for(lambda: scalar('sum(tcfarm_worker_rays_total{type="primary"})') > 0,
             "the workers' rays in Prometheus", timeout=60)
    assert scalar("tcfarm_workers_live") == live_workers


def metric_names(expr):
    return set(re.findall(r"\b(tcfarm_[a-z_]+|up)\b", expr))


def test_grafana_dashboard_queries_what_the_farm_exports(cluster, finished_job):
    dashboard = json.loads(DASHBOARD.read_text())
    datasource = (ROOT / "deploy" / "grafana" / "provisioning" / "datasources" / "prometheus.yml")
    uid = re.search(r"uid:\s*(\S+)", datasource.read_text()).group(1)
    assert dashboard["uid"] and dashboard["title"] and dashboard["panels"]
    wait_for(lambda: cluster.prometheus_query("tcfarm_worker_tasks_total"), "worker samples")
    exported = set(requests.get(cluster.prometheus + "/api/v1/label/__name__/values",
                                timeout=10).json()["data"])
    ids = [panel["id"] for panel in dashboard["panels"]]
    assert len(ids) == len(set(ids)), "panel ids repeat"
    used = set()
    for panel in dashboard["panels"]:
        assert panel["datasource"]["uid"] == uid, panel["title"]
        assert panel["targets"], panel["title"]
        for target in panel["targets"]:
            names = metric_names(target["expr"])
            assert names, (panel["title"], target["expr"])
            missing = {name for name in names if name not in exported}
            assert not missing, f"panel {panel['title']!r} queries {missing}, not exported"
            cluster.prometheus_query(target["expr"])  # valid PromQL, or the query fails
            used |= names
    # The coherence figures a user opens the dashboard for are all on it.
    for name in ("tcfarm_pixels_traced_total", "tcfarm_pixels_copied_total", "tcfarm_traced_pixel_ratio",
                 "tcfarm_worker_rays_total", "tcfarm_worker_rays_per_second",
                 "tcfarm_worker_scene_cache_hits_total", "tcfarm_spot_check_mismatches_total"):
        assert name in used, name


def test_the_api_and_dashboard_are_published(cluster):
    page = requests.get(cluster.url + "/", timeout=10)
    assert page.status_code == 200 and "<html" in page.text.lower()
    chart = requests.get(cluster.url + "/node_modules/chart.js/dist/chart.umd.js", timeout=10)
    assert chart.status_code == 200 and len(chart.content) > 100_000
    anonymous = requests.post(cluster.url + "/api/v1/jobs", json={"scene": {"camera": 1}}, timeout=10)
    assert anonymous.status_code == 401 and anonymous.json()["error"]["code"] == "unauthorized"
    assert requests.get(cluster.url + "/metrics", timeout=10).status_code == 401
    bad = requests.post(cluster.url + "/api/v1/jobs", json={"scene": {"camera": 1}}, timeout=10,
                        headers={"Authorization": f"Bearer {cluster.tokens['admin']}"})
    assert bad.status_code == 400
    assert bad.json()["error"]["code"] == "invalid_scene"


def test_workers_authenticate_with_keys_made_at_first_start(cluster):
    """`keys` made the pairs into their volumes; the coordinator serves CURVE with them, its
    secret private to its user, and the workers, holding theirs, connected."""
    logs = cluster.run("logs", "--no-color", "coordinator")
    assert "workers authenticate with CURVE" in logs, logs[-2000:]
    client = Client(cluster.url, token=cluster.tokens["read"])
    wait_for(lambda: len(client.workers()["workers"]) >= 1, "a worker with keys connected")
    coordinator = cluster.containers("coordinator")[0]
    secret = docker("exec", coordinator, "stat", "-c", "%a %u", "/etc/tcfarm/keys/coordinator.key")
    assert secret.stdout.split() == ["600", "10001"], secret.stderr
    # Each worker enrolled a key of its own: a ban of one is not a ban of the pool.
    live = len(cluster.running_containers("worker"))
    wait_for(lambda: len(client.workers()["workers"]) >= live, "every live worker connected")
    principals = [w["principal"] for w in client.workers()["workers"]]
    assert len(set(principals)) == len(principals) >= live, principals
    assert all(p.startswith("key:") for p in principals), principals
