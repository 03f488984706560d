"""A real `tcfarm-worker serve` fetches texture images by hash from a fake coordinator that
speaks wire version 2 (proto/wire.md, section 7, "Assets"): what the worker asks for, what
it keeps in its cache, what it refuses, and what it answers for the tasks that wait.

The fake coordinator drives every step, so nothing here waits on a clock: a message the
worker must not send is shown absent by a later message it sends only after it would have
(one connection keeps order). Timeouts are generous limits, never assertions."""
import collections
import hashlib
import json
import pathlib
import random
import re
import signal
import struct
import subprocess
import sys
import time
import urllib.request

import msgpack
import pytest
import zmq

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "gltf"))
import make_gltf  # noqa: E402  (its PNG writer)
from farm_harness import WORKER  # noqa: E402
from test_assets import textured_scene  # noqa: E402

WIRE_VERSION = 2
READY, TASK, RESULT, SCENE_GET, SCENE, HEARTBEAT, ERROR, DISCONNECT, ASSET_GET, ASSET = range(1, 11)
NAMES = {1: "READY", 2: "TASK", 3: "RESULT", 4: "SCENE_GET", 5: "SCENE", 6: "HEARTBEAT", 7: "ERROR",
         8: "DISCONNECT", 9: "ASSET_GET", 10: "ASSET"}
# A limit on waiting for the worker, far beyond what any step takes on a loaded machine.
WAIT_S = 120
# The fake coordinator heartbeats this often unless a test silences it, far more often than
# the worker's coordinator timeout (5 s by default) needs.
HEARTBEAT_S = 0.25
ASSET_MAX_MIB = 1
# textured_scene's image is 64x48; the task covers a few spans of one frame.
WIDTH, HEIGHT, FRAME = 64, 48, 2
SPANS = [(0, 100), (1000, 1600), (3000, WIDTH * HEIGHT)]

Message = collections.namedtuple("Message", "command header payload")


def sha256(data):
    return hashlib.sha256(data).hexdigest()


def image(seed):
    """A PNG of its own for each seed, so each test's asset has a hash no other test fetched.
    Noise does not compress: a few KiB, enough for pieces and gaps of hundreds of bytes."""
    texels = random.Random(seed)
    rows = [[tuple(texels.randrange(256) for _ in range(3)) for _ in range(32)] for _ in range(32)]
    data = make_gltf.png_bytes(rows)
    assert len(data) > 2000
    return data


def scene_naming(asset, **material):
    """Scene JSON bytes whose texture is the asset named by hash, and their hash."""
    scene = textured_scene({"asset": asset, "filter": "nearest"})
    scene["materials"]["printed"].update(material)
    data = json_bytes(scene)
    return data, sha256(data)


def json_bytes(value):
    return json.dumps(value).encode()


def task_pixels():
    return [index for begin, end in SPANS for index in range(begin, end)]


class FakeCoordinator:
    """A ROUTER on loopback that speaks wire version 2 to one worker at a time. It keeps the
    worker's current connection alive with heartbeats while a test waits, unless silenced."""

    def __init__(self):
        self.context = zmq.Context()
        self.socket = self.context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        port = self.socket.bind_to_random_port("tcp://127.0.0.1")
        self.endpoint = f"tcp://127.0.0.1:{port}"
        self.worker = None  # the identity of the connection that said READY last
        self.silent = False
        self.last_heartbeat = 0.0
        self.heard = []  # every message but HEARTBEAT, in order

    def close(self):
        self.socket.close()
        self.context.term()

    def send(self, command, header, payload=b""):
        self.send_frames([bytes([WIRE_VERSION]), bytes([command]), msgpack.packb(header), payload])

    def send_frames(self, frames):
        self.socket.send_multipart([self.worker, *frames])

    def next(self, timeout=WAIT_S):
        """The worker's next message other than HEARTBEAT."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.poll(0.05)
            if message:
                return message
        raise TimeoutError(f"the worker said nothing in {timeout} s after {self.heard}")

    def expect(self, command):
        message = self.next()
        assert message.command == command, f"expected {NAMES[command]}, got {describe(message)}"
        return message

    def poll(self, seconds):
        """Heartbeats when due, then one message other than HEARTBEAT if one arrives in time."""
        now = time.monotonic()
        if self.worker and not self.silent and now - self.last_heartbeat >= HEARTBEAT_S:
            self.send(HEARTBEAT, {})
            self.last_heartbeat = now
        if not self.socket.poll(int(seconds * 1000)):
            return None
        identity, version, command, header, payload = self.socket.recv_multipart()
        assert version == bytes([WIRE_VERSION])
        message = Message(command[0], msgpack.unpackb(header), payload)
        if message.command in (HEARTBEAT, DISCONNECT):  # liveness; DISCONNECT: a worker stopped
            return None
        if message.command == READY:
            self.worker = identity
        self.heard.append(message)
        return message

    def wait_until(self, condition, what):
        """Keeps the worker's connection alive until condition() holds; no message may come."""
        deadline = time.monotonic() + WAIT_S
        while not condition():
            assert time.monotonic() < deadline, f"{what}: not after {WAIT_S} s"
            message = self.poll(0.05)
            assert message is None, f"while waiting for {what}, the worker said {describe(message)}"

    # What a coordinator says.

    def task(self, task_id, scene_hash):
        header = {"task_id": task_id, "job_id": 7, "scene_hash": scene_hash, "frame": FRAME,
                  "width": WIDTH, "height": HEIGHT, "window": 0}
        self.send(TASK, header, b"".join(struct.pack("<II", begin, end) for begin, end in SPANS))

    def scene(self, scene_json, scene_hash):
        get = self.expect(SCENE_GET)
        assert get.header["scene_hash"] == scene_hash
        self.send(SCENE, {"scene_hash": scene_hash}, scene_json)

    def asset_piece(self, asset, offset, total_size, data):
        self.send(ASSET, {"asset_hash": asset, "offset": offset, "total_size": total_size}, data)

    def asset(self, asset, data, pieces=3):
        """The asset in `pieces` pieces, in order of offset."""
        size = max(1, -(-len(data) // pieces))
        for offset in range(0, len(data), size):
            self.asset_piece(asset, offset, len(data), data[offset:offset + size])


def describe(message):
    return f"{NAMES.get(message.command, message.command)} {message.header}"


class Worker:
    def __init__(self, coordinator, cache, log, *extra):
        self.log = log
        self.process = subprocess.Popen(
            [str(WORKER), "serve", "--coordinator", coordinator.endpoint, "--asset-cache", str(cache),
             "--asset-max-mib", str(ASSET_MAX_MIB), "--threads", "1", "--name", "asset-fetch", *extra],
            stdout=subprocess.DEVNULL, stderr=open(log, "w"))
        coordinator.expect(READY)

    def alive(self):
        return self.process.poll() is None

    def stop(self):
        if self.alive():
            self.process.send_signal(signal.SIGTERM)
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()

    def metrics_url(self):
        match = re.search(r"metrics on (http://\S+/metrics)", self.log.read_text())
        return match and match.group(1)


@pytest.fixture
def coordinator():
    fake = FakeCoordinator()
    yield fake
    fake.close()


@pytest.fixture
def start_worker(coordinator, tmp_path):
    workers = []

    def start(cache, *extra):
        worker = Worker(coordinator, cache, tmp_path / f"worker{len(workers)}.log", *extra)
        workers.append(worker)
        return worker

    yield start
    for worker in workers:
        worker.stop()


@pytest.fixture
def cache(tmp_path):
    return tmp_path / "asset-cache"


def cached_files(cache):
    """Every file in the cache, the half-written ones included."""
    return sorted(str(p.relative_to(cache)) for p in cache.rglob("*") if p.is_file())


def exr_rgb(path):
    """The pixels of an uncompressed float RGB EXR (tcfarm-render --exr-compression none),
    12 bytes each (r, g, b), in pixel index order. Its scanline blocks end the file: per
    row, y and the byte count, then the row's B, G and R floats (channels sorted by name)."""
    data = path.read_bytes()
    row = 4 * WIDTH
    block = 8 + 3 * row
    blocks = data[len(data) - HEIGHT * block:]
    pixels = bytearray()
    for y in range(HEIGHT):
        line = blocks[y * block:(y + 1) * block]
        assert struct.unpack("<ii", line[:8]) == (y, 3 * row), "not an uncompressed float RGB EXR"
        b, g, r = (line[8 + c * row:8 + (c + 1) * row] for c in range(3))
        for x in range(0, row, 4):
            pixels += r[x:x + 4] + g[x:x + 4] + b[x:x + 4]
    return bytes(pixels)


def reference_rgb(texture, directory):
    """The task's pixels as `tcfarm-worker render` traces the scene with the image as a file."""
    directory.mkdir()
    (directory / "texture.png").write_bytes(texture)
    (directory / "scene.json").write_bytes(json_bytes(textured_scene({"image": "texture.png", "filter": "nearest"})))
    rendered = subprocess.run(
        [str(WORKER), "render", str(directory / "scene.json"), "--frames", str(FRAME), "--out",
         str(directory / "frames"), "--no-png", "--exr-compression", "none", "--threads", "1"],
        capture_output=True, text=True, timeout=600)
    assert rendered.returncode == 0, rendered.stderr
    frame = exr_rgb(directory / "frames" / f"frame_{FRAME:04d}.exr")
    return b"".join(frame[12 * index:12 * index + 12] for index in task_pixels())


def check_result(message, task_id, reference=None):
    assert message.command == RESULT, describe(message)
    assert message.header["task_id"] == task_id and message.header["frame"] == FRAME
    assert message.header["pixel_count"] == len(task_pixels())
    if reference is not None:
        assert message.payload == reference, "the traced pixels differ from tcfarm-worker render's"


def fetch_and_trace(coordinator, texture, task_ids, pieces=3):
    """Tasks for a fresh scene naming `texture`, the scene, the one ASSET_GET answered in
    pieces; returns the RESULTs."""
    asset = sha256(texture)
    scene_json, scene_hash = scene_naming(asset)
    for task_id in task_ids:
        coordinator.task(task_id, scene_hash)
    coordinator.scene(scene_json, scene_hash)
    assert coordinator.expect(ASSET_GET).header == {"asset_hash": asset}
    coordinator.asset(asset, texture, pieces)
    return [coordinator.next() for _ in task_ids]


def test_a_texture_is_fetched_once_in_pieces_and_traced_as_from_a_file(coordinator, start_worker, cache, tmp_path):
    texture = image(0)
    reference = reference_rgb(texture, tmp_path / "reference")
    asset = sha256(texture)
    scene_json, scene_hash = scene_naming(asset)
    start_worker(cache)
    coordinator.task(1, scene_hash)
    coordinator.task(2, scene_hash)
    coordinator.scene(scene_json, scene_hash)
    assert coordinator.expect(ASSET_GET).header == {"asset_hash": asset}
    coordinator.task(3, scene_hash)  # arrives while the scene waits for its texture
    coordinator.asset(asset, texture, pieces=4)
    for task_id in (1, 2, 3):
        check_result(coordinator.next(), task_id, reference)
    assert [NAMES[m.command] for m in coordinator.heard] == ["READY", "SCENE_GET", "ASSET_GET"] + ["RESULT"] * 3
    assert (cache / asset).read_bytes() == texture
    assert cached_files(cache) == [asset]


def test_a_cached_texture_is_not_fetched_again(coordinator, start_worker, cache, tmp_path):
    texture = image(1)
    reference = reference_rgb(texture, tmp_path / "reference")
    asset = sha256(texture)
    worker = start_worker(cache)
    (result,) = fetch_and_trace(coordinator, texture, [1])
    check_result(result, 1, reference)
    fetched = len(coordinator.heard)
    # Another scene with the same image: built at once from the cache.
    other_json, other_hash = scene_naming(asset, diffuse=[0.5, 1, 1])
    assert other_hash != scene_naming(asset)[1]
    coordinator.task(2, other_hash)
    coordinator.scene(other_json, other_hash)
    check_result(coordinator.next(), 2)
    # A new worker process on the same folder finds it there too.
    worker.stop()
    start_worker(cache)
    scene_json, scene_hash = scene_naming(asset)
    coordinator.task(3, scene_hash)
    coordinator.scene(scene_json, scene_hash)
    check_result(coordinator.next(), 3, reference)
    assert [NAMES[m.command] for m in coordinator.heard[fetched:]] == ["SCENE_GET", "RESULT", "READY", "SCENE_GET",
                                                                        "RESULT"]
    assert cached_files(cache) == [asset]


def assert_tasks_failed_naming(coordinator, asset, task_ids, reason):
    for task_id in task_ids:
        error = coordinator.expect(ERROR)
        assert error.header["task_id"] == task_id
        assert asset in error.header["message"], error.header
        assert re.search(reason, error.header["message"]), error.header


def serve_after_failure(coordinator, worker, cache, texture, task_id):
    """The worker lives on: the next task for the scene fetches the asset afresh and is traced."""
    assert worker.alive()
    (result,) = fetch_and_trace(coordinator, texture, [task_id])
    check_result(result, task_id)
    assert cached_files(cache) == [sha256(texture)]


def start_failing_download(coordinator, texture, task_ids):
    """Tasks for a scene naming texture, up to the worker's ASSET_GET; returns the hash."""
    asset = sha256(texture)
    scene_json, scene_hash = scene_naming(asset)
    for task_id in task_ids:
        coordinator.task(task_id, scene_hash)
    coordinator.scene(scene_json, scene_hash)
    assert coordinator.expect(ASSET_GET).header == {"asset_hash": asset}
    return asset


def test_a_piece_after_a_gap_fails_the_waiting_tasks(coordinator, start_worker, cache):
    texture = image(2)
    worker = start_worker(cache)
    asset = start_failing_download(coordinator, texture, [1, 2])
    coordinator.asset_piece(asset, 0, len(texture), texture[:100])
    coordinator.asset_piece(asset, 150, len(texture), texture[150:])
    assert_tasks_failed_naming(coordinator, asset, [1, 2], r"piece at byte 150 where byte 100 was due")
    assert cached_files(cache) == []
    serve_after_failure(coordinator, worker, cache, texture, 3)


def test_bytes_that_do_not_hash_to_the_name_fail_the_waiting_tasks(coordinator, start_worker, cache):
    texture = image(3)
    worker = start_worker(cache)
    asset = start_failing_download(coordinator, texture, [1, 2])
    forged = texture[:-1] + bytes([texture[-1] ^ 1])
    coordinator.asset(asset, forged)
    assert_tasks_failed_naming(coordinator, asset, [1, 2], "hash to " + sha256(forged))
    assert cached_files(cache) == []
    serve_after_failure(coordinator, worker, cache, texture, 3)


def test_an_asset_over_the_workers_limit_fails_the_waiting_tasks(coordinator, start_worker, cache):
    texture = image(4)
    worker = start_worker(cache)
    asset = start_failing_download(coordinator, texture, [1, 2])
    coordinator.asset_piece(asset, 0, ASSET_MAX_MIB * 2**20 + 1, texture)
    assert_tasks_failed_naming(coordinator, asset, [1, 2], "--asset-max-mib")
    assert cached_files(cache) == []
    serve_after_failure(coordinator, worker, cache, texture, 3)


def test_an_error_naming_the_asset_fails_the_waiting_tasks(coordinator, start_worker, cache):
    texture = image(5)
    worker = start_worker(cache)
    asset = start_failing_download(coordinator, texture, [1, 2])
    coordinator.asset_piece(asset, 0, len(texture), texture[:100])  # a download under way, too
    coordinator.send(ERROR, {"task_id": 0, "scene_hash": "", "message": "unreadable on this farm",
                             "asset_hash": asset})
    assert_tasks_failed_naming(coordinator, asset, [1, 2], "unreadable on this farm")
    assert cached_files(cache) == []
    serve_after_failure(coordinator, worker, cache, texture, 3)


def test_pieces_nobody_asked_for_are_ignored(coordinator, start_worker, cache):
    unasked = image(6)
    worker = start_worker(cache)
    coordinator.asset(sha256(unasked), unasked)
    # A download under way is no licence for pieces of other assets either.
    texture = image(7)
    asset = start_failing_download(coordinator, texture, [1])
    coordinator.asset(sha256(unasked), unasked)
    coordinator.asset(asset, texture)
    check_result(coordinator.next(), 1)  # the unasked pieces came first, on the same connection
    assert worker.alive()
    assert cached_files(cache) == [asset]


def malformed_count(url):
    with urllib.request.urlopen(url, timeout=30) as response:
        text = response.read().decode()
    return float(re.search(r"^tcfarm_worker_messages_malformed_total (\S+)$", text, re.M).group(1))


def test_malformed_asset_messages_are_dropped_and_counted(coordinator, start_worker, cache):
    worker = start_worker(cache, "--metrics", "127.0.0.1:0")
    coordinator.wait_until(worker.metrics_url, "the worker's metrics address in its log")
    url = worker.metrics_url()
    before = malformed_count(url)
    texture = image(8)
    asset = start_failing_download(coordinator, texture, [1])
    bad = [
        {"asset_hash": asset, "offset": 0, "total_size": 10},                # 20 bytes past total_size
        {"asset_hash": asset.upper(), "offset": 0, "total_size": len(texture)},  # not lowercase hex
        {"asset_hash": asset[:63], "offset": 0, "total_size": len(texture)},     # too short
        {"asset_hash": asset, "offset": len(texture), "total_size": len(texture)},  # past the end
    ]
    payloads = [texture[:20], texture, texture, texture[:1]]
    for fields, payload in zip(bad, payloads):
        coordinator.send_frames([bytes([WIRE_VERSION]), bytes([ASSET]), msgpack.packb(fields), payload])
    coordinator.wait_until(lambda: malformed_count(url) >= before + len(bad), "the malformed messages counted")
    assert malformed_count(url) == before + len(bad)
    assert worker.alive() and cached_files(cache) == []
    # Dropped, not taken for pieces: the download goes on from byte 0.
    coordinator.asset(asset, texture)
    check_result(coordinator.next(), 1)
    assert cached_files(cache) == [asset]


def test_a_reconnect_drops_a_download_under_way(coordinator, start_worker, cache):
    texture = image(9)
    # Long enough that only the silence below makes the worker reconnect.
    worker = start_worker(cache, "--coordinator-timeout", "3000")
    asset = start_failing_download(coordinator, texture, [1])
    coordinator.asset_piece(asset, 0, len(texture), texture[:100])
    old_connection = coordinator.worker
    coordinator.silent = True  # the worker takes the coordinator for gone and says READY anew
    coordinator.expect(READY)
    coordinator.silent = False
    assert coordinator.worker != old_connection
    # The rest of the old download, on the new connection: nobody asked for it there.
    coordinator.asset_piece(asset, 100, len(texture), texture[100:])
    scene_json, scene_hash = scene_naming(asset)
    coordinator.task(2, scene_hash)
    coordinator.scene(scene_json, scene_hash)  # task 1 went with the old connection
    assert cached_files(cache) == []
    assert coordinator.expect(ASSET_GET).header == {"asset_hash": asset}
    coordinator.asset(asset, texture)
    check_result(coordinator.next(), 2)
    assert worker.alive() and cached_files(cache) == [asset]
