"""Slow and many clients against a real coordinator: idle and trickling connections must not
stall /healthz, and a burst of concurrent submissions must lose nothing."""
import http.client
import json
import socket
import threading
import time
import urllib.parse

import pytest

from farm_harness import LocalFarm

SUBMITTER = "burst-submit-0123456789abcdef"
ADMIN = "burst-admin-0123456789abcdef"
SCENE = {"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
         "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}],
         "render": {"width": 8, "height": 6, "frames": {"start": 0, "count": 2}}}
IDLE_CONNECTIONS = 40
TRICKLING_CONNECTIONS = 40
BURST = 200
HEALTHZ_BOUND_SECONDS = 5  # generous: it answers in milliseconds when nothing stalls it


@pytest.fixture
def farm(tmp_path):
    with LocalFarm(tmp_path, workers=0, api_tokens={SUBMITTER: "submit", ADMIN: "admin"}) as farm:
        yield farm


def address(farm):
    parsed = urllib.parse.urlsplit(farm.url)
    return parsed.hostname, parsed.port


def healthz_seconds(farm):
    host, port = address(farm)
    started = time.monotonic()
    connection = http.client.HTTPConnection(host, port, timeout=60)
    try:
        connection.request("GET", "/healthz")
        response = connection.getresponse()
        assert response.status == 200, response.read()
        response.read()
    finally:
        connection.close()
    return time.monotonic() - started


class Trickler(threading.Thread):
    """Sends a request to each socket one byte a second, never finishing its headers."""

    def __init__(self, sockets):
        super().__init__(daemon=True)
        self.sockets, self.stop, self.bytes_sent = sockets, threading.Event(), 0

    def run(self):
        prefix = b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Trickle: "
        for sock in self.sockets:
            sock.sendall(prefix)
        while not self.stop.wait(1.0):
            for sock in self.sockets:
                try:
                    sock.sendall(b"a")
                    self.bytes_sent += 1
                except OSError:
                    pass


def test_idle_and_trickling_connections_do_not_stall_healthz(farm):
    host, port = address(farm)
    idle = [socket.create_connection((host, port), timeout=60) for _ in range(IDLE_CONNECTIONS)]
    trickling = [socket.create_connection((host, port), timeout=60) for _ in range(TRICKLING_CONNECTIONS)]
    trickler = Trickler(trickling)
    trickler.start()
    try:
        time.sleep(1.5)  # every connection accepted, the trickles under way
        latencies = [healthz_seconds(farm) for _ in range(5)]
        print(f"/healthz with {IDLE_CONNECTIONS} idle and {TRICKLING_CONNECTIONS} trickling connections open: "
              f"{', '.join(f'{s * 1000:.1f}' for s in latencies)} ms (max {max(latencies) * 1000:.1f} ms)")
        assert max(latencies) < HEALTHZ_BOUND_SECONDS
        # The server closes a connection that sends nothing (read timeout): the idle ones end.
        started = time.monotonic()
        for sock in idle:
            sock.settimeout(60)
            assert sock.recv(1) == b""
        print(f"idle connections closed by the server after {time.monotonic() - started + 1.5:.1f} s")
        assert healthz_seconds(farm) < HEALTHZ_BOUND_SECONDS
    finally:
        trickler.stop.set()
        trickler.join()
        for sock in idle + trickling:
            sock.close()
    assert trickler.bytes_sent > 0


def submit(host, port, results, index, barrier):
    body = json.dumps({"scene": SCENE, "name": f"burst-{index}"})
    barrier.wait()
    connection = http.client.HTTPConnection(host, port, timeout=120)
    try:
        connection.request("POST", "/api/v1/jobs", body, {"Content-Type": "application/json",
                                                          "Authorization": f"Bearer {SUBMITTER}"})
        response = connection.getresponse()
        payload = response.read()
        results[index] = (response.status, json.loads(payload).get("id"))
    except ConnectionResetError:
        results[index] = ("reset", None)
    except OSError as error:
        results[index] = (type(error).__name__, None)
    finally:
        connection.close()


def test_a_burst_of_concurrent_submissions_loses_nothing(farm):
    host, port = address(farm)
    results = [None] * BURST
    barrier = threading.Barrier(BURST)
    threads = [threading.Thread(target=submit, args=(host, port, results, i, barrier)) for i in range(BURST)]
    started = time.monotonic()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=300)
    seconds = time.monotonic() - started
    accepted = [job_id for status, job_id in results if isinstance(status, int) and 200 <= status < 300]
    resets = sum(1 for status, _ in results if status == "reset")
    others = [status for status, _ in results if not (isinstance(status, int) and 200 <= status < 300)]
    stored = {job["id"] for job in farm.client.jobs(limit=1000)}
    lost = [job_id for job_id in accepted if job_id not in stored]
    print(f"burst of {BURST} concurrent submissions in {seconds:.2f} s: {len(accepted)} accepted (2xx), "
          f"{resets} connection resets, {len(others)} other failures, {len(lost)} lost jobs")
    assert resets == 0
    assert others == []
    assert len(accepted) == BURST and len(set(accepted)) == BURST
    assert lost == []
    for job_id in accepted[:: BURST // 10]:
        assert farm.client.job(job_id)["name"].startswith("burst-")
