"""How surely colluding liars are caught, and what catching them costs: the grey and subtle
collusion cases of tests/e2e/test_collusion.py (real workers behind liar_proxy.py, each with
a key of its own, on a CURVE farm), each run N times on a fresh farm, on the 12-sphere scene
at 64x48, 10 frames.

  .venv/bin/python tests/bench/trust_bench.py                  # every case, 10 runs each
  .venv/bin/python tests/bench/trust_bench.py --repeats 3 --cases exact-subtle-2,brute-subtle-3

Cases named `-late` connect the liars after the honest worker (they then get the job's later
tasks: the frames traced again to verify it); the others connect them first, as the tests do.

One row per case: the runs in which every liar that altered a value it sent was banned
("caught"), the runs in which some liar altered a value ("lied"), the runs that completed, the pixels that differ from `tcfarm-worker render` in
completed jobs (exact strategies; search: beyond the same job on the farm before liars
joined), honest workers banned, the referee's CPU as a share of the workers' trace CPU
(mean over runs), and the catch probabilities the job states for its sample. It prints
figures; it asserts nothing.
"""
import argparse
import json
import pathlib
import shutil
import statistics
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "e2e"))
from farm_harness import COORDINATOR, WORKER, LocalFarm, compare, render_reference, small_scene  # noqa: E402
from liar_proxy import start_colluding_liars  # noqa: E402
from tcfarm.client import FINAL_STATES, trace_cost_seconds  # noqa: E402
from test_worker_auth import coordinator_keys, keygen, read_key, worker_keys  # noqa: E402

ROOT = HERE.parents[1]
SCENE = ROOT / "tests/scenes/paper_b_twelve_spheres.json"
FRAMES = 10
WAIT_S = 300
# A job that shows no progress for this long waits for a worker: with no honest one there, one
# joins; with one (banned meanwhile), the run counts as not done.
STILL_S = 15
# name: (strategy, policy, liars, with an honest worker, the honest worker connected first).
# Liars connected first take the job's first tasks; connected after the honest worker, they
# get what comes later (the frames traced again to verify the job). search runs the same job
# without liars first, so its honest worker is always there first.
CASES = {
    "exact-grey-2": ("exact", "grey", 2, True, False),
    "exact-grey-2-late": ("exact", "grey", 2, True, True),
    "exact-subtle-2": ("exact", "subtle", 2, True, False),
    "exact-subtle-2-late": ("exact", "subtle", 2, True, True),
    "exact-checks-2": ("exact", "honest_on_checks", 2, True, False),
    "brute-grey-2": ("brute", "grey", 2, True, False),
    "auto-subtle-1": ("auto", "subtle", 1, True, False),
    "search-grey-2": ("search", "grey", 2, True, True),
    "brute-subtle-3": ("brute", "subtle", 3, False, False),
}


def make_keys(directory):
    secret, public = keygen(COORDINATOR, directory / "coordinator", "coordinator")
    allowed = directory / "allowed"
    allowed.mkdir()
    worker_secret, worker_public = keygen(WORKER, directory / "worker", "worker")
    shutil.copy(worker_public, allowed / "worker.pub")
    return {"secret": secret, "public": public, "allowed": allowed, "worker": worker_secret,
            "honest": "key:" + read_key(worker_public)}


def start_liars(farm, keys, directory, count, policy):
    return start_colluding_liars(farm.zmq, keys, directory, count, policy)


def wait_final(farm, job_id, timeout=WAIT_S, still_s=None):
    """The job once it has ended, or after `timeout` seconds; with still_s, also once it has
    shown no progress for that long (it waits for a worker)."""
    deadline, last, since = time.monotonic() + timeout, None, time.monotonic()
    while time.monotonic() < deadline:
        job = farm.client.job(job_id)
        if job["state"] in FINAL_STATES:
            return job
        progress = (job["frames"]["done"], json.dumps(job["stats"].get("error", {}).get("audit")))
        if progress != last:
            last, since = progress, time.monotonic()
        if still_s is not None and time.monotonic() - since > still_s:
            break
        time.sleep(0.1)
    return farm.client.job(job_id)


def run_once(directory, scene, reference, strategy, policy, liar_count, honest, honest_first, verbose=False):
    """One run on a fresh farm; returns its figures."""
    keys = make_keys(directory)
    options = {"bin_width": 4} if strategy == "search" else {}
    with LocalFarm(directory, workers=0, coordinator_args=coordinator_keys(keys)) as farm:
        baseline = None
        if honest and honest_first:
            farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(1, timeout=60)
        if strategy == "search":
            baseline = farm.run_job(scene, strategy=strategy, timeout=WAIT_S, **options)
        liars = start_liars(farm, keys, directory, liar_count, policy)
        try:
            if honest and not honest_first:
                farm.add_worker(*worker_keys(keys, keys["worker"]))
            farm.wait_for_workers(liar_count + int(honest), timeout=60)
            job = farm.client.submit(scene, strategy=strategy, **options)
            job = wait_final(farm, job["id"], still_s=STILL_S)
            if job["state"] not in FINAL_STATES and not honest:  # waits for a worker: an honest one joins
                farm.add_worker(*worker_keys(keys, keys["worker"]))
                job = wait_final(farm, job["id"])
            bans = {entry["principal"] for entry in farm.client.distrusted_workers()}
        finally:
            for liar in liars:
                liar.stop()
        guilty = {liar.principal for liar in liars if liar.altered(job["id"])}
        wrong = None
        if job["state"] == "completed":
            wrong = compare(reference, farm.store / str(job["id"]))["differing_pixels"]
            if baseline is not None:
                wrong = max(0, wrong - compare(reference, farm.store / str(baseline["id"]))["differing_pixels"])
        stats = job["stats"]
        sample = stats["error"]["referee_sample"]
        if verbose:
            print(f"  run: job {job['state']}, wrong {wrong}; liars "
                  f"{[(liar.name, liar.figures(job['id']), liar.principal in bans) for liar in liars]}; "
                  f"honest banned {keys['honest'] in bans}; audit {stats['error'].get('audit')}", flush=True)
        worker_cpu = trace_cost_seconds(stats) + stats.get("verify_trace_cpu_seconds", 0)
        return {"caught": guilty <= bans, "lied": bool(guilty), "completed": job["state"] == "completed",
                "wrong": wrong, "honest_banned": keys["honest"] in bans,
                "referee_share": sample["referee_cpu_seconds"] / worker_cpu if worker_cpu > 0 else 0.0,
                "altered": sum(liar.altered(job["id"]) for liar in liars),
                "catch": sample["catch_probability"], "share": sample["share"]}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--verbose", action="store_true", help="a line for each run too")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated, of: " + ", ".join(CASES))
    args = parser.parse_args()
    scene = small_scene(SCENE, width=64, height=48, frames=FRAMES)
    with tempfile.TemporaryDirectory() as top:
        top = pathlib.Path(top)
        reference = render_reference(scene, top / "reference")
        print(f"{'case':20} {'caught':>9} {'lied':>5} {'done':>5} {'wrong px':>9} {'honest bans':>11} "
              f"{'referee CPU':>11} {'altered/run':>11} {'share':>6}  stated catch (16/frame, 1/frame, 16 in 1 frame)")
        for name in args.cases.split(","):
            strategy, policy, liar_count, honest, honest_first = CASES[name]
            runs = []
            for repeat in range(args.repeats):
                directory = top / f"{name}-{repeat}"
                directory.mkdir()
                runs.append(run_once(directory, scene, reference, strategy, policy, liar_count, honest, honest_first,
                                     args.verbose))
                shutil.rmtree(directory, ignore_errors=True)
            n = len(runs)
            wrong = [r["wrong"] for r in runs if r["wrong"] is not None]
            catch = runs[-1]["catch"]
            print(f"{name:20} {sum(r['caught'] for r in runs):>4} of {n:<2} {sum(r['lied'] for r in runs):>5} "
                  f"{sum(r['completed'] for r in runs):>5} {sum(wrong):>9} {sum(r['honest_banned'] for r in runs):>11} "
                  f"{statistics.mean(r['referee_share'] for r in runs):>10.1%} "
                  f"{statistics.mean(r['altered'] for r in runs):>11.1f} {runs[-1]['share']:>6.3f}  "
                  f"{catch['altering_16_pixels_every_frame']:.6f}, {catch['altering_1_pixel_every_frame']:.3f}, "
                  f"{catch['altering_16_pixels_of_one_frame']:.3f}", flush=True)


if __name__ == "__main__":
    main()
