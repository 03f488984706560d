"""`exact` promises 0 wrong pixels, so it checks itself loudly: a worker that returns wrong
values (here a ZeroMQ peer that says READY and answers every task with grey) is caught by
exact's own checks (spot checks of copied pixels, its brute-force reference frame), and the
job record and /metrics say the job is suspect. The coordinator traces the disputed pixels
itself, distrusts the liar (it gets no more tasks) and has every frame its values reached
traced again by the honest worker: the job's frames end bit-identical to brute force. An
honest farm's job is not suspect."""
import pathlib
import struct
import threading
import time

import msgpack
import pytest
import zmq

from farm_harness import LocalFarm, compare, render_reference, small_scene
from test_asset_fetch import DISCONNECT, HEARTBEAT, READY, RESULT, TASK, WIRE_VERSION
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
        self.disconnects = 0
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
                elif len(frames) >= 2 and frames[1][0] == DISCONNECT:
                    # Told to go: it says READY again at once, as a stubborn liar would.
                    self.disconnects += 1
                    self.send(READY, {"capacity": 4, "threads": 1, "name": "liar"})
            if time.monotonic() - last_sent > 1:
                self.send(HEARTBEAT, {})
                last_sent = time.monotonic()

    def stop(self):
        self.stopping.set()
        self.join(timeout=10)
        self.socket.close()


def test_exact_marks_a_job_suspect_when_a_worker_lies_and_repairs_what_it_wrote(tmp_path):
    scene = small_scene(SCENE, width=64, height=48, frames=12)
    reference = render_reference(scene, tmp_path / "reference")
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        honest = farm.run_job(scene, strategy="exact")
        assert "suspect" not in honest["stats"]["error"], honest["stats"]["error"]
        assert "audit" not in honest["stats"]["error"], honest["stats"]["error"]
        liar = LyingWorker(farm.zmq)
        liar.start()
        try:
            farm.wait_for_workers(2)
            job = farm.run_job(scene, strategy="exact", spot_check_share=0.02)
            answered_by_the_end = liar.answered
            time.sleep(1)  # it keeps saying READY and HEARTBEAT: nothing more comes to it
            assert liar.answered == answered_by_the_end
        finally:
            liar.stop()
        assert liar.answered > 0, "the lying worker was given no task"
        error = job["stats"]["error"]
        suspect, audit = error.get("suspect"), error.get("audit")
        print(f"lying worker answered {liar.answered} tasks; suspect: {suspect}; audit: {audit}")
        assert suspect and suspect["pixels_disagreeing"] > 0, error
        assert suspect["frames"], suspect
        assert audit["workers_distrusted"] == ["liar"], audit
        # The evidence: the referee's unseen sample, a check that disagreed, or both.
        assert audit["job_values_wrong"] + audit["checks_wrong"] + error["referee_sample"]["pixels_wrong"] >= 1, error
        assert audit["frames_rewritten"] >= 1 and audit["pixels_rewritten"] > 0, audit
        assert audit["repairs_owed"] == 0 and audit["disputes_open"] == 0, audit
        # The promise kept after all: every frame as brute force traces it.
        result = compare(reference, farm.store / str(job["id"]))
        assert result["frames"] == 12 and result["differing_pixels"] == 0, result
        assert farm.metric("tcfarm_suspect_jobs_total") == 1
        assert farm.metric("tcfarm_suspect_pixels_total") == suspect["pixels_disagreeing"]
        assert farm.metric("tcfarm_workers_distrusted_total") == 1
        assert farm.metric("tcfarm_frames_rewritten_total") == audit["frames_rewritten"]
        assert farm.metric("tcfarm_pixels_rewritten_total") == audit["pixels_rewritten"]
        # The farm goes on with its honest worker: the next job is exact and not suspect.
        after = farm.run_job(scene, strategy="exact")
        assert "suspect" not in after["stats"]["error"], after["stats"]["error"]
        assert compare(reference, farm.store / str(after["id"]))["differing_pixels"] == 0
