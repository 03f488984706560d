"""The main job: render an example animation on a local farm with brute force, the paper's
search and auto, and report what temporal coherence bought (traced-pixel ratio, time) and
what it cost (error against brute force).

  python scripts/demo_farm.py [--scene tests/scenes/paper_b_twelve_spheres.json] [--bin-width 10]
"""
import argparse
import json
import pathlib
import shutil
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from farm_harness import LocalFarm, compare  # noqa: E402
from tcfarm.client import trace_cost_seconds  # noqa: E402


def run(farm, scene, label, **options):
    job = farm.client.submit(scene, name=label, **options)
    job = farm.client.wait(job["id"], timeout=3600)
    if job["state"] != "completed":
        sys.exit(f"{label}: job {job['id']} {job['state']}: {job.get('error')}")
    return job


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(ROOT / "tests/scenes/paper_b_twelve_spheres.json"))
    parser.add_argument("--bin-width", type=int, default=10)
    parser.add_argument("--out", default=str(ROOT / "out" / "demo"))
    args = parser.parse_args()

    out = pathlib.Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    scene = json.loads(pathlib.Path(args.scene).read_text())
    with LocalFarm(out, workers=0, local_workers=1, worker_threads=0) as farm:
        farm.wait_for_workers(1)
        print(f"local farm: {farm.url} (workers on {farm.zmq}), frames in {farm.store}")
        brute = run(farm, scene, "brute", strategy="brute")
        jobs = [run(farm, scene, f"search n={args.bin_width}", strategy="search",
                    bin_width=args.bin_width),
                run(farm, scene, "auto", strategy="auto")]
        errors = [compare(farm.store / str(brute["id"]), farm.store / str(job["id"]))
                  for job in jobs]

    name = pathlib.Path(args.scene).stem
    for job in [brute] + jobs:
        stats = job["stats"]
        print(f"{name} {label(job):>17}: traced-pixel ratio {job['traced_pixel_ratio']:.4f}, "
              f"wall {stats['wall_seconds']:.2f} s, trace {stats['trace_seconds']:.2f} s, "
              f"trace CPU {trace_cost_seconds(stats):.2f} s")
    for job, error in zip(jobs, errors):
        relative = trace_cost_seconds(job["stats"]) / trace_cost_seconds(brute["stats"])
        wall = job["stats"]["wall_seconds"] / brute["stats"]["wall_seconds"]
        psnr = "inf" if error["psnr_db"] is None else f"{error['psnr_db']:.1f} dB"
        print(f"{label(job)} against brute force: relative cost {relative:.3f} (trace CPU time), "
              f"{wall:.3f} (wall); error: {error['differing_pixels']} pixels differ "
              f"({100 * error['differing_share']:.3f} %), max abs {error['max_abs_error']:.4g}, "
              f"PSNR {psnr}")


def label(job):
    """The job's name, with what auto chose."""
    if job["name"] != "auto":
        return job["name"]
    strategy = job["stats"]["strategy"]
    return f"auto: {strategy['name']} {strategy['bin_width']}"


if __name__ == "__main__":
    main()
