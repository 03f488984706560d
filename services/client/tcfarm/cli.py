"""tcfarm: drive a render farm from the command line.

  tcfarm submit SCENE.json [--frames A:B] [--strategy search|brute] [--bin-width N] [--wait]
  tcfarm status JOB
  tcfarm wait JOB
  tcfarm cancel JOB
  tcfarm workers
"""
import argparse
import json
import os
import sys

from tcfarm.client import ApiError, Client


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
    if job.get("error"):
        parts.append(f"error: {job['error']}")
    return ", ".join(parts)


def _progress(job):
    sys.stderr.write("\r" + _summary(job) + " " * 8)
    sys.stderr.flush()


def cmd_submit(client, args):
    try:
        with open(args.scene) as f:
            scene = json.load(f)
    except OSError as e:
        raise ApiError(0, "bad_input", f"cannot read scene {args.scene}: {e.strerror}")
    except ValueError as e:
        raise ApiError(0, "bad_input", f"{args.scene} is not JSON: {e}")
    job = client.submit(scene, name=args.name or os.path.basename(args.scene),
                        frames=args.frames, strategy=args.strategy, bin_width=args.bin_width,
                        tolerance=args.tolerance, priority=args.priority)
    if not args.wait:
        print(json.dumps(job) if args.json else f"submitted job {job['id']}")
        return 0
    job = client.wait(job["id"], on_progress=None if args.json else _progress)
    if not args.json:
        sys.stderr.write("\n")
    print(json.dumps(job) if args.json else _summary(job))
    return 0 if job["state"] == "completed" else 1


def main(argv=None):
    parser = argparse.ArgumentParser(prog="tcfarm", description="Drive a tcfarm render farm.")
    parser.add_argument("--url", default=os.environ.get("TCFARM_URL", "http://127.0.0.1:8080"))
    parser.add_argument("--json", action="store_true", help="print JSON records")
    sub = parser.add_subparsers(dest="command", required=True)
    submit = sub.add_parser("submit", help="submit a scene")
    submit.add_argument("scene")
    submit.add_argument("--name")
    submit.add_argument("--frames", type=_frames)
    submit.add_argument("--strategy", choices=["search", "brute"])
    submit.add_argument("--bin-width", type=int)
    submit.add_argument("--tolerance", type=float)
    submit.add_argument("--priority", type=int)
    submit.add_argument("--wait", action="store_true", help="wait, showing progress")
    for name in ("status", "wait", "cancel"):
        sub.add_parser(name).add_argument("job", type=int)
    sub.add_parser("workers")
    args = parser.parse_args(argv)
    client = Client(args.url)
    try:
        if args.command == "submit":
            return cmd_submit(client, args)
        if args.command == "workers":
            print(json.dumps(client.workers(), indent=1))
            return 0
        if args.command == "cancel":
            job = client.cancel(args.job)
        elif args.command == "wait":
            job = client.wait(args.job)
        else:
            job = client.job(args.job)
        print(json.dumps(job) if args.json else _summary(job))
        return 0
    except ApiError as e:
        print(f"tcfarm: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
