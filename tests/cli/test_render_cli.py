"""The standalone renderer through its real entry point: a process, files, exit codes."""
import json
import re
import struct
import subprocess

from deforming_scenes import deforming_set
from farm_harness import compare


def run(binary, *args):
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def small(scene_path, tmp_path, width=64, height=48, count=3):
    scene = json.loads(scene_path.read_text())
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": count})
    out = tmp_path / scene_path.name
    out.write_text(json.dumps(scene))
    return out


def test_render_writes_every_frame_and_reports(worker_binary, scenes_dir, tmp_path):
    scene = small(scenes_dir / "paper_b_twelve_spheres.json", tmp_path)
    result = run(worker_binary, "render", scene, "--frames", "0:2", "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    for frame in range(3):
        assert (tmp_path / "out" / f"frame_{frame:04d}.exr").stat().st_size > 0
        png = (tmp_path / "out" / f"frame_{frame:04d}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = struct.unpack(">II", png[16:24])
        assert (width, height) == (64, 48)
    assert "rendered 3 frames of 64x48" in result.stdout
    assert "coherence: frame-to-frame mean" in result.stdout
    assert "rays: primary 9216," in result.stdout  # 3 frames x 64 x 48, one sample


def test_every_paper_scene_loads_and_renders(worker_binary, scenes_dir, tmp_path):
    for path in sorted(scenes_dir.glob("paper_*.json")):
        scene = small(path, tmp_path, 32, 24, 2)
        result = run(worker_binary, "render", scene, "--out", tmp_path / path.stem, "--no-png")
        assert result.returncode == 0, f"{path.name}: {result.stderr}"
        assert (tmp_path / path.stem / "frame_0001.exr").exists()


def test_bad_scene_names_the_json_pointer(worker_binary, scenes_dir, tmp_path):
    scene = json.loads((scenes_dir / "paper_a_one_sphere.json").read_text())
    scene["shapes"][1]["radius"] = -1
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(scene))
    result = run(worker_binary, "render", path, "--out", tmp_path / "out")
    assert result.returncode == 1
    assert "scene/shapes/1/radius" in result.stderr
    assert "expected" in result.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_bad_arguments_are_usage_errors(worker_binary, scenes_dir, tmp_path):
    scene = scenes_dir / "paper_a_one_sphere.json"
    for args in (["--frames", "5:2"], ["--frames", "x"], ["--bogus"], ["--threads", "-3"]):
        result = run(worker_binary, "render", scene, *args)
        assert result.returncode == 2, args
        assert "usage" in result.stderr or "expected" in result.stderr, args
    assert run(worker_binary, "frobnicate").returncode == 2
    missing = run(worker_binary, "render", tmp_path / "missing.json")
    assert missing.returncode == 1
    assert "missing.json" in missing.stderr


def test_obj_file_renders_as_a_scene(worker_binary, scenes_dir, tmp_path):
    # A whole OBJ (with its MTL) through the import seam: default camera, light and settings.
    scene = scenes_dir / "obj" / "still_life.obj"
    result = run(worker_binary, "render", scene, "--out", tmp_path / "out", "--no-exr")
    assert result.returncode == 0, result.stderr
    png = (tmp_path / "out" / "frame_0000.png").read_bytes()
    assert struct.unpack(">II", png[16:24]) == (640, 480)
    assert "rendered 1 frames of 640x480" in result.stdout


def test_bad_obj_names_the_file_and_line(worker_binary, tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    result = run(worker_binary, "render", path, "--out", tmp_path / "out")
    assert result.returncode == 1
    assert "bad.obj line 3: vertex reference 3" in result.stderr


def test_deforming_work_is_counted_and_left_out_for_rigid_scenes(worker_binary, scenes_dir, tmp_path):
    scene = tmp_path / "deforming.json"
    scene.write_text(json.dumps(deforming_set(32, 24, frames=12)))
    result = run(worker_binary, "render", scene, "--out", tmp_path / "deforming", "--no-png")
    assert result.returncode == 0, result.stderr
    counts = re.search(r"deforming meshes: (\d+) poses computed, (\d+) shared, (\d+) vertices deformed",
                       result.stdout)
    # The arm holds still over frames 4..7: 9 of its 12 frames are posed; the blob all 12.
    assert counts and [int(n) for n in counts.groups()] == [9 + 12, 3, 9 * 20 + 12 * 6], result.stdout
    rigid = run(worker_binary, "render", small(scenes_dir / "paper_a_one_sphere.json", tmp_path, 32, 24, 3),
                "--out", tmp_path / "rigid", "--no-png")
    assert "deforming meshes: 0 poses computed, 0 shared, 0 vertices deformed" in rigid.stdout


def test_view_changes_only_the_png_previews(worker_binary, scenes_dir, tmp_path):
    # --view standard is the default: the same PNG bytes. Another view (or an exposure) is
    # another preview of the same EXR master.
    scene = small(scenes_dir / "paper_b_twelve_spheres.json", tmp_path, count=1)
    outputs = {
        "default": [],
        "standard": ["--view", "standard", "--exposure", "0"],
        "neutral": ["--view", "khr-pbr-neutral"],
        "brighter": ["--exposure", "1.5"],
    }
    for name, flags in outputs.items():
        result = run(worker_binary, "render", scene, "--out", tmp_path / name, *flags)
        assert result.returncode == 0, (name, result.stderr)
    png = {name: (tmp_path / name / "frame_0000.png").read_bytes() for name in outputs}
    assert png["standard"] == png["default"]
    assert png["neutral"] != png["default"]
    assert png["brighter"] != png["default"]
    for name in ("standard", "neutral", "brighter"):  # the EXRs' pixels (their headers hold a date)
        assert compare(tmp_path / "default", tmp_path / name)["differing_pixels"] == 0, name


def test_bad_view_or_exposure_is_a_usage_error(worker_binary, scenes_dir, tmp_path):
    scene = scenes_dir / "paper_a_one_sphere.json"
    for args in (["--view", "filmic"], ["--exposure", "nan"], ["--exposure", "100"], ["--exposure", "x"]):
        result = run(worker_binary, "render", scene, "--out", tmp_path / "out", *args)
        assert result.returncode == 2, args
        assert args[0] in result.stderr, (args, result.stderr)
