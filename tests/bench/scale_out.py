"""How a job's cost and parallelism hold as the farm grows: each scene rendered by each
strategy on a local farm of W one-thread worker processes, for each W. CPU cost is the
tracing threads' CPU time (what `stats.cost` prices), so it means something even when the
W workers share a few cores; wall time does not, there.

  .venv/bin/python tests/bench/scale_out.py                      # W = 1, 4, 16, 64
  .venv/bin/python tests/bench/scale_out.py --workers 1,16 --scenes b --strategies auto

Each job runs --repeat times (3), in rounds: every strategy once, then brute force. A
job's relative CPU cost is its work over the mean of the brute-force runs either side of
it on the same farm, and the round whose cost is the median counts. Per row: the
strategy as resolved (and its bin width or segment length), the traced-pixel
ratio, the relative CPU cost, the work and span in CPU seconds of tracing, parallelism (work / span:
the most workers the job can keep busy), and the job's wall seconds. Every job renders
its scene as a first render does (see `fresh`). Last, per scene and strategy, the CPU cost
at each W over the smallest W's: the job's work, and its cost against brute force.
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import WORKER, LocalFarm  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENES = {"a": ROOT / "tests/scenes/paper_a_one_sphere.json",
          "b": ROOT / "tests/scenes/paper_b_twelve_spheres.json"}
# Strategy name and the bin width (segment length) it is asked with.
STRATEGIES = {"brute": ("brute", 2), "search": ("search", 10), "exact": ("exact", 60), "auto": ("auto", 10)}


def gltf_scene(directory, width, height, frames):
    """The glTF test animation (a turntable of boxes under a still camera), as the canonical
    JSON scene the farm gets for it, `frames` frames over its one second."""
    subprocess.run([sys.executable, str(ROOT / "tests/gltf/make_gltf.py"), str(directory)], check=True,
                   capture_output=True)
    printed = subprocess.run([str(WORKER), "render", str(directory / "animated_hierarchy.gltf"),
                              "--fps", str(frames - 1), "--size", f"{width}x{height}", "--print-scene"],
                             check=True, capture_output=True, text=True)
    return json.loads(printed.stdout)


def load_scene(name, directory, width, height, frames):
    scene = gltf_scene(directory, width, height, frames) if name == "gltf" else \
        json.loads(SCENES[name].read_text())
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": frames})
    return scene


def fresh(scene, serial=[0]):
    """The scene with a background no two jobs share: a new scene hash, so every job meets
    its scene as a first render does (no worker has it built or cached), whatever ran
    before it on the farm. Where no ray escapes, nothing else changes."""
    serial[0] += 1
    scene = json.loads(json.dumps(scene))
    background = scene.get("background", [0.0, 0.0, 0.0])
    scene["background"] = [background[0], background[1], background[2] + 1e-6 * serial[0]]
    return scene


def run_job(farm, scene, strategy, bin_width):
    job = farm.client.submit(fresh(scene), strategy=strategy, bin_width=bin_width)
    job = farm.client.wait(job["id"], poll_seconds=0.05, timeout=3600)
    if job["state"] != "completed":
        raise RuntimeError(f"job {job['id']} {job['state']}: {job.get('error')}")
    stats = job["stats"]
    parallelism = stats.get("parallelism", {})
    resolved = stats["strategy"]
    return {"strategy": f"{resolved['name']} {resolved['bin_width']}",
            "traced": job["traced_pixel_ratio"],
            "work": parallelism.get("work_seconds", 0.0),
            "span": parallelism.get("span_seconds", 0.0),
            "parallelism": parallelism.get("parallelism", 0.0),
            "wall": stats["wall_seconds"]}


def measured_round(farm, scene, strategies, previous_brute):
    """One round: each strategy once, then brute force. Each strategy's cost is its work over
    the mean of the brute-force runs either side of it (`previous_brute`, the one that ends
    this round), so that the machine's drift falls on both sides of the ratio alike."""
    rows = {asked: run_job(farm, scene, *STRATEGIES[asked]) for asked in strategies if asked != "brute"}
    brute = run_job(farm, scene, *STRATEGIES["brute"])
    yardstick = (previous_brute["work"] + brute["work"]) / 2
    for row in rows.values():
        row["cost"] = row["work"] / yardstick
    rows["brute"] = dict(brute, cost=brute["work"] / yardstick)
    return rows, brute


def measure(farm, scene, strategies, repeat):
    """Per strategy, the round of `repeat` whose cost is the median, so that one round
    slowed by whatever else shares the cores neither lowers nor raises it."""
    previous = run_job(farm, scene, *STRATEGIES["brute"])
    rounds = []
    for _ in range(max(1, repeat)):
        rows, previous = measured_round(farm, scene, strategies, previous)
        rounds.append(rows)
    return {asked: sorted((r[asked] for r in rounds), key=lambda row: row["cost"])[len(rounds) // 2]
            for asked in strategies}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", default="1,4,16,64", help="farm sizes, comma-separated")
    parser.add_argument("--scenes", default="a,b,gltf", help="a, b (the paper's), gltf")
    parser.add_argument("--strategies", default="brute,search,exact,auto")
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=3,
                        help="rounds of every job; the round of median cost counts")
    args = parser.parse_args()
    width, height = map(int, args.size.split("x"))
    sizes = [int(w) for w in args.workers.split(",")]
    strategies = args.strategies.split(",")
    results = {}
    print(f"{'scene':6} {'W':>3} {'asked':8} {'ran as':11} {'traced':>7} {'CPU cost':>8} {'work s':>7} "
          f"{'span s':>7} {'parallel':>8} {'wall s':>7}")
    with tempfile.TemporaryDirectory() as directory:
        directory = pathlib.Path(directory)
        scenes = {name: load_scene(name, directory, width, height, args.frames) for name in args.scenes.split(",")}
        for workers in sizes:
            (directory / f"farm{workers}").mkdir()
            with LocalFarm(directory / f"farm{workers}", workers=workers, worker_threads=1) as farm:
                farm.wait_for_workers(workers, timeout=120)
                # Worker processes live long on a farm: their one-time start (threads,
                # first pages) is paid here, not by the first job measured.
                run_job(farm, load_scene("a", directory, 64, 48, 2), "brute", 2)
                for name, scene in scenes.items():
                    for asked, row in measure(farm, scene, strategies, args.repeat).items():
                        results[name, asked, workers] = row
                        print(f"{name:6} {workers:3} {asked:8} {row['strategy']:11} {row['traced']:7.4f} "
                              f"{row['cost']:8.3f} {row['work']:7.2f} {row['span']:7.3f} {row['parallelism']:8.1f} "
                              f"{row['wall']:7.2f}", flush=True)
    # The same job on every farm: its work should not grow with W. Beside it, the cost
    # against each farm's own brute force, which also carries that job's noise.
    print(f"\nAt W over at W = {sizes[0]}: work (the same job's CPU seconds), and CPU cost against brute force:")
    for name in scenes:
        for asked in strategies:
            first = results[name, asked, sizes[0]]
            text = "  ".join(f"W={w}: {results[name, asked, w]['work'] / first['work']:.3f} "
                             f"({results[name, asked, w]['cost'] / first['cost']:.3f})" for w in sizes)
            print(f"  {name:6} {asked:8} {text}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
