"""Who may work for the farm (proto/wire.md, sections 5, 6 and 10): CurveZMQ keys made by
`keygen`, a coordinator that lets in only the workers on its allow-list, and tasks whose
RESULT or ERROR counts only from the worker they were given to.

Rogue workers are pyzmq DEALERs that speak the wire protocol (the constants and message
shape of test_asset_fetch.py) but trace nothing. Timeouts are generous limits, never
assertions."""
import re
import shutil
import struct
import subprocess
import threading
import time

import msgpack
import pytest
import zmq

from farm_harness import COORDINATOR, WORKER, LocalFarm, compare, render_reference, small_scene
from test_asset_fetch import ERROR, HEARTBEAT, READY, RESULT, TASK, WIRE_VERSION

WAIT_S = 120


def keygen(program, directory, name):
    result = subprocess.run([str(program), "keygen", "--out", str(directory), "--name", name],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return directory / f"{name}.key", directory / f"{name}.pub"


def read_key(path):
    """The key in a key file, as keygen writes it (comments start with #)."""
    [key] = [line.strip() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    return key


@pytest.fixture
def keys(tmp_path):
    """The coordinator's pair, an allow-list folder with one worker's public key, and a
    second worker pair that is not on it."""
    secret, public = keygen(COORDINATOR, tmp_path / "coordinator", "coordinator")
    allowed = tmp_path / "allowed"
    allowed.mkdir()
    worker_secret, worker_public = keygen(WORKER, tmp_path / "worker", "worker")
    shutil.copy(worker_public, allowed / "worker.pub")
    unlisted_secret, unlisted_public = keygen(WORKER, tmp_path / "unlisted", "unlisted")
    return {"secret": secret, "public": public, "allowed": allowed, "worker": worker_secret,
            "unlisted": unlisted_secret, "unlisted_public": unlisted_public}


def coordinator_keys(keys):
    return ("--curve-secret", str(keys["secret"]), "--worker-keys", str(keys["allowed"]))


def worker_keys(keys, secret):
    return ("--curve-secret", str(secret), "--coordinator-key", str(keys["public"]))


def labelled(metrics, name, **labels):
    text = ",".join(f'{k}="{v}"' for k, v in labels.items())
    match = re.search(rf"^{re.escape(name)}{{{re.escape(text)}}} (\S+)$", metrics, re.M)
    assert match, f"{name}{{{text}}} is not exported"
    return float(match.group(1))


def counter(metrics, name):
    match = re.search(rf"^{re.escape(name)} (\S+)$", metrics, re.M)
    assert match, f"{name} is not exported"
    return float(match.group(1))


def wait_for(condition, what, timeout=WAIT_S):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"{what}: not after {timeout} s"
        time.sleep(0.05)


class RogueWorker(threading.Thread):
    """A DEALER that never traces. It says READY (unless ready=False), answers every TASK it
    is given with ERROR, and with guess=True keeps sending grey RESULTs and ERRORs for task
    ids it guesses (they are sequential from 1), and for each task it failed, again and
    again for a while: the coordinator gives that task to another worker, and some of these
    replies arrive while that worker holds it. `curve`: (secret key file, coordinator's
    public key file), or none for no CURVE at all."""

    GUESSED_IDS = 400
    REPLY_TO_FAILED_SECONDS = 2.0

    def __init__(self, endpoint, curve=None, ready=True, guess=False):
        super().__init__(daemon=True)
        self.endpoint, self.curve, self.ready, self.guess = endpoint, curve, ready, guess
        self.received = []  # the command of every message the coordinator sent it
        self.tasks = 0
        self.stop = threading.Event()

    def run(self):
        context = zmq.Context()
        socket = context.socket(zmq.DEALER)
        socket.linger = 0
        if self.curve:
            secret_file, server_file = self.curve
            secret = read_key(secret_file).encode()
            socket.curve_secretkey = secret
            socket.curve_publickey = zmq.curve_public(secret)
            socket.curve_serverkey = read_key(server_file).encode()
        socket.connect(self.endpoint)
        if self.ready:
            self.send(socket, READY, {"capacity": 4, "threads": 1, "name": "rogue"})
        guess, last_heartbeat = 1, 0.0
        failed = {}  # task id -> until when its replies go on
        while not self.stop.is_set():
            if socket.poll(20):
                version, command, header, payload = socket.recv_multipart()
                self.received.append(command[0])
                if command[0] == TASK:
                    self.tasks += 1
                    task = msgpack.unpackb(header)
                    self.send(socket, ERROR, {"task_id": task["task_id"], "scene_hash": task["scene_hash"],
                                              "message": "this worker fails every task"})
                    if self.guess:  # the task now goes to another worker: answer it anyway
                        failed[task["task_id"]] = time.monotonic() + self.REPLY_TO_FAILED_SECONDS
            if self.guess:
                now = time.monotonic()
                for task_id, until in list(failed.items()):
                    if now < until:
                        self.send_guesses(socket, task_id)
                    else:
                        del failed[task_id]
                for _ in range(20):
                    self.send_guesses(socket, guess)
                    guess = guess % self.GUESSED_IDS + 1
            if time.monotonic() - last_heartbeat > 0.5:
                self.send(socket, HEARTBEAT, {})
                last_heartbeat = time.monotonic()
        socket.close()
        context.term()

    def send_guesses(self, socket, task_id):
        grey = struct.pack("<3f", 0.5, 0.5, 0.5)
        self.send(socket, RESULT, {"task_id": task_id, "job_id": 1, "frame": 0, "pixel_count": 1,
                                   "has_horizons": False, "trace_seconds": 0.0, "primary_rays": 1,
                                   "shadow_rays": 0, "reflection_rays": 0, "refraction_rays": 0}, grey)
        self.send(socket, ERROR, {"task_id": task_id, "scene_hash": "", "message": "guessed"})

    @staticmethod
    def send(socket, command, header, payload=b""):
        try:
            socket.send_multipart([bytes([WIRE_VERSION]), bytes([command]), msgpack.packb(header), payload],
                                  zmq.NOBLOCK)
        except zmq.Again:  # not connected (refused): nothing to send to
            pass

    def close(self):
        self.stop.set()
        self.join(timeout=30)


@pytest.fixture(scope="module")
def scene(scenes_dir):
    return small_scene(scenes_dir / "paper_a_one_sphere.json", width=96, height=72, frames=8)


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory):
    return render_reference(scene, tmp_path_factory.mktemp("reference"))


def run_and_compare(farm, scene, reference, **options):
    job = farm.run_job(scene, strategy="brute", **options)
    error = compare(reference, farm.store / str(job["id"]))
    print(f"job {job['id']}: {error['differing_pixels']} pixels differ in {error['frames']} frames")
    return error


# --- keys and flags -----------------------------------------------------------------------

def test_keygen_writes_a_private_secret_and_keeps_existing_files(tmp_path):
    secret, public = keygen(COORDINATOR, tmp_path, "c")
    assert secret.stat().st_mode & 0o777 == 0o600
    assert len(read_key(secret)) == 40 and len(read_key(public)) == 40
    again = subprocess.run([str(COORDINATOR), "keygen", "--out", str(tmp_path), "--name", "c"],
                           capture_output=True, text=True, timeout=60)
    assert again.returncode == 1 and "--force" in again.stderr, again.stderr
    assert read_key(public) == read_key(tmp_path / "c.pub")


def refused_start(program, *args):
    result = subprocess.run([str(program), "serve", *map(str, args)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, (result.returncode, result.stderr)
    return result.stderr


def test_flags_that_cannot_be_used_are_refused_naming_them(keys, tmp_path):
    store = tmp_path / "store"
    assert "--insecure-no-auth" in refused_start(COORDINATOR, "--zmq", "tcp://*:0", "--store", store)
    assert "without --worker-keys" in refused_start(COORDINATOR, "--curve-secret", keys["secret"], "--store", store)
    bad = tmp_path / "bad.key"
    bad.write_text("# not a key\nshort\n")
    message = refused_start(COORDINATOR, "--curve-secret", bad, "--worker-keys", keys["allowed"], "--store", store)
    assert f"{bad} line 2" in message
    assert "not a folder" in refused_start(COORDINATOR, *coordinator_keys(keys)[:2], "--worker-keys",
                                           tmp_path / "nowhere", "--store", store)
    assert "without --coordinator-key" in refused_start(WORKER, "--curve-secret", keys["worker"])
    assert str(bad) in refused_start(WORKER, "--curve-secret", keys["worker"], "--coordinator-key", bad)


def test_insecure_no_auth_starts_beyond_loopback(tmp_path):
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--zmq", "tcp://0.0.0.0:*", "--insecure-no-auth")):
        pass
    assert "--insecure-no-auth: any process" in (tmp_path / "coordinator.log").read_text()


# --- CURVE ----------------------------------------------------------------------------------

def test_only_listed_workers_get_tasks_and_the_job_is_bit_identical(keys, scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        assert "public key is " + read_key(keys["public"]) in (tmp_path / "coordinator.log").read_text()
        without_keys = RogueWorker(farm.zmq)
        unlisted = RogueWorker(farm.zmq, curve=(keys["unlisted"], keys["public"]))
        wrong_server_key = RogueWorker(farm.zmq, curve=(keys["worker"], keys["unlisted_public"]))
        rogues = [without_keys, unlisted, wrong_server_key]
        for rogue in rogues:
            rogue.start()
        farm.add_worker(*worker_keys(keys, keys["worker"]))
        farm.wait_for_workers(1, timeout=WAIT_S)
        wait_for(lambda: labelled(farm.metrics(), "tcfarm_workers_refused_total", reason="key_not_allowed") >= 1
                 and labelled(farm.metrics(), "tcfarm_workers_refused_total", reason="handshake_failed") >= 2,
                 "the rogues refused")
        error = run_and_compare(farm, scene, reference)
        for rogue in rogues:
            rogue.close()
        metrics = farm.metrics()
        print("refused:", labelled(metrics, "tcfarm_workers_refused_total", reason="key_not_allowed"), "by key,",
              labelled(metrics, "tcfarm_workers_refused_total", reason="handshake_failed"), "in the handshake")
        assert error["differing_pixels"] == 0
        for rogue in rogues:
            assert rogue.received == [], "a refused worker heard from the coordinator"
        assert [w["name"] for w in farm.client.workers()["workers"]] == ["test-0"]
        assert "refused worker key " + read_key(keys["unlisted_public"]) in (tmp_path / "coordinator.log").read_text()


def reconnect_delays(log):
    return [int(ms) for ms in re.findall(r"refused this worker: .*; reconnecting in (\d+) ms", log)]


def test_a_refused_worker_backs_off_and_joins_once_its_key_is_listed(keys, scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        farm.add_worker(*worker_keys(keys, keys["unlisted"]))
        wait_for(lambda: len(reconnect_delays(farm.worker_log(0).read_text())) >= 3, "three refusals")
        assert farm.client.workers()["workers"] == []
        shutil.copy(keys["unlisted_public"], keys["allowed"] / "second.pub")  # no restart
        farm.wait_for_workers(1, timeout=WAIT_S)
        delays = reconnect_delays(farm.worker_log(0).read_text())
        print("reconnect delays after refusals (ms):", delays)
        # Each refusal waits longer than the one before (0.5 s doubling, up to 8 s): no spinning.
        assert delays[:3] == [500, 1000, 2000]
        assert "the key was refused" in farm.worker_log(0).read_text()
        assert run_and_compare(farm, scene, reference)["differing_pixels"] == 0


def test_local_workers_get_keys_of_their_own(keys, scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=0, local_workers=2, coordinator_args=coordinator_keys(keys)) as farm:
        farm.wait_for_workers(2, timeout=WAIT_S)
        # A key each: a ban of one local worker is not a ban of the other.
        principals = [w["principal"] for w in farm.client.workers()["workers"]]
        assert len(set(principals)) == 2 and all(p.startswith("key:") for p in principals), principals
        assert run_and_compare(farm, scene, reference)["differing_pixels"] == 0


# --- tasks belong to their worker -----------------------------------------------------------

def test_replies_for_guessed_task_ids_change_nothing(scenes_dir, tmp_path):
    # Tasks that take the honest worker tens of milliseconds: the rogue's replies for the
    # tasks it failed reach the coordinator while the honest worker holds them.
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", width=256, height=192, frames=8)
    scene["render"]["samples_per_pixel"] = 4
    reference = render_reference(scene, tmp_path / "reference")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=1) as farm:
        farm.wait_for_workers(1)
        rogue = RogueWorker(farm.zmq, guess=True)
        rogue.start()
        farm.wait_for_workers(2)
        error = run_and_compare(farm, scene, reference)
        rogue.close()
        metrics = farm.metrics()
        foreign = counter(metrics, "tcfarm_task_replies_foreign_total")
        print(f"rogue: {rogue.tasks} tasks given, all answered ERROR; {foreign:.0f} replies for "
              f"other workers' tasks dropped")
        assert error["differing_pixels"] == 0
        assert foreign > 0


def test_a_worker_that_fails_every_task_does_not_fail_the_job(scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=0) as farm:
        rogue = RogueWorker(farm.zmq)
        rogue.start()
        farm.wait_for_workers(1)
        job = farm.client.submit(scene, strategy="brute")
        # Alone, it fails tasks that then wait for a different worker: the job waits too.
        wait_for(lambda: rogue.tasks >= 1, "a task for the failing worker")
        assert farm.client.job(job["id"])["state"] == "running"
        farm.add_worker()
        job = farm.client.wait(job["id"], timeout=300)
        rogue.close()
        assert job["state"] == "completed", job
        retried = counter(farm.metrics(), "tcfarm_task_errors_retried_total")
        print(f"failing worker: {rogue.tasks} tasks, {retried:.0f} sent on to another worker")
        assert retried >= 1
        error = compare(reference, farm.store / str(job["id"]))
        assert error["differing_pixels"] == 0
