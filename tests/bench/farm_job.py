"""Renders one scene as one job on a fresh local farm (coordinator + one worker using all
cores) and prints the job's figures. As a whole process it is the farm's end-to-end cost,
to set beside the standalone renderer (`tcfarm-worker render`) on the same frames:

  python tests/bench/farm_job.py tests/scenes/paper_b_twelve_spheres.json --strategy brute
"""
import argparse
import json
import pathlib
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import LocalFarm  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("scene")
    parser.add_argument("--strategy", default="brute")
    parser.add_argument("--bin-width", type=int, default=10)
    args = parser.parse_args()
    scene = json.loads(pathlib.Path(args.scene).read_text())
    with tempfile.TemporaryDirectory() as directory:
        with LocalFarm(directory, workers=0, local_workers=1, worker_threads=0) as farm:
            farm.wait_for_workers(1)
            job = farm.client.submit(scene, strategy=args.strategy, bin_width=args.bin_width)
            job = farm.client.wait(job["id"], poll_seconds=0.05, timeout=3600)
    stats = job["stats"]
    print(f"{job['state']}: traced-pixel ratio {job['traced_pixel_ratio']:.4f}, "
          f"wall {stats['wall_seconds']:.2f} s, trace {stats['trace_seconds']:.2f} s")
    return 0 if job["state"] == "completed" else 1


if __name__ == "__main__":
    sys.exit(main())
