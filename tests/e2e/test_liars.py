"""Trust nobody, not even a worker with a key. A liar here is a ZeroMQ peer that says READY
with a large capacity, so that it takes every task it can, and answers each at once with
grey pixels: well-formed results with wrong values. It may hold a CURVE key that the
coordinator allows, and it may reconnect on a new socket (a new identity) again and again.

What must hold, whatever the liar does (the farm's rules: proto/wire.md, section 11):
- the coordinator's referee traces a secret share of every value a worker sends: the liar
  is caught by it, and its job is repaired, never reported verified with wrong pixels;
- a liar is banned by its key, so a new connection does not make it someone else; the ban
  outlives the coordinator and an admin can lift it;
- `exact` and `brute` end with 0 pixels differing from `tcfarm-worker render`; `search`
  repairs the frames the liar's traces reached.
Timeouts are generous limits, never assertions."""
import struct
import threading
import time

import msgpack
import pytest
import zmq

from farm_harness import LocalFarm, differing_pixels, render_reference, small_scene
from test_asset_fetch import DISCONNECT, HEARTBEAT, READY, RESULT, TASK, WIRE_VERSION
from test_worker_auth import coordinator_keys, keygen, keys, read_key, wait_for, worker_keys  # noqa: F401

WAIT_S = 300
FRAMES = 10


class Liar(threading.Thread):
    """Answers every TASK with grey. reconnect_s: opens a new socket (a new identity at the
    coordinator) this often, and on every DISCONNECT. curve: (secret key file, the
    coordinator's public key file)."""

    def __init__(self, endpoint, curve=None, reconnect_s=None, name="liar"):
        super().__init__(daemon=True)
        self.endpoint, self.curve, self.reconnect_s, self.name = endpoint, curve, reconnect_s, name
        self.context = zmq.Context()
        self.answered = 0
        self.connections = 0
        self.stopping = threading.Event()

    def connect(self):
        socket = self.context.socket(zmq.DEALER)
        socket.linger = 0
        if self.curve:
            secret = read_key(self.curve[0]).encode()
            socket.curve_secretkey = secret
            socket.curve_publickey = zmq.curve_public(secret)
            socket.curve_serverkey = read_key(self.curve[1]).encode()
        socket.connect(self.endpoint)
        self.connections += 1
        self.send(socket, READY, {"capacity": 64, "threads": 16, "name": self.name})
        return socket

    @staticmethod
    def send(socket, command, header, payload=b""):
        try:
            socket.send_multipart([bytes([WIRE_VERSION]), bytes([command]), msgpack.packb(header), payload],
                                  zmq.NOBLOCK)
        except zmq.Again:
            pass

    def answer(self, socket, header, payload):
        spans = struct.unpack("<%dI" % (len(payload) // 4), payload)
        pixels = sum(end - begin for begin, end in zip(spans[0::2], spans[1::2]))
        rgb = struct.pack("<%df" % (3 * pixels), *([0.5] * 3 * pixels))
        horizons = struct.pack("<%di" % pixels, *([header["frame"] + 1] * pixels)) if header["window"] else b""
        self.send(socket, RESULT, {"task_id": header["task_id"], "job_id": header["job_id"],
                                   "frame": header["frame"], "pixel_count": pixels,
                                   "has_horizons": bool(header["window"]), "trace_seconds": 0.001,
                                   "primary_rays": pixels, "shadow_rays": 0, "reflection_rays": 0,
                                   "refraction_rays": 0}, rgb + horizons)
        self.answered += 1

    def run(self):
        socket = self.connect()
        connected_at = last_sent = time.monotonic()
        while not self.stopping.is_set():
            reconnect = self.reconnect_s and time.monotonic() - connected_at > self.reconnect_s
            if socket.poll(20):
                frames = socket.recv_multipart()
                if len(frames) == 4 and frames[1][0] == TASK:
                    self.answer(socket, msgpack.unpackb(frames[2]), frames[3])
                elif len(frames) >= 2 and frames[1][0] == DISCONNECT:
                    reconnect = True
            if reconnect:
                socket.close()
                socket = self.connect()
                connected_at = time.monotonic()
            if time.monotonic() - last_sent > 0.5:
                self.send(socket, HEARTBEAT, {})
                last_sent = time.monotonic()
        socket.close()

    def stop(self):
        self.stopping.set()
        self.join(timeout=30)
        self.context.term()


@pytest.fixture(scope="module")
def scene(scenes_dir):
    return small_scene(scenes_dir / "paper_b_twelve_spheres.json", width=64, height=48, frames=FRAMES)


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory):
    return render_reference(scene, tmp_path_factory.mktemp("reference"))


def differing(farm, reference, job):
    return differing_pixels(farm, reference, job, FRAMES)


@pytest.mark.parametrize("strategy", ["exact", "brute"])
def test_a_liar_alone_is_caught_by_the_referee_and_its_job_repaired(strategy, scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=0) as farm:
        liar = Liar(farm.zmq)
        liar.start()
        try:
            farm.wait_for_workers(1)
            job = farm.client.submit(scene, strategy=strategy)
            # Alone, it is checked by the referee, caught and banned, and what it traced is
            # repaired by the referee: the job completes only with the referee's values.
            wait_for(lambda: farm.client.distrusted_workers(), "the liar banned", timeout=WAIT_S)
        finally:
            liar.stop()
        alone = farm.client.job(job["id"])
        if alone["state"] == "running":
            farm.add_worker()  # tasks it held when banned wait for an honest worker
        job = farm.client.wait(job["id"], timeout=WAIT_S)
        error = job["stats"]["error"]
        print(f"{strategy}: liar answered {liar.answered} tasks; checked by {error['checked_by']}; "
              f"audit {error['audit']}")
        assert job["state"] == "completed", job
        assert liar.answered > 0, "the liar was given no task"
        assert error["referee_sample"]["pixels_wrong"] > 0, error
        assert error["audit"]["workers_distrusted"] == ["liar"], error
        assert error["audit"]["repairs_owed"] == 0, error
        assert differing(farm, reference, job) == 0
        assert [b["name"] for b in farm.client.distrusted_workers()] == ["liar"]


@pytest.mark.parametrize("strategy", ["exact", "brute"])
def test_a_keyed_liar_that_reconnects_is_banned_by_its_key(strategy, keys, scene, reference, tmp_path):
    liar_secret, liar_public = keygen(__import__("farm_harness").WORKER, tmp_path / "liar", "liar")
    (keys["allowed"] / "liar.pub").write_text(liar_public.read_text())
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        liar = Liar(farm.zmq, curve=(liar_secret, keys["public"]), reconnect_s=0.3)
        liar.start()
        try:
            farm.wait_for_workers(1)
            farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(2)
            job = farm.run_job(scene, strategy=strategy, timeout=WAIT_S)
            answered = liar.answered
            # It goes on reconnecting under new identities: nothing more comes to it.
            after = farm.run_job(scene, strategy=strategy, timeout=WAIT_S)
            assert liar.answered == answered
        finally:
            liar.stop()
        audit = job["stats"]["error"].get("audit")
        print(f"{strategy}: liar answered {answered} tasks over {liar.connections} connections; audit {audit}")
        assert answered > 0 and liar.connections > 2
        assert audit["workers_distrusted"] == ["liar"], audit  # the honest worker never is
        assert audit["repairs_owed"] == 0, audit
        assert differing(farm, reference, job) == 0
        assert differing(farm, reference, after) == 0
        banned = farm.client.distrusted_workers()
        assert [b["principal"] for b in banned] == ["key:" + read_key(liar_public)], banned


def test_a_ban_outlives_the_coordinator_and_an_admin_lifts_it(keys, scene, tmp_path):
    liar_secret, liar_public = keygen(__import__("farm_harness").WORKER, tmp_path / "liar", "liar")
    (keys["allowed"] / "liar.pub").write_text(liar_public.read_text())
    principal = "key:" + read_key(liar_public)
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        liar = Liar(farm.zmq, curve=(liar_secret, keys["public"]))
        liar.start()
        try:
            farm.wait_for_workers(1)
            farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(2)
            farm.run_job(scene, strategy="exact", timeout=WAIT_S)
        finally:
            liar.stop()
    tokens = {"admin-token-0123456789abcdef": "admin", "read-token-0123456789abcdef0": "read"}
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys), api_tokens=tokens) as farm:
        liar = Liar(farm.zmq, curve=(liar_secret, keys["public"]))
        liar.start()
        try:
            time.sleep(1)  # time enough to say READY: it is not let in
            assert farm.client.workers()["workers"] == []
            assert [b["principal"] for b in farm.client.distrusted_workers()] == [principal]
            reader = type(farm.client)(farm.url, token="read-token-0123456789abcdef0")
            with pytest.raises(Exception) as refused:
                reader.lift_ban(principal)
            assert getattr(refused.value, "status", None) == 403, refused.value
            farm.client.lift_ban(principal)
            assert farm.client.distrusted_workers() == []
            with pytest.raises(Exception) as unknown:
                farm.client.lift_ban(principal)
            assert getattr(unknown.value, "status", None) == 404, unknown.value
        finally:
            liar.stop()
        # Lifted: the same key is heard again on its next connection. The farm takes a lift
        # in at its next turn, so a READY that comes sooner is still refused: the liar
        # connects anew every second, as a worker refused would, until it is heard.
        again = Liar(farm.zmq, curve=(liar_secret, keys["public"]), reconnect_s=1)
        again.start()
        try:
            farm.wait_for_workers(1)
        finally:
            again.stop()


def test_search_repairs_what_a_liar_traced(scene, reference, tmp_path):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        honest = farm.run_job(scene, strategy="search", bin_width=4)
        liar = Liar(farm.zmq)
        liar.start()
        try:
            farm.wait_for_workers(2)
            job = farm.run_job(scene, strategy="search", bin_width=4, timeout=WAIT_S)
        finally:
            liar.stop()
        error = job["stats"]["error"]
        print(f"search: liar answered {liar.answered} tasks; referee sample {error['referee_sample']}; "
              f"audit {error.get('audit')}")
        assert liar.answered > 0
        assert error["referee_sample"]["pixels_wrong"] > 0, error
        assert error["audit"]["workers_distrusted"] == ["liar"], error
        assert error["audit"]["repairs_owed"] == 0, error
        # Repaired frames are traced in full: never more wrong than search on an honest farm.
        assert differing(farm, reference, job) <= differing(farm, reference, honest)
