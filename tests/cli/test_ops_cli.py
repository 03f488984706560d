"""Running a farm day to day from the command line: list, delete, retry, priority, events and
watch, through the installed `tcfarm` command against a live local farm."""
import http.server
import json
import re
import subprocess
import threading
import time

import pytest

from farm_harness import LocalFarm, small_scene
from installed_client import run_installed


def tiny(scenes_dir, frames=2):
    return small_scene(scenes_dir / "paper_a_one_sphere.json", 16, 16, frames)


@pytest.fixture(scope="module")
def listed(tmp_path_factory, scenes_dir):
    """A farm without workers holding 45 jobs: names "shot-01".."shot-45", every third a
    guarded job, every fifth canceled."""
    with LocalFarm(tmp_path_factory.mktemp("list-farm"), workers=0) as farm:
        jobs = []
        for index in range(1, 46):
            job = farm.client.submit(tiny(scenes_dir), name=f"Shot-{index:02d}",
                                     strategy="guarded" if index % 3 == 0 else "search", bin_width=2)
            if index % 5 == 0:
                farm.client.cancel(job["id"])
            jobs.append(job)
        yield farm, jobs


def table_ids(stdout):
    return [int(line.split()[0]) for line in stdout.splitlines()[1:] if line.split()[0].isdigit()]


def test_list_is_a_table_a_page_at_a_time(listed, tcfarm):
    farm, jobs = listed
    first = tcfarm(farm, "list")
    assert first.returncode == 0, first.stderr
    header = first.stdout.splitlines()[0].split()
    assert header[:3] == ["id", "name", "state"] and "priority" in header
    newest = [job["id"] for job in reversed(jobs)]
    assert table_ids(first.stdout) == newest[:20]
    assert first.stdout.splitlines()[-1] == "showing 1-20 of 45 jobs; next: --page 2"
    third = tcfarm(farm, "list", "--page", "3")
    assert table_ids(third.stdout) == newest[40:]
    assert third.stdout.splitlines()[-1] == "showing 41-45 of 45 jobs"
    by_offset = tcfarm(farm, "list", "--offset", "5", "--limit", "3")
    assert table_ids(by_offset.stdout) == newest[5:8]
    assert by_offset.stdout.splitlines()[-1] == "showing 6-8 of 45 jobs; next: --offset 8"
    page = json.loads(tcfarm(farm, "list", "--json", "--limit", "2", "--offset", "4").stdout)
    assert (page["total"], page["offset"], page["limit"]) == (45, 4, 2)
    assert [job["id"] for job in page["jobs"]] == newest[4:6]


def test_list_filters_by_state_strategy_and_name(listed, tcfarm):
    farm, jobs = listed
    canceled = tcfarm(farm, "list", "--state", "canceled", "--limit", "100")
    assert table_ids(canceled.stdout) == [job["id"] for job in reversed(jobs[4::5])]
    assert all(" canceled " in line for line in canceled.stdout.splitlines()[1:-1])
    guarded = tcfarm(farm, "list", "--strategy", "guarded", "--state", "canceled,queued,running")
    assert table_ids(guarded.stdout) == [job["id"] for job in reversed(jobs[2::3])]
    named = tcfarm(farm, "list", "--name", "shot-3")  # any case
    assert [line.split()[1] for line in named.stdout.splitlines()[1:-1]] == \
        [f"Shot-{i}" for i in range(39, 29, -1)]
    assert named.stdout.splitlines()[-1] == "showing 1-10 of 10 jobs"
    none = tcfarm(farm, "list", "--name", "no such shot")
    assert none.returncode == 0 and none.stdout.strip() == "no jobs match (of 0)"


def test_delete_asks_first_and_frees_the_store(tmp_path, scenes_dir, tcfarm):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.run_job(tiny(scenes_dir, frames=4), name="to delete")
        folder = farm.store / str(job["id"])
        assert folder.is_dir()
        kept = tcfarm(farm, "delete", job["id"], stdin="n\n")
        assert kept.returncode == 1
        assert f"delete job {job['id']} 'to delete' (completed, 4 frames written)" in kept.stderr
        assert "not deleted (answer y, or pass --yes)" in kept.stderr
        assert farm.client.job(job["id"])["state"] == "completed"
        deleted = tcfarm(farm, "delete", job["id"], stdin="y\n")
        assert deleted.returncode == 0, deleted.stderr
        freed = int(re.search(r"deleted job \d+, freed .* \(([\d,]+) bytes\)", deleted.stdout).group(1).replace(",", ""))
        assert freed > 0
        assert not folder.exists()
        gone = tcfarm(farm, "status", job["id"])
        assert gone.returncode == 1 and "job_not_found (404)" in gone.stderr

        # With no worker left the job cannot finish before the delete arrives: still active.
        farm.workers[0].terminate()
        farm.workers[0].wait()
        running = farm.client.submit(tiny(scenes_dir, frames=400), name="busy")
        refused = tcfarm(farm, "delete", running["id"], "--yes")
        assert refused.returncode == 1 and "job_active (409)" in refused.stderr, refused.stderr
        farm.client.cancel(running["id"])
        assert tcfarm(farm, "delete", running["id"], "--yes").returncode == 0


def test_retry_and_priority(tmp_path, scenes_dir, tcfarm):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny(scenes_dir), name="again")
        farm.client.cancel(job["id"])
        retried = tcfarm(farm, "retry", job["id"])
        assert retried.returncode == 0, retried.stderr
        assert retried.stdout.startswith(f"queued again: job {job['id']} ")
        assert farm.client.job(job["id"])["state"] in ("queued", "running")
        again = tcfarm(farm, "retry", job["id"])
        assert again.returncode == 1 and "job_not_retryable (409)" in again.stderr

        lowered = tcfarm(farm, "priority", job["id"], "-50")
        assert lowered.returncode == 0, lowered.stderr
        assert lowered.stdout.startswith(f"priority -50: job {job['id']} ")
        assert farm.client.job(job["id"])["priority"] == -50
        too_high = tcfarm(farm, "priority", job["id"], "101")
        assert too_high.returncode == 1 and "(400)" in too_high.stderr and "priority" in too_high.stderr
        renamed = tcfarm(farm, "rename", job["id"], "new name")
        assert renamed.returncode == 0 and farm.client.job(job["id"])["name"] == "new name"


def test_events_of_a_finished_job(tmp_path, scenes_dir, tcfarm):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.run_job(tiny(scenes_dir, frames=3), name="told")
        result = tcfarm(farm, "events", job["id"])
        assert result.returncode == 0, result.stderr
        types = [line.split()[4] for line in result.stdout.splitlines()]
        assert types[0] == "submitted" and types[-1] == "completed", result.stdout
        assert "started" in types and "frames_written" in types
        assert all(f"job {job['id']} " in line for line in result.stdout.splitlines())
        as_json = [json.loads(line) for line in tcfarm(farm, "--json", "events", job["id"]).stdout.splitlines()]
        assert [event["type"] for event in as_json] == types
        assert [event["seq"] for event in as_json] == sorted(event["seq"] for event in as_json)


def test_events_follow_prints_them_as_they_happen_and_stops_at_the_end(tmp_path, scenes_dir, installed_tcfarm):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny(scenes_dir, frames=3), name="followed")
        other = farm.client.submit(tiny(scenes_dir), name="someone else's")
        follower = subprocess.Popen([str(installed_tcfarm), "--url", farm.url, "events", str(job["id"]),
                                     "--follow"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        watchdog = threading.Timer(120, follower.kill)  # a follower that never ends fails
        watchdog.start()
        try:
            assert follower.stdout.readline().split()[4] == "submitted"  # the past first
            farm.client.update(job["id"], priority=7)  # a live event
            seen = []
            while "priority_changed" not in seen:
                line = follower.stdout.readline()
                assert line, f"the follower stopped after {seen}"
                seen.append(line.split()[4])
            farm.client.cancel(other["id"])  # another job's: not shown
            farm.add_worker()
            rest, errors = follower.communicate(timeout=120)
        finally:
            watchdog.cancel()
            if follower.poll() is None:
                follower.kill()
        assert follower.returncode == 0, errors
        types = [line.split()[4] for line in rest.splitlines()]
        assert "frames_written" in types and types[-1] == "completed", rest
        assert all(f"job {job['id']} " in line for line in rest.splitlines())


def test_watch_follows_the_event_stream(tmp_path, scenes_dir, tcfarm):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.client.submit(tiny(scenes_dir, frames=20), name="watched")
        result = tcfarm(farm, "watch", job["id"])
        assert result.returncode == 0, result.stderr
        assert "polling instead" not in result.stderr
        assert "20/20 frames" in result.stderr and f"job {job['id']} completed" in result.stdout


class _FarmWithoutStream(http.server.BaseHTTPRequestHandler):
    """A farm of one finished job that refuses the event stream, as one without it does."""
    job = None

    def do_GET(self):
        if self.path.startswith("/api/v1/jobs/1"):
            body, status = json.dumps(self.job), 200
        else:
            body, status = json.dumps({"error": {"status": 404, "code": "not_found",
                                                 "message": f"no route GET {self.path.split('?')[0]}"}}), 404
        data = body.encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, *args):
        pass


def test_watch_polls_where_the_stream_is_refused(installed_tcfarm):
    _FarmWithoutStream.job = {"id": 1, "name": "old", "state": "completed", "strategy": "search",
                              "bin_width": 2, "priority": 0, "traced_pixel_ratio": 0.5, "stats": {},
                              "frames": {"start": 0, "end": 1, "count": 2, "done": 2}}
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _FarmWithoutStream)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}"
        started = time.monotonic()
        result = run_installed(installed_tcfarm, "--url", url, "watch", "1", timeout=60)
    finally:
        server.shutdown()
    assert result.returncode == 0, result.stderr
    assert "the farm's event stream is refused (not_found (404): no route GET /api/v1/events): polling instead" \
        in result.stderr
    assert "2/2 frames" in result.stderr and "job 1 completed" in result.stdout
    assert time.monotonic() - started < 30
