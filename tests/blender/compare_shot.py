"""Renders the glTF that make_shot.py exported with tcfarm and compares it with Cycles'
frame: the mean luminance of the directly lit pixels of each object.

    python3 tests/blender/compare_shot.py SHOT_DIR [--worker build/worker/tcfarm-worker]

Which object a pixel shows comes from Cycles' Object Index pass, eroded by a pixel so that
edges (antialiased differently by the two renderers) do not count. A pixel is directly lit
when its luminance is over LIT_SHARE of the object's bright end (its 95th percentile) in
both images: shadows (black in Cycles, tcfarm's ambient term) and the unlit sides drop out,
whatever the two images' overall scales. Emissive objects are left out, and so is the
background. The figure that matters is `lit_diffuse`, the floor and the ball together: the
gold Suzanne is printed too, but a Phong highlight and a GGX one have different shapes, so
its mean says little about the lights' units.

Writes SHOT_DIR/tcfarm/ (tcfarm's frame) and ARTIFACTS/side_by_side.png (Cycles | tcfarm,
each as its renderer wrote its PNG) and prints the figures as JSON.
"""
import argparse
import json
import pathlib
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
TOLERANCE = 0.10  # |tcfarm / Cycles - 1| on the directly lit diffuse pixels
LIT_SHARE = 0.2
DIFFUSE_OBJECTS = ("Floor", "Ball")
REC709 = np.array([0.2126, 0.7152, 0.0722])


def read_exr(path):
    """{channel name: float array (rows top first)} of an EXR, as oiiotool prints them."""
    info = subprocess.run(["oiiotool", "--info", "-v", str(path)], check=True, capture_output=True,
                          text=True, timeout=60).stdout
    names = next(line.split(":", 1)[1] for line in info.splitlines()
                 if line.strip().startswith("channel list:"))
    names = [name.strip() for name in names.split(",")]
    dump = subprocess.run(["oiiotool", "--dumpdata", str(path)], check=True, capture_output=True,
                          text=True, timeout=60).stdout.splitlines()
    width, height = (int(n) for n in dump[0].split(":", 1)[1].split(",")[0].split("x"))
    # Each pixel is a line "Pixel (x, y): v0 v1 ...", rows top first, x fastest.
    values = np.array([line.split(":", 1)[1].split() for line in dump[1:] if "Pixel (" in line],
                      dtype=np.float64).reshape(height, width, len(names))
    return {name: values[..., i] for i, name in enumerate(names)}


def rgb(channels, prefix=""):
    return np.stack([channels[prefix + c] for c in "RGB"], axis=-1)


def render_tcfarm(shot_dir, shot, worker):
    """tcfarm's frame showing the moment Cycles rendered: the exporter puts Blender's frame
    f at f / fps seconds, and tcfarm's frame f shows f / fps."""
    out = shot_dir / "tcfarm"
    width, height = shot["size"]
    subprocess.run([str(worker), "render", str(shot_dir / "shot.gltf"), "--size", f"{width}x{height}",
                    "--frames", str(shot["frame"]), "--fps", str(shot["fps"]), "--spp", "4",
                    "--out", str(out)], check=True, capture_output=True, timeout=300)
    return out / f"frame_{shot['frame']:04d}"


def interior(index_image, value):
    """Pixels showing the object of pass index `value` whose 8 neighbours show it too."""
    inside = np.rint(index_image) == value
    padded = np.pad(inside, 1)
    height, width = inside.shape
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            inside = inside & padded[dy:dy + height, dx:dx + width]
    return inside


def lit(luminance, mask):
    bright_end = np.percentile(luminance[mask], 95) if mask.any() else 0
    return mask & (luminance > LIT_SHARE * bright_end)


def figures(cycles, tcfarm, mask):
    cycles_mean, tcfarm_mean = float(cycles[mask].mean()), float(tcfarm[mask].mean())
    return {"pixels": int(mask.sum()), "cycles": round(cycles_mean, 5), "tcfarm": round(tcfarm_mean, 5),
            "ratio": round(tcfarm_mean / cycles_mean, 4)}


def compare_images(shot, cycles_rgb, tcfarm_rgb, index_image):
    cycles, tcfarm = cycles_rgb @ REC709, tcfarm_rgb @ REC709
    masks = {}
    for name, value in shot["pass_index"].items():
        if name in shot["emissive"]:
            continue
        inside = interior(index_image, value)
        masks[name] = lit(cycles, inside) & lit(tcfarm, inside)
    result = {name: figures(cycles, tcfarm, mask) for name, mask in masks.items()}
    diffuse = np.logical_or.reduce([masks[name] for name in DIFFUSE_OBJECTS])
    result["lit_diffuse"] = figures(cycles, tcfarm, diffuse)
    return result


def side_by_side(cycles_png, tcfarm_png, artifacts):
    artifacts.mkdir(parents=True, exist_ok=True)
    path = artifacts / "side_by_side.png"
    subprocess.run(["oiiotool", str(cycles_png), "--ch", "R,G,B", str(tcfarm_png), "--ch", "R,G,B",
                    "--mosaic", "2x1", "-o", str(path)], check=True, capture_output=True, timeout=60)
    return path


def compare(shot_dir, worker, artifacts):
    shot_dir = pathlib.Path(shot_dir)
    shot = json.loads((shot_dir / "shot.json").read_text())
    frame = render_tcfarm(shot_dir, shot, worker)
    cycles = read_exr(shot_dir / "cycles.exr")
    result = compare_images(shot, rgb(cycles, "ViewLayer.Combined."), rgb(read_exr(frame.with_suffix(".exr"))),
                            cycles["ViewLayer.IndexOB.X"])
    result["side_by_side"] = str(side_by_side(shot_dir / "cycles.png", frame.with_suffix(".png"), artifacts))
    result["cycles_render_seconds"] = shot["render_seconds"]
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("shot_dir", type=pathlib.Path)
    parser.add_argument("--worker", type=pathlib.Path, default=ROOT / "build" / "worker" / "tcfarm-worker")
    parser.add_argument("--artifacts", type=pathlib.Path, default=ROOT / "tests" / "artifacts" / "blender")
    args = parser.parse_args()
    result = compare(args.shot_dir, args.worker, args.artifacts)
    print(json.dumps(result, indent=2))
    return 0 if abs(result["lit_diffuse"]["ratio"] - 1) <= TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
