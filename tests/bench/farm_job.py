"""Renders one scene as one job on a fresh local farm (coordinator + one worker using all
cores) and prints the job's figures. As a whole process it is the farm's end-to-end cost,
to set beside the standalone renderer (`tcfarm-worker render`) on the same frames:

  python tests/bench/farm_job.py tests/scenes/paper_b_twelve_spheres.json --strategy brute

With --pair STRATEGY it renders the scene twice on the same farm, brute force and then
STRATEGY, and prints the job wall and the trace CPU of the second over the first's: what a
user waits for beside what the job costs. Each job's line also gives the CPU the coordinator
process and the worker processes spent while it ran (their own, tracing or not).

  python tests/bench/farm_job.py tests/scenes/paper_b_twelve_spheres.json --pair auto --size 1280x720 --spp 4
"""
import argparse
import json
import os
import pathlib
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import LocalFarm  # noqa: E402


def process_cpu_seconds(pid):
    """User and system CPU seconds of a process so far (Linux /proc), its ended threads included."""
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def children_of(parent):
    pids = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            if stat.read_text().rsplit(")", 1)[1].split()[1] == str(parent):
                pids.append(int(stat.parent.name))
        except OSError:
            pass  # gone meanwhile
    return pids


def farm_cpu_seconds(farm):
    """CPU seconds so far of the coordinator and, together, of the worker processes it started."""
    workers = children_of(farm.coordinator.pid)
    return process_cpu_seconds(farm.coordinator.pid), sum(process_cpu_seconds(pid) for pid in workers)


def run(farm, scene, strategy, bin_width):
    coordinator_before, workers_before = farm_cpu_seconds(farm)
    job = farm.client.submit(scene, strategy=strategy, bin_width=bin_width)
    job = farm.client.wait(job["id"], poll_seconds=0.05, timeout=3600)
    coordinator_after, workers_after = farm_cpu_seconds(farm)
    stats = job["stats"]
    # Beside the tracing threads' CPU, the processes' own: what shares the cores with tracing.
    print(f"{strategy}: {job['state']}: traced-pixel ratio {job['traced_pixel_ratio']:.4f}, "
          f"wall {stats['wall_seconds']:.2f} s, trace {stats['trace_seconds']:.2f} s, "
          f"trace CPU {stats.get('trace_cpu_seconds', float('nan')):.2f} s; "
          f"coordinator process CPU {coordinator_after - coordinator_before:.2f} s, "
          f"worker processes CPU {workers_after - workers_before:.2f} s")
    # What trust cost: the referee's unseen sample, beside the workers' tracing.
    sample = stats["error"]["referee_sample"]
    trace_cpu = stats.get("trace_cpu_seconds") or float("nan")
    catch = sample["catch_probability"]
    print(f"{strategy}: referee's unseen sample {100 * sample['share']:.2f} % of {sample['pixels_sent']} px sent "
          f"({sample['referee_traces']} referee traces, {sample['horizon_checks']} of them for horizons): "
          f"referee CPU {sample['referee_cpu_seconds']:.2f} s = {100 * sample['referee_cpu_seconds'] / trace_cpu:.1f} % "
          f"of the trace CPU; a worker altering 16 px of every frame is caught with probability "
          f"{catch['altering_16_pixels_every_frame']:.7f}, 1 px of every frame {catch['altering_1_pixel_every_frame']:.3f}")
    return job


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("scene")
    parser.add_argument("--strategy", default="brute")
    parser.add_argument("--bin-width", type=int, default=10)
    parser.add_argument("--pair", metavar="STRATEGY", help="brute force, then STRATEGY, on the same farm")
    parser.add_argument("--size", help="WxH instead of the scene's")
    parser.add_argument("--spp", type=int, help="samples per pixel instead of the scene's")
    args = parser.parse_args()
    scene = json.loads(pathlib.Path(args.scene).read_text())
    if args.size:
        width, height = map(int, args.size.split("x"))
        scene["render"].update(width=width, height=height)
    if args.spp:
        scene["render"]["samples_per_pixel"] = args.spp
    with tempfile.TemporaryDirectory() as directory:
        with LocalFarm(directory, workers=0, local_workers=1, worker_threads=0) as farm:
            farm.wait_for_workers(1)
            if not args.pair:
                return 0 if run(farm, scene, args.strategy, args.bin_width)["state"] == "completed" else 1
            brute = run(farm, scene, "brute", args.bin_width)
            other = run(farm, scene, args.pair, args.bin_width)
    wall = other["stats"]["wall_seconds"] / brute["stats"]["wall_seconds"]
    cpu = other["stats"]["trace_cpu_seconds"] / brute["stats"]["trace_cpu_seconds"]
    # What the job also traced to check itself (exact's brute-force reference frame, spot
    # checks): work the job's wall holds but its trace CPU leaves out (stats.cost counts it by part).
    checks = other["stats"].get("verify_trace_cpu_seconds", 0.0) / brute["stats"]["trace_cpu_seconds"]
    print(f"{args.pair} against brute force: job wall {wall:.3f}, trace CPU {cpu:.3f}, wall / CPU {wall / cpu:.2f}; "
          f"with its checks' CPU {cpu + checks:.3f}, wall / that {wall / (cpu + checks):.2f}")
    return 0 if brute["state"] == other["state"] == "completed" else 1


if __name__ == "__main__":
    sys.exit(main())
