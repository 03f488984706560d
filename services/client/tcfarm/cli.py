"""tcfarm: drive a render farm from the command line.

  tcfarm submit SCENE.json|MODEL.obj|SHOT.glb [--frames A:B] [--strategy S] [--bin-width N] [--verify all|K] [--wait]
  tcfarm list [--state S[,S]] [--strategy S] [--name TEXT] [--limit N] [--page P|--offset O]
  tcfarm status JOB           the job, its verification figures and each frame's state
  tcfarm watch JOB            progress bar with ETA and the live traced-pixel ratio
  tcfarm wait JOB
  tcfarm events JOB [--follow]
  tcfarm frames JOB --out DIR [--format png|exr]
  tcfarm cancel JOB | retry JOB | delete JOB [--yes] | priority JOB N | rename JOB NAME
  tcfarm workers
  tcfarm strategies           the strategies the farm runs, and its default
  tcfarm distrusted [--lift PRINCIPAL]   workers banned for returning wrong values
  tcfarm analyze JOB|DIR      coherence of a job's frames (from the farm) or of a folder

Global options: --url (TCFARM_URL), --token (TCFARM_TOKEN) for a farm with API tokens,
--cacert (TCFARM_CACERT) for an https farm whose certificate authority is its own,
--json for machine-readable output, --version.
"""
import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

from tcfarm import __version__
from tcfarm.client import FINAL_STATES, ApiError, Client, sha256_file
from tcfarm.scene_files import NotItsFormat, SceneFileError, scene_files

# Strategy names are not checked here: the farm knows its own (GET /api/v1/strategies), and its
# 400 names a strategy it does not run.
STRATEGY_HELP = "one of the farm's strategies (tcfarm strategies lists them)"


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
    if ratio is not None and job["frames"]["done"] > 0:  # 0 before any frame is no figure
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
    """--fps, --size, --animation, --camera, --spp, --light-units: how the farm imports a scene file."""
    options = {key: value for key, value in (("fps", args.fps), ("size", args.size),
                                              ("animation", args.animation), ("camera", args.camera),
                                              ("spp", args.spp), ("light_units", args.light_units))
               if value is not None}
    if not options:
        return {}
    if files is not None and files.scene_file is None:
        raise ApiError(0, "bad_input", "--fps, --size, --animation, --camera, --spp and --light-units apply "
                                       "to a scene file (.gltf, .glb, .obj), not to a JSON scene")
    return {"import": options}  # a reserved word in Python, a plain field name in the API


def _size(text):
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT") from None
    return [width, height]


# A scene file larger than this is checked after its upload, not sent inline first: the
# farm's JSON bodies are bounded (64 MiB by default) and base64 adds a third.
_INLINE_CHECK_BYTES = 32 << 20


def _check_scene(client, path, files, job_options):
    """Asks the farm whether it would take the scene before any asset is uploaded: a file it
    refuses (an HTML page named .glb) is refused here, with the farm's message, and none of
    its bytes stored. files: the scene's files as found here, or None when they could not
    be read (the farm then says what the file is). A farm without the check is not asked."""
    path = pathlib.Path(path)
    if files is not None and files.scene is not None:
        scene, scene_file, data = files.scene, None, None
        assets = files.assets
    else:
        scene, scene_file = None, path.name
        data = path.read_bytes() if path.stat().st_size <= _INLINE_CHECK_BYTES else None
        assets = {name: local for name, local in (files.assets.items() if files else ())
                  if data is None or name != scene_file}
    hashes = {name: sha256_file(local) for name, local in assets.items()}
    try:
        return client.check_scene(scene, scene_file=scene_file, scene_file_data=data,
                                  assets=hashes or None, **job_options)
    except ApiError as e:
        if e.status in (404, 405):
            return None  # a farm from before the check
        raise


def cmd_submit(client, args):
    try:
        files, unreadable = scene_files(args.scene), None
    except NotItsFormat as e:
        # The scene file is not what its name says: the farm, asked below, says what it is.
        if e.path != pathlib.Path(args.scene):
            raise ApiError(0, "bad_input", str(e))
        files, unreadable = None, e
    except SceneFileError as e:
        raise ApiError(0, "bad_input", str(e))
    job_options = dict(name=args.name or os.path.basename(args.scene), frames=args.frames,
                       strategy=args.strategy, bin_width=args.bin_width, tolerance=args.tolerance,
                       priority=args.priority, verify=args.verify, view=args.view,
                       exposure=args.exposure)
    import_options = _import_options(args, files)
    if files is None or files.assets:  # else nothing travels first: the submit refuses the same way
        _check_scene(client, args.scene, files, dict(job_options, **import_options))
    if unreadable is not None:
        raise ApiError(0, "bad_input", str(unreadable))
    assets = _upload(client, files, args.json)
    job = client.submit(files.scene, assets=assets,
                        scene_file=files.scene_file, **job_options, **import_options)
    if not args.json:
        for line in _warning_lines(job):
            sys.stderr.write(f"warning: {line}\n")
    if not args.wait:
        print(json.dumps(job) if args.json else f"submitted job {job['id']}")
        return 0
    job = client.wait(job["id"], on_progress=None if args.json else _ProgressBar())
    if not args.json:
        sys.stderr.write("\n")
    print(json.dumps(job) if args.json else _summary(job))
    return 0 if job["state"] == "completed" else 1


def _warning_lines(job):
    """Each import warning as one line: "[code] file at pointer: message"."""
    lines = []
    for warning in job.get("warnings", []):
        if isinstance(warning, str):  # a job recorded before warnings had codes
            lines.append(warning)
            continue
        where = warning.get("file", "") + (f" at {warning['pointer']}" if warning.get("pointer") else "")
        lines.append(f"[{warning.get('code', '?')}] {where}: {warning.get('message', '')}")
    return lines


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


# Where a source checkout builds the coordinator (scripts/build), relative to the checkout.
_BUILT_COORDINATOR = pathlib.Path("build") / "coordinator" / "tcfarm-coordinator"
COORDINATOR_ENV = "TCFARM_COORDINATOR"


def _native_analyzer():
    """(path of tcfarm-coordinator, or None; where it was looked for). It reads a folder of
    EXR frames exactly; `pip install` brings only this client, so it is found at
    $TCFARM_COORDINATOR when that is set, else on PATH, else in the build/ folder of a
    checkout around the current folder or around this package (an editable or PYTHONPATH
    install)."""
    named = os.environ.get(COORDINATOR_ENV)
    if named:  # said outright: that one or none
        if os.path.isfile(named) and os.access(named, os.X_OK):
            return named, []
        return None, [f"${COORDINATOR_ENV}={named}, which is not an executable file"]
    looked = [f"${COORDINATOR_ENV} (not set)"]
    found = shutil.which("tcfarm-coordinator")
    if found:
        return found, looked
    looked.append("tcfarm-coordinator on PATH")
    starts = [pathlib.Path.cwd(), pathlib.Path(__file__).resolve().parent]
    for start in starts:
        for folder in [start, *start.parents]:
            candidate = folder / _BUILT_COORDINATOR
            if candidate.is_file() and os.access(candidate, os.X_OK):
                return str(candidate), looked
    looked.append(f"{_BUILT_COORDINATOR} in {starts[0]} and the folders above it")
    return None, looked


def _missing_analyzer_message(looked):
    return ("analyzing a folder of frames needs the coordinator program tcfarm-coordinator, which "
            "reads the EXR frames exactly; `pip install` brings only this client. Looked for "
            + "; ".join(looked) + ". Build it from the tcfarm source (bash scripts/bootstrap && "
            "bash scripts/build, which makes build/coordinator/tcfarm-coordinator), then set "
            f"{COORDINATOR_ENV}=/path/to/build/coordinator/tcfarm-coordinator or put it on PATH. "
            "`tcfarm analyze JOB_ID` needs only the farm")


def cmd_analyze(client, args):
    if not args.target.isdigit():
        if not pathlib.Path(args.target).is_dir():
            raise ApiError(0, "bad_input", f"{args.target} is neither a job id nor a folder")
        analyzer, looked = _native_analyzer()
        if not analyzer:
            raise ApiError(0, "missing_tool", _missing_analyzer_message(looked))
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


# --- tables and figures ---------------------------------------------------------------

def _table(headers, rows, right=()):
    """Columns as wide as their widest cell; the columns named in `right` (numbers) aligned
    right. Returns the lines."""
    cells = [list(map(str, headers))] + [[str(cell) for cell in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(headers))]

    def line(row):
        return "  ".join(cell.rjust(width) if headers[i] in right else cell.ljust(width)
                         for i, (cell, width) in enumerate(zip(row, widths))).rstrip()

    return [line(cells[0])] + [line(row) for row in cells[1:]]


def _bytes(count):
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if count >= size:
            return f"{count / size:.1f} {unit}"
    return f"{count} bytes"


def _rate(pixels_per_second):
    if pixels_per_second >= 1e6:
        return f"{pixels_per_second / 1e6:.2f} Mpx/s"
    if pixels_per_second >= 1e3:
        return f"{pixels_per_second / 1e3:.1f} kpx/s"
    return f"{pixels_per_second:.0f} px/s" if pixels_per_second > 0 else "-"


def _strategy(job):
    chosen = (job.get("stats") or {}).get("strategy") or {}
    name, width = chosen.get("name", job["strategy"]), chosen.get("bin_width", job["bin_width"])
    if name == "brute":
        return "brute"
    if width == 0:
        return f"{name}, surveying"
    return f"exact L={width}" if name == "exact" else f"{name} n={width}"


def _cost_lines(job):
    """Why the strategy, what auto weighed, and the job's one predicted relative CPU cost
    beside the measured one (against brute force = 1)."""
    stats = job.get("stats") or {}
    strategy, cost = stats.get("strategy") or {}, stats.get("cost") or {}
    lines = [f"why: {strategy['reason']}"] if strategy.get("reason") else []
    weighed = [f"{c['strategy']} {_figure(c.get('predicted_relative_cost'))} ({c.get('from', '?')})"
               for c in strategy.get("candidates") or []]
    if weighed:
        lines.append("auto weighed: " + ", ".join(weighed))
    figures = [f"{name} {value:.3f}" for name, value in
               (("predicted", strategy.get("predicted_relative_cost")),
                ("measured", cost.get("measured_relative_cost"))) if value is not None]
    if figures:
        lines.append("relative CPU cost: " + ", ".join(figures))
    return lines


def _figure(value):
    return "unknown yet" if value is None else f"{value:.3f}"


def _when(iso):
    """"2024-05-01T12:34:56.789Z" as "2024-05-01 12:34:56"; "-" for none."""
    return iso[:19].replace("T", " ") if iso else "-"


def cmd_workers(client, args):
    farm = client.workers()
    if args.json:
        print(json.dumps(farm, indent=1))
        return 0
    workers = farm.get("workers", [])
    if workers:
        rows = [(w["name"], w["threads"], w["capacity"], w["in_flight"], w["tasks_done"],
                 f"{w['pixels_done']:,}",
                 _rate(w["pixels_done"] / w["trace_seconds"] if w["trace_seconds"] > 0 else 0),
                 f"{w['seconds_since_heard']:.1f} s ago") for w in workers]
        print("\n".join(_table(("name", "threads", "capacity", "in flight", "tasks done",
                                "pixels done", "throughput", "last heard"), rows,
                               right=("threads", "capacity", "in flight", "tasks done",
                                      "pixels done", "throughput"))))
    else:
        print("no workers connected")
    print(f"{len(workers)} workers, {farm.get('queued_tasks', 0)} tasks queued, "
          f"{farm.get('in_flight_tasks', 0)} in flight")
    return 0


def cmd_strategies(client, args):
    listed = client.strategies()
    if args.json:
        print(json.dumps(listed, indent=1))
        return 0
    for name in listed["strategies"]:
        print(f"{name} (default)" if name == listed["default"] else name)
    return 0


def cmd_distrusted(client, args):
    if args.lift:
        client.lift_ban(args.lift)
        print(f"lifted the ban of {args.lift}")
        return 0
    bans = client.distrusted_workers()
    if args.json:
        print(json.dumps(bans, indent=1))
        return 0
    if not bans:
        print("no worker is banned")
        return 0
    rows = [(b["principal"], b["name"], _when(b["banned_at"]), b["why"]) for b in bans]
    print("\n".join(_table(("principal", "name", "banned", "why"), rows)))
    return 0


def _verification_lines(job):
    """The job's error figures in words: spot checks, the comparison with brute force
    (--verify), and anything suspect. "not measured yet" until there is a measurement."""
    error = (job.get("stats") or {}).get("error") or {}
    lines = []
    spot = error.get("spot_checks")
    if spot and spot.get("pixels_checked"):
        low, high = spot.get("ci95_percent", [0, 0])
        lines.append(f"spot checks: {spot['pixels_checked']:,} copied pixels traced again, "
                     f"{spot['mismatches']:,} wrong; estimated {spot['estimated_error_percent']:.4f} % "
                     f"of all pixels wrong (95 % CI {low:.4f}-{high:.4f} %)")
    elif job["state"] in FINAL_STATES:
        lines.append("spot checks: none made (a frame compared with brute force, or with "
                     "nothing copied, needs none)")
    else:
        lines.append("spot checks: not measured yet")
    reference = error.get("reference")
    if reference is not None:
        compared, requested = reference.get("frames_compared", 0), reference.get("frames_requested", 0)
        if compared:
            psnr = reference.get("psnr_db")
            psnr = "infinite (identical)" if psnr is None else f"{psnr:.2f} dB"
            lines.append(f"against brute force ({compared}/{requested} frames compared): "
                         f"{reference['percent_differing']:.4f} % of pixels differ "
                         f"({reference['pixels_differing']:,}), max error "
                         f"{reference['max_abs_error']:.6g}, PSNR {psnr}, SSIM {reference['ssim']:.4f}")
        else:
            lines.append(f"against brute force: not measured yet (0/{requested} frames compared)")
    sample = error.get("referee_sample")
    if sample:
        lines.append(_referee_sample_line(sample))
    suspect = error.get("suspect")
    if suspect:
        frames = ", ".join(sorted(suspect.get("frames", {}), key=int))
        lines.append(f"SUSPECT: {suspect['pixels_disagreeing']:,} pixels disagree (frames {frames}): "
                     f"{suspect.get('why', '')}")
    audit = error.get("audit")
    if audit:
        lines.append("audit: " + ", ".join(f"{key.replace('_', ' ')} {value}"
                                           for key, value in audit.items()))
    return lines


def _referee_sample_line(sample):
    """The referee's unseen sample in words: what it traced of the workers' values, what it
    found, what it cost, and how surely it catches a worker altering 16 pixels a frame."""
    share = f"{100 * sample['share']:.2f} % of every worker's pixels"
    if not sample.get("referee_traces"):
        return f"referee's unseen sample: none traced yet (it traces {share})"
    missed = 1 - sample["catch_probability"]["altering_16_pixels_every_frame"]
    odds = f"1 in {round(1 / missed):,} missed" if missed > 0 else "none missed"
    return (f"referee's unseen sample: {share} ({sample['pixels_sampled']:,} px drawn, "
            f"{sample['pixels_wrong']:,} wrong, {sample['referee_cpu_seconds']:.2f} s referee CPU); "
            f"a worker altering 16 px a frame: {odds}")


# One character a frame: what `status` draws of each frame's state.
FRAME_MARKS = {"written": "#", "tracing": "+", "queued": ".", "failed": "x"}


def _frame_strip(states):
    frames = states.get("frames", [])
    strip = "".join(FRAME_MARKS.get(frame["state"], "?") for frame in frames)
    counts = states["counts"]
    legend = ", ".join(f"{counts[state]} {state}" for state in FRAME_MARKS if counts.get(state))
    return [f"frames: {legend}", "  " + strip + "   (# written, + tracing, . queued, x failed)"]


def cmd_status(client, args):
    job = client.job(args.job)
    if args.json:
        print(json.dumps(job))
        return 0
    print(_summary(job))
    details = [f"strategy {_strategy(job)}, priority {job['priority']}",
               f"submitted {_when(job['submitted_at'])}, started {_when(job['started_at'])}, "
               f"finished {_when(job['finished_at'])}"]
    details += _cost_lines(job)
    if job.get("view", "standard") != "standard" or job.get("exposure", 0):
        details.append(f"previews: view {job['view']}, exposure {job['exposure']:+g} EV")
    details += _verification_lines(job)
    details += [f"warning: {line}" for line in _warning_lines(job)]
    try:
        details += _frame_strip(client.frame_states(args.job))
    except ApiError as e:
        if e.status not in (404, 405):  # a farm without per-frame states says nothing of them
            raise
    print("\n".join("  " + line for line in details))
    return 0


# --- the job list and the daily actions ---------------------------------------------------

def _states(text):
    states = [state.strip() for state in text.split(",") if state.strip()]
    known = ("queued", "running", "completed", "failed", "canceled")
    for state in states:
        if state not in known:
            raise argparse.ArgumentTypeError(f"{state!r} is not a job state; expected one or more "
                                             f"of {', '.join(known)}, separated by commas")
    return ",".join(states)


def _positive(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return value


def _job_row(job):
    frames = job["frames"]
    ratio = job.get("traced_pixel_ratio")
    return (job["id"], job["name"], job["state"], f"{frames['done']}/{frames['count']}",
            f"{100 * job.get('progress', 0):.0f} %", "-" if not frames["done"] else f"{ratio:.4f}",
            _strategy(job), job["priority"], _when(job["submitted_at"]))


def cmd_list(client, args):
    offset = args.offset if args.page is None else (args.page - 1) * args.limit
    page = client.job_page(state=args.state, strategy=args.strategy, name=args.name,
                           limit=args.limit, offset=offset)
    if args.json:
        print(json.dumps(page))
        return 0
    jobs, total = page["jobs"], page.get("total", len(page["jobs"]))
    offset = page.get("offset", offset or 0)
    if not jobs:
        print(f"no jobs match (of {total})" if offset == 0 else
              f"no jobs at offset {offset}: {total} match")
        return 0
    headers = ("id", "name", "state", "frames", "done", "traced", "strategy", "priority", "submitted")
    print("\n".join(_table(headers, [_job_row(job) for job in jobs],
                           right=("id", "frames", "done", "traced", "priority"))))
    last = offset + len(jobs)
    more = ""
    if last < total:
        limit = page.get("limit", args.limit)
        more = (f"; next: --page {offset // limit + 2}" if offset % limit == 0
                else f"; next: --offset {last}")
    print(f"showing {offset + 1}-{last} of {total} jobs{more}")
    return 0


def _confirm(question):
    """Asks on the terminal; anything but y or yes, or no answer at all, is no."""
    sys.stderr.write(question + " [y/N] ")
    sys.stderr.flush()
    answer = sys.stdin.readline()
    return answer.strip().lower() in ("y", "yes")


def cmd_delete(client, args):
    if not args.yes:
        job = client.job(args.job)
        question = (f"delete job {job['id']} {job['name']!r} ({job['state']}, "
                    f"{job['frames']['done']} frames written), its frames and the assets no "
                    "other job uses?")
        if not _confirm(question):
            print(f"tcfarm: job {args.job} not deleted (answer y, or pass --yes)", file=sys.stderr)
            return 1
    deleted = client.delete(args.job)
    if args.json:
        print(json.dumps(deleted))
    else:
        freed = deleted.get("freed_bytes", 0)
        print(f"deleted job {deleted.get('deleted', args.job)}, freed {_bytes(freed)} ({freed:,} bytes)")
    return 0


def _print_job(job, args, verb=None):
    print(json.dumps(job) if args.json else (f"{verb}: " if verb else "") + _summary(job))
    return 0


def _event_line(event):
    """time, job, type and the farm's message (or, without one, the event's own fields)."""
    said = event.get("message") or " ".join(
        f"{key}={value}" for key, value in event.items() if key not in ("seq", "job", "time", "type"))
    return f"{_when(event.get('time'))}  job {event.get('job')}  {event.get('type', ''):<16} {said}".rstrip()


def _print_event(event, args):
    print(json.dumps(event) if args.json else _event_line(event), flush=True)


def cmd_events(client, args):
    past = client.events(args.job)
    for event in past:
        _print_event(event, args)
    if not args.follow:
        return 0
    job = client.job(args.job)
    if job["state"] in FINAL_STATES:
        sys.stderr.write(f"job {args.job} is {job['state']}: nothing more to follow\n")
        return 0
    last = max((event["seq"] for event in past), default=None)
    for event in client.stream_events(after=last, read_timeout=args.read_timeout, job=args.job):
        if event.get("job") != args.job:
            continue
        _print_event(event, args)
        if event.get("type") in FINAL_STATES:  # the event that puts the job in its final state
            return 0
    return 0


def _follow(client, job_id, on_job, read_timeout):
    """Calls on_job with the job's record now and after each of its events, until the job
    reaches a final state; returns its last record. Follows the farm's event stream, and
    polls instead where the farm refuses it."""
    try:
        events = client.stream_events(read_timeout=read_timeout, job=job_id)
    except ApiError as e:
        if e.status == 0:
            raise  # unreachable: polling would not do better
        sys.stderr.write(f"the farm's event stream is refused ({e}): polling instead\n")
        return client.wait(job_id, on_progress=on_job)
    job = client.job(job_id)  # after the stream opened: nothing between is missed
    on_job(job)
    while job["state"] not in FINAL_STATES:
        event = next(events)
        if event.get("job") == job_id:
            job = client.job(job_id)
            on_job(job)
    return job


def cmd_watch(client, args):
    job = _follow(client, args.job, _ProgressBar(), args.read_timeout)
    sys.stderr.write("\n")
    print(json.dumps(job) if args.json else _summary(job))
    return 0


def _job_argument(parser):
    parser.add_argument("job", type=int, help="the job's id (tcfarm list shows them)")


def _parser():
    parser = argparse.ArgumentParser(prog="tcfarm", description="Drive a tcfarm render farm: submit "
                                     "scenes, follow and manage jobs, download frames.")
    parser.add_argument("--version", action="version", version=f"tcfarm {__version__}",
                        help="print the client's version and exit")
    parser.add_argument("--url", default=os.environ.get("TCFARM_URL", "http://127.0.0.1:8080"),
                        help="the farm's address (default: $TCFARM_URL, else http://127.0.0.1:8080)")
    parser.add_argument("--token", default=os.environ.get("TCFARM_TOKEN"),
                        help="API token of the farm (default: $TCFARM_TOKEN)")
    parser.add_argument("--cacert", default=os.environ.get("TCFARM_CACERT"),
                        help="PEM file of the certificate authority of an https farm with its own "
                             "(default: $TCFARM_CACERT)")
    parser.add_argument("--json", action="store_true", help="print JSON records")
    # --json may come after the command too; left unsaid there, the global one stands.
    after = argparse.ArgumentParser(add_help=False)
    after.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                       help="print JSON records")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name, text, description=None):
        return commands.add_parser(name, help=text, parents=[after],
                                   description=description or text[0].upper() + text[1:] + ".")

    submit = command("submit", "submit a scene (JSON, glTF/GLB or OBJ), uploading the files it "
                               "references that the farm lacks")
    submit.add_argument("scene", help="the scene file: .json, .gltf, .glb or .obj")
    submit.add_argument("--name", help="the job's name (default: the file's name)")
    submit.add_argument("--frames", type=_frames, help="A:B, the frames to render, inclusive "
                                                        "(default: the scene's; a glTF file's may run past "
                                                        "its animation, holding the last key)")
    submit.add_argument("--strategy", help=f"how to save tracing: {STRATEGY_HELP} "
                                           "(default: the farm's)")
    submit.add_argument("--bin-width", type=int, help="bin width n (search, guarded) or segment "
                                                      "length (exact)")
    submit.add_argument("--tolerance", type=float, help="largest difference two pixel values may "
                                                        "have and count as equal (default 0: bitwise)")
    submit.add_argument("--priority", type=int, help="-100..100, higher runs first (default 0)")
    submit.add_argument("--verify", type=_verify, help="'all' or K: also render K frames "
                                                        "brute force and report the error")
    submit.add_argument("--view", choices=["standard", "khr-pbr-neutral"],
                        help="how the PNG previews show the linear frames: standard (clamped, "
                             "the default) or khr-pbr-neutral (the Khronos PBR Neutral tone "
                             "mapper); the EXRs keep the values as traced")
    submit.add_argument("--exposure", type=float, metavar="EV",
                        help="exposure of the PNG previews in stops, -32..32 (default 0)")
    submit.add_argument("--wait", action="store_true", help="wait, showing progress")
    submit.add_argument("--fps", type=float, help="frames per second an animated file is sampled at (glTF)")
    submit.add_argument("--size", type=_size, help="WIDTHxHEIGHT of the frames of a scene file")
    submit.add_argument("--animation", help="the glTF animation to play, by name or index")
    submit.add_argument("--camera", help="the glTF camera to look through, by name or index")
    submit.add_argument("--spp", type=int, help="samples per pixel of a scene file")
    submit.add_argument("--light-units", choices=["photometric", "radiometric"],
                        help="glTF light intensities: photometric (candela and lux at 683 lm/W, as Blender "
                             "exports them; the farm's default) or radiometric (taken as they are)")

    listing = command("list", "list jobs, newest first, with filters and pages")
    listing.add_argument("--state", type=_states, help="only jobs in these states, e.g. "
                                                       "running or failed,canceled")
    listing.add_argument("--strategy", help=f"only jobs of these strategies, e.g. exact or "
                                            f"search,brute: {STRATEGY_HELP}")
    listing.add_argument("--name", help="only jobs whose name contains this (any case)")
    listing.add_argument("--limit", type=_positive, default=20, help="jobs a page (default 20)")
    where = listing.add_mutually_exclusive_group()
    where.add_argument("--page", type=_positive, help="the page to show, from 1")
    where.add_argument("--offset", type=int, default=0, help="jobs to skip (default 0)")

    for name, text in (("status", "a job's state, figures, verification and frames"),
                       ("wait", "wait until a job finishes, quietly; print its summary"),
                       ("cancel", "cancel a queued or running job"),
                       ("retry", "queue a failed or canceled job again (frames already written "
                                 "are kept)")):
        _job_argument(command(name, text))
    for name, text in (("watch", "follow a job live: progress bar, ETA, traced-pixel ratio"),
                       ("events", "a job's events: submitted, started, frames written, ...")):
        follower = command(name, text)
        _job_argument(follower)
        if name == "events":
            follower.add_argument("--follow", action="store_true",
                                  help="go on printing its events as they happen, until it finishes")
        follower.add_argument("--read-timeout", type=float, default=30.0,
                              help="seconds of silence after which the event stream is opened "
                                   "again (default 30)")
    delete = command("delete", "delete a finished job: its frames, the assets no other job "
                               "uses, and its record",
                     "Delete a finished job: its frames, the assets no other job uses, and its "
                     "record. Cancel a running job first.")
    _job_argument(delete)
    delete.add_argument("--yes", "-y", action="store_true", help="do not ask for confirmation")
    priority = command("priority", "change a job's priority",
                       "Change a job's priority: higher runs first and gets a larger share of "
                       "the workers.")
    _job_argument(priority)
    priority.add_argument("priority", type=int, help="-100..100")
    rename = command("rename", "change a job's name")
    _job_argument(rename)
    rename.add_argument("name", help="the new name")

    frames = command("frames", "download a job's finished frames into a folder")
    _job_argument(frames)
    frames.add_argument("--out", required=True, help="the folder to write frame_NNNN files to")
    frames.add_argument("--format", choices=["png", "exr"], default="png",
                        help="png (8-bit) or exr (the float frames) (default png)")
    command("workers", "the workers connected, what each has done, and the tasks queued")
    command("strategies", "the strategies the farm runs, its default marked")
    distrusted = command("distrusted", "workers banned for returning wrong values",
                         "Workers the farm banned for returning wrong values (by CURVE key, or "
                         "by name and address without CURVE), or --lift one ban (an admin "
                         "token's right).")
    distrusted.add_argument("--lift", metavar="PRINCIPAL",
                            help="let the worker banned as PRINCIPAL work again")
    analyze = command("analyze", "coherence of a job (id) or a folder of frames",
                      "Coherence of a job's frames (by id, from the farm) or of a folder of EXR "
                      f"frames (needs tcfarm-coordinator: ${COORDINATOR_ENV}, PATH or a build/ "
                      "folder).")
    analyze.add_argument("target", help="a job id, or a folder of frames")
    return parser


def main(argv=None):
    args = _parser().parse_args(argv)
    try:
        client = Client(args.url, token=args.token, cacert=args.cacert)
    except (OSError, ValueError) as e:  # an unreadable or malformed --cacert file
        print(f"tcfarm: --cacert {args.cacert}: {e}", file=sys.stderr)
        return 1
    commands = {
        "submit": cmd_submit, "frames": cmd_frames, "analyze": cmd_analyze, "workers": cmd_workers,
        "strategies": cmd_strategies, "distrusted": cmd_distrusted,
        "status": cmd_status, "list": cmd_list, "delete": cmd_delete, "events": cmd_events,
        "watch": cmd_watch,
        "wait": lambda client, args: _print_job(client.wait(args.job), args),
        "cancel": lambda client, args: _print_job(client.cancel(args.job), args),
        "retry": lambda client, args: _print_job(client.retry(args.job), args, "queued again"),
        "priority": lambda client, args: _print_job(
            client.update(args.job, priority=args.priority), args, f"priority {args.priority}"),
        "rename": lambda client, args: _print_job(
            client.update(args.job, name=args.name), args, "renamed"),
    }
    try:
        return commands[args.command](client, args)
    except ApiError as e:
        print(f"tcfarm: {e}{_access_hint(e, args.token)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


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
