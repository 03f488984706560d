"""Import cost of compressed glTF geometry: a UV sphere of 2 x RINGS x SEGMENTS triangles
(1 million by default) written by write_compressed_gltf plain, Draco-compressed (lossless
sequential, and edgebreaker with 14-bit positions) and meshopt-compressed, each as GLB,
imported by `tcfarm-worker render FILE --print-scene` (import and the scene's JSON, no
tracing) and rendered by `tcfarm-worker render FILE --frames 0:0 --size 32x24 --no-png`
(import, the Embree build, one tiny frame). Prints per file its size, the median wall time
and CPU time (user + system: steadier on a shared machine) of REPEAT runs and the child's
peak resident memory; no figure is asserted. TCFARM_BUILD
names another build to measure:

  python tests/bench/compressed_import.py
  python tests/bench/compressed_import.py --rings 250 --segments 500 --repeat 5
"""
import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import BUILD, WORKER  # noqa: E402

WRITER = BUILD / "proto" / "write_compressed_gltf"
FILES = ("plain.glb", "draco.glb", "draco_edgebreaker.glb", "meshopt.glb")


def measured(command):
    """(wall seconds, CPU seconds, peak RSS in MiB) of one run of `command`, which must succeed."""
    start = time.monotonic()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.monotonic() - start
    error = process.stderr.read().decode()
    process.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed: {error.strip()}")
    return seconds, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def figures(command, repeat):
    runs = [measured(command) for _ in range(repeat)]
    return tuple(statistics.median(run[i] for run in runs) for i in (0, 1)) + (max(run[2] for run in runs),)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rings", type=int, default=500)
    parser.add_argument("--segments", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        start = time.monotonic()
        subprocess.run([str(WRITER), str(args.rings), str(args.segments), str(folder)], check=True)
        print(f"{2 * args.rings * args.segments} triangles, {(args.rings + 1) * (args.segments + 1)} vertices; "
              f"files written in {time.monotonic() - start:.1f} s")
        print(f"{'':<30}{'--print-scene':^28}  {'render 32x24, 1 frame':^28}")
        print(f"{'file':<22}{'MiB':>8}" + f"  {'wall s':>8}{'CPU s':>8}{'peak MiB':>10}" * 2)
        for name in FILES:
            path = folder / name
            imported = figures([WORKER, "render", path, "--print-scene"], args.repeat)
            out = folder / ("out_" + path.stem)
            rendered = figures([WORKER, "render", path, "--frames", "0:0", "--size", "32x24", "--no-png",
                                "--out", out], args.repeat)
            print(f"{name:<22}{path.stat().st_size / 2**20:>8.1f}" +
                  "".join(f"  {wall:>8.2f}{cpu:>8.2f}{peak:>10.0f}" for wall, cpu, peak in (imported, rendered)))


if __name__ == "__main__":
    main()
