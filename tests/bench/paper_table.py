"""The paper's evaluation (Figure 9) on this farm: each paper animation rendered with
brute force and with each strategy and bin width; relative cost, the theoretical cost of
equation 3 with the measured d, pixels traced and error against brute force.

  python tests/bench/paper_table.py [--bin-widths 10] [--strategies search] [--markdown FILE]

Relative cost is the job's tracing time over the brute-force job's tracing time, both
summed over tasks as the workers report them, measured in the same run.
"""
import argparse
import json
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from farm_harness import LocalFarm, compare  # noqa: E402

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


def run_job(farm, scene, **options):
    job = farm.client.submit(scene, **options)
    job = farm.client.wait(job["id"], poll_seconds=0.05, timeout=3600)
    if job["state"] != "completed":
        sys.exit(f"job {job['id']} {job['state']}: {job.get('error')}")
    return job


def measure_scene(farm, name, strategies, widths):
    scene = json.loads((ROOT / "tests" / "scenes" / f"{name}.json").read_text())
    brute = run_job(farm, scene, strategy="brute")
    frames = brute["frames"]["count"]
    d = 1 - brute["stats"]["coherence"]["frame_to_frame"]["mean"]
    rows = []
    for strategy in strategies:
        for width in widths:
            job = run_job(farm, scene, strategy=strategy, bin_width=width)
            error = compare(farm.store / str(brute["id"]), farm.store / str(job["id"]))
            rows.append({
                "scene": name, "strategy": strategy, "bin_width": width, "d": d,
                "relative_cost": job["stats"]["trace_seconds"] / brute["stats"]["trace_seconds"],
                "relative_wall": job["stats"]["wall_seconds"] / brute["stats"]["wall_seconds"],
                "theoretical": equation3_relative_cost(frames, width, d),
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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin-widths", default="10", type=parse_widths)
    parser.add_argument("--strategies", default="search")
    parser.add_argument("--scenes", default=",".join(SCENES))
    parser.add_argument("--markdown")
    parser.add_argument("--json")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        with LocalFarm(directory, workers=0, local_workers=1, worker_threads=0) as farm:
            farm.wait_for_workers(1)
            for name in args.scenes.split(","):
                rows += measure_scene(farm, name, args.strategies.split(","), args.bin_widths)
                print(markdown([r for r in rows if r["scene"] == name]).split("\n", 2)[2],
                      flush=True)
    table = markdown(rows)
    print(table)
    if args.markdown:
        pathlib.Path(args.markdown).write_text(table + "\n")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
