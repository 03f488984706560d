"""The coordinator's resident memory with large jobs and no worker: it submits JOBS jobs of
WIDTHxHEIGHT frames, FRAMES frames, 1024 samples a pixel (the default strategy), and prints
the coordinator's VmRSS before, with them accepted, and after canceling them, with the
jobs' states. TCFARM_BUILD names another build to measure (one of another commit):

  python tests/bench/coordinator_memory.py --size 6144x6144 --frames 100000 --jobs 3
  TCFARM_BUILD=../main/build python tests/bench/coordinator_memory.py
"""
import argparse
import json
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import LocalFarm  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


def rss_gib(process):
    with open(f"/proc/{process.pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / (1 << 20)
    raise RuntimeError(f"no VmRSS for process {process.pid}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", default="6144x6144", help="WIDTHxHEIGHT of each job's frames")
    parser.add_argument("--frames", type=int, default=100000)
    parser.add_argument("--jobs", type=int, default=3)
    parser.add_argument("--settle", type=float, default=5, help="seconds to wait after submitting and canceling")
    args = parser.parse_args()
    width, height = (int(side) for side in args.size.split("x"))
    scene = json.loads((ROOT / "tests" / "scenes" / "paper_a_one_sphere.json").read_text())
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": args.frames},
                           samples_per_pixel=1024)
    with tempfile.TemporaryDirectory() as folder, LocalFarm(folder, workers=0) as farm:
        time.sleep(1)
        before = rss_gib(farm.coordinator)
        jobs = [farm.client.submit(scene)["id"] for _ in range(args.jobs)]
        time.sleep(args.settle)
        accepted = rss_gib(farm.coordinator)
        states = [farm.client.job(job)["state"] for job in jobs]
        for job in jobs:
            farm.client.cancel(job)
        time.sleep(args.settle)
        after = rss_gib(farm.coordinator)
    print(f"coordinator RSS: {before:.2f} GiB before; {accepted:.2f} GiB with {args.jobs} jobs "
          f"({', '.join(states)}); {after:.2f} GiB after canceling them")


if __name__ == "__main__":
    main()
