"""`tcfarm-coordinator analyze` through its real entry point, on frames the worker rendered."""
import json
import os
import pathlib
import re
import shutil
import struct
import subprocess
import zlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("TCFARM_BUILD", ROOT / "build"))
WIDTH, HEIGHT, FRAMES = 64, 48, 8


def run(binary, *args):
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="session")
def coordinator_binary():
    path = BUILD / "coordinator" / "tcfarm-coordinator"
    if not path.exists():
        pytest.fail(f"{path} is missing: build first (bash scripts/build)")
    return path


def small(scene_path, directory, width=WIDTH, height=HEIGHT, count=FRAMES):
    scene = json.loads(scene_path.read_text())
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": count})
    out = directory / f"{scene_path.stem}_{width}x{height}x{count}.json"
    out.write_text(json.dumps(scene))
    return out


def render(worker, scene, out):
    result = run(worker, "render", scene, "--out", out)
    assert result.returncode == 0, result.stderr
    return result.stdout


def coherence_printed(render_stdout):
    """The percentages of the worker's line 'coherence: frame-to-frame mean ..., long-term ...'."""
    line = next(line for line in render_stdout.splitlines() if line.startswith("coherence:"))
    values = [float(v) for v in re.findall(r"([0-9.]+)%", line)]
    assert len(values) == 6, line
    return {"frame_to_frame": values[:3], "long_term": values[3:]}


def paeth(left, up, corner):
    p = left + up - corner
    distances = [abs(p - left), abs(p - up), abs(p - corner)]
    return (left, up, corner)[distances.index(min(distances))]


def unfilter(kind, line, previous):
    """Undoes one PNG filter (RFC 2083, section 6) on a row of 3-byte pixels, in place."""
    for i in range(len(line)):
        left = line[i - 3] if i >= 3 else 0
        up, corner = previous[i], previous[i - 3] if i >= 3 else 0
        predicted = [0, left, up, (left + up) // 2, paeth(left, up, corner)][kind]
        line[i] = (line[i] + predicted) & 255


def png_gray_pixels(path):
    """The first channel of each pixel of an 8-bit RGB PNG (the mask is gray)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    position, idat, width, height = 8, b"", 0, 0
    while position < len(data):
        length, kind = struct.unpack(">I4s", data[position:position + 8])
        body = data[position + 8:position + 8 + length]
        if kind == b"IHDR":
            width, height, depth, color = struct.unpack(">IIBB", body[:10])
            assert (depth, color) == (8, 2), "expected 8-bit RGB"
        elif kind == b"IDAT":
            idat += body
        position += 12 + length
    raw, stride = zlib.decompress(idat), 3 * width + 1
    rows, previous = [], bytearray(3 * width)
    for y in range(height):
        line = bytearray(raw[y * stride + 1:(y + 1) * stride])
        unfilter(raw[y * stride], line, previous)
        rows.append(line)
        previous = line
    return width, height, [row[3 * x] for row in rows for x in range(width)]


@pytest.fixture(scope="module")
def sphere_frames(worker_binary, scenes_dir, tmp_path_factory):
    directory = tmp_path_factory.mktemp("sphere")
    stdout = render(worker_binary, small(scenes_dir / "paper_a_one_sphere.json", directory),
                    directory / "frames")
    return directory / "frames", stdout


def test_json_agrees_with_the_worker_coherence(coordinator_binary, sphere_frames):
    frames, render_stdout = sphere_frames
    result = run(coordinator_binary, "analyze", frames, "--json")
    assert result.returncode == 0, result.stderr
    analysis = json.loads(result.stdout)
    assert (analysis["frames"], analysis["width"], analysis["height"]) == (FRAMES, WIDTH, HEIGHT)

    printed = coherence_printed(render_stdout)
    for kind in ("frame_to_frame", "long_term"):
        stats = analysis[kind]
        got = [round(100 * stats[key], 2) for key in ("mean", "min", "max")]
        assert got == pytest.approx(printed[kind], abs=0.0051), kind
        assert len(stats["by_frame"]) == FRAMES - 1
    # Frame 1 against frame 0 is both the first frame-to-frame and the first long-term value.
    assert analysis["long_term"]["by_frame"][0] == analysis["frame_to_frame"]["by_frame"][0]
    assert analysis["d"] == pytest.approx(1 - analysis["frame_to_frame"]["mean"])
    assert analysis["d"] > 0, "the sphere moves: some pixels must change"

    events = analysis["events_by_duration"]
    assert len(events) == FRAMES + 1 and events[0] == 0
    volume = sum(duration * count for duration, count in enumerate(events))
    assert volume == FRAMES * WIDTH * HEIGHT
    assert analysis["event_count"] == sum(events)
    assert analysis["mean_event_duration"] == pytest.approx(volume / sum(events))
    assert sum(analysis["volume_share_by_duration"]) == pytest.approx(1.0)
    # Pixels that never change are the events that span the whole sequence.
    assert 1 - analysis["changed_pixel_share"] == pytest.approx(events[FRAMES] / (WIDTH * HEIGHT))

    widths = [p["bin_width"] for p in analysis["predictions"]]
    assert widths == list(range(2, FRAMES + 1))
    assert analysis["predictions"][0]["relative_cost"] == pytest.approx(1.0)
    costs = [p["relative_cost"] for p in analysis["predictions"]]
    assert costs == sorted(costs, reverse=True)
    assert 2 <= analysis["best_bin_width"] <= FRAMES
    assert "change_mask" not in analysis


def test_text_summary(coordinator_binary, sphere_frames):
    frames, render_stdout = sphere_frames
    result = run(coordinator_binary, "analyze", frames)
    assert result.returncode == 0, result.stderr
    text = result.stdout
    assert f"frames: {FRAMES} of {WIDTH}x{HEIGHT}" in text
    mean = coherence_printed(render_stdout)["frame_to_frame"][0]
    assert f"frame-to-frame coherence: mean {mean:.2f}%" in text
    assert "long-term coherence: mean" in text
    assert "mean duration" in text and "pixels that ever change" in text
    for n in range(2, FRAMES + 1):
        assert f"n={n} " in text
    assert re.search(r"best bin width up to 10: n=\d+", text)


def test_change_mask_is_white_where_nothing_changes(coordinator_binary, sphere_frames, tmp_path):
    frames, _ = sphere_frames
    mask_path = tmp_path / "mask.png"
    result = run(coordinator_binary, "analyze", frames, "--json", "--change-mask", mask_path)
    assert result.returncode == 0, result.stderr
    analysis = json.loads(result.stdout)
    width, height, values = png_gray_pixels(mask_path)
    assert (width, height) == (WIDTH, HEIGHT)
    assert set(values) <= {0, 255}
    assert values.count(0) / len(values) == pytest.approx(analysis["changed_pixel_share"])
    assert 0 < values.count(0) < len(values)


def test_png_frames_when_there_is_no_exr(coordinator_binary, sphere_frames, tmp_path):
    frames, _ = sphere_frames
    pngs = tmp_path / "pngs"
    pngs.mkdir()
    for png in frames.glob("frame_*.png"):
        shutil.copy(png, pngs / png.name)
    (pngs / "notes.png").write_bytes(b"not a frame")  # not frame_*: ignored
    result = run(coordinator_binary, "analyze", pngs, "--json")
    assert result.returncode == 0, result.stderr
    analysis = json.loads(result.stdout)
    assert analysis["frames"] == FRAMES
    # 8-bit codes hide changes below one code: at least as coherent as the float frames.
    exact = json.loads(run(coordinator_binary, "analyze", frames, "--json").stdout)
    assert analysis["frame_to_frame"]["mean"] >= exact["frame_to_frame"]["mean"]


def test_errors_name_the_folder_or_file(coordinator_binary, worker_binary, scenes_dir,
                                        sphere_frames, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    result = run(coordinator_binary, "analyze", empty)
    assert result.returncode == 1
    assert str(empty) in result.stderr and "no frame" in result.stderr

    missing = tmp_path / "missing"
    result = run(coordinator_binary, "analyze", missing, "--json")
    assert result.returncode == 1
    assert str(missing) in result.stderr
    assert result.stdout == ""

    frames, _ = sphere_frames
    mixed = tmp_path / "mixed"
    shutil.copytree(frames, mixed)
    other_scene = small(scenes_dir / "paper_a_one_sphere.json", tmp_path, 32, 24, 1)
    other = render(worker_binary, other_scene, tmp_path / "other")
    assert "rendered 1 frames" in other
    shutil.copy(tmp_path / "other" / "frame_0000.exr", mixed / "frame_0099.exr")
    result = run(coordinator_binary, "analyze", mixed)
    assert result.returncode == 1
    assert "frame_0099.exr" in result.stderr and "32x24" in result.stderr

    broken = tmp_path / "broken"
    shutil.copytree(frames, broken)
    (broken / "frame_0003.exr").write_bytes(b"not an image")
    result = run(coordinator_binary, "analyze", broken)
    assert result.returncode == 1
    assert "frame_0003.exr" in result.stderr


def test_bad_usage(coordinator_binary, sphere_frames):
    frames, _ = sphere_frames
    for args in ([], ["--json"], [frames, frames], [frames, "--bogus"], [frames, "--change-mask"]):
        result = run(coordinator_binary, "analyze", *args)
        assert result.returncode == 2, args
        assert "usage" in result.stderr, args


def test_compare_reports_ssim(coordinator_binary, sphere_frames, tmp_path):
    frames, _ = sphere_frames
    same = json.loads(run(coordinator_binary, "compare", frames, frames, "--json").stdout)
    assert same["ssim"] == 1.0
    # Each frame against the next one: the sphere moved, so the structure differs a little.
    shifted = tmp_path / "shifted"
    shifted.mkdir()
    for frame in range(FRAMES - 1):
        shutil.copy(frames / f"frame_{frame + 1:04d}.exr", shifted / f"frame_{frame:04d}.exr")
    reference = tmp_path / "reference"
    reference.mkdir()
    for frame in range(FRAMES - 1):
        shutil.copy(frames / f"frame_{frame:04d}.exr", reference / f"frame_{frame:04d}.exr")
    result = run(coordinator_binary, "compare", reference, shifted, "--json")
    assert result.returncode == 0, result.stderr
    error = json.loads(result.stdout)
    assert 0 < error["ssim"] < 1
    text = run(coordinator_binary, "compare", reference, shifted).stdout
    assert re.search(r"SSIM 0\.\d{6}", text)
