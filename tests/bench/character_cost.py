"""What `exact` and `auto` cost against brute force on one shot, on a fresh local farm (a
coordinator and one worker using all cores), and how close exact's traced pixels come to
the pixels that change at all:

  python tests/bench/character.py /tmp/walk.glb
  python tests/bench/character_cost.py /tmp/walk.glb --size 640x480 --frames 0:47

The shot is a glTF or OBJ file (imported by the farm, as `tcfarm submit FILE --size WxH
--frames A:B` sends it) or a tcfarm JSON scene. Each strategy renders the same frames; the
markdown table gives per strategy the traced-pixel ratio, trace CPU (stats.trace_cpu_seconds)
and job wall over brute force's, what the job ran (auto's choice) and its one prediction of
its relative cost (stats.strategy.predicted_relative_cost), the pixels that differ from brute force's frames, and exact's traced ratio
over the share of pixels that change: the first frame plus each later frame's changed
pixels over all pixels, from `tcfarm-coordinator analyze` of brute force's frames.
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import COORDINATOR, LocalFarm  # noqa: E402
from tcfarm.scene_files import scene_files  # noqa: E402


def submission(client, path, size, spp):
    """(scene, options) for client.submit: a JSON scene with its size and samples set, or a
    scene file uploaded with its buffers and images and imported at that size."""
    files = scene_files(path)
    upload = client.upload_assets([str(local) for local in files.assets.values()])
    options = {"assets": {name: upload.hashes[str(local)] for name, local in files.assets.items()} or None}
    if files.scene is None:
        imported = {key: value for key, value in (("size", size), ("spp", spp)) if value is not None}
        options.update(scene_file=files.scene_file, **{"import": imported or None})
        return None, options
    render = files.scene["render"]
    if size:
        render.update(width=size[0], height=size[1])
    if spp:
        render["samples_per_pixel"] = spp
    return files.scene, options


def coordinator_json(*args):
    result = subprocess.run([str(COORDINATOR), *map(str, args), "--json"], capture_output=True, text=True,
                            timeout=3600)
    if result.returncode != 0:
        sys.exit(f"tcfarm-coordinator {args[0]} failed: {result.stderr.strip()}")
    return json.loads(result.stdout)


def changing_share(frames_dir):
    """The first frame and every later frame's changed pixels, over all the frames' pixels:
    what a renderer that traced exactly the pixels that change would trace."""
    coherence = coordinator_json("analyze", frames_dir)["frame_to_frame"]["by_frame"]  # unchanged shares
    return (1 + sum(1 - unchanged for unchanged in coherence)) / (1 + len(coherence))


class WorkerWatch:
    """Ends the bench when the farm has had no worker for `grace` seconds: the only worker,
    dropped for returning wrong values, is banned, and the job would wait for ever."""

    def __init__(self, farm, grace=15.0):
        self.farm, self.grace, self.since, self.asked = farm, grace, None, 0.0

    def __call__(self, job):
        if time.monotonic() - self.asked < 1:  # asked once a second: the job is polled far more often
            return
        self.asked = time.monotonic()
        if self.farm.client.workers()["workers"]:
            self.since = None
            return
        self.since = self.since or time.monotonic()
        if time.monotonic() - self.since > self.grace:
            log = (self.farm.directory / "coordinator.log").read_text().splitlines()
            dropped = "\n".join(dict.fromkeys(line for line in log if "dropped" in line or "banned" in line))
            sys.exit(f"job {job['id']} ({job['strategy']}) has no worker left:\n{dropped}")


def render(farm, scene, options, strategy, repeat):
    """The job of `strategy` with the least trace CPU of `repeat` runs, and their least wall."""
    jobs = []
    for _ in range(repeat):
        job = farm.client.submit(scene, strategy=strategy, **options)
        job = farm.client.wait(job["id"], poll_seconds=0.05, on_progress=WorkerWatch(farm))
        if job["state"] != "completed":
            sys.exit(f"{strategy}: job {job['id']} {job['state']}: {job.get('error')}")
        jobs.append(job)
    best = min(jobs, key=lambda job: job["stats"]["trace_cpu_seconds"])
    return best, min(job["stats"]["wall_seconds"] for job in jobs)


def figure(value):
    return "-" if value is None else f"{value:.3f}"


def table(rows, brute, brute_wall, share):
    """The markdown table: one row per strategy, brute force's figures the unit. Predicted:
    the job's one prediction of its CPU cost against brute force's (stats.strategy)."""
    lines = ["| strategy | ran | traced-pixel ratio | traced / changing | trace CPU / brute | wall / brute "
             "| predicted | differing pixels |", "| --- " * 8 + "|"]
    for strategy, (job, wall, differing) in rows.items():
        stats = job["stats"]
        lines.append(f"| {strategy} | {stats['strategy']['name']} | {job['traced_pixel_ratio']:.4f} "
                     f"| {job['traced_pixel_ratio'] / share:.2f} "
                     f"| {stats['trace_cpu_seconds'] / brute['stats']['trace_cpu_seconds']:.3f} "
                     f"| {wall / brute_wall:.3f} | {figure(stats['strategy'].get('predicted_relative_cost'))} "
                     f"| {differing} |")
    return "\n".join(lines)


def weighed(job):
    """What auto weighed: "brute 1.000 (definition), exact 1.021 (scene)"."""
    return ", ".join(f"{c['strategy']} {figure(c.get('predicted_relative_cost'))} ({c.get('from', '?')})"
                     for c in job["stats"]["strategy"].get("candidates", []))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="a glTF, GLB or OBJ file, or a tcfarm JSON scene")
    parser.add_argument("--size", help="WxH (default: the scene's; 640x480 for a scene file)")
    parser.add_argument("--frames", default=None, help="A:B, both inclusive (default: the scene's)")
    parser.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    parser.add_argument("--strategies", default="auto,exact",
                        help="besides brute force, comma-separated, run in this order (auto prices exact by the "
                             "scene's prices once an exact job has measured them)")
    parser.add_argument("--guarded", action="store_true", help="also guarded")
    parser.add_argument("--repeat", type=int, default=1, help="runs per strategy; the least is kept")
    args = parser.parse_args()
    size = [int(n) for n in args.size.lower().split("x")] if args.size else None
    strategies = ["brute"] + [s for s in args.strategies.split(",") if s and s != "brute"]
    if args.guarded and "guarded" not in strategies:
        strategies.append("guarded")
    with tempfile.TemporaryDirectory() as directory:
        with LocalFarm(directory, workers=0, local_workers=1, worker_threads=0) as farm:
            farm.wait_for_workers(1)
            scene, options = submission(farm.client, args.scene, size, args.spp)
            if args.frames:
                start, _, end = args.frames.partition(":")
                options["frames"] = {"start": int(start), "end": int(end or start)}
            jobs = {strategy: render(farm, scene, options, strategy, max(1, args.repeat)) for strategy in strategies}
            brute_dir = farm.store / str(jobs["brute"][0]["id"])
            share = changing_share(brute_dir)
            rows = {strategy: (job, wall, coordinator_json("compare", brute_dir, farm.store / str(job["id"]))
                               ["differing_pixels"]) for strategy, (job, wall) in jobs.items()}
    brute, brute_wall = jobs["brute"]
    print(f"{pathlib.Path(args.scene).name}: {brute['width']}x{brute['height']}, {brute['frames']['count']} frames; "
          f"brute force: trace CPU {brute['stats']['trace_cpu_seconds']:.2f} s, wall {brute_wall:.2f} s; "
          f"pixels that change: {share:.4f}\n")
    print(table(rows, brute, brute_wall, share))
    if "auto" in jobs:
        auto = jobs["auto"][0]
        print(f"\nauto weighed {weighed(auto)}: {auto['stats']['strategy'].get('reason', '')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
