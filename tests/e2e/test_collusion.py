"""Workers with valid keys that collude. Each liar here is a real `tcfarm-worker serve` behind
a man in the middle (liar_proxy.py) that alters the values of its results by a policy and
holds a CURVE key of its own, on the coordinator's allow-list; the liars of a case share
what they altered, so that one checking another's values sends the same lie back. Only the
coordinator's referee is beyond them, and the referee's unseen sample (a secret share of
every result's pixels, traced again by the referee: job.stats.error.referee_sample) is the
check that no number of colluders can see.

What must hold, whatever they do:
- `exact`, `brute` and `auto` complete with 0 pixels differing from `tcfarm-worker render`;
  `search` stays within the error of the same job on a farm with no liar;
- every liar that altered a value it sent a job is banned, by its key;
- an honest worker is never banned (a ban needs evidence against the worker it names).

TCFARM_TRUST_REPEATS (default 1) runs each case that many times. Timeouts are generous
limits, never assertions."""
import json
import os
import time

import pytest

from farm_harness import LocalFarm
from liar_proxy import HONEST_TASKS, start_colluding_liars
from tcfarm.client import FINAL_STATES, trace_cost_seconds
# The liars' scene (the 12 spheres, 64x48, 10 frames), its reference, and the count of
# pixels a job's frames differ from it by: the same as the lone liars' tests.
from test_liars import differing, reference, scene  # noqa: F401
from test_worker_auth import coordinator_keys, keys, read_key, wait_for, worker_keys  # noqa: F401

WAIT_S = 300
REPEATS = range(int(os.environ.get("TCFARM_TRUST_REPEATS", "1")))
# Jobs run before the measured one, at most, for liars that are honest for their first tasks.
MAX_WARM_UP_JOBS = 8
# A job with no worker left that shows no progress for this long waits for a worker.
STILL_S = 15




def honest_principal(keys):
    return "key:" + read_key(keys["worker"].with_suffix(".pub"))


def start_liars(farm, keys, directory, count, policy):
    return start_colluding_liars(farm.zmq, keys, directory, count, policy)


def stop_all(liars):
    failures = []
    for liar in liars:
        try:
            liar.stop()
        except RuntimeError as failure:
            failures.append(failure)
    assert not failures, failures


def banned(farm):
    return {entry["principal"]: entry for entry in farm.client.distrusted_workers()}


def lying(liars, jobs):
    """The liars that altered a value they sent one of these jobs."""
    return [liar for liar in liars if any(liar.altered(job["id"]) for job in jobs)]


def report(label, job, liars):
    stats = job["stats"]
    sample = stats["error"]["referee_sample"]
    worker_cpu = trace_cost_seconds(stats) + stats.get("verify_trace_cpu_seconds", stats["verify_trace_seconds"])
    share = sample["referee_cpu_seconds"] / worker_cpu if worker_cpu > 0 else float("nan")
    print(f"{label}: job {job['id']} {job['state']}; liars {[(liar.name, liar.figures(job['id'])) for liar in liars]}")
    print(f"{label}: referee sample share {sample['share']:.4f}, catch probability {sample['catch_probability']}; "
          f"referee CPU {sample['referee_cpu_seconds']:.3f} s = {share:.1%} of the workers' trace CPU "
          f"({worker_cpu:.3f} s); the whole sample: {json.dumps(sample)}")
    print(f"{label}: checked by {stats['error'].get('checked_by')}; audit {stats['error'].get('audit')}")


def trust_log(farm, lines=40):
    """The coordinator's log lines about checks, disputes, repairs and bans (the last few)."""
    words = ("distrusted", "dropped worker", "check found", "traced again", "verification", "completed")
    log = (farm.directory / "coordinator.log").read_text(errors="replace").splitlines()
    kept = [line for line in log if any(word in line for word in words)][-lines:]
    return f"{farm.directory / 'coordinator.log'}:\n" + "\n".join(kept)


def assert_trusted_rightly(farm, liars, jobs, honest=None):
    """Every liar that altered a value it sent these jobs is banned by its key; nobody else is
    (the honest worker least of all). A ban is in place by the time its job completes; the
    wait is a limit for a coordinator that bans later."""
    guilty = {liar.principal for liar in lying(liars, jobs)}
    share = jobs[-1]["stats"]["error"]["referee_sample"]["share"]
    try:
        wait_for(lambda: guilty <= set(banned(farm)), "every liar that altered a value banned", timeout=30)
    except AssertionError:
        pass  # the assertion below names who is missing
    bans = banned(farm)
    names = {liar.principal: liar.name for liar in liars}
    # Beside a miss, the chance that the sample alone would have missed it at its least
    # share: a figure for whoever reads the failure, not an excuse for it.
    misses = {liar.name: f"{sum(liar.altered(job['id']) for job in jobs)} pixels altered, sample alone "
              f"misses with p <= {(1 - share) ** sum(liar.altered(job['id']) for job in jobs):.2g}"
              for liar in liars if liar.principal in guilty - set(bans)}
    assert guilty <= set(bans), (f"not banned: {misses}; banned: {[(b['name'], b.get('why')) for b in bans.values()]}; "
                                 f"error {json.dumps(jobs[-1]['stats']['error'])}; {trust_log(farm)}")
    if honest:
        assert honest not in bans, f"the honest worker is banned: {bans[honest]}; {trust_log(farm)}"
    assert set(bans) <= set(names), f"banned beyond the liars: {bans}"


def wait_job(farm, job_id, honest=None, timeout=WAIT_S):
    """The job once it has ended; fails at once when the honest worker is banned meanwhile
    (its job may then wait for a worker for ever), naming the ban and the job's error."""
    deadline = time.monotonic() + timeout
    while True:
        job = farm.client.job(job_id)
        if job["state"] in FINAL_STATES:
            return job
        bans = banned(farm) if honest else {}
        assert honest not in bans, (f"the honest worker is banned: {bans[honest]}; job {job['state']}, "
                                    f"{job['frames']}, error {json.dumps(job['stats'].get('error'))}; "
                                    f"{trust_log(farm)}")
        assert time.monotonic() < deadline, f"job {job_id} still running after {timeout} s: {job}"
        time.sleep(0.2)


def run_checked(farm, scene, strategy, reference, liars, label, honest=None, **options):
    job = farm.client.submit(scene, strategy=strategy, **options)
    job = wait_job(farm, job["id"], honest)
    report(label, job, liars)
    assert job["state"] == "completed", job
    wrong = differing(farm, reference, job)
    print(f"{label}: {wrong} pixels differ from the reference")
    assert wrong == 0, f"{wrong} pixels differ; error {job['stats']['error']}"
    return job


def colluding_case(tmp_path, keys, scene, reference, strategy, policy, liar_count, label, honest_first=False,
                   **options):
    """`liar_count` liars of `policy` and one honest worker, on a CURVE farm; runs `strategy`
    (after enough jobs for liars that are honest at first to start lying) and checks it.
    honest_first: the honest worker is connected before the liars (it then takes the job's
    first tasks, and the liars what comes after: the frames traced again to verify the job).
    Returns the last job."""
    honest = honest_principal(keys)
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        if honest_first:
            farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(1, timeout=60)
        liars = start_liars(farm, keys, tmp_path, liar_count, policy)
        try:
            if not honest_first:
                farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(liar_count + 1, timeout=60)
            jobs = []
            if policy == "honest_then_lying":
                while min(liar.figures()["tasks"] for liar in liars) < HONEST_TASKS:
                    assert len(jobs) < MAX_WARM_UP_JOBS, [liar.figures() for liar in liars]
                    jobs.append(run_checked(farm, scene, strategy, reference, liars, f"{label} warm-up", honest,
                                            **options))
                    if not lying(liars, jobs):
                        assert banned(farm) == {}, "a worker is banned while every value it sent was honest"
            jobs.append(run_checked(farm, scene, strategy, reference, liars, label, honest, **options))
            assert lying(liars, jobs), f"no liar altered a value of a job: {[liar.figures() for liar in liars]}"
            assert_trusted_rightly(farm, liars, jobs, honest)
        finally:
            stop_all(liars)
    return jobs[-1]


@pytest.mark.parametrize("repeat", REPEATS)
@pytest.mark.parametrize("policy", ["grey", "subtle", "honest_then_lying", "honest_on_checks"])
def test_two_colluding_liars_of_any_policy_are_banned_and_an_exact_job_stays_exact(
        policy, repeat, keys, scene, reference, tmp_path):
    colluding_case(tmp_path, keys, scene, reference, "exact", policy, 2, f"exact {policy} x2")


@pytest.mark.parametrize("repeat", REPEATS)
@pytest.mark.parametrize("strategy", ["brute", "auto"])
def test_two_grey_liars_beside_an_honest_worker_leave_every_exact_strategy_exact(
        strategy, repeat, keys, scene, reference, tmp_path):
    colluding_case(tmp_path, keys, scene, reference, strategy, "grey", 2, f"{strategy} grey x2")


@pytest.mark.parametrize("repeat", REPEATS)
def test_grey_liars_that_join_after_the_honest_worker_are_banned_and_the_job_reports_its_true_error(
        repeat, keys, scene, reference, tmp_path):
    job = colluding_case(tmp_path, keys, scene, reference, "exact", "grey", 2, "exact grey x2 joining late",
                         honest_first=True)
    # What the job says it verified is the truth: its frames are exact, whoever traced the
    # frames it compared them with.
    verified = job["stats"]["error"].get("reference", {})
    assert verified.get("pixels_differing", 0) == 0, verified


@pytest.mark.parametrize("repeat", REPEATS)
def test_an_honest_worker_beside_one_liar_is_never_banned_and_auto_stays_exact(
        repeat, keys, scene, reference, tmp_path):
    colluding_case(tmp_path, keys, scene, reference, "auto", "subtle", 1, "auto subtle x1")


@pytest.mark.parametrize("repeat", REPEATS)
def test_two_grey_liars_leave_search_within_the_error_of_an_honest_farm(repeat, keys, scene, reference, tmp_path):
    honest = honest_principal(keys)
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        farm.add_worker(*worker_keys(keys, keys["worker"]))
        farm.wait_for_workers(1, timeout=60)
        alone = farm.run_job(scene, strategy="search", bin_width=4, timeout=WAIT_S)
        liars = start_liars(farm, keys, tmp_path, 2, "grey")
        try:
            farm.wait_for_workers(3, timeout=60)
            job = farm.client.submit(scene, strategy="search", bin_width=4)
            job = wait_job(farm, job["id"], honest)
            report("search grey x2", job, liars)
            assert job["state"] == "completed", job
            assert any(liar.altered(job["id"]) for liar in liars), [liar.figures() for liar in liars]
            assert_trusted_rightly(farm, liars, [job], honest)
        finally:
            stop_all(liars)
        honest_error, error = differing(farm, reference, alone), differing(farm, reference, job)
        print(f"search grey x2: {error} pixels differ; {honest_error} on the farm without liars")
        assert error <= honest_error, job["stats"]["error"]


def finished_alone(farm, job_id, still_s=STILL_S):
    """Whether the job ends with no worker to trace for it (the referee's repairs are all it
    gets): false once it has made no progress for still_s seconds, waiting for a worker."""
    last, since = None, time.monotonic()
    while True:
        job = farm.client.job(job_id)
        if job["state"] in FINAL_STATES:
            return True
        progress = (job["frames"]["done"], json.dumps(job["stats"].get("error", {}).get("audit")))
        if progress != last:
            last, since = progress, time.monotonic()
        if time.monotonic() - since > still_s:
            return False
        time.sleep(0.2)


@pytest.mark.parametrize("repeat", REPEATS)
def test_three_subtle_liars_alone_are_banned_and_brute_completes_exact_with_repairs_or_an_honest_worker(
        repeat, keys, scene, reference, tmp_path):
    honest = honest_principal(keys)
    with LocalFarm(tmp_path, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        liars = start_liars(farm, keys, tmp_path, 3, "subtle")
        try:
            farm.wait_for_workers(3, timeout=60)
            job = farm.client.submit(scene, strategy="brute")
            every = {liar.principal for liar in liars}

            def settled():
                return farm.client.job(job["id"])["state"] in FINAL_STATES or every <= set(banned(farm))

            wait_for(settled, "the job ended or every liar banned", timeout=WAIT_S)
            # With every liar banned the job finishes on the referee's repairs, or its traces
            # wait for a worker: then an honest one joins. The limit is on that wait.
            if not finished_alone(farm, job["id"]):
                print("brute subtle x3: the job waits for a worker; an honest one joins")
                farm.add_worker(*worker_keys(keys, keys["worker"]))
            job = wait_job(farm, job["id"], honest)
            report("brute subtle x3", job, liars)
            assert job["state"] == "completed", job
            wrong = differing(farm, reference, job)
            print(f"brute subtle x3: {wrong} pixels differ from the reference")
            assert wrong == 0, job["stats"]["error"]
            assert any(liar.altered(job["id"]) for liar in liars), [liar.figures() for liar in liars]
            assert_trusted_rightly(farm, liars, [job], honest)
        finally:
            stop_all(liars)
