"""`exact` promises 0 wrong pixels, so it checks itself loudly: a worker that returns wrong
values (here a ZeroMQ peer that says READY and answers every task with grey) is caught by
exact's own checks (spot checks of copied pixels, its brute-force reference frame), and the
job record and /metrics say the job is suspect. An honest farm's job is not."""
import pathlib
import re
import struct
import threading
import time

import msgpack
import pytest
import zmq

from farm_harness import LocalFarm, small_scene
from test_asset_fetch import HEARTBEAT, READY, RESULT, TASK, WIRE_VERSION
SCENE = pathlib.Path(__file__).resolve().parents[1] / "scenes" / "paper_b_twelve_spheres.json"


class LyingWorker(threading.Thread):
    """Says READY and answers every TASK at once with grey pixels and horizons of the next
    frame: well-formed results with wrong values."""

    def __init__(self, endpoint):
        super().__init__(daemon=True)
        self.socket = zmq.Context.instance().socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.connect(endpoint)
        self.answered = 0
        self.stopping = threading.Event()

    def send(self, command, header, payload=b""):
        self.socket.send_multipart([bytes([WIRE_VERSION]), bytes([command]), msgpack.packb(header), payload])

    def answer(self, header, payload):
        spans = struct.unpack("<%dI" % (len(payload) // 4), payload)
        pixels = sum(end - begin for begin, end in zip(spans[0::2], spans[1::2]))
        rgb = struct.pack("<%df" % (3 * pixels), *([0.5] * 3 * pixels))
        horizons = struct.pack("<%di" % pixels, *([header["frame"] + 1] * pixels)) if header["window"] else b""
        self.send(RESULT, {"task_id": header["task_id"], "job_id": header["job_id"], "frame": header["frame"],
                           "pixel_count": pixels, "has_horizons": bool(header["window"]),
                           "trace_seconds": 0.001, "primary_rays": pixels, "shadow_rays": 0,
                           "reflection_rays": 0, "refraction_rays": 0}, rgb + horizons)
        self.answered += 1

    def run(self):
        self.send(READY, {"capacity": 4, "threads": 1, "name": "liar"})
        last_sent = time.monotonic()
        while not self.stopping.is_set():
            if self.socket.poll(200):
                frames = self.socket.recv_multipart()
                if len(frames) == 4 and frames[1][0] == TASK:
                    self.answer(msgpack.unpackb(frames[2]), frames[3])
                    last_sent = time.monotonic()
            if time.monotonic() - last_sent > 1:
                self.send(HEARTBEAT, {})
                last_sent = time.monotonic()

    def stop(self):
        self.stopping.set()
        self.join(timeout=10)
        self.socket.close()


def metric(farm, name):
    match = re.search(r"^%s (\S+)$" % name, farm.metrics(), re.M)
    assert match, f"{name} is not exported"
    return float(match.group(1))


def test_exact_marks_a_job_suspect_when_a_worker_lies(tmp_path):
    scene = small_scene(SCENE, width=64, height=48, frames=12)
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        honest = farm.run_job(scene, strategy="exact")
        assert "suspect" not in honest["stats"]["error"], honest["stats"]["error"]
        liar = LyingWorker(farm.zmq)
        liar.start()
        try:
            farm.wait_for_workers(2)
            job = farm.run_job(scene, strategy="exact", spot_check_share=0.02)
        finally:
            liar.stop()
        assert liar.answered > 0, "the lying worker was given no task"
        suspect = job["stats"]["error"].get("suspect")
        print(f"lying worker answered {liar.answered} tasks; suspect: {suspect}")
        assert suspect and suspect["pixels_disagreeing"] > 0, job["stats"]["error"]
        assert suspect["frames"], suspect
        assert metric(farm, "tcfarm_suspect_jobs_total") == 1
        assert metric(farm, "tcfarm_suspect_pixels_total") == suspect["pixels_disagreeing"]
