"""The paper's evaluation (Figure 9) on this farm: each paper animation rendered with
brute force and with each strategy and bin width; relative cost, the theoretical cost of
equation 3 with the measured d, pixels traced and error against brute force.

  python tests/bench/paper_table.py [--bin-widths 2-10] [--strategies search,guarded,auto]
      [--exact-lengths 10,20,30,60] [--markdown FILE] [--json FILE] [--plots DIR]

Relative cost is the job's tracing time over the brute-force job's tracing time, both
summed over tasks as the workers report them, measured in the same run: CPU seconds of
the tracing threads, which waiting for shared cores does not inflate. "rel. wall" is
the jobs' elapsed time, encoding of the frame files included. Brute force is run first and
again after every few jobs (--brute-every; after one unmeasured job that warms the farm
and loads the scene), and each job's ratios are over the mean of the brute-force runs
just before and just after it.
"""
import argparse
import json
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from farm_harness import LocalFarm, compare  # noqa: E402
from tcfarm.client import trace_cost_seconds  # noqa: E402

SCENES = ["paper_a_one_sphere", "paper_b_twelve_spheres", "paper_c_terrain_flyover"]
# Figure 9 of the paper, bin width 10: relative CPU, theoretical, pixels traced, % error.
PAPER_N10 = {"paper_a_one_sphere": (0.17, 0.18, 0.19, 0.1),
             "paper_b_twelve_spheres": (0.29, 0.25, 0.3, 0.59),
             "paper_c_terrain_flyover": (0.63, 0.29, 0.48, 2.4)}


def equation3_relative_cost(frames, bin_width, d):
    """1 / P of the paper's equation 3: the share of brute-force work Search needs."""
    whole, rem = divmod(frames - 1, bin_width - 1)
    a = 1 + whole * (1 + (bin_width - 2) * d)
    b = 0 if rem == 0 else (rem - 1) * d + 1
    return (a + b) / frames


def parse_widths(text):
    if "-" in text:
        low, high = map(int, text.split("-"))
        return list(range(low, high + 1))
    return [int(w) for w in text.split(",")]


def exact_relative_cost(frames, length, d):
    """Exact's analogue of equation 3: each segment's first frame in full, then the
    pixels that change (d per frame, if horizons were tight)."""
    segments = -(-frames // length)
    return (segments + (frames - segments) * d) / frames


def measure_scene(farm, name, strategies, widths, exact_lengths, brute_every):
    scene = json.loads((ROOT / "tests" / "scenes" / f"{name}.json").read_text())
    # The scene's first job pays for sending and loading it, and the first job on a farm
    # for warming the processes: run once, not measured.
    farm.run_job(scene, timeout=3600, strategy="brute")
    runs = [(s, w) for s in strategies if s != "auto" for w in widths]
    runs += [("exact", l) for l in exact_lengths]
    if "auto" in strategies:
        runs.append(("auto", None))  # it chooses its own strategy and width
    # Brute force again every brute_every jobs, and each job priced against the mean of the
    # brute-force runs just before and just after it: the machine's speed drifts (by a sixth
    # over one scene's runs on a shared machine), and so both sides of a ratio see the same.
    brutes = [farm.run_job(scene, timeout=3600, strategy="brute")]
    jobs = []
    for index, (strategy, width) in enumerate(runs):
        job = farm.run_job(scene, timeout=3600, strategy=strategy, bin_width=width or 10)
        jobs.append((strategy, width, job, len(brutes) - 1))
        if (index + 1) % brute_every == 0 or index + 1 == len(runs):
            brutes.append(farm.run_job(scene, timeout=3600, strategy="brute"))
    brute = brutes[0]
    frames = brute["frames"]["count"]
    d = 1 - brute["stats"]["coherence"]["frame_to_frame"]["mean"]
    costs = [trace_cost_seconds(b["stats"]) for b in brutes]
    print(f"{name}: brute force's CPU over the runs, against its first: "
          + " ".join(f"{c / costs[0]:.3f}" for c in costs), flush=True)
    rows = []
    for strategy, width, job, before in jobs:
        brute_cost = (costs[before] + costs[before + 1]) / 2
        brute_wall = (brutes[before]["stats"]["wall_seconds"] + brutes[before + 1]["stats"]["wall_seconds"]) / 2
        error = compare(farm.store / str(brute["id"]), farm.store / str(job["id"]))
        if strategy == "auto":
            chosen = job["stats"]["strategy"]
            width = chosen["bin_width"]
            strategy = f"auto ({chosen['name']})"
        rows.append({
            "scene": name, "strategy": strategy, "bin_width": width, "d": d,
            "relative_cost": trace_cost_seconds(job["stats"]) / brute_cost,
            "relative_wall": job["stats"]["wall_seconds"] / brute_wall,
            "brute_drift": costs[before + 1] / costs[before],
            "theoretical": (exact_relative_cost(frames, width, d) if "exact" in strategy
                            else equation3_relative_cost(frames, width, d)),
            "wall_seconds": job["stats"]["wall_seconds"],
            "trace_seconds": job["stats"]["trace_seconds"],
            "trace_cpu_seconds": job["stats"].get("trace_cpu_seconds"),
            "pixels_traced": job["traced_pixel_ratio"],
            "error_percent": 100 * error["differing_share"],
            "psnr_db": error["psnr_db"],
        })
    return rows


def markdown(rows):
    lines = ["| scene | strategy | n | d | rel. cost | theoretical | cost/theo. | pixels traced "
             "| % error | PSNR dB | rel. wall | paper n=10 (cost, theo., traced, % err) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        paper = PAPER_N10[r["scene"]] if r["bin_width"] == 10 else None
        psnr = "inf" if r["psnr_db"] is None else f"{r['psnr_db']:.1f}"
        lines.append(
            f"| {r['scene']} | {r['strategy']} | {r['bin_width']} | {r['d']:.3f} "
            f"| {r['relative_cost']:.3f} | {r['theoretical']:.3f} "
            f"| {r['relative_cost'] / r['theoretical']:.2f} | {r['pixels_traced']:.3f} "
            f"| {r['error_percent']:.3f} | {psnr} | {r['relative_wall']:.3f} "
            f"| {', '.join(map(str, paper)) if paper else ''} |")
    return "\n".join(lines)


def plots(rows, directory):
    """Figure 10 style: relative cost (measured, theoretical) and % error against bin
    width per scene and strategy; and error against run time for every job."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    colours = {"search": "C0", "guarded": "C1", "exact": "C2", "auto (exact)": "C3",
               "auto (guarded)": "C3"}
    scenes = sorted({r["scene"] for r in rows})
    figure, axes = plt.subplots(len(scenes), 2, figsize=(11, 3.4 * len(scenes)), squeeze=False)
    for i, scene in enumerate(scenes):
        for strategy in sorted({r["strategy"] for r in rows}):
            mine = sorted((r for r in rows if r["scene"] == scene and r["strategy"] == strategy),
                          key=lambda r: r["bin_width"])
            if not mine:
                continue
            widths = [r["bin_width"] for r in mine]
            colour = colours.get(strategy)
            if strategy.startswith("auto"):  # one job: the width it chose, marked
                axes[i][0].scatter(widths, [r["relative_cost"] for r in mine], marker="*", s=160,
                                   color=colour, zorder=3, label=strategy)
                axes[i][1].scatter(widths, [r["error_percent"] for r in mine], marker="*", s=160,
                                   color=colour, zorder=3, label=strategy)
                continue
            axes[i][0].plot(widths, [r["relative_cost"] for r in mine], "o-", color=colour,
                            label=strategy)
            axes[i][0].plot(widths, [r["theoretical"] for r in mine], ":", color=colour,
                            label=f"{strategy}, theory")
            axes[i][1].plot(widths, [r["error_percent"] for r in mine], "o-", color=colour,
                            label=strategy)
        axes[i][0].set(title=f"{scene}: relative cost", xlabel="bin width / segment length",
                       ylabel="cost / brute force")
        axes[i][1].set(title=f"{scene}: pixels in error", xlabel="bin width / segment length",
                       ylabel="% pixels differing")
        axes[i][0].legend(fontsize=7)
        axes[i][1].legend(fontsize=7)
    figure.tight_layout()
    figure.savefig(directory / "cost_and_error_by_bin_width.png", dpi=90)

    figure, axis = plt.subplots(figsize=(7, 5))
    for strategy in sorted({r["strategy"] for r in rows}):
        mine = [r for r in rows if r["strategy"] == strategy]
        axis.scatter([r["relative_cost"] for r in mine], [r["error_percent"] for r in mine],
                     color=colours.get(strategy), label=strategy)
    axis.set(xlabel="relative cost (tracing time / brute force)", ylabel="% pixels differing",
             title="error against run time, all paper animations")
    axis.legend()
    figure.tight_layout()
    figure.savefig(directory / "error_against_run_time.png", dpi=90)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin-widths", default="10", type=parse_widths)
    parser.add_argument("--strategies", default="search")
    parser.add_argument("--exact-lengths", default="", type=lambda t: parse_widths(t) if t else [])
    parser.add_argument("--scenes", default=",".join(SCENES))
    parser.add_argument("--brute-every", type=int, default=4, help="jobs between brute-force runs")
    parser.add_argument("--plots")
    parser.add_argument("--replot", help="redraw --plots from a --json file, render nothing")
    parser.add_argument("--markdown")
    parser.add_argument("--json")
    args = parser.parse_args()
    if args.replot:
        plots(json.loads(pathlib.Path(args.replot).read_text()), args.plots or ".")
        return
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        with LocalFarm(directory, workers=0, local_workers=1, worker_threads=0) as farm:
            farm.wait_for_workers(1)
            for name in args.scenes.split(","):
                rows += measure_scene(farm, name, args.strategies.split(","), args.bin_widths,
                                      args.exact_lengths, args.brute_every)
                print(markdown([r for r in rows if r["scene"] == name]).split("\n", 2)[2],
                      flush=True)
    table = markdown(rows)
    print(table)
    if args.markdown:
        pathlib.Path(args.markdown).write_text(table + "\n")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    if args.plots:
        plots(rows, args.plots)


if __name__ == "__main__":
    main()
