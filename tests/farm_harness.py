"""Starts real coordinator and worker processes on loopback for cross-process tests."""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
BUILD = pathlib.Path(os.environ.get("TCFARM_BUILD", ROOT / "build"))
COORDINATOR = BUILD / "coordinator" / "tcfarm-coordinator"
WORKER = BUILD / "worker" / "tcfarm-worker"
sys.path.insert(0, str(ROOT / "services" / "client"))

from tcfarm.client import Client  # noqa: E402


def wait_until(condition, what, timeout=300, poll=0.02):
    """Polls `condition` until it holds; fails naming `what` after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(poll)


class LocalFarm:
    """A coordinator on ephemeral loopback ports plus worker processes we control."""

    def __init__(self, directory, workers=2, worker_threads=1, local_workers=0,
                 coordinator_args=(), api_tokens=None):
        """api_tokens: {token: role} to start the coordinator with --api-tokens (self.client
        then uses the first admin token, self.tokens holds them all); None: no tokens."""
        self.directory = pathlib.Path(directory)
        self.tokens = dict(api_tokens or {})
        if api_tokens:
            tokens_file = self.directory / "api-tokens.txt"
            tokens_file.write_text("".join(f"{role} {token}\n" for token, role in self.tokens.items()))
            coordinator_args = (*coordinator_args, "--api-tokens", str(tokens_file))
        self.store = self.directory / "store"
        self.worker_threads = worker_threads
        self.workers = []
        self.coordinator = subprocess.Popen(
            [str(COORDINATOR), "serve", "--http", "127.0.0.1:0", "--zmq", "tcp://127.0.0.1:*",
             "--store", str(self.store), "--local-workers", str(local_workers),
             "--worker-threads", str(worker_threads), *coordinator_args],
            stdout=subprocess.PIPE, stderr=open(self.directory / "coordinator.log", "w"),
            text=True)
        line = self.coordinator.stdout.readline()
        match = re.search(r"http=(\S+) zmq=(\S+)", line)
        if not match:
            self.close()
            raise RuntimeError(f"coordinator did not start: {line!r}; see {self.directory}")
        self.url, self.zmq = match.group(1), match.group(2)
        self.token = next((t for t, role in self.tokens.items() if role == "admin"), None)
        self.client = Client(self.url, token=self.token)
        for _ in range(workers):
            self.add_worker()

    def add_worker(self, *extra_args):
        index = len(self.workers)
        process = subprocess.Popen(
            [str(WORKER), "serve", "--coordinator", self.zmq, "--threads",
             str(self.worker_threads), "--name", f"test-{index}", *extra_args],
            stdout=subprocess.DEVNULL, stderr=open(self.worker_log(index), "w"))
        self.workers.append(process)
        return process

    def worker_log(self, index):
        return self.directory / f"worker{index}.log"

    def add_worker_with_metrics(self, timeout=10):
        """Starts a worker serving /metrics on a free port; returns (process, base URL)."""
        index = len(self.workers)
        process = self.add_worker("--metrics", "127.0.0.1:0")
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            match = re.search(r"metrics on (http://\S+)/metrics", self.worker_log(index).read_text())
            if match:
                return process, match.group(1)
            if process.poll() is not None:
                break
            time.sleep(0.02)
        raise RuntimeError(f"worker {index} did not serve metrics; see {self.worker_log(index)}")

    def wait_for_workers(self, count, timeout=10):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if len(self.client.workers()["workers"]) >= count:
                return
            time.sleep(0.05)
        raise TimeoutError(f"fewer than {count} workers connected after {timeout} s")

    def run_job(self, scene, timeout=300, **options):
        """Submits a job, waits for it, and insists it completed."""
        job = self.client.submit(scene, **options)
        job = self.client.wait(job["id"], timeout=timeout)
        assert job["state"] == "completed", job
        return job

    def metrics(self):
        import urllib.request
        headers = {"Authorization": f"Bearer {self.token}"} if self.token else {}
        request = urllib.request.Request(self.url + "/metrics", headers=headers)
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.read().decode()

    def metric(self, name):
        """One unlabelled metric's value; fails when the coordinator does not export it."""
        match = re.search(rf"^{re.escape(name)} (\S+)$", self.metrics(), re.M)
        assert match, f"{name} is not exported"
        return float(match.group(1))

    def close(self):
        for process in self.workers + [self.coordinator]:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
        for process in self.workers + [self.coordinator]:
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def small_scene(path, width=160, height=120, frames=21):
    scene = json.loads(pathlib.Path(path).read_text())
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": frames})
    return scene


def render_reference(scene, directory):
    """The brute-force reference through the standalone renderer."""
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    scene_path = directory / "scene.json"
    scene_path.write_text(json.dumps(scene))
    subprocess.run([str(WORKER), "render", str(scene_path), "--out", str(directory / "frames"),
                    "--no-png"], check=True, capture_output=True, timeout=600)
    return directory / "frames"


def compare(reference_dir, test_dir):
    result = subprocess.run([str(COORDINATOR), "compare", str(reference_dir), str(test_dir),
                             "--json"], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def memory_bytes(pid, field):
    """VmHWM (peak resident) or VmRSS of a process, in bytes."""
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise AssertionError(f"/proc/{pid}/status has no {field}")


def reset_peak(pid):
    """Starts VmHWM afresh from VmRSS (Linux 4.0+), so a peak measured after is the caller's;
    returns that VmRSS."""
    with open(f"/proc/{pid}/clear_refs", "w") as clear_refs:
        clear_refs.write("5")
    return memory_bytes(pid, "VmRSS")


def differing_pixels(farm, reference, job, frames):
    """Pixels of the job's frames that differ from the reference renderer's; insists every
    one of its `frames` frames is there."""
    result = compare(reference, farm.store / str(job["id"]))
    assert result["frames"] == frames, result
    return result["differing_pixels"]


def tcfarm_cli(farm, *args, env=None):
    """The tcfarm command line against this farm, as a user runs it (with the farm's admin
    token in TCFARM_TOKEN when it has tokens, unless env says otherwise)."""
    given = dict(env or {})
    if farm.token and "TCFARM_TOKEN" not in given:
        given["TCFARM_TOKEN"] = farm.token
    env = dict(os.environ, PYTHONPATH=str(ROOT / "services" / "client"), **given)
    return subprocess.run([sys.executable, "-m", "tcfarm.cli", "--url", farm.url, *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=600)


def submit_file_and_compare(farm, path, flags, reference, strategy="exact"):
    """`tcfarm submit PATH FLAGS --wait` against `tcfarm-worker render PATH FLAGS` (written
    to `reference`). Returns the job record and the comparison; prints the job's
    traced-pixel ratio and the differing pixels."""
    rendered = subprocess.run([str(WORKER), "render", str(path), *map(str, flags), "--out", str(reference),
                               "--no-png"], capture_output=True, text=True, timeout=600)
    assert rendered.returncode == 0, rendered.stderr
    result = tcfarm_cli(farm, "--json", "submit", path, *flags, "--strategy", strategy, "--wait")
    assert result.returncode == 0, result.stderr
    job = json.loads(result.stdout.strip().splitlines()[-1])
    assert job["state"] == "completed", job
    error = compare(reference, farm.store / str(job["id"]))
    print(f"{pathlib.Path(path).name} {strategy}: traced-pixel ratio {job['traced_pixel_ratio']:.3f}, "
          f"{error['differing_pixels']} pixels differ in {error['frames']} frames")
    return job, error
