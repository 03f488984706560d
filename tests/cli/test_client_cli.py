"""The tcfarm CLI against a live local farm: real processes, real HTTP, and the command as
`pip install` leaves it (tests/cli/conftest.py)."""
import json
import re

import pytest

from farm_harness import BUILD, ROOT, LocalFarm, small_scene
from installed_client import run_installed


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("cli-farm"), workers=1) as farm:
        farm.wait_for_workers(1)
        yield farm


@pytest.fixture(scope="module")
def scene_file(scenes_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "spheres.json"
    path.write_text(json.dumps(small_scene(scenes_dir / "paper_b_twelve_spheres.json", 64, 48, 6)))
    return path


@pytest.fixture(scope="module")
def finished_job(farm, scene_file, installed_tcfarm):
    result = run_installed(installed_tcfarm, "--url", farm.url, "--json", "submit", scene_file,
                           "--strategy", "search", "--bin-width", "3", "--wait")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_submit_and_wait_shows_progress_and_the_result(farm, scene_file, tcfarm):
    result = tcfarm(farm, "submit", scene_file, "--strategy", "exact", "--wait")
    assert result.returncode == 0, result.stderr
    assert "completed" in result.stdout and "traced-pixel ratio" in result.stdout
    assert "trace CPU" in result.stdout
    assert "ETA" in result.stderr and "frames" in result.stderr


def test_status_watch_and_workers(farm, finished_job, tcfarm):
    status = tcfarm(farm, "status", finished_job["id"])
    assert status.returncode == 0 and f"job {finished_job['id']} completed" in status.stdout
    watch = tcfarm(farm, "watch", finished_job["id"])
    assert watch.returncode == 0 and "6/6 frames" in watch.stderr


def test_workers_is_a_table_and_json_on_request(farm, finished_job, tcfarm):
    table = tcfarm(farm, "workers")
    assert table.returncode == 0, table.stderr
    lines = table.stdout.splitlines()
    assert lines[0].split()[:3] == ["name", "threads", "capacity"], table.stdout
    assert "throughput" in lines[0] and "last heard" in lines[0]
    row = next(line for line in lines if line.startswith("test-0"))
    assert re.search(r"\bs ago$", row) and "px/s" in row, row  # it has traced, so a throughput
    assert re.match(r"1 workers, \d+ tasks queued, \d+ in flight", lines[-1]), lines[-1]
    for args in (("--json", "workers"), ("workers", "--json")):
        raw = tcfarm(farm, *args)
        assert raw.returncode == 0 and json.loads(raw.stdout)["workers"][0]["name"] == "test-0"


def test_version_is_the_installed_packages(farm, tcfarm):
    result = tcfarm(farm, "--version")
    assert result.returncode == 0
    source = (ROOT / "services" / "client" / "tcfarm" / "__init__.py").read_text()
    version = re.search(r'__version__ = "([^"]+)"', source).group(1)
    assert result.stdout.strip() == f"tcfarm {version}"


@pytest.fixture(scope="module")
def verified_job(farm, scene_file, installed_tcfarm):
    result = run_installed(installed_tcfarm, "--url", farm.url, "--json", "submit", scene_file,
                           "--strategy", "search", "--bin-width", "3", "--verify", "all", "--wait")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_status_shows_the_verification_figures(farm, verified_job, tcfarm):
    reference = verified_job["stats"]["error"]["reference"]
    spot = verified_job["stats"]["error"]["spot_checks"]
    status = tcfarm(farm, "status", verified_job["id"])
    assert status.returncode == 0, status.stderr
    text = status.stdout
    assert "against brute force (6/6 frames compared): " in text, text
    assert f"{reference['percent_differing']:.4f} % of pixels differ" in text
    assert f"max error {reference['max_abs_error']:.6g}" in text
    psnr = "infinite (identical)" if reference["psnr_db"] is None else f"{reference['psnr_db']:.2f} dB"
    assert f"PSNR {psnr}, SSIM {reference['ssim']:.4f}" in text
    # Every frame was compared, so none was spot checked.
    assert spot["pixels_checked"] == 0 and "spot checks: none made" in text
    assert "strategy search n=3, priority 0" in text and "not measured yet" not in text


def test_status_shows_the_spot_checks(farm, finished_job, tcfarm):
    spot = finished_job["stats"]["error"]["spot_checks"]
    assert spot["pixels_checked"] > 0
    status = tcfarm(farm, "status", finished_job["id"])
    assert status.returncode == 0, status.stderr
    low, high = spot["ci95_percent"]
    assert (f"spot checks: {spot['pixels_checked']:,} copied pixels traced again, "
            f"{spot['mismatches']:,} wrong; estimated {spot['estimated_error_percent']:.4f} % of all "
            f"pixels wrong (95 % CI {low:.4f}-{high:.4f} %)") in status.stdout, status.stdout
    assert "brute force" not in status.stdout  # not asked for
    sample = finished_job["stats"]["error"]["referee_sample"]
    assert sample["referee_traces"] > 0
    assert (f"referee's unseen sample: {100 * sample['share']:.2f} % of every worker's pixels "
            f"({sample['pixels_sampled']:,} px drawn, {sample['pixels_wrong']:,} wrong, ") in status.stdout, \
        status.stdout
    assert "\n  frames: 6 written\n    ######   (# written, + tracing, . queued, x failed)" in status.stdout


def test_status_of_a_job_not_measured_yet_says_so(tmp_path, scene_file, installed_tcfarm):
    with LocalFarm(tmp_path, workers=0) as idle:  # no worker: the job stays queued
        job = idle.client.submit(json.loads(scene_file.read_text()), strategy="search",
                                 bin_width=3, verify={"frames": "all"})
        status = run_installed(installed_tcfarm, "--url", idle.url, "status", job["id"])
    assert status.returncode == 0, status.stderr
    assert re.search(rf"job {job['id']} (queued|running), frames 0/6", status.stdout), status.stdout
    # Nothing written: each frame queued, or tracing (handed out, with no worker to take it).
    assert re.search(r"\n  frames: (\d (queued|tracing)(, )?)+\n    [.+]{6}   \(# written", status.stdout), \
        status.stdout
    assert "spot checks: not measured yet" in status.stdout
    assert "PSNR" not in status.stdout and "SSIM" not in status.stdout
    assert "traced-pixel ratio" not in status.stdout  # no frame, no ratio


def test_a_running_jobs_comparison_not_made_yet_is_not_a_result():
    from tcfarm.cli import _verification_lines  # farm_harness put the client on the path
    running = {"state": "running", "stats": {"error": {
        "spot_checks": {"pixels_checked": 0, "mismatches": 0, "estimated_error_percent": 0.0,
                        "ci95_percent": [0.0, 51.0]},
        "reference": {"frames_requested": 6, "frames_compared": 0, "pixels_differing": 0,
                      "percent_differing": 0.0, "max_abs_error": 0.0, "psnr_db": None, "ssim": 1.0}}}}
    assert _verification_lines(running) == [
        "spot checks: not measured yet", "against brute force: not measured yet (0/6 frames compared)"]


def test_the_referee_sample_not_traced_yet_is_not_a_result():
    from tcfarm.cli import _referee_sample_line  # farm_harness put the client on the path
    sample = {"share": 0.1, "pixels_sampled": 12, "pixels_wrong": 0, "referee_traces": 0,
              "referee_cpu_seconds": 0.0, "catch_probability": {"altering_16_pixels_every_frame": 0.81}}
    assert _referee_sample_line(sample) == \
        "referee's unseen sample: none traced yet (it traces 10.00 % of every worker's pixels)"
    sample.update(referee_traces=12, pixels_wrong=3, referee_cpu_seconds=0.5)
    assert _referee_sample_line(sample) == (
        "referee's unseen sample: 10.00 % of every worker's pixels (12 px drawn, 3 wrong, 0.50 s referee CPU); "
        "a worker altering 16 px a frame: 1 in 5 missed")


def test_frames_are_downloaded(farm, finished_job, tmp_path, tcfarm):
    result = tcfarm(farm, "frames", finished_job["id"], "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    pngs = sorted(tmp_path.glob("frame_*.png"))
    assert len(pngs) == 6
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_analyze_a_job_and_a_folder(farm, finished_job, tcfarm, tmp_path):
    job = tcfarm(farm, "analyze", finished_job["id"])
    assert job.returncode == 0, job.stderr
    assert "frame-to-frame coherence" in job.stdout and "n=3:" in job.stdout
    coordinator = BUILD / "coordinator" / "tcfarm-coordinator"
    folder = tcfarm(farm, "--json", "analyze", farm.store / str(finished_job["id"]),
                    env={"TCFARM_COORDINATOR": str(coordinator)}, cwd=tmp_path)
    assert folder.returncode == 0, folder.stderr
    assert json.loads(folder.stdout)["frames"] == 6


def test_analyze_a_folder_after_pip_install_alone_says_what_it_needs(farm, finished_job, tcfarm,
                                                                     tmp_path):
    # Outside any checkout, with nothing on PATH but the system's: the command cannot find the
    # coordinator program, and says what it is, where it looked and how to get it.
    env = {"PATH": "/usr/bin:/bin"}
    result = tcfarm(farm, "analyze", farm.store / str(finished_job["id"]), env=env, cwd=tmp_path)
    assert result.returncode == 1
    message = result.stderr
    assert len(message.strip().splitlines()) == 1, message
    for needed in ("tcfarm-coordinator", "$TCFARM_COORDINATOR (not set)", "on PATH",
                   f"build/coordinator/tcfarm-coordinator in {tmp_path}", "bash scripts/build",
                   "TCFARM_COORDINATOR=/path/to/build/coordinator/tcfarm-coordinator",
                   "`tcfarm analyze JOB_ID` needs only the farm"):
        assert needed in message, (needed, message)
    wrong = tcfarm(farm, "analyze", farm.store / str(finished_job["id"]), cwd=tmp_path,
                   env={**env, "TCFARM_COORDINATOR": str(tmp_path / "nope")})
    assert wrong.returncode == 1 and f"TCFARM_COORDINATOR={tmp_path / 'nope'}, which is not an " \
                                      "executable file" in wrong.stderr


def test_bad_input_is_one_clear_line_and_a_nonzero_exit(farm, scene_file, tmp_path, tcfarm):
    missing = tcfarm(farm, "submit", tmp_path / "nope.json")
    assert missing.returncode == 1 and "cannot read scene" in missing.stderr
    bad = json.loads(scene_file.read_text())
    bad["shapes"][1]["radius"] = -1
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    invalid = tcfarm(farm, "submit", tmp_path / "bad.json")
    assert invalid.returncode == 1
    assert "invalid_scene (400) at /scene/shapes/1/radius" in invalid.stderr
    unknown = tcfarm(farm, "status", 99999)
    assert unknown.returncode == 1 and "job_not_found (404)" in unknown.stderr
    assert len(unknown.stderr.strip().splitlines()) == 1
    usage = tcfarm(farm, "submit", scene_file, "--frames", "x:y")
    assert usage.returncode == 2


def test_cancel_of_a_finished_job_is_refused(farm, finished_job, tcfarm):
    result = tcfarm(farm, "cancel", finished_job["id"])
    assert result.returncode == 1 and "job_finished (409)" in result.stderr


def test_strategies_come_from_the_farm(farm, tcfarm):
    listed = tcfarm(farm, "--json", "strategies")
    assert listed.returncode == 0, listed.stderr
    served = json.loads(listed.stdout)
    assert "exact" in served["strategies"] and served["default"] in served["strategies"]
    shown = tcfarm(farm, "strategies").stdout.splitlines()
    assert shown == [f"{name} (default)" if name == served["default"] else name
                     for name in served["strategies"]]
    # The CLI passes any name on: the farm's 400 names the one it does not run.
    unknown = tcfarm(farm, "list", "--strategy", "magic")
    assert unknown.returncode == 1 and '"magic" is not a strategy' in unknown.stderr, unknown.stderr
