"""Running a farm day to day, through a real coordinator and real workers: finding jobs among
a thousand, priorities that order the work, cancel and retry with the frames kept, per-frame
state, deleting a job with its files and assets, following every job's events as a live
stream, and retention across a restart."""
import http.client
import json
import re
import threading
import time
import urllib.error
import urllib.parse
import urllib.request

import pytest

from farm_harness import LocalFarm, compare, small_scene, wait_until
from tcfarm.client import ApiError

TIMEOUT = 300


def api(farm, method, path, body=None):
    """The farm's answer as JSON; ApiError for an error."""
    return farm.client._request(method, path, body)


def raw(farm, method, path, data=None, headers=None):
    """(status, JSON body) for any request, bytes sent as they are."""
    headers = dict(headers or {})
    if data is not None:
        headers.setdefault("Content-Type", "application/json")
    if farm.token:
        headers["Authorization"] = f"Bearer {farm.token}"
    request = urllib.request.Request(farm.url + path, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def tiny_scene(frames=1):
    return {"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
            "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}],
            "render": {"width": 8, "height": 6, "frames": {"start": 0, "count": frames}}}


def follow_events(farm, path, until, timeout=TIMEOUT, headers=None, token=None, opened=None):
    """Reads the Server-Sent Events at `path` with a plain HTTP client until `until(events)`;
    returns the events as (id, type, data) in the order they came. token: instead of the
    farm's own. opened: a threading.Event set once the server has answered, when the
    stream's starting point is fixed."""
    parsed = urllib.parse.urlsplit(farm.url)
    connection = http.client.HTTPConnection(parsed.hostname, parsed.port, timeout=timeout)
    headers = dict(headers or {})
    if token or farm.token:
        headers["Authorization"] = f"Bearer {token or farm.token}"
    connection.request("GET", path, headers=headers)
    response = connection.getresponse()
    assert response.status == 200, response.read()
    assert response.getheader("Content-Type").startswith("text/event-stream")
    if opened:
        opened.set()
    events, fields = [], {}
    try:
        for line in response:
            line = line.decode().rstrip("\n")
            if line.startswith(":"):
                continue  # a comment: the keepalive
            if line:
                name, _, value = line.partition(": ")
                fields[name] = value
                continue
            if fields:
                events.append((int(fields["id"]), fields["event"], json.loads(fields["data"])))
                fields = {}
                if until(events):
                    return events
    finally:
        connection.close()
    raise AssertionError(f"the stream ended after {len(events)} events")


# ---------------------------------------------------------------------------------------
# Finding a job among a thousand


def test_a_thousand_jobs_are_found_filtered_and_paged(tmp_path):
    strategies = ["search", "exact", "brute", "guarded", "auto"]
    # No workers: the jobs stay where they are, and a thousand submissions cost no rendering.
    with LocalFarm(tmp_path, workers=0) as farm:
        ids = []
        for i in range(1000):
            job = farm.client.submit(tiny_scene(), name=f"Shot-{i:04d}", strategy=strategies[i % 5])
            ids.append(job["id"])
        for job_id in ids[10:20]:
            farm.client.cancel(job_id)

        def timed(query):
            start = time.monotonic()
            answer = api(farm, "GET", "/api/v1/jobs" + query)
            return answer, time.monotonic() - start

        page, seconds = timed("?offset=2&limit=2")
        assert [job["id"] for job in page["jobs"]] == [ids[-3], ids[-4]]
        assert (page["total"], page["offset"], page["limit"]) == (1000, 2, 2)
        found, seconds = timed("?name=shot-0421")
        assert [job["id"] for job in found["jobs"]] == [ids[421]] and found["total"] == 1
        assert seconds < 1.0, f"finding one job among 1000 took {seconds:.2f} s"
        canceled, _ = timed("?state=canceled&limit=3")
        assert canceled["total"] == 10 and [job["id"] for job in canceled["jobs"]] == ids[19:16:-1]
        exact, _ = timed("?strategy=exact&name=SHOT-00")
        assert exact["total"] == 20  # Shot-0001, -0006, ... below 0100
        assert all(job["strategy"] == "exact" for job in exact["jobs"])
        seen = []
        for offset in range(0, 1000, 300):
            seen += [job["id"] for job in api(farm, "GET", f"/api/v1/jobs?limit=300&offset={offset}")["jobs"]]
        assert seen == ids[::-1]


# ---------------------------------------------------------------------------------------
# Priorities, and the frames of a running job


def test_a_job_turned_to_minus_50_runs_after_a_job_of_0(tmp_path, scenes_dir):
    """Both jobs run at once (the farm runs up to four), on one worker that takes one task at
    a time: the job of 0 gets 51 tasks to every one of the job of -50. With every priority
    below 0 weighed as 0, the older job finished first."""
    scene = small_scene(scenes_dir / "paper_b_twelve_spheres.json", 320, 240, 24)
    with LocalFarm(tmp_path, workers=0) as farm:
        low = farm.client.submit(scene, strategy="brute", name="low")
        wait_until(lambda: farm.client.job(low["id"])["state"] == "running", "the first job to start")
        changed = api(farm, "PATCH", f"/api/v1/jobs/{low['id']}", {"priority": -50})
        assert changed["priority"] == -50
        high = farm.client.submit(scene, strategy="brute", name="high")
        wait_until(lambda: farm.client.job(high["id"])["state"] == "running", "the second job to start")
        farm.add_worker("--capacity", "1")

        # Per-frame state while the job of 0 runs: every frame is there, in one state.
        seen_tracing = False
        while True:
            frames = api(farm, "GET", f"/api/v1/jobs/{high['id']}/frames")
            counts = frames["counts"]
            assert [f["frame"] for f in frames["frames"]] == list(range(24))
            assert sum(counts.values()) == 24 and counts["failed"] == 0
            for frame in frames["frames"]:
                assert (frame["traced"] is None) == (frame["state"] != "written"), frame
            seen_tracing = seen_tracing or counts["tracing"] > 0
            if frames["state"] != "running":
                break
            time.sleep(0.05)
        assert seen_tracing, "no frame was ever seen tracing while the job ran"
        high = farm.client.wait(high["id"], timeout=TIMEOUT)
        assert high["state"] == "completed"
        low_now = farm.client.job(low["id"])
        print(f"the job of 0 completed with the job of -50 at {low_now['frames']['done']} of 24 frames")
        assert low_now["state"] == "running" and low_now["frames"]["done"] < 24
        low = farm.client.wait(low["id"], timeout=TIMEOUT)
        assert low["state"] == "completed" and low["finished_at"] > high["finished_at"]
        frames = api(farm, "GET", f"/api/v1/jobs/{high['id']}/frames")
        assert frames["counts"] == {"queued": 0, "tracing": 0, "written": 24, "failed": 0}
        assert all(f["traced"] + f["copied"] == 320 * 240 for f in frames["frames"])
        types = [event["type"] for event in api(farm, "GET", f"/api/v1/jobs/{low['id']}/events")["events"]]
        assert types[:3] == ["submitted", "started", "priority_changed"]


# ---------------------------------------------------------------------------------------
# Cancel, retry: the frames written are kept, and the output is a straight run's


@pytest.fixture(scope="module")
def one_worker_farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("retry-farm"), workers=1) as farm:
        farm.wait_for_workers(1)
        yield farm


def moving_camera(scene):
    scene = json.loads(json.dumps(scene))
    scene["camera"]["position"] = {"polynomial": [[0, 0.02], [0], [10]]}
    return scene


@pytest.mark.parametrize("strategy,bin_width,camera", [
    ("search", 6, "still"), ("guarded", 6, "still"), ("exact", 6, "still"), ("brute", 2, "still"),
    ("auto", 10, "still"), ("auto", 10, "moving")])
def test_a_canceled_job_retried_keeps_its_frames_and_matches_a_straight_run(one_worker_farm, scenes_dir, strategy,
                                                                             bin_width, camera):
    farm = one_worker_farm
    frames = 36
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 240, 180, frames)
    # Four samples a pixel: the job must outlast noticing its third frame and canceling.
    scene["render"]["samples_per_pixel"] = 4
    if camera == "moving":
        scene = moving_camera(scene)
    job = farm.client.submit(scene, strategy=strategy, bin_width=bin_width)
    try:
        check_cancel_and_retry(farm, scene, job, strategy, bin_width, camera, frames)
    finally:
        # A job that never finished would keep the module's farm busy for the tests after.
        for leftover in api(farm, "GET", "/api/v1/jobs?state=queued,running")["jobs"]:
            farm.client.cancel(leftover["id"])


def check_cancel_and_retry(farm, scene, job, strategy, bin_width, camera, frames):
    wait_until(lambda: farm.client.job(job["id"])["frames"]["done"] >= 3, "three frames", timeout=120)
    canceled = farm.client.cancel(job["id"])
    assert canceled["state"] == "canceled"
    kept = canceled["frames"]["done"]
    assert 0 < kept < frames, f"canceled with {kept} of {frames} frames: not mid-job"
    with pytest.raises(ApiError) as refused:
        farm.client.cancel(job["id"])
    assert refused.value.code == "job_finished"

    retried = api(farm, "POST", f"/api/v1/jobs/{job['id']}/retry")
    assert (retried["id"], retried["state"], retried["frames"]["done"]) == (job["id"], "queued", kept)
    resumed = farm.client.wait(job["id"], timeout=120)
    assert resumed["state"] == "completed", resumed
    assert resumed["stats"]["resumed_frames"] == kept
    assert resumed["frames"]["done"] == frames
    straight = farm.run_job(scene, strategy=strategy, bin_width=bin_width, timeout=120)
    assert straight["stats"]["strategy"]["name"] == resumed["stats"]["strategy"]["name"]
    error = compare(farm.store / str(straight["id"]), farm.store / str(job["id"]))
    print(f"{strategy} ({camera} camera, {resumed['stats']['strategy']['name']}): canceled with {kept} of "
          f"{frames} frames, retraced {resumed['stats']['retraced_frames']} frames; "
          f"{error['differing_pixels']} pixels differ from a straight run")
    assert error["frames"] == frames and error["differing_pixels"] == 0
    types = [event["type"] for event in api(farm, "GET", f"/api/v1/jobs/{job['id']}/events")["events"]]
    assert types.index("canceled") < types.index("retried") < types.index("completed")
    assert types.count("started") == 2
    with pytest.raises(ApiError) as refused:
        api(farm, "POST", f"/api/v1/jobs/{job['id']}/retry")
    assert (refused.value.status, refused.value.code) == (409, "job_not_retryable")


# ---------------------------------------------------------------------------------------
# Delete: the job's folder, its unshared assets, and the store's size


def mesh_scene(files, frames=4):
    shapes = [{"type": "mesh", "file": file} for file in files]
    shapes.append({"type": "sphere", "center": [-2, 0.6, 1.5], "radius": 0.5,
                   "motion": {"polynomial": [[0, 0.5], [0], [0]]}})
    return {"camera": {"position": [0, 4, 9], "look_at": [0, 0.5, 0]},
            "lights": [{"type": "point", "position": [4, 8, 5], "intensity": [60, 60, 60]}],
            "shapes": shapes, "render": {"width": 96, "height": 72, "frames": {"start": 0, "count": frames}}}


def test_delete_removes_the_jobs_files_and_the_assets_no_other_job_names(one_worker_farm, tmp_path, scenes_dir):
    farm = one_worker_farm
    (tmp_path / "own.obj").write_text("v -1 0 0\nv 1 0 0\nv 0 1.5 0\nf 1 2 3\n# only the first job's\n")
    (tmp_path / "shared.obj").write_text("v -3 0 -1\nv 3 0 -1\nv 0 3 -1\nf 1 2 3\n# both jobs'\n")
    hashes = farm.client.upload_assets([str(tmp_path / "own.obj"), str(tmp_path / "shared.obj")]).hashes
    own, shared = hashes[str(tmp_path / "own.obj")], hashes[str(tmp_path / "shared.obj")]
    first = farm.run_job(mesh_scene(["own.obj", "shared.obj"]), assets={"own.obj": own, "shared.obj": shared})
    second = farm.run_job(mesh_scene(["shared.obj"]), assets={"shared.obj": shared})
    folder = farm.store / str(first["id"])
    # Once no job renders, the frames are compressed and previewed: then the folder is final.
    wait_until(lambda: (folder / ".finished").exists(), "the first job's frames to be finished", timeout=60)
    folder_bytes = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())

    # Deleting a job still running is refused; canceled, it goes at once, frames being
    # written or not, and nothing brings its folder back.
    big = farm.client.submit(small_scene(scenes_dir / "paper_a_one_sphere.json", 320, 240, 60), strategy="brute")
    wait_until(lambda: farm.client.job(big["id"])["frames"]["done"] >= 1, "the big job's first frame")
    with pytest.raises(ApiError) as refused:
        api(farm, "DELETE", f"/api/v1/jobs/{big['id']}")
    assert (refused.value.status, refused.value.code) == (409, "job_active")
    assert "cancel it first" in str(refused.value)
    farm.client.cancel(big["id"])
    assert api(farm, "DELETE", f"/api/v1/jobs/{big['id']}")["deleted"] == big["id"]
    time.sleep(1)
    assert not (farm.store / str(big["id"])).exists()

    # The store's size is measured every few seconds: wait until it counts the first job.
    wait_until(lambda: farm.metric("tcfarm_store_bytes") >= folder_bytes, "the store's size to count the job",
               timeout=30, poll=0.5)
    before = farm.metric("tcfarm_store_bytes")
    deleted_before = farm.metric("tcfarm_jobs_deleted_total")
    answer = api(farm, "DELETE", f"/api/v1/jobs/{first['id']}")
    assert answer == {"deleted": first["id"], "freed_bytes": folder_bytes + (tmp_path / "own.obj").stat().st_size}
    assert not folder.exists()
    assert not (farm.store / "assets" / own).exists()
    assert (farm.store / "assets" / shared).exists()  # the second job names it
    assert farm.client.missing_assets([own, shared]) == [own]
    assert farm.metric("tcfarm_store_bytes") <= before - answer["freed_bytes"]
    assert farm.metric("tcfarm_jobs_deleted_total") == deleted_before + 1
    for method, path in (("GET", ""), ("GET", "/frames"), ("GET", "/events"), ("DELETE", ""), ("POST", "/retry"),
                         ("GET", "/frames/0.png")):
        with pytest.raises(ApiError) as gone:
            api(farm, method, f"/api/v1/jobs/{first['id']}{path}")
        assert (gone.value.status, gone.value.code) == (404, "job_not_found"), path
    assert farm.client.job(second["id"])["state"] == "completed"
    # A new job never takes a deleted one's id.
    assert farm.client.submit(tiny_scene())["id"] > big["id"]


# ---------------------------------------------------------------------------------------
# Events: live, for all jobs, and in the coordinator's log


def test_events_are_followed_live_as_server_sent_events(tmp_path, scenes_dir):
    tokens = {"admin-token-0123456789": "admin", "reader-token-0123456789": "read"}
    with LocalFarm(tmp_path, workers=1, api_tokens=tokens) as farm:
        farm.wait_for_workers(1)
        scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 160, 120, 30)
        opened = threading.Event()
        got = {}

        def follow():
            got["events"] = follow_events(
                farm, "/api/v1/events",
                lambda events: any(e[1] == "completed" and e[2]["job"] == got.get("job") for e in events),
                opened=opened)

        follower = threading.Thread(target=follow)
        follower.start()
        # The stream is open before the job exists: all of it comes live.
        assert opened.wait(TIMEOUT), "the event stream did not open"
        job = farm.client.submit(scene, strategy="search", bin_width=6, name="followed")
        got["job"] = job["id"]
        follower.join(TIMEOUT)
        assert not follower.is_alive()
        mine = [e for e in got["events"] if e[2]["job"] == job["id"]]
        types = [e[1] for e in mine]
        assert types[0] == "submitted" and types[1] == "started" and types[-1] == "completed", types
        assert "frames_written" in types
        assert all(a[0] < b[0] for a, b in zip(mine, mine[1:]))  # seq increases
        told = set()
        for _, kind, event in mine:
            if kind == "frames_written":
                assert event["count"] <= 10 and " written" in event["message"]
                for first, last in event["ranges"]:
                    told.update(range(first, last + 1))
        assert told == set(range(30))  # every frame told once the job completes
        completed = mine[-1][2]
        assert completed["traced_pixel_ratio"] > 0 and completed["wall_seconds"] > 0

        # A reader replays the log from a seq (as EventSource does after a reconnect).
        replay = follow_events(farm, f"/api/v1/events?job={job['id']}", lambda events: events[-1][1] == "completed",
                               headers={"Last-Event-ID": str(mine[0][0])}, token="reader-token-0123456789")
        assert [e[0] for e in replay] == [e[0] for e in mine[1:]]
        per_job = api(farm, "GET", f"/api/v1/jobs/{job['id']}/events")["events"]
        assert [e["seq"] for e in per_job] == [e[0] for e in mine]

        log = (tmp_path / "coordinator.log").read_text()
        assert f"job {job['id']} submitted: submitted 'followed'" in log
        assert re.search(rf"^job {job['id']} frames_written: .* written", log, re.M)
        assert f"job {job['id']} completed: completed: 30 frames" in log
        for token in tokens:
            assert token not in log


# ---------------------------------------------------------------------------------------
# Retention across restarts


def finished_jobs(farm, count, scene):
    """Completed jobs whose frames the finisher has also compressed and previewed, so
    that their folders no longer change size."""
    ids = [farm.run_job(scene, strategy="brute")["id"] for _ in range(count)]
    for i in ids:
        wait_until(lambda: (farm.store / str(i) / ".finished").exists(), f"job {i}'s frames to be finished", timeout=60)
    return ids


def test_retention_deletes_finished_jobs_at_start(tmp_path, scenes_dir):
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 160, 120, 4)
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        old = finished_jobs(farm, 2, scene)
        canceled = farm.client.submit(tiny_scene())
    # A restart with --keep-days 0: every finished job goes at start, the queued one stays.
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--keep-days", "0")) as farm:
        wait_until(lambda: not any((farm.store / str(i)).exists() for i in old), "the retention at start", timeout=30)
        listed = api(farm, "GET", "/api/v1/jobs")
        assert [job["id"] for job in listed["jobs"]] == [canceled["id"]] and listed["total"] == 1
        wait_until(lambda: farm.metric("tcfarm_jobs_deleted_total") == 2, "two deletions counted", timeout=10)
        farm.client.cancel(canceled["id"])
        # Finished now, so the next round (a minute later) would take it; it is still here.
        assert farm.client.job(canceled["id"])["state"] == "canceled"
        log = (tmp_path / "coordinator.log").read_text()
        assert f"job {old[0]} deleted: deleted by the retention: finished more than 0 days ago" in log

    # A budget: the earliest finished jobs go until the store fits.
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        jobs = finished_jobs(farm, 3, scene)
    sizes = {i: sum(f.stat().st_size for f in (tmp_path / "store" / str(i)).rglob("*") if f.is_file()) for i in jobs}
    total = sum(f.stat().st_size for f in (tmp_path / "store").rglob("*") if f.is_file())
    budget = total - sizes[jobs[0]] // 2
    database_before = database_bytes(tmp_path / "store")
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--store-budget", str(budget))) as farm:
        # The canceled job finished earliest of all: it goes first, then the first of the three.
        wait_until(lambda: not (farm.store / str(jobs[0])).exists(), "the budget at start", timeout=30)
        remaining = [job["id"] for job in api(farm, "GET", "/api/v1/jobs")["jobs"]]
        assert remaining == [jobs[2], jobs[1]]
        # The database lives in the store and grows by what the deletions logged (its
        # write-ahead log), after the retention weighed the store: that growth is allowed.
        measured = farm.metric("tcfarm_store_bytes")
        assert measured <= budget + max(0, database_bytes(farm.store) - database_before)


def database_bytes(store):
    return sum(f.stat().st_size for f in store.glob("jobs.db*") if f.is_file())


# ---------------------------------------------------------------------------------------
# Bad input to the new routes: 4xx, in the one error shape


def test_bad_input_to_the_new_routes_is_refused_in_the_error_shape(one_worker_farm):
    farm = one_worker_farm
    job = farm.run_job(tiny_scene(), name="for bad input")
    jid = job["id"]
    cases = [
        ("GET", "/api/v1/jobs?state=done", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/jobs?strategy=fast", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/jobs?offset=-2", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/jobs?limit=2&limit=3", None, 400, "invalid_parameter"),
        ("DELETE", "/api/v1/jobs/abc", None, 400, "invalid_parameter"),
        ("DELETE", "/api/v1/jobs/99999999999999999999", None, 400, "invalid_parameter"),
        ("DELETE", "/api/v1/jobs/987654", None, 404, "job_not_found"),
        ("POST", "/api/v1/jobs/-1/retry", None, 400, "invalid_parameter"),
        ("POST", "/api/v1/jobs/987654/retry", None, 404, "job_not_found"),
        ("POST", f"/api/v1/jobs/{jid}/retry", None, 409, "job_not_retryable"),
        ("PATCH", f"/api/v1/jobs/{jid}", b"{\"priority\": ", 400, "invalid_json"),
        ("PATCH", f"/api/v1/jobs/{jid}", b"{}", 400, "missing_field"),
        ("PATCH", f"/api/v1/jobs/{jid}", b"{\"priority\": 150}", 400, "invalid_field"),
        ("PATCH", f"/api/v1/jobs/{jid}", b"{\"name\": \"\"}", 400, "invalid_field"),
        ("PATCH", f"/api/v1/jobs/{jid}", b"{\"owner\": \"me\"}", 400, "unknown_field"),
        ("PATCH", "/api/v1/jobs/x1", b"{\"priority\": 1}", 400, "invalid_parameter"),
        ("PATCH", "/api/v1/jobs/987654", b"{\"priority\": 1}", 404, "job_not_found"),
        ("GET", "/api/v1/jobs/zz/frames", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/jobs/987654/frames", None, 404, "job_not_found"),
        ("GET", f"/api/v1/jobs/{jid}/events?after=soon", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/jobs/987654/events", None, 404, "job_not_found"),
        ("GET", "/api/v1/events?after=-1", None, 400, "invalid_parameter"),
        ("GET", "/api/v1/events?job=987654", None, 404, "job_not_found"),
        ("PUT", f"/api/v1/jobs/{jid}", b"{}", 405, "method_not_allowed"),
    ]
    for method, path, data, status, code in cases:
        got_status, body = raw(farm, method, path, data)
        assert (got_status, body["error"]["code"]) == (status, code), (method, path, body)
        assert set(body) == {"error"} and body["error"]["status"] == status and body["error"]["message"]
    pointers = {b"{\"priority\": 150}": "/priority", b"{\"name\": \"\"}": "/name", b"{\"owner\": \"me\"}": "/owner"}
    for data, pointer in pointers.items():
        assert raw(farm, "PATCH", f"/api/v1/jobs/{jid}", data)[1]["error"]["pointer"] == pointer
    assert farm.client.job(jid)["name"] == "for bad input"
