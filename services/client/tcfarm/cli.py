"""tcfarm: drive a render farm from the command line.

  tcfarm submit SCENE.json|MODEL.obj [--frames A:B] [--strategy S] [--bin-width N] [--verify all|K] [--wait]
  tcfarm status JOB
  tcfarm watch JOB            progress bar with ETA and the live traced-pixel ratio
  tcfarm wait JOB
  tcfarm frames JOB --out DIR [--format png|exr]
  tcfarm cancel JOB
  tcfarm workers
  tcfarm analyze JOB|DIR      coherence of a job's frames (from the farm) or of a folder

Global options: --url (TCFARM_URL), --token (TCFARM_TOKEN) for a farm with API tokens,
--cacert (TCFARM_CACERT) for an https farm whose certificate authority is its own.
"""
import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

from tcfarm.client import ApiError, Client
from tcfarm.scene_files import SceneFileError, scene_files

# The coordinator's strategies (proto/openapi.yaml; tests/cli/test_client_cli.py keeps them equal).
STRATEGIES = ("auto", "exact", "guarded", "search", "brute")


def _frames(text):
    start, _, end = text.partition(":")
    try:
        return {"start": int(start), "end": int(end or start)}
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A:B (inclusive frame range), got {text!r}")


def _summary(job):
    stats = job.get("stats") or {}
    ratio = job.get("traced_pixel_ratio")
    parts = [f"job {job['id']} {job['state']}",
             f"frames {job['frames']['done']}/{job['frames']['count']}"]
    if ratio is not None:
        parts.append(f"traced-pixel ratio {ratio:.4f}")
    if "wall_seconds" in stats:
        parts.append(f"wall {stats['wall_seconds']:.2f} s")
    if "trace_seconds" in stats:
        parts.append(f"trace {stats['trace_seconds']:.2f} s")
    if "trace_cpu_seconds" in stats:
        parts.append(f"trace CPU {stats['trace_cpu_seconds']:.2f} s")
    if job.get("error"):
        parts.append(f"error: {job['error']}")
    return ", ".join(parts)


def _progress(job):
    sys.stderr.write("\r" + _summary(job) + " " * 8)
    sys.stderr.flush()


class _ProgressBar:
    """One line, redrawn: a bar, frames done, ETA from the rate so far, traced ratio."""

    def __init__(self, stream=sys.stderr, width=30):
        self.stream, self.width, self.started = stream, width, time.monotonic()

    def __call__(self, job):
        done, count = job["frames"]["done"], job["frames"]["count"]
        filled = int(self.width * done / count) if count else 0
        elapsed = time.monotonic() - self.started
        eta = "?" if done == 0 else f"{elapsed * (count - done) / done:.0f}s"
        ratio = job.get("traced_pixel_ratio")
        ratio = "-" if ratio is None else f"{ratio:.3f}"
        self.stream.write(f"\rjob {job['id']} [{'#' * filled}{'.' * (self.width - filled)}] "
                          f"{done}/{count} frames, ETA {eta}, traced ratio {ratio}, "
                          f"{job['state']}   ")
        self.stream.flush()


def _upload(client, files, quiet):
    """Uploads what the farm lacks of the scene's files; returns the submission's assets."""
    if not files.assets:
        return None
    upload = client.upload_assets([str(path) for path in files.assets.values()])
    if not quiet:
        sent = set(upload.uploaded)
        size = sum(path.stat().st_size for path in files.assets.values()
                   if upload.hashes[str(path)] in sent)
        sys.stderr.write(f"assets: {len(files.assets)} files, {len(sent)} uploaded "
                         f"({size / 2**20:.1f} MiB), the rest already on the farm\n")
    return {name: upload.hashes[str(path)] for name, path in files.assets.items()}


def _import_options(args, files):
    """--fps, --size, --animation, --camera, --spp: how the farm imports a scene file."""
    options = {key: value for key, value in (("fps", args.fps), ("size", args.size),
                                              ("animation", args.animation), ("camera", args.camera),
                                              ("spp", args.spp)) if value is not None}
    if not options:
        return {}
    if files.scene_file is None:
        raise ApiError(0, "bad_input", "--fps, --size, --animation, --camera and --spp apply to a "
                                       "scene file (.gltf, .glb, .obj), not to a JSON scene")
    return {"import": options}  # a reserved word in Python, a plain field name in the API


def _size(text):
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT") from None
    return [width, height]


def cmd_submit(client, args):
    try:
        files = scene_files(args.scene)
    except SceneFileError as e:
        raise ApiError(0, "bad_input", str(e))
    assets = _upload(client, files, args.json)
    job = client.submit(files.scene, name=args.name or os.path.basename(args.scene),
                        frames=args.frames, strategy=args.strategy, bin_width=args.bin_width,
                        tolerance=args.tolerance, priority=args.priority, verify=args.verify,
                        assets=assets, scene_file=files.scene_file, **_import_options(args, files))
    if not args.wait:
        print(json.dumps(job) if args.json else f"submitted job {job['id']}")
        return 0
    job = client.wait(job["id"], on_progress=None if args.json else _ProgressBar())
    if not args.json:
        sys.stderr.write("\n")
    print(json.dumps(job) if args.json else _summary(job))
    return 0 if job["state"] == "completed" else 1


def _verify(text):
    if text == "all":
        return {"frames": "all"}
    try:
        return {"sample": int(text)}
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'all' or a number of frames, got {text!r}")


def cmd_frames(client, args):
    job = client.job(args.job)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = 0
    for index, traced in enumerate(job.get("traced_per_frame", [])):
        if traced < 0:
            continue  # not finished yet
        frame = job["frames"]["start"] + index
        (out / f"frame_{frame:04d}.{args.format}").write_bytes(
            client.frame(args.job, frame, args.format))
        written += 1
    print(f"{written} of {job['frames']['count']} frames of job {args.job} in {out}")
    return 0


def _native_analyzer():
    """tcfarm-coordinator, for reading a folder of EXR frames exactly."""
    found = shutil.which("tcfarm-coordinator")
    if found:
        return found
    here = pathlib.Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "build" / "coordinator" / "tcfarm-coordinator"
        if candidate.exists():
            return str(candidate)
    return None


def cmd_analyze(client, args):
    if not args.target.isdigit():
        if not pathlib.Path(args.target).is_dir():
            raise ApiError(0, "bad_input", f"{args.target} is neither a job id nor a folder")
        analyzer = _native_analyzer()
        if not analyzer:
            raise ApiError(0, "missing_tool", "analyzing a folder needs tcfarm-coordinator on "
                                              "PATH (build the project); a job id works anywhere")
        command = [analyzer, "analyze", args.target] + (["--json"] if args.json else [])
        return subprocess.run(command).returncode
    job = client.job(int(args.target))
    analysis = (job.get("stats") or {}).get("analysis")
    if analysis is None:
        raise ApiError(0, "not_ready", f"job {args.target} is {job['state']}: its analysis "
                                       "is made when it completes")
    if args.json:
        print(json.dumps(analysis))
        return 0
    f2f, long_term = analysis["frame_to_frame"], analysis["long_term"]
    print(f"job {args.target}: {analysis['frames']} frames, frame-to-frame coherence "
          f"{100 * f2f['mean']:.2f} % (min {100 * f2f['min']:.2f}, max {100 * f2f['max']:.2f}), "
          f"long-term {100 * long_term['mean']:.2f} %, d = {analysis['d']:.4f}")
    costs = ", ".join(f"n={p['bin_width']}: {p['relative_cost']:.3f}"
                      for p in analysis["predictions"] if p["bin_width"] <= 10)
    print(f"equation 3, relative cost by bin width: {costs}")
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(prog="tcfarm", description="Drive a tcfarm render farm.")
    parser.add_argument("--url", default=os.environ.get("TCFARM_URL", "http://127.0.0.1:8080"))
    parser.add_argument("--token", default=os.environ.get("TCFARM_TOKEN"),
                        help="API token of the farm (default: $TCFARM_TOKEN)")
    parser.add_argument("--cacert", default=os.environ.get("TCFARM_CACERT"),
                        help="PEM file of the certificate authority of an https farm with its own "
                             "(default: $TCFARM_CACERT)")
    parser.add_argument("--json", action="store_true", help="print JSON records")
    sub = parser.add_subparsers(dest="command", required=True)
    submit = sub.add_parser("submit", help="submit a scene (JSON, or OBJ), uploading the files "
                                           "it references that the farm lacks")
    submit.add_argument("scene")
    submit.add_argument("--name")
    submit.add_argument("--frames", type=_frames)
    submit.add_argument("--strategy", choices=STRATEGIES)
    submit.add_argument("--bin-width", type=int)
    submit.add_argument("--tolerance", type=float)
    submit.add_argument("--priority", type=int)
    submit.add_argument("--verify", type=_verify, help="'all' or K: also render K frames "
                                                        "brute force and report the error")
    submit.add_argument("--wait", action="store_true", help="wait, showing progress")
    submit.add_argument("--fps", type=float, help="frames per second an animated file is sampled at (glTF)")
    submit.add_argument("--size", type=_size, help="WIDTHxHEIGHT of the frames of a scene file")
    submit.add_argument("--animation", help="the glTF animation to play, by name or index")
    submit.add_argument("--camera", help="the glTF camera to look through, by name or index")
    submit.add_argument("--spp", type=int, help="samples per pixel of a scene file")
    for name in ("status", "wait", "watch", "cancel"):
        sub.add_parser(name).add_argument("job", type=int)
    frames = sub.add_parser("frames", help="download a job's finished frames")
    frames.add_argument("job", type=int)
    frames.add_argument("--out", required=True)
    frames.add_argument("--format", choices=["png", "exr"], default="png")
    sub.add_parser("workers")
    sub.add_parser("analyze", help="coherence of a job (id) or a folder of frames").add_argument(
        "target")
    args = parser.parse_args(argv)
    try:
        client = Client(args.url, token=args.token, cacert=args.cacert)
    except (OSError, ValueError) as e:  # an unreadable or malformed --cacert file
        print(f"tcfarm: --cacert {args.cacert}: {e}", file=sys.stderr)
        return 1
    try:
        if args.command == "submit":
            return cmd_submit(client, args)
        if args.command == "frames":
            return cmd_frames(client, args)
        if args.command == "analyze":
            return cmd_analyze(client, args)
        if args.command == "workers":
            print(json.dumps(client.workers(), indent=1))
            return 0
        if args.command == "cancel":
            job = client.cancel(args.job)
        elif args.command == "wait":
            job = client.wait(args.job)
        elif args.command == "watch":
            job = client.wait(args.job, on_progress=_ProgressBar())
            sys.stderr.write("\n")
        else:
            job = client.job(args.job)
        print(json.dumps(job) if args.json else _summary(job))
        return 0
    except ApiError as e:
        print(f"tcfarm: {e}{_access_hint(e, args.token)}", file=sys.stderr)
        return 1


def _access_hint(error, token):
    """How to get in, after a 401 or 403."""
    if error.status == 401 and not token:
        return "; pass a token with --token TOKEN or the environment variable TCFARM_TOKEN"
    if error.status == 401:
        return "; the farm does not know this token (--token or TCFARM_TOKEN): ask its operator for one"
    if error.status == 403:
        return "; this token's role is too low: submitting needs a submit token, cancelling others' jobs admin"
    return ""


if __name__ == "__main__":
    sys.exit(main())
