"""Renders each asset of make_assets.py with the tracer (tcfarm-worker render) and with the
Khronos glTF Sample Renderer (khronos_render.py), and compares their linear values.

    python3 tests/reference/compare.py [--worker build/worker/tcfarm-worker] [--size 256x192]
                                       [--only NAME ...] [--out tests/artifacts/reference]

Compared are the lit pixels: covered in both images, not on a silhouette (a pixel whose
neighbour is background: the two anti-alias edges differently), and with a brightest
channel above LIT_THRESHOLD in both. A pixel's error is its largest channel difference over
the reference's brightest channel. Per asset: the median, the 95th percentile, the worst
pixel, and how much of the image one renderer covers and the other does not. Writes
NAME.png per asset: tracer | Khronos | difference (x4), in sRGB.
"""
import argparse
import dataclasses
import pathlib
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))

import make_assets  # noqa: E402
from khronos_render import KhronosRenderer, parse_size, srgb_bytes  # noqa: E402

LIT_THRESHOLD = 0.01  # linear; darker pixels say little about shading and much about noise
DEFAULT_OUT = ROOT / "tests" / "artifacts" / "reference"
# How the tracer is asked to shade as the Sample Renderer does: no shadows (it has none) and
# glTF light intensities taken as they are (as it takes them), not as photometric units,
# and no ambient term (it has no light but its punctual ones with image-based light off).
WORKER_FLAGS = [["--no-shadows"], ["--light-units", "radiometric"], ["--ambient", "0"]]


@dataclasses.dataclass
class Row:
    name: str
    lit: int                 # pixels compared
    median: float            # relative errors, 0.01 = 1 %
    p95: float
    worst: float
    worst_at: tuple          # (x, y)
    coverage: float          # share of the image covered by one renderer only
    tracer_s: float
    khronos_s: float


def read_exr(path):
    """Linear float32 H x W x 3 of an EXR, through oiiotool's pixel dump (no Python
    bindings of OpenImageIO needed)."""
    text = subprocess.run(["oiiotool", "--info", "-v", "--dumpdata", str(path)], check=True,
                          capture_output=True, text=True).stdout
    size = re.search(r":\s+(\d+)\s+x\s+(\d+),\s+(\d+) channel", text)
    width, height, channels = (int(v) for v in size.groups())
    values = re.findall(r"Pixel \((\d+), (\d+)\):((?: \S+)+)", text)
    image = np.zeros((height, width, channels), np.float32)
    for x, y, pixel in values:
        image[int(y), int(x)] = [float(v) for v in pixel.split()]
    return image[..., :3]


def supported_flags(worker):
    """The WORKER_FLAGS this worker knows (its render --help names them), and those it lacks."""
    help_text = subprocess.run([str(worker), "render", "--help"], capture_output=True, text=True).stdout
    known = [flag for flag in WORKER_FLAGS if flag[0] in help_text]
    return [part for flag in known for part in flag], [flag[0] for flag in WORKER_FLAGS if flag not in known]


def render_tracer(worker, gltf, width, height, flags, out_dir):
    subprocess.run([str(worker), "render", str(gltf), "--size", f"{width}x{height}", "--frames", "0",
                    "--out", str(out_dir), *flags], check=True, capture_output=True, text=True)
    return read_exr(pathlib.Path(out_dir) / "frame_0000.exr")


def interior(covered):
    """Covered pixels whose four neighbours are covered too."""
    inside = covered.copy()
    inside[1:, :] &= covered[:-1, :]
    inside[:-1, :] &= covered[1:, :]
    inside[:, 1:] &= covered[:, :-1]
    inside[:, :-1] &= covered[:, 1:]
    inside[0, :] = inside[-1, :] = False
    inside[:, 0] = inside[:, -1] = False
    return inside


def measure(name, tracer, khronos, alpha, tracer_s=0.0, khronos_s=0.0):
    """The Row of one asset from the two linear images and the reference's coverage."""
    khronos_covered = alpha > 0.5
    tracer_bright = tracer.max(axis=2)
    khronos_bright = khronos.max(axis=2)
    # The tracer's background is black: something it draws brighter than the threshold where
    # the reference drew nothing, or nothing where the reference drew something lit, is a
    # difference in coverage.
    only_one = (~khronos_covered & (tracer_bright > LIT_THRESHOLD)) | \
               (khronos_covered & (khronos_bright > LIT_THRESHOLD) & (tracer_bright == 0))
    inside = interior(khronos_covered) & interior(tracer_bright > 0)
    coverage = float((only_one & (interior(khronos_covered) | interior(~khronos_covered))).mean())
    lit = inside & (tracer_bright > LIT_THRESHOLD) & (khronos_bright > LIT_THRESHOLD)
    error = np.abs(tracer - khronos).max(axis=2) / np.maximum(khronos_bright, LIT_THRESHOLD)
    values = error[lit]
    if values.size == 0:
        return Row(name, 0, float("nan"), float("nan"), float("nan"), (-1, -1), coverage, tracer_s, khronos_s)
    worst = np.unravel_index(np.where(lit, error, -1).argmax(), error.shape)
    return Row(name, int(values.size), float(np.median(values)), float(np.percentile(values, 95)),
               float(values.max()), (int(worst[1]), int(worst[0])), coverage, tracer_s, khronos_s)


def write_side_by_side(path, tracer, khronos):
    from PIL import Image
    difference = np.abs(tracer - khronos) * 4
    strip = np.concatenate([tracer, khronos, difference], axis=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(srgb_bytes(strip), "RGB").save(path)
    return path


def compare_all(worker, width=256, height=192, only=None, out_dir=DEFAULT_OUT, log=print):
    """Rows of every asset (or those named in only); writes the side-by-side PNGs."""
    flags, missing = supported_flags(worker)
    if missing:
        log(f"note: {worker} lacks {' '.join(missing)}: rendering without")
    rows = []
    with tempfile.TemporaryDirectory(prefix="reference-") as temp, KhronosRenderer() as khronos_renderer:
        temp = pathlib.Path(temp)
        for name, gltf in make_assets.write_all(temp / "assets").items():
            if only and name not in only:
                continue
            start = time.monotonic()
            tracer = render_tracer(worker, gltf, width, height, flags, temp / "tracer" / name)
            tracer_s = time.monotonic() - start
            start = time.monotonic()
            khronos, alpha = khronos_renderer.render_rgba(gltf, width, height)
            khronos_s = time.monotonic() - start
            rows.append(measure(name, tracer, khronos, alpha, tracer_s, khronos_s))
            write_side_by_side(pathlib.Path(out_dir) / f"{name}.png", tracer, khronos)
    return rows


def format_table(rows):
    lines = [f"{'asset':26} {'lit px':>7} {'median':>8} {'p95':>8} {'worst':>8} {'at':>10} "
             f"{'1-cover':>8} {'tracer s':>8} {'khronos s':>9}"]
    for r in rows:
        lines.append(f"{r.name:26} {r.lit:7d} {r.median:8.1%} {r.p95:8.1%} {r.worst:8.1%} "
                     f"{str(r.worst_at):>10} {r.coverage:8.2%} {r.tracer_s:8.2f} {r.khronos_s:9.2f}")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worker", type=pathlib.Path, default=ROOT / "build" / "worker" / "tcfarm-worker")
    parser.add_argument("--size", type=parse_size, default=(256, 192))
    parser.add_argument("--only", nargs="*")
    parser.add_argument("--out", type=pathlib.Path, default=DEFAULT_OUT)
    args = parser.parse_args(argv)
    rows = compare_all(args.worker, *args.size, only=args.only, out_dir=args.out)
    print(format_table(rows))
    print(f"side by side (tracer | Khronos | difference x4): {args.out}")


if __name__ == "__main__":
    main()
