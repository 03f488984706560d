"""One memory budget for all running jobs, seen from outside: a real coordinator with no
worker, large jobs submitted, and its resident memory read from /proc/PID/status. Jobs
accepted do not multiply it, a job that does not fit now waits queued (and lets a small
one pass), one that could never fit is a 413, and cancel gives the memory back."""
import json

import pytest

from farm_harness import LocalFarm, wait_until
from tcfarm.client import ApiError

MIB = 1 << 20
# 4096x4096 frames take 192 MiB as float RGB; a 100,000-frame search at n = 10 needs
# 25 of them one bin at a time (4.7 GiB), so 8 GiB for the farm runs one such job.
FARM_MEMORY_MIB = 8192
FRAME_BYTES = 4096 * 4096 * 12


def rss_bytes(process):
    """The process's resident memory (VmRSS), from /proc."""
    with open(f"/proc/{process.pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError(f"no VmRSS in /proc/{process.pid}/status")


def scene(scenes_dir, width, height, frames, spp=1024):
    one_sphere = json.loads((scenes_dir / "paper_a_one_sphere.json").read_text())
    one_sphere["render"].update(width=width, height=height, frames={"start": 0, "count": frames},
                                samples_per_pixel=spp)
    return one_sphere


def state(farm, job_id):
    return farm.client.job(job_id)["state"]


@pytest.fixture
def farm(tmp_path):
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--farm-memory", str(FARM_MEMORY_MIB))) as farm:
        yield farm


def test_large_jobs_share_one_memory_budget_and_give_it_back(farm, scenes_dir):
    coordinator = farm.coordinator
    large = scene(scenes_dir, 4096, 4096, 100000)
    # A first job submitted and canceled: the HTTP server, the job database and the
    # dispatcher have done their first allocations before the baseline is read.
    warm = farm.client.submit(scene(scenes_dir, 64, 64, 10), strategy="search", bin_width=10)
    wait_until(lambda: state(farm, warm["id"]) == "running", "the warm-up job to run", timeout=30)
    farm.client.cancel(warm["id"])
    wait_until(lambda: state(farm, warm["id"]) == "canceled",
               "the warm-up job to be canceled", timeout=30)
    before = rss_bytes(coordinator)

    jobs = [farm.client.submit(large, strategy="search", bin_width=10)["id"] for _ in range(3)]
    wait_until(lambda: state(farm, jobs[0]) == "running", "the first large job to run", timeout=30)
    # The others do not fit beside it: they stay queued, claim after claim.
    for _ in range(10):
        assert [state(farm, job) for job in jobs[1:]] == ["queued", "queued"]
        farm.client.job(jobs[0])  # a claim interval or more per round
    # A small job fits in what the large one leaves, and passes the large ones waiting.
    small = farm.client.submit(scene(scenes_dir, 64, 64, 10), strategy="search", bin_width=10)["id"]
    wait_until(lambda: state(farm, small) == "running", "the small job to pass the queued ones", timeout=30)
    assert [state(farm, job) for job in jobs[1:]] == ["queued", "queued"]

    accepted = rss_bytes(coordinator)
    print(f"coordinator RSS: {before / MIB:.1f} MiB before, {accepted / MIB:.1f} MiB with 3 large jobs "
          f"accepted (1 running, 2 queued) and a small one running")
    # A job waiting for workers holds none of its frames, and the queued ones nothing.
    assert accepted - before < FRAME_BYTES

    # Memory frees: canceling the running large job lets the next one run.
    farm.client.cancel(jobs[0])
    wait_until(lambda: state(farm, jobs[1]) == "running", "the second large job to run once the first ends",
               timeout=30)
    assert state(farm, jobs[2]) == "queued"

    for job in (jobs[2], jobs[1], small):
        farm.client.cancel(job)
    wait_until(lambda: all(state(farm, job) == "canceled" for job in jobs + [small]), "every job canceled",
               timeout=30)
    after = rss_bytes(coordinator)
    print(f"coordinator RSS after canceling them: {after / MIB:.1f} MiB")
    assert after <= before * 1.2, (before, after)


def test_a_job_that_could_never_fit_is_refused_at_submit(farm, scenes_dir):
    # 8192x8192 frames take 768 MiB; one bin at a time holds 25 of them: 18.75 GiB.
    with pytest.raises(ApiError) as refused:
        farm.client.submit(scene(scenes_dir, 8192, 8192, 100000), strategy="search", bin_width=10)
    assert refused.value.status == 413 and refused.value.code == "job_too_large"
    assert "it needs 18.76 GiB" in str(refused.value), str(refused.value)
    assert f"the farm has {FARM_MEMORY_MIB / 1024:.2f} GiB for all its running jobs" in str(refused.value)
    assert farm.client.jobs() == []  # nothing was queued


def test_a_canceled_job_gives_its_frames_memory_back(tmp_path, scenes_dir):
    # 1024x1024 frames take 12 MiB: a search at n = 10 holds tens of them while a worker
    # traces it, and the frame finisher reads them back once it is canceled.
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        coordinator = farm.coordinator
        before = rss_bytes(coordinator)
        job = farm.client.submit(scene(scenes_dir, 1024, 1024, 400, spp=1), strategy="search", bin_width=10)["id"]
        peak = before
        def some_frames_done():
            nonlocal peak
            peak = max(peak, rss_bytes(coordinator))
            return farm.client.job(job)["frames"]["done"] >= 10
        wait_until(some_frames_done, "10 frames of the job written", timeout=120)
        farm.client.cancel(job)
        # The finisher compresses the frames written once the farm is idle; then the job
        # is done with.
        wait_until(lambda: (farm.store / str(job) / ".finished").exists(), "the canceled job's frames finished",
                   timeout=120)
        # The marker is written just before the finisher frees what it read.
        settled = []
        def back_near_before():
            settled.append(rss_bytes(coordinator))
            return settled[-1] <= before * 1.2
        try:
            wait_until(back_near_before, "the coordinator's RSS back within 20 % of before", timeout=10, poll=0.5)
        finally:
            print(f"coordinator RSS: {before / MIB:.1f} MiB before, {peak / MIB:.1f} MiB at most while rendering, "
                  f"{settled[-1] / MIB:.1f} MiB after cancel")
        assert peak - before > 10 * 12 * MIB  # the job did hold frames
