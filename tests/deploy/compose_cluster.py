"""Drives the docker-compose cluster (docker-compose.yml) for tests: a uniquely named
project on free host ports, with the engine, Compose and the base image made ready by
deploy/ensure-docker."""
import json
import os
import re
import shutil
import socket
import subprocess
import time
import uuid

import requests

from farm_harness import ROOT


def free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def compose_command():
    """`docker compose` where the plugin exists, else Debian's `docker-compose`."""
    if subprocess.run(["docker", "compose", "version"], capture_output=True).returncode == 0:
        return ["docker", "compose"]
    if shutil.which("docker-compose"):
        return ["docker-compose"]
    raise RuntimeError("neither `docker compose` nor `docker-compose` is installed")


def ensure_docker():
    result = subprocess.run(["bash", str(ROOT / "deploy" / "ensure-docker")], capture_output=True,
                            text=True, timeout=1800)
    if result.returncode != 0:
        raise RuntimeError("deploy/ensure-docker failed:\n" + result.stdout + result.stderr)


# Project names carry the test process's pid, so a later run can tell the projects of
# runs that died before tearing down (their containers restart with the engine) from
# those of a run still going.
PROJECT_PREFIX = "tcfarmtest"
PROJECT_NAME = re.compile(PROJECT_PREFIX + r"(\d+)x[0-9a-f]{8}")


def process_exists(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def compose_projects():
    """Every Compose project name with a container, network or volume in the engine."""
    label = '{{.Label "com.docker.compose.project"}}'
    names = set()
    for listing in (["ps", "-a"], ["network", "ls"], ["volume", "ls"]):
        result = docker(*listing, "--filter", "label=com.docker.compose.project", "--format", label)
        if result.returncode != 0:
            raise RuntimeError(f"docker {' '.join(listing)} failed: {result.stderr}")
        names.update(result.stdout.split())
    return names


def remove_stale_projects():
    """Takes down what test runs that were killed mid-way left in the engine."""
    for project in sorted(compose_projects()):
        match = PROJECT_NAME.fullmatch(project)
        if match and not process_exists(int(match.group(1))):
            subprocess.run(compose_command() + ["-f", str(ROOT / "docker-compose.yml"), "-p", project,
                                                "down", "-v", "--remove-orphans"],
                           cwd=ROOT, capture_output=True, text=True, timeout=300, check=True)


class ComposeCluster:
    def __init__(self, log_dir):
        self.log_dir = log_dir
        self.project = f"{PROJECT_PREFIX}{os.getpid()}x{uuid.uuid4().hex[:8]}"
        self.http_port = free_port()
        self.prometheus_port = free_port()
        self.url = f"http://127.0.0.1:{self.http_port}"
        self.prometheus = f"http://127.0.0.1:{self.prometheus_port}"
        self.env = dict(os.environ, TCFARM_HTTP_PORT=str(self.http_port),
                        TCFARM_PROMETHEUS_PORT=str(self.prometheus_port))
        self.base = compose_command() + ["-f", str(ROOT / "docker-compose.yml"), "-p", self.project]

    def run(self, *args, timeout=600, check=True):
        result = subprocess.run(self.base + list(args), cwd=ROOT, env=self.env, capture_output=True,
                                text=True, timeout=timeout)
        if check and result.returncode != 0:
            raise RuntimeError(f"{' '.join(args)} failed ({result.returncode}):\n"
                               f"{result.stdout[-4000:]}\n{result.stderr[-4000:]}")
        return result.stdout

    def build(self):
        # Both tcfarm images come from one Dockerfile: built one after the other, the
        # second reuses the first's build stage from the engine's layer cache.
        for service in ("coordinator", "worker", "prometheus"):
            self.run("build", service, timeout=3600)

    def up(self, workers):
        self.run("up", "-d", "--scale", f"worker={workers}", timeout=600)

    def down(self):
        (self.log_dir / "compose.log").write_text(self.run("logs", "--no-color", check=False))
        self.run("down", "-v", "--remove-orphans", check=False)

    def api_tokens(self):
        """{role: token} of the tokens the coordinator made at its first start."""
        text = self.run("exec", "-T", "coordinator", "cat", "/var/lib/tcfarm-tokens/api-tokens")
        return {role: token for role, token in
                (line.split() for line in text.splitlines() if line.strip() and not line.startswith("#"))}

    def containers(self, service):
        return self.run("ps", "-q", service).split()

    def running_containers(self, service):
        running = []
        for container in self.containers(service):
            state = inspect(container)["State"]
            if state["Running"]:
                running.append(container)
        return running

    def wait_http(self, url, timeout=120):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                if requests.get(url, timeout=2).status_code == 200:
                    return
            except requests.RequestException:
                pass
            time.sleep(0.5)
        raise TimeoutError(f"{url} did not answer 200 within {timeout} s")

    def prometheus_query(self, expr):
        response = requests.get(self.prometheus + "/api/v1/query", params={"query": expr}, timeout=10)
        body = response.json()
        assert body["status"] == "success", (expr, body)
        return body["data"]["result"]


def inspect(container):
    result = subprocess.run(["docker", "inspect", container], capture_output=True, text=True,
                            check=True, timeout=30)
    return json.loads(result.stdout)[0]


def docker(*args, timeout=120):
    return subprocess.run(["docker", *args], capture_output=True, text=True, timeout=timeout)
