"""The tcfarm CLI against a live local farm: real processes, real HTTP."""
import json
import os
import subprocess
import sys

import pytest

from farm_harness import ROOT, LocalFarm, small_scene


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("cli-farm"), workers=1) as farm:
        farm.wait_for_workers(1)
        yield farm


def tcfarm(farm, *args):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "services" / "client"))
    return subprocess.run([sys.executable, "-m", "tcfarm.cli", "--url", farm.url, *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def scene_file(scenes_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "spheres.json"
    path.write_text(json.dumps(small_scene(scenes_dir / "paper_b_twelve_spheres.json", 64, 48, 6)))
    return path


@pytest.fixture(scope="module")
def finished_job(farm, scene_file):
    result = tcfarm(farm, "--json", "submit", scene_file, "--strategy", "search", "--bin-width", "3",
                    "--wait")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_submit_and_wait_shows_progress_and_the_result(farm, scene_file):
    result = tcfarm(farm, "submit", scene_file, "--strategy", "exact", "--wait")
    assert result.returncode == 0, result.stderr
    assert "completed" in result.stdout and "traced-pixel ratio" in result.stdout
    assert "trace CPU" in result.stdout
    assert "ETA" in result.stderr and "frames" in result.stderr


def test_status_watch_and_workers(farm, finished_job):
    status = tcfarm(farm, "status", finished_job["id"])
    assert status.returncode == 0 and f"job {finished_job['id']} completed" in status.stdout
    watch = tcfarm(farm, "watch", finished_job["id"])
    assert watch.returncode == 0 and "6/6 frames" in watch.stderr
    workers = tcfarm(farm, "workers")
    assert workers.returncode == 0 and json.loads(workers.stdout)["workers"]


def test_frames_are_downloaded(farm, finished_job, tmp_path):
    result = tcfarm(farm, "frames", finished_job["id"], "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    pngs = sorted(tmp_path.glob("frame_*.png"))
    assert len(pngs) == 6
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_analyze_a_job_and_a_folder(farm, finished_job):
    job = tcfarm(farm, "analyze", finished_job["id"])
    assert job.returncode == 0, job.stderr
    assert "frame-to-frame coherence" in job.stdout and "n=3:" in job.stdout
    folder = tcfarm(farm, "--json", "analyze", farm.store / str(finished_job["id"]))
    assert folder.returncode == 0, folder.stderr
    assert json.loads(folder.stdout)["frames"] == 6


def test_bad_input_is_one_clear_line_and_a_nonzero_exit(farm, scene_file, tmp_path):
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


def test_cancel_of_a_finished_job_is_refused(farm, finished_job):
    result = tcfarm(farm, "cancel", finished_job["id"])
    assert result.returncode == 1 and "job_finished (409)" in result.stderr


def test_strategy_choices_are_the_apis():
    # The coordinator's own list is checked against the same spec (api_server_test).
    yaml = pytest.importorskip("yaml")
    from tcfarm.cli import STRATEGIES  # farm_harness put the client on the path
    spec = yaml.safe_load((ROOT / "proto" / "openapi.yaml").read_text())
    schemas = spec["components"]["schemas"]
    enums = [schema["properties"]["strategy"]["enum"] for schema in schemas.values()
             if "strategy" in schema.get("properties", {})]
    assert len(enums) == 2 and all(sorted(enum) == sorted(STRATEGIES) for enum in enums), enums
