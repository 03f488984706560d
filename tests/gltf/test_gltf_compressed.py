"""Compressed glTF geometry and WebP textures through `tcfarm-worker render` and the farm:
files written by Draco's and meshoptimizer's own encoders (write_compressed_gltf, lossless
settings) render bit-identically to their plain twins, a Draco-compressed skinned sphere
bends as its plain twin does, the farm renders a Draco file as `tcfarm-worker render` does,
and an EXT_texture_webp texture shows its WebP image, not its fallback."""
import base64
import json
import pathlib
import re
import shutil
import subprocess
import sys

import pytest
import requests

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import make_gltf  # noqa: E402
from farm_harness import BUILD, LocalFarm, compare, submit_file_and_compare  # noqa: E402

WRITER = BUILD / "proto" / "write_compressed_gltf"
# A sphere of 2 x 24 x 48 triangles: enough to cover many pixels with many triangles.
RINGS, SEGMENTS = 24, 48
SIZE = ("--size", "96x72")
# The skinned sphere's one-second bend at 4 frames a second: 5 frames.
SKINNED = ("--fps", "4", "--size", "64x48")


def run(*args):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=600)


def render(worker_binary, path, out, *flags):
    result = run(worker_binary, "render", path, *flags, "--out", out, "--no-png")
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    if not WRITER.exists():
        pytest.fail(f"{WRITER} is missing: build first (bash scripts/build)")
    folder = tmp_path_factory.mktemp("compressed")
    result = run(WRITER, RINGS, SEGMENTS, folder)
    assert result.returncode == 0, result.stderr
    return folder


def printed_scene(worker_binary, path, *flags):
    result = run(worker_binary, "render", path, "--print-scene", *flags)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.mark.parametrize("name", ["draco.gltf", "draco.glb"])
def test_lossless_draco_renders_as_its_plain_twin(worker_binary, written, tmp_path, name):
    """Lossless Draco (sequential: vertex and triangle order kept) decodes to the plain file's
    very scene."""
    plain = render(worker_binary, written / "plain.gltf", tmp_path / "plain", *SIZE)
    error = compare(plain, render(worker_binary, written / name, tmp_path / "draco", *SIZE))
    assert error["frames"] == 1 and error["differing_pixels"] == 0, error
    assert printed_scene(worker_binary, written / name) == printed_scene(worker_binary, written / "plain.gltf")


@pytest.mark.parametrize("name", ["meshopt.gltf", "meshopt.glb"])
def test_meshopt_renders_as_its_plain_twin_in_its_triangle_order(worker_binary, written, tmp_path, name):
    """meshopt's index codec may rotate a triangle's corners (abc as bca): the same surface,
    but a hit's attributes are then summed in another order, which moves some pixels by a
    rounding (measured: 656 of 6912 pixels, by at most 5.3e-8). Against the plain file in
    meshopt's own triangle order no pixel differs; against the original, only roundings."""
    compressed = render(worker_binary, written / name, tmp_path / "compressed", *SIZE)
    twin = render(worker_binary, written / "meshopt_order_plain.gltf", tmp_path / "twin", *SIZE)
    error = compare(twin, compressed)
    assert error["frames"] == 1 and error["differing_pixels"] == 0, error
    original = compare(render(worker_binary, written / "plain.gltf", tmp_path / "plain", *SIZE), compressed)
    assert original["max_abs_error"] < 1e-6, original


def test_skinned_draco_bends_as_its_plain_twin(worker_binary, written, tmp_path):
    """JOINTS_0 and WEIGHTS_0 as Draco generic attributes: every frame of the bend as plain."""
    plain = render(worker_binary, written / "skinned.gltf", tmp_path / "plain", *SKINNED)
    draco = render(worker_binary, written / "skinned_draco.gltf", tmp_path / "draco", *SKINNED)
    error = compare(plain, draco)
    assert error["frames"] == 5 and error["differing_pixels"] == 0, error
    # The bend moves pixels (a skin read wrongly, all on the root, would not): the last
    # frame, named as the first, against the first.
    (tmp_path / "first").mkdir()
    (tmp_path / "last").mkdir()
    shutil.copy(plain / "frame_0000.exr", tmp_path / "first" / "frame_0000.exr")
    shutil.copy(plain / "frame_0004.exr", tmp_path / "last" / "frame_0000.exr")
    assert compare(tmp_path / "first", tmp_path / "last")["differing_pixels"] > 0


def scene_cache_misses(url):
    metrics = requests.get(url + "/metrics", timeout=10).text
    return float(re.search(r"^tcfarm_worker_scene_cache_misses_total (\S+)$", metrics, re.M)[1])


def test_farm_renders_draco_files_as_tcfarm_worker_render(written, tmp_path):
    """`tcfarm submit FILE --strategy exact --wait`: the coordinator decodes the file into the
    scene it sends, bit-identical to the standalone render. Workers never see Draco: the
    Draco GLB and the plain file are one scene to them, built once."""
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=0) as farm:
        _, url = farm.add_worker_with_metrics()
        farm.wait_for_workers(1)
        for name, flags, frames, misses in (("draco.glb", SIZE, 1, 1), ("plain.gltf", SIZE, 1, 1),
                                            ("skinned_draco.gltf", SKINNED, 5, 2)):
            job, error = submit_file_and_compare(farm, written / name, flags, tmp_path / f"reference-{name}")
            assert error["differing_pixels"] == 0 and error["frames"] == frames, (name, error)
            assert scene_cache_misses(url) == misses, name


def data_uri(mime, data):
    return f"data:{mime};base64," + base64.b64encode(data).decode()


def test_webp_texture_shows_its_webp_image(worker_binary, tmp_path):
    """The textured quad with its texture as a WebP (EXT_texture_webp) and a black PNG as the
    fallback `source` renders as the quad whose PNG holds the WebP's decoded texels."""
    gltf = json.loads(make_gltf.textured_quad().gltf_text())
    png = base64.b64decode(gltf["images"][0]["uri"].split(",", 1)[1])
    (tmp_path / "quad.png").write_bytes(png)
    # oiiotool writes lossy WebP: the twin holds what it decodes to, as an 8-bit PNG.
    for args in (("quad.png", "-o", "quad.webp"), ("quad.webp", "-d", "uint8", "-o", "decoded.png")):
        result = subprocess.run(["oiiotool", *args], cwd=tmp_path, capture_output=True, text=True, timeout=60)
        assert result.returncode == 0, result.stderr
    webp = (tmp_path / "quad.webp").read_bytes()
    assert webp[:4] == b"RIFF" and webp[8:12] == b"WEBP"
    twin = json.loads(json.dumps(gltf))
    twin["images"] = [{"uri": data_uri("image/png", (tmp_path / "decoded.png").read_bytes())}]
    black = make_gltf.png_bytes([[(0, 0, 0), (0, 0, 0)], [(0, 0, 0), (0, 0, 0)]])
    gltf["images"] = [{"uri": data_uri("image/png", black)}, {"uri": data_uri("image/webp", webp)}]
    gltf["textures"][0]["extensions"] = {"EXT_texture_webp": {"source": 1}}
    gltf["extensionsUsed"] = gltf.get("extensionsUsed", []) + ["EXT_texture_webp"]
    for name, document in (("twin.gltf", twin), ("webp.gltf", gltf)):
        (tmp_path / name).write_text(json.dumps(document))
    reference = render(worker_binary, tmp_path / "twin.gltf", tmp_path / "twin", "--size", "33x25")
    error = compare(reference, render(worker_binary, tmp_path / "webp.gltf", tmp_path / "webp", "--size", "33x25"))
    assert error["frames"] == 1 and error["differing_pixels"] == 0, error
    # Not the fallback: the black PNG renders otherwise.
    del gltf["textures"][0]["extensions"]
    (tmp_path / "fallback.gltf").write_text(json.dumps(gltf))
    fallback = render(worker_binary, tmp_path / "fallback.gltf", tmp_path / "fallback", "--size", "33x25")
    assert compare(reference, fallback)["differing_pixels"] > 0
