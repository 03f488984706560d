"""glTF files through `tcfarm-worker render` and through the farm: generated files render
with closed-form pixels, the render flags choose what they say, broken files are refused
naming where, and exact equals brute force on an animated hierarchy and on skinned and
morphing meshes."""
import base64
import hashlib
import json
import math
import pathlib
import re
import struct
import subprocess
import sys

import jsonschema
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bench"))

import character  # noqa: E402
import make_gltf  # noqa: E402
from farm_harness import LocalFarm, compare, render_reference, submit_file_and_compare, tcfarm_cli  # noqa: E402

# Debian's assimp-testmodels (scripts/bootstrap installs it), read where it lies.
TEST_MODELS = pathlib.Path("/usr/share/assimp/models/glTF2")
# A skin and a morph that nobody in the project wrote.
SIMPLE_SKIN = "simple_skin/simple_skin.gltf"
MORPH_CUBE = "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"


def run(binary, *args):
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=300)


def exr_pixels(path):
    """{(x, y): (r, g, b)} of a float EXR, as oiiotool prints them."""
    result = subprocess.run(["oiiotool", "--dumpdata", str(path)], capture_output=True, text=True,
                            check=True, timeout=60)
    pixels = {}
    for match in re.finditer(r"Pixel \((\d+), (\d+)\): (\S+) (\S+) (\S+)", result.stdout):
        pixels[int(match[1]), int(match[2])] = tuple(float(v) for v in match.group(3, 4, 5))
    return pixels


def printed_scene(worker_binary, path, *flags):
    result = run(worker_binary, "render", path, "--print-scene", *flags)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    directory = tmp_path_factory.mktemp("gltf")
    return {name: make().write(directory / name) for name, make in make_gltf.EXAMPLES.items()}


@pytest.mark.parametrize("name", ["red_quad.gltf", "red_quad.glb"])
def test_red_quad_covers_the_centre(worker_binary, files, tmp_path, name):
    out = tmp_path / "out"
    result = run(worker_binary, "render", files[name], "--size", "33x25", "--out", out, "--no-png")
    assert result.returncode == 0, result.stderr
    assert "rendered 1 frames of 33x25" in result.stdout
    pixels = exr_pixels(out / "frame_0000.exr")
    r, g, b = pixels[16, 12]
    # glTF's BRDF in closed form at the centre, where the eye ray, the light and the normal
    # are one (V = L = N = H): a head-on light of 1 lux is E = 1/683 W/m2; the dielectric's
    # Fresnel is f0 = 0.04; roughness 1 gives D = 1/pi and the visibility 1/4. Diffuse
    # (1 - 0.04) * base / pi, specular 0.04 / (4 pi), and the ambient 0.05 of (base + f0).
    irradiance = 1 / 683
    specular = 0.04 * 0.25 / math.pi * irradiance
    assert g == b and g == pytest.approx(0.05 * 0.04 + specular, rel=1e-5), (r, g, b)
    assert r == pytest.approx(0.05 * 1.04 + 0.96 / math.pi * irradiance + specular, rel=1e-5), (r, g, b)
    # The quad's side of 2 fills 2 / (2 * 3 * tan(0.4)) = 79 % of the height: corners are empty.
    assert pixels[0, 0] == (0.0, 0.0, 0.0) and pixels[32, 24] == (0.0, 0.0, 0.0)


def test_flags_choose_frames_animation_camera_size_and_samples(worker_binary, files):
    path = files["animated_hierarchy.gltf"]
    scene = printed_scene(worker_binary, path)
    assert scene["render"]["frames"] == {"start": 0, "count": 25}  # 1 s at 24 per second
    assert (scene["render"]["width"], scene["render"]["height"]) == (640, 480)
    assert printed_scene(worker_binary, path, "--fps", "12")["render"]["frames"]["count"] == 13
    hop = printed_scene(worker_binary, path, "--animation", "hop")
    assert hop["render"]["frames"]["count"] == 7  # 0.25 s: frames 0 to ceil(6)
    assert printed_scene(worker_binary, path, "--animation", "1") == hop
    main = printed_scene(worker_binary, path, "--camera", "main")
    assert main == scene
    side = printed_scene(worker_binary, path, "--camera", "side", "--size", "200x100", "--spp", "3")
    assert side["camera"]["fov_degrees"] == pytest.approx(0.6 * 180 / 3.141592653589793)
    assert (side["render"]["width"], side["render"]["height"]) == (200, 100)
    assert side["render"]["samples_per_pixel"] == 3

    for flags, named in ((["--size", "0x5"], "--size"), (["--fps", "0"], "--fps"), (["--spp", "0"], "--spp")):
        result = run(worker_binary, "render", path, "--print-scene", *flags)
        assert result.returncode == 2 and named in result.stderr, (flags, result.stderr)
    result = run(worker_binary, "render", path, "--print-scene", "--animation", "nope")
    assert result.returncode == 1
    assert "scene/animations: animated_hierarchy.gltf: no animation named or numbered \"nope\"" in result.stderr


@pytest.mark.skipif(not TEST_MODELS.exists(), reason="assimp-testmodels is not installed (scripts/bootstrap)")
@pytest.mark.parametrize("model,where", [
    ("IndexOutOfRange/IndexOutOfRange.gltf", "scene/accessors/0: IndexOutOfRange.gltf: index 0 is 255"),
    ("BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", "scene/accessors/2: BoxWithInfinites.glb"),
    ("RecursiveNodes/RecursiveNodes.gltf", "scene/nodes/0: RecursiveNodes.gltf"),
    ("MissingBin/BoxTextured.gltf", "scene/buffers/0/uri: BoxTextured.gltf"),
])
def test_broken_models_are_refused_naming_where(worker_binary, tmp_path, model, where):
    result = run(worker_binary, "render", TEST_MODELS / model, "--out", tmp_path)
    assert result.returncode == 1
    assert where in result.stderr, result.stderr


@pytest.mark.parametrize("how", ["data", "view", "file"])
def test_a_textured_quad_shows_its_texels_where_its_coordinates_put_them(worker_binary, tmp_path, how):
    """baseColorTexture through every way glTF stores an image (a data URI, a GLB's buffer
    view, a file beside the .gltf), decoded from sRGB: each quarter of the quad shows one
    texel in glTF's BRDF under a head-on light of 1 lux, as the red quad's closed form."""
    path = make_gltf.textured_quad(how).write(tmp_path / ("quad.glb" if how == "view" else "quad.gltf"))
    (tmp_path / "quad.png").write_bytes(make_gltf.png_bytes(make_gltf.QUAD_TEXELS))
    out = tmp_path / "out"
    result = run(worker_binary, "render", path, "--size", "33x25", "--out", out, "--no-png")
    assert result.returncode == 0, result.stderr
    pixels = exr_pixels(out / "frame_0000.exr")
    # The quad spans about x 9..23 and y 5..19; the middle of each quarter shows one texel.
    for (x, y), texel in {(13, 9): (1, 0, 0), (19, 9): (0, 1, 0), (13, 15): (0, 0, 1), (19, 15): (1, 1, 1)}.items():
        got = pixels[x, y]
        # Off the centre the eye ray leans a little: a closed form to 1 %.
        irradiance = 1 / 683
        want = [0.05 * (code + 0.04) + (0.96 * code + 0.01) / math.pi * irradiance for code in texel]
        assert got == pytest.approx(want, rel=0.01), ((x, y), got, texel)


@pytest.mark.parametrize("min_filter, mipmaps", [(None, True), (9987, True), (9984, True), (9729, False), (9728, False)])
def test_a_samplers_minification_filter_says_whether_the_texture_has_mip_levels(worker_binary, tmp_path, min_filter,
                                                                                mipmaps):
    """glTF's minFilter LINEAR or NEAREST asks for the full image at every distance (no mip
    levels); the mipmapped filters and no sampler filter by the ray's footprint."""
    g = make_gltf.Gltf()
    png = make_gltf.png_bytes(make_gltf.QUAD_TEXELS)
    printed = g.material("printed", (1.0, 1.0, 1.0), texture=g.texture(png, "data", min_filter=min_filter))
    g.node(mesh=g.mesh([{"positions": make_gltf.quad(2.0), "indices": [0, 1, 2, 0, 2, 3], "material": printed,
                         "uvs": [0, 1, 1, 1, 1, 0, 0, 0]}]))
    path = g.write(tmp_path / "quad.gltf")
    texture = printed_scene(worker_binary, path)["materials"]["printed"]["pbr"]["base_color_texture"]
    assert texture.get("mipmaps", True) is mipmaps, texture


@pytest.mark.skipif(not TEST_MODELS.exists(), reason="assimp-testmodels is not installed (scripts/bootstrap)")
def test_good_models_render(worker_binary, tmp_path):
    """Good files render with nothing left out: the only warnings say what the import added
    (a camera, a light) or, for BoxTextured's NEAREST_MIPMAP_LINEAR, how a filter is drawn."""
    added = {"default_camera", "default_light"}
    for model, also in (("BoxTextured-glTF-Binary/BoxTextured.glb", {"sampler_filter_approximated"}),
                        ("cameras/Cameras.gltf", set()), (SIMPLE_SKIN, set()), (MORPH_CUBE, set())):
        result = run(worker_binary, "render", TEST_MODELS / model, "--size", "32x24", "--frames", "0",
                     "--out", tmp_path / pathlib.Path(model).stem, "--no-exr")
        assert result.returncode == 0, (model, result.stderr)
        codes = set(re.findall(r"^warning: \[(\w+)\]", result.stderr, re.M))
        assert result.stderr.count("warning") == len(re.findall(r"^warning: \[", result.stderr, re.M)), result.stderr
        assert codes <= added | also, (model, result.stderr)


def farm_exact_equals_reference(scene, reference_scene, tmp_path):
    """scene through the farm with exact on two workers against reference_scene through
    tcfarm-worker render: no pixel differs. Returns the job record."""
    reference = render_reference(reference_scene, tmp_path / "reference")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        job = farm.run_job(scene, strategy="exact", bin_width=8)
        error = compare(reference, farm.store / str(job["id"]))
    assert error["differing_pixels"] == 0, error
    return job


def test_farm_exact_equals_brute_force_on_an_animated_hierarchy(worker_binary, files, tmp_path):
    scene = printed_scene(worker_binary, files["animated_hierarchy.gltf"], "--fps", "12", "--size", "96x72")
    assert scene["render"]["frames"]["count"] == 13
    floor = next(shape for shape in scene["shapes"] if shape.get("name") == "floor")
    assert floor["colors"][0] == pytest.approx([1, 0.6, 0.3], abs=1 / 255)  # COLOR_0, the alpha left out
    job = farm_exact_equals_reference(scene, scene, tmp_path)
    # The still floor and sign keep their pixels between the movers' passes.
    assert job["traced_pixel_ratio"] < 0.6, job["traced_pixel_ratio"]  # 0.29 when written


def inlined(scene):
    """The scene with each shared mesh written into every shape that places it."""
    scene = json.loads(json.dumps(scene))
    meshes = scene.pop("meshes", {})
    for shape in scene["shapes"]:
        if "mesh_ref" in shape:
            shape.update(meshes[shape.pop("mesh_ref")])
    return scene


FOREST_FLAGS = ("--fps", "12", "--size", "64x48")


def test_a_mesh_placed_by_many_nodes_is_written_once(worker_binary, files):
    shared = printed_scene(worker_binary, files["forest.gltf"], *FOREST_FLAGS)
    flattened = printed_scene(worker_binary, files["forest_flattened.gltf"], *FOREST_FLAGS)
    assert list(shared["meshes"]) == ["tree"]
    placements = [shape for shape in shared["shapes"] if shape.get("mesh_ref") == "tree"]
    assert len(placements) == 50
    assert sum(shape["motion"] != [0, 0, 0] for shape in placements) == 50
    # The tree's triangles once, the floor's inline: each glTF mesh of the flattened file
    # is placed once, so stays inline.
    assert sum("triangles" in shape for shape in shared["shapes"]) == 1
    assert "meshes" not in flattened
    assert inlined(shared) == flattened
    assert len(json.dumps(shared)) * 3 < len(json.dumps(flattened))


def test_shared_mesh_renders_the_bits_of_its_flattened_twin(worker_binary, files, tmp_path):
    frames = {}
    for name in ("forest.gltf", "forest_flattened.gltf"):
        out = tmp_path / name
        result = run(worker_binary, "render", files[name], *FOREST_FLAGS, "--out", out, "--no-png")
        assert result.returncode == 0, result.stderr
        assert "rendered 13 frames of 64x48" in result.stdout
        frames[name] = out
    error = compare(frames["forest_flattened.gltf"], frames["forest.gltf"])
    assert error["differing_pixels"] == 0, error


def test_farm_exact_equals_brute_force_on_instanced_animation(worker_binary, files, tmp_path):
    scene = printed_scene(worker_binary, files["forest.gltf"], *FOREST_FLAGS)
    job = farm_exact_equals_reference(scene, inlined(scene), tmp_path)
    print("instanced forest: traced pixel ratio %.3f" % job["traced_pixel_ratio"])


def test_farm_exact_equals_brute_force_on_a_cube_seen_only_in_a_mirror(worker_binary, files, tmp_path):
    """The cube is behind the camera: only the mirror's reflected rays find it, so exact
    must re-trace the mirror's pixels as it moves and keep the rest."""
    scene = printed_scene(worker_binary, files["seen_in_a_mirror.gltf"], "--fps", "12", "--size", "96x72")
    direct = subprocess.run([str(worker_binary), "render", files["seen_in_a_mirror.gltf"], "--fps", "12",
                             "--size", "96x72", "--out", tmp_path / "direct"], capture_output=True, text=True)
    assert direct.returncode == 0 and "reflection 0," not in direct.stdout, direct.stdout
    job = farm_exact_equals_reference(scene, scene, tmp_path)
    print("cube seen in a mirror: traced pixel ratio %.3f" % job["traced_pixel_ratio"])
    assert job["traced_pixel_ratio"] < 0.9


VALIDATOR = pathlib.Path(__file__).resolve().parent / "node_modules" / "gltf-validator"


def assert_valid(paths):
    """The Khronos validator finds no error and no warning in any of the files."""
    result = subprocess.run(["node", str(VALIDATOR.parent.parent / "validate.js"), *map(str, paths)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    for report in json.loads(result.stdout):
        issues = report["issues"]
        assert (issues["numErrors"], issues["numWarnings"]) == (0, 0), (report["uri"], issues["messages"])


@pytest.mark.skipif(not VALIDATOR.exists(), reason="gltf-validator is not installed (scripts/bootstrap)")
def test_generated_files_pass_the_khronos_validator(files):
    assert_valid(files.values())


def submit_and_compare(farm, path, flags, reference):
    """exact through the farm against tcfarm-worker render: every pixel of 13 frames."""
    job, error = submit_file_and_compare(farm, path, flags, reference)
    assert error["differing_pixels"] == 0 and error["frames"] == 13, (path.name, error)
    return job


def test_tcfarm_submit_renders_a_gltf_as_tcfarm_worker_render_does(worker_binary, files, tmp_path):
    """The user's path: `tcfarm submit shot.glb --fps --size --strategy exact --wait`, the
    file and its buffer uploaded, imported on the coordinator, bit-identical to the
    standalone render of the same file with the same flags."""
    # The hierarchy as a .gltf with its buffer beside it, and as a .glb.
    gltf = json.loads(files["animated_hierarchy.gltf"].read_text())
    external = tmp_path / "shot"
    external.mkdir()
    (external / "shot.bin").write_bytes(base64.b64decode(gltf["buffers"][0]["uri"].split(",", 1)[1]))
    gltf["buffers"][0]["uri"] = "shot.bin"
    (external / "shot.gltf").write_text(json.dumps(gltf))
    glb = make_gltf.EXAMPLES["animated_hierarchy.gltf"]().write(tmp_path / "shot.glb")
    flags = ("--fps", "12", "--size", "96x72")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        # The .glb with its lights taken as they are (683 times brighter than as photometric
        # units): the farm must import it as the standalone renderer does.
        for path, more in ((external / "shot.gltf", ()), (glb, ("--light-units", "radiometric"))):
            submit_and_compare(farm, path, flags + more, tmp_path / f"reference-{path.suffix[1:]}")
        # Import options belong to a scene file: with a JSON scene they are refused.
        scene = tmp_path / "scene.json"
        scene.write_text(json.dumps(printed_scene(worker_binary, glb, *flags)))
        result = tcfarm_cli(farm, "submit", scene, "--fps", "12")
        assert result.returncode != 0 and "scene file" in result.stderr


def test_a_textured_gltf_renders_through_the_farm_as_tcfarm_worker_render_does(worker_binary, tmp_path):
    """A shot with rotation, a hierarchy, all three interpolations, textures (a file
    beside the .gltf, a data URI, a GLB's buffer view), point, spot and directional lights,
    a still camera. Workers fetch the images by hash; exact equals the standalone render."""
    shot = tmp_path / "shot"
    shot.mkdir()
    make_gltf.textured_turntable("file").write(shot / "turntable.gltf")
    (shot / "floor.png").write_bytes(make_gltf.floor_png())
    glb = make_gltf.textured_turntable("view").write(tmp_path / "turntable.glb")
    flags = ("--fps", "12", "--size", "96x72")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        for path in (shot / "turntable.gltf", glb):
            job = submit_and_compare(farm, path, flags, tmp_path / f"reference-{path.suffix[1:]}")
            assert job["traced_pixel_ratio"] < 0.8, job["traced_pixel_ratio"]
    # The images are in the store under their hashes: the file uploaded, the embedded ones
    # stored when the coordinator imported the file.
    floor = hashlib.sha256((shot / "floor.png").read_bytes()).hexdigest()
    assert (farm.store / "assets" / floor).exists()


def test_every_core_texture_renders_through_the_farm_as_tcfarm_worker_render_does(worker_binary, tmp_path):
    """Normal, metallic-roughness, occlusion and emissive maps, TEXCOORD_1, a texture
    transform, emissive strength, an alpha mask, blending and a one-sided material on an
    animated file: exact through the farm equals the standalone render, pixel for pixel, and
    the maps show (the frame differs from the same file without them)."""
    gltf = make_gltf.pbr_turntable("data").write(tmp_path / "pbr.gltf")
    plain = make_gltf.textured_turntable("data").write(tmp_path / "plain.gltf")
    flags = ("--fps", "12", "--size", "96x72")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        job = submit_and_compare(farm, gltf, flags, tmp_path / "reference")
        assert job["traced_pixel_ratio"] < 0.8, job["traced_pixel_ratio"]
    maps, without = tmp_path / "maps", tmp_path / "without"
    for path, out in ((gltf, maps), (plain, without)):
        subprocess.run([str(worker_binary), "render", str(path), *flags, "--frames", "0", "--out", str(out)],
                       check=True, capture_output=True)
    assert (maps / "frame_0000.png").read_bytes() != (without / "frame_0000.png").read_bytes()


def test_a_json_scene_adds_to_the_gltf_it_imports_on_the_farm_as_at_home(worker_binary, tmp_path):
    """A tcfarm JSON scene imports a glTF (in a subfolder, its buffer and image beside it)
    and adds a light, a sphere, a background, its own render size and frames, and picks
    the glTF's side camera. tcfarm submit uploads the scene's files and the glTF's; the
    farm's exact frames equal tcfarm-worker render's."""
    shot = tmp_path / "shot"
    (shot / "set").mkdir(parents=True)
    gltf = make_gltf.textured_turntable("file")
    document = json.loads(gltf.gltf_text())
    (shot / "set" / "turntable.bin").write_bytes(base64.b64decode(document["buffers"][0]["uri"].split(",", 1)[1]))
    document["buffers"][0]["uri"] = "turntable.bin"
    (shot / "set" / "turntable.gltf").write_text(json.dumps(document))
    (shot / "set" / "floor.png").write_bytes(make_gltf.floor_png())
    scene = {"import": {"file": "set/turntable.gltf", "fps": 12, "camera": "side"},
             "render": {"width": 80, "height": 60, "frames": {"start": 0, "count": 13}},
             "background": [0.1, 0.15, 0.3],
             "materials": {"gold": {"diffuse": [0.8, 0.6, 0.1], "specular": [0.5, 0.4, 0.1], "reflectivity": 0.3}},
             "lights": [{"type": "point", "position": [-3, 4, 2], "intensity": [20, 10, 10]}],
             "shapes": [{"type": "sphere", "center": [-2, 1, 1], "radius": 0.7, "material": "gold"}]}
    (shot / "scene.json").write_text(json.dumps(scene))
    printed = printed_scene(worker_binary, shot / "scene.json")
    assert len(printed["lights"]) == 4 and printed["background"] == [0.1, 0.15, 0.3]
    assert printed["shapes"][-1]["type"] == "sphere" and printed["render"]["width"] == 80
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        job = submit_and_compare(farm, shot / "scene.json", (), tmp_path / "reference")
    assert job["width"] == 80


def test_a_gltf_embedding_a_broken_image_is_refused_at_submit_naming_it(worker_binary, tmp_path):
    """An embedded image whose bytes end inside its header: tcfarm-worker render says which
    image, and the farm refuses the submission (400 at /scene_file) rather than fail a job."""
    document = json.loads(make_gltf.textured_quad("data").gltf_text())
    truncated = make_gltf.png_bytes(make_gltf.QUAD_TEXELS)[:40]
    document["images"][0]["uri"] = "data:image/png;base64," + base64.b64encode(truncated).decode()
    path = tmp_path / "broken.gltf"
    path.write_text(json.dumps(document))
    rendered = run(worker_binary, "render", path, "--out", tmp_path / "out")
    assert rendered.returncode != 0 and "broken.gltf at /images/0" in rendered.stderr, rendered.stderr
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=1) as farm:
        result = tcfarm_cli(farm, "submit", path)
        assert result.returncode != 0
        assert "invalid_scene (400) at /scene_file" in result.stderr, result.stderr
        assert "broken.gltf at /images/0" in result.stderr and "cannot be used" in result.stderr
        assert farm.client.jobs() == []


def test_an_optional_extension_not_implemented_is_reported_by_render_and_submit(worker_binary, tmp_path):
    """extensionsUsed naming an extension the importer does not implement: the scene renders
    without it, and tcfarm-worker render, tcfarm submit, tcfarm status, the job record and
    the coordinator's metrics all say so, with its code and pointer."""
    document = json.loads(make_gltf.red_quad().gltf_text())
    used = document.setdefault("extensionsUsed", [])
    used.append("KHR_materials_sheen")
    path = tmp_path / "sheen.gltf"
    path.write_text(json.dumps(document))
    said = f'sheen.gltf at /extensionsUsed/{len(used) - 1}: extension "KHR_materials_sheen" is not implemented'
    rendered = run(worker_binary, "render", path, "--size", "8x6", "--out", tmp_path / "out", "--no-png")
    assert rendered.returncode == 0, rendered.stderr
    assert f"warning: [extension_not_implemented] {said}" in rendered.stderr, rendered.stderr
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=1) as farm:
        result = tcfarm_cli(farm, "submit", path, "--size", "8x6")
        assert result.returncode == 0, result.stderr
        assert f"warning: [extension_not_implemented] {said}" in result.stderr, result.stderr
        job = farm.client.jobs()[0]
        warnings = farm.client.job(job["id"])["warnings"]
        pointer = f"/extensionsUsed/{len(used) - 1}"
        assert {"code": "extension_not_implemented", "file": "sheen.gltf", "pointer": pointer,
                "message": 'extension "KHR_materials_sheen" is not implemented; what it adds is left out'} in warnings
        status = tcfarm_cli(farm, "status", str(job["id"]))
        assert f"warning: [extension_not_implemented] {said}" in status.stdout, status.stdout
        counted = re.search(r'^tcfarm_import_warnings_total\{code="extension_not_implemented"\} (\S+)$',
                            farm.metrics(), re.M)
        assert counted and float(counted.group(1)) == 1, farm.metrics()


def test_a_moving_glTF_camera_makes_auto_pick_guarded_and_say_why(tmp_path):
    """exact cannot copy a pixel when the camera moves, so auto picks guarded, and the job
    record says which and why."""
    gltf = make_gltf.animated_hierarchy()
    eye = next(i for i, node in enumerate(gltf.doc["nodes"]) if node.get("name") == "eye")
    gltf.animate(eye, "translation", [0.0, 1.0], [0, 2.5, 6, 0.8, 2.5, 6])
    path = gltf.write(tmp_path / "dolly.gltf")
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=2) as farm:
        farm.wait_for_workers(2)
        result = tcfarm_cli(farm, "--json", "submit", path, "--fps", "8", "--size", "64x48", "--strategy", "auto", "--wait")
        assert result.returncode == 0, result.stderr
        job = json.loads(result.stdout.strip().splitlines()[-1])
    strategy = job["stats"]["strategy"]
    assert strategy["name"] == "guarded", strategy
    assert "camera" in strategy["reason"], strategy


# --- skins and morph targets ---------------------------------------------------------------

DEFORMING = ("skinned_arm.gltf", "morphing_blob.gltf", "skinned_in_a_mirror.gltf")
SCENE_SCHEMA = json.loads((pathlib.Path(__file__).resolve().parents[2] / "proto" / "scene.schema.json").read_text())
DEFORMING_FLAGS = ("--fps", "12", "--size", "96x72")


@pytest.mark.parametrize("name", DEFORMING)
def test_a_deforming_file_becomes_a_skinned_or_morphing_mesh(worker_binary, files, name):
    """The skin (two joints, weights summing to 1, no motion of its own) or the morph (two
    targets, a cubic spline of weights) as scene JSON that the scene schema accepts."""
    scene = printed_scene(worker_binary, files[name], *DEFORMING_FLAGS)
    jsonschema.Draft202012Validator(SCENE_SCHEMA).validate(scene)
    assert scene["render"]["frames"]["count"] == 13
    deforming = [shape for shape in scene["shapes"] if "skin" in shape or "morph" in shape]
    assert len(deforming) == 1 and all("motion" in s for s in scene["shapes"] if s not in deforming)
    shape = deforming[0]
    if "skin" in shape:
        skin = shape["skin"]
        assert "motion" not in shape and len(skin["joints"]) == 2 and len(shape["triangles"]) == 400
        assert len(skin["vertex_joints"]) == len(skin["vertex_weights"]) == len(shape["vertices"])
        assert all(abs(sum(w) - 1) < 1e-6 for w in skin["vertex_weights"])
        assert "keyframes" in skin["joints"][1]["rotation"]  # the elbow bends
    else:
        morph = shape["morph"]
        assert len(morph["targets"]) == 2 and all(len(t["normals"]) == len(shape["vertices"]) for t in morph["targets"])
        assert morph["weights"]["interpolation"] == "cubicspline" and len(morph["weights"]["keyframes"]) == 3
        # glTF's per-second tangents, per frame at 12 frames per second.
        assert morph["weights"]["keyframes"][0]["out_tangent"] == [2 / 12, 0]


def test_a_skinned_mesh_of_50000_triangles_is_generated_valid(worker_binary, tmp_path):
    """The benchmark's skinned mesh, generated on demand: at least 50,000 triangles, valid."""
    path = make_gltf.skinned_arm(detail=50000).write(tmp_path / "arm50k.gltf")
    scene = printed_scene(worker_binary, path, "--fps", "12")
    arm = next(shape for shape in scene["shapes"] if "skin" in shape)
    assert len(arm["triangles"]) >= 50000
    if VALIDATOR.exists():
        assert_valid([path])


def accessor_values(gltf, index):
    """An accessor's values as make_gltf.Gltf packed them (tightly, in its one buffer)."""
    accessor = gltf.doc["accessors"][index]
    view = gltf.doc["bufferViews"][accessor["bufferView"]]
    count = accessor["count"] * make_gltf._COMPONENTS[accessor["type"]]
    return list(struct.unpack_from("<%d%s" % (count, make_gltf._FORMATS[accessor["componentType"]]),
                                   gltf.buffer, view["byteOffset"]))


def skinned_attribute(gltf, name):
    node = next(n for n in gltf.doc["nodes"] if "skin" in n)
    return gltf.doc["meshes"][node["mesh"]]["primitives"][0]["attributes"], name


def weights_zero(gltf):
    attributes, name = skinned_attribute(gltf, "WEIGHTS_0")
    weights = accessor_values(gltf, attributes[name])
    weights[4:8] = [0, 0, 0, 0]
    attributes[name] = gltf.accessor(weights, "VEC4")
    return f"/accessors/{attributes[name]}", "vertex 1's weights are all 0"


def joint_out_of_range(gltf):
    attributes, name = skinned_attribute(gltf, "JOINTS_0")
    joints = accessor_values(gltf, attributes[name])
    joints[0] = 2
    attributes[name] = gltf.accessor(joints, "VEC4", make_gltf.UNSIGNED_BYTE)
    return f"/accessors/{attributes[name]}", "vertex 0 names joint 2 (weight 1.0) of skin 0, which has 2"


def skeleton_outside_the_scene(gltf):
    gltf.doc["skins"][0]["skeleton"] = gltf._add("nodes", {"name": "elsewhere"})
    return "/skins/0/skeleton", "which is not in the rendered scene"


def inverse_binds_short(gltf):
    accessor = gltf.doc["skins"][0]["inverseBindMatrices"]
    gltf.doc["accessors"][accessor]["count"] = 1
    return f"/accessors/{accessor}/count", "1 inverse bind matrices for 2 joints"


def weights_unlike_targets(gltf):
    mesh = next(i for i, m in enumerate(gltf.doc["meshes"]) if m.get("name") == "blob")
    gltf.doc["meshes"][mesh]["weights"] = [0.5]
    return f"/meshes/{mesh}/weights", "1 weights for 2 morph targets"


def target_short(gltf):
    mesh = next(m for m in gltf.doc["meshes"] if m.get("name") == "blob")
    accessor = mesh["primitives"][0]["targets"][1]["POSITION"]
    gltf.doc["accessors"][accessor]["count"] -= 1
    return f"/accessors/{accessor}/count", "position deltas for a primitive of"


BAD_DEFORMATIONS = [("skinned_arm.gltf", weights_zero), ("skinned_arm.gltf", joint_out_of_range),
                    ("skinned_arm.gltf", skeleton_outside_the_scene), ("skinned_arm.gltf", inverse_binds_short),
                    ("morphing_blob.gltf", weights_unlike_targets), ("morphing_blob.gltf", target_short)]


def test_bad_skins_and_morphs_are_refused_naming_the_file_and_pointer(worker_binary, tmp_path):
    """A vertex without weight, a weighted joint index out of range, a skeleton outside
    the scene, too few inverse bind matrices, weights or deltas whose counts differ: the
    standalone render exits 1 and the API answers 400, both naming the file and the glTF
    pointer."""
    broken = []
    for example, spoil in BAD_DEFORMATIONS:
        gltf = make_gltf.EXAMPLES[example]()
        pointer, problem = spoil(gltf)
        path = gltf.write(tmp_path / f"{spoil.__name__}.gltf")
        result = run(worker_binary, "render", path, "--out", tmp_path / "out")
        assert result.returncode == 1, (path.name, result.stderr)
        assert f"scene{pointer}: {path.name}: " in result.stderr and problem in result.stderr, result.stderr
        broken.append((path, pointer, problem))
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=1) as farm:
        for path, pointer, problem in broken:
            result = tcfarm_cli(farm, "submit", path)
            assert result.returncode != 0
            assert "invalid_scene (400) at /scene_file" in result.stderr, result.stderr
            assert f"{pointer}: {path.name}: " in result.stderr and problem in result.stderr, result.stderr
        assert farm.client.jobs() == []


@pytest.fixture(scope="module")
def deforming_farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("deforming_farm"), workers=2) as farm:
        farm.wait_for_workers(2)
        yield farm


@pytest.mark.parametrize("name,flags,frames", [
    *((name, DEFORMING_FLAGS, 13) for name in DEFORMING),
    # 5.5 s and 4.2 s sampled 4 times a second.
    (TEST_MODELS / SIMPLE_SKIN, ("--fps", "4", "--size", "64x48"), 23),
    (TEST_MODELS / MORPH_CUBE, ("--fps", "4", "--size", "64x48"), 18),
], ids=lambda value: pathlib.Path(value).stem if isinstance(value, (str, pathlib.Path)) else None)
def test_farm_exact_equals_brute_force_on_deforming_meshes(deforming_farm, files, tmp_path, name, flags, frames):
    """Each file submitted (with its buffers) and rendered by the farm
    with exact, against `tcfarm-worker render` of the same file (every pixel traced): no
    pixel differs. Prints the share of pixels exact copied instead of tracing."""
    path = files[name] if name in files else pathlib.Path(name)
    if not path.exists():
        pytest.skip("assimp-testmodels is not installed (scripts/bootstrap)")
    job, error = submit_file_and_compare(deforming_farm, path, flags, tmp_path / "reference")
    assert error["differing_pixels"] == 0 and error["frames"] == frames, (path.name, error)
    copied = 1 - job["traced_pixel_ratio"]
    print(f"{path.name}: exact copied {copied:.1%} of the pixels, 0 differ from brute force")
    # The still set around the character is copied: 74 %, 72 % and 81 % when written (the
    # arm's upper half, which its shoulder holds still, counting as still).
    if path.name in DEFORMING:
        assert copied > 0.5, copied


@pytest.mark.parametrize("variant", sorted(character.VARIANTS))
def test_the_cost_benchmarks_shots_are_valid_and_exact_renders_them_as_brute_force(worker_binary, deforming_farm,
                                                                                   tmp_path, variant):
    """tests/bench/character.py's shots, small (3,000 triangles, 6 frames): valid, as many
    triangles as asked on what moves (the character: 22 joints, weights summing to 1,
    blended at the joints), and exact on the farm bit-identical to `tcfarm-worker render`."""
    shot = character.VARIANTS[variant](triangles=3000, frames=6)
    path = shot.write(tmp_path / f"{variant}.glb")
    if VALIDATOR.exists():
        assert_valid([path])
    flags = ("--size", "96x72")
    scene = printed_scene(worker_binary, path, *flags)
    moving = [shape for shape in scene["shapes"] if "keyframes" in json.dumps(shape)]  # the room holds still
    assert [shape["name"] for shape in moving] == {"skinned": ["character"], "rigid": ["part0", "part1", "part2", "part3"],
                                                   "morphed": ["shape"]}[variant]
    assert sum(len((scene["meshes"][shape["mesh_ref"]] if "mesh_ref" in shape else shape)["triangles"])
               for shape in moving) >= 3000
    if variant == "skinned":
        assert len(shot.doc["skins"][0]["joints"]) == 22  # the root, which no vertex follows, imported as a parent
        skin = moving[0]["skin"]
        assert all(abs(sum(w) - 1) < 1e-6 for w in skin["vertex_weights"])
        assert any(sum(w > 0 for w in weights) >= 2 for weights in skin["vertex_weights"])
    job, error = submit_file_and_compare(deforming_farm, path, flags, tmp_path / "reference")
    assert error["differing_pixels"] == 0 and error["frames"] == 6, error
    assert job["traced_pixel_ratio"] < 1, job["traced_pixel_ratio"]


def weights_under_one(gltf):
    """The sums old exporters write: each vertex's weights scaled by 0.685, 0.237 or 0.898 in
    turn. Returns the new WEIGHTS_0 accessor."""
    attributes, name = skinned_attribute(gltf, "WEIGHTS_0")
    scales = (0.685, 0.237, 0.898)
    weights = accessor_values(gltf, attributes[name])
    attributes[name] = gltf.accessor([w * scales[i // 4 % 3] for i, w in enumerate(weights)], "VEC4")
    return attributes[name]


def test_old_exporters_weights_and_frames_past_the_animation_render_on_the_farm_as_at_home(worker_binary,
                                                                                           deforming_farm, tmp_path):
    """The skinned arm with weights summing to 0.685, 0.237 and 0.898, asked for frames 0 to
    20 of its 13 (0 to 12): tcfarm-worker render and tcfarm submit both accept it and say so
    (weights divided by their sum, frames 13-20 holding the last key), and the farm's exact
    frames are the bits of tcfarm-worker render's."""
    gltf = make_gltf.skinned_arm()
    weights = weights_under_one(gltf)
    vertices = gltf.doc["accessors"][weights]["count"]
    path = gltf.write(tmp_path / "old_arm.gltf")
    said = {
        "weights_renormalised": f"old_arm.gltf at /accessors/{weights}: {vertices} of {vertices} vertices have "
                                "weights that do not sum to 1 (vertex 1's sum to 0.237, the furthest); each "
                                "vertex's weights are divided by their sum",
        "frames_past_animation": "old_arm.gltf at /animations/0: frames 13-20 hold the last key (the animation "
                                 "ends at frame 12)",
    }
    flags = ("--fps", "12", "--size", "64x48", "--frames", "0:20")
    reference = tmp_path / "reference"
    rendered = run(worker_binary, "render", path, *flags, "--out", reference, "--no-png")
    assert rendered.returncode == 0, rendered.stderr
    for code, line in said.items():
        assert f"warning: [{code}] {line}\n" in rendered.stderr, rendered.stderr
    submitted = tcfarm_cli(deforming_farm, "submit", path, *flags, "--strategy", "exact", "--wait")
    assert submitted.returncode == 0, submitted.stderr
    for code, line in said.items():
        assert f"warning: [{code}] {line}\n" in submitted.stderr, submitted.stderr
    job = deforming_farm.client.job(max(job["id"] for job in deforming_farm.client.jobs()))
    assert job["state"] == "completed" and job["frames"]["start"] == 0 and job["frames"]["end"] == 20, job
    error = compare(reference, deforming_farm.store / str(job["id"]))
    assert error["differing_pixels"] == 0 and error["frames"] == 21, error
    # Past the end the arm holds its last pose: frame 20 is frame 12.
    assert exr_pixels(reference / "frame_0020.exr") == exr_pixels(reference / "frame_0012.exr")


def test_a_json_scene_still_refuses_frames_outside_its_own_range(deforming_farm, tmp_path):
    """A tcfarm scene importing the arm sets its own range (13 frames); frames past it are
    refused, as for any tcfarm scene, not extended."""
    make_gltf.skinned_arm().write(tmp_path / "arm.gltf")
    scene = {"import": {"file": "arm.gltf", "fps": 12}, "render": {"width": 16, "height": 12}}
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    result = tcfarm_cli(deforming_farm, "submit", tmp_path / "scene.json", "--frames", "0:20")
    assert result.returncode != 0
    assert "/frames/end" in result.stderr and "the scene's frame range [0, 12]" in result.stderr, result.stderr
