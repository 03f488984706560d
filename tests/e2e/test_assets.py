"""Assets travel with the job: files a scene references are uploaded by hash to a real
coordinator, laid out for its scene parser, and the job renders on real workers exactly as
the standalone renderer renders the same scene from disk."""
import hashlib
import json
import pathlib
import re
import shutil
import subprocess
import sys
import urllib.error
import urllib.request

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "gltf"))
import make_gltf  # noqa: E402  (its PNG writer)
from farm_harness import WORKER, LocalFarm, compare, submit_file_and_compare, tcfarm_cli
from tcfarm.client import ApiError

MAX_FILE_MIB = 1
MAX_JOB_MIB = 2


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("assets-farm"), workers=2, coordinator_args=(
            "--asset-max-file-mib", str(MAX_FILE_MIB), "--asset-max-job-mib", str(MAX_JOB_MIB))) as farm:
        farm.wait_for_workers(2)
        yield farm


@pytest.fixture(scope="module")
def still_life(scenes_dir):
    return scenes_dir / "obj" / "still_life.obj"


def sha256(data):
    return hashlib.sha256(data).hexdigest()


def put(farm, hash_, data):
    """PUT raw bytes; (status, JSON body), whatever the status."""
    request = urllib.request.Request(f"{farm.url}/api/v1/assets/{hash_}", data=data, method="PUT",
                                     headers={"Content-Type": "application/octet-stream"})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def uploads(farm):
    """How many asset uploads the coordinator has accepted."""
    match = re.search(r"^tcfarm_asset_uploads_total (\S+)$", farm.metrics(), re.M)
    assert match, "tcfarm_asset_uploads_total is not exported"
    return float(match.group(1))


def scene_with_mesh_file(file, width=64, height=48, frames=8):
    """The still life's geometry as a mesh file beside a sphere that rolls across it."""
    return {
        "camera": {"position": [0, 4, 9], "look_at": [0, 0.5, 0]},
        "lights": [{"type": "point", "position": [4, 8, 5], "intensity": [60, 60, 60]}],
        "materials": {"clay": {"diffuse": [0.7, 0.6, 0.5]},
                      "mirror": {"diffuse": [0.1, 0.1, 0.1], "specular": [0.9, 0.9, 0.9],
                                 "shininess": 200, "reflectivity": 0.5}},
        "shapes": [{"type": "mesh", "file": file, "material": "clay"},
                   {"type": "sphere", "center": [-2, 0.6, 1.5], "radius": 0.5, "material": "mirror",
                    "motion": {"polynomial": [[0, 0.5], [0], [0]]}}],
        "render": {"width": width, "height": height, "frames": {"start": 0, "count": frames}},
    }


def test_upload_missing_and_reupload(farm):
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# upload test\n"
    hash_ = sha256(data)
    assert farm.client.missing_assets([hash_]) == [hash_]
    assert put(farm, hash_, data) == (201, {"sha256": hash_, "size": len(data)})
    assert farm.client.missing_assets([hash_]) == []
    assert put(farm, hash_, data) == (200, {"sha256": hash_, "size": len(data)})
    assert (farm.store / "assets" / hash_).read_bytes() == data


def test_bytes_that_are_not_the_named_asset_are_refused(farm):
    hash_ = sha256(b"what the client meant")
    status, body = put(farm, hash_, b"what arrived")
    assert status == 400 and body["error"]["code"] == "asset_hash_mismatch"
    assert sha256(b"what arrived") in body["error"]["message"]
    assert farm.client.missing_assets([hash_]) == [hash_]


def test_an_asset_over_the_limit_is_413_naming_it(farm):
    data = b"x" * (MAX_FILE_MIB * 2**20 + 1)
    status, body = put(farm, sha256(data), data)
    assert status == 413 and body["error"]["code"] == "payload_too_large"
    assert "--asset-max-file-mib" in body["error"]["message"]
    assert farm.client.missing_assets([sha256(data)]) == [sha256(data)]


def test_a_path_escaping_the_folder_is_refused_with_its_pointer(farm, still_life):
    hash_ = farm.client.upload_assets([str(still_life)]).hashes[str(still_life)]
    for path, pointer in (("../still_life.obj", "/assets/..~1still_life.obj"),
                          ("/etc/passwd", "/assets/~1etc~1passwd")):
        with pytest.raises(ApiError) as error:
            farm.client.submit(scene_with_mesh_file("still_life.obj"), assets={path: hash_})
        assert (error.value.status, error.value.code, error.value.pointer) == (400, "invalid_field", pointer)


def test_a_missing_asset_is_named(farm):
    lacking = sha256(b"never uploaded")
    with pytest.raises(ApiError) as error:
        farm.client.submit(scene_with_mesh_file("mesh.obj"), assets={"mesh.obj": lacking})
    assert (error.value.status, error.value.code, error.value.pointer) == (400, "missing_asset", "/assets/mesh.obj")
    assert lacking in str(error.value)


def textured_scene(texture):
    """A printed quad facing the camera, a sphere rolling in front of it."""
    scene = scene_with_mesh_file("unused.obj", frames=6)
    scene["materials"]["printed"] = {"diffuse": [1, 1, 1], "diffuse_texture": texture}
    scene["shapes"][0] = {"type": "mesh", "material": "printed",
                          "vertices": [[-3, -1, -1], [3, -1, -1], [3, 3, -1], [-3, 3, -1]],
                          "uvs": [[0, 2], [3, 2], [3, 0], [0, 0]], "triangles": [[0, 1, 2], [0, 2, 3]]}
    return scene


def test_a_textured_scene_renders_on_workers_as_from_disk(farm, tmp_path):
    """`tcfarm submit scene.json` uploads the image the scene names; workers fetch it by
    hash and trace what tcfarm-worker render traces from the folder, bit for bit."""
    folder = tmp_path / "textured"
    folder.mkdir()
    (folder / "bricks.png").write_bytes(make_gltf.png_bytes(make_gltf.checker(6, (180, 60, 40), (220, 210, 190))))
    (folder / "scene.json").write_text(json.dumps(textured_scene({"image": "bricks.png", "filter": "nearest"})))
    reference = tmp_path / "reference"
    job, error = submit_file_and_compare(farm, folder / "scene.json", (), reference)
    assert error["differing_pixels"] == 0 and error["frames"] == 6, error
    # The same image named by its hash, uploaded by the submission: the same frames.
    hash_ = sha256((folder / "bricks.png").read_bytes())
    assert (farm.store / "assets" / hash_).exists()
    by_hash = farm.run_job(textured_scene({"asset": hash_, "filter": "nearest"}), strategy="brute")
    assert compare(reference, farm.store / str(by_hash["id"]))["differing_pixels"] == 0


def test_a_texture_the_farm_lacks_is_named_and_no_job_is_made(farm):
    lacking = sha256(b"an image never uploaded")
    jobs_before = len(farm.client.jobs())
    with pytest.raises(ApiError) as error:
        farm.client.submit(textured_scene({"asset": lacking}))
    assert (error.value.status, error.value.code) == (400, "missing_asset")
    assert error.value.pointer == "/scene/materials/printed/diffuse_texture/asset"
    assert lacking in str(error.value) and "PUT /api/v1/assets" in str(error.value)
    with pytest.raises(ApiError) as error:
        farm.client.submit(textured_scene({"asset": "not-a-hash"}))
    assert (error.value.status, error.value.code) == (400, "invalid_scene")
    assert len(farm.client.jobs()) == jobs_before


@pytest.mark.parametrize("bytes_, problem", [
    (b"GIF89a not really", "not an image"),
    (make_gltf.png_bytes(make_gltf.checker(64, (200, 0, 0), (0, 0, 200)))[:120], "do not decode"),
])
def test_an_image_no_worker_could_read_is_refused_at_submit(farm, tmp_path, bytes_, problem):
    """An image is decoded once at submit: one that is not an image, or whose pixel data
    ends early, is a 400 naming the texture, and no job is made to fail on every worker."""
    folder = tmp_path / "broken"
    folder.mkdir()
    (folder / "broken.png").write_bytes(bytes_)
    (folder / "scene.json").write_text(json.dumps(textured_scene({"image": "broken.png"})))
    jobs_before = len(farm.client.jobs())
    result = tcfarm_cli(farm, "submit", folder / "scene.json")
    assert result.returncode == 1, result.stdout
    assert 'scene/materials/printed/diffuse_texture: texture image "broken.png" cannot be used' in result.stderr
    assert problem in result.stderr, result.stderr
    assert len(farm.client.jobs()) == jobs_before


def test_assets_past_the_job_limit_are_413_naming_it(farm, still_life):
    blobs = [bytes([i]) * (MAX_FILE_MIB * 2**20) for i in range(MAX_JOB_MIB + 1)]
    for blob in blobs:
        assert put(farm, sha256(blob), blob)[0] in (200, 201)
    hash_ = farm.client.upload_assets([str(still_life)]).hashes[str(still_life)]
    assets = {f"padding/{i}.bin": sha256(blob) for i, blob in enumerate(blobs)}
    assets["still_life.obj"] = hash_
    with pytest.raises(ApiError) as error:
        farm.client.submit(scene_with_mesh_file("still_life.obj"), assets=assets)
    assert (error.value.status, error.value.code, error.value.pointer) == (413, "job_too_large", "/assets")
    assert "--asset-max-job-mib" in str(error.value)


@pytest.mark.parametrize("strategy", ["exact", "brute"])
def test_a_scene_with_an_obj_mesh_file_renders_as_from_disk(farm, still_life, tmp_path, strategy):
    scene = scene_with_mesh_file("meshes/still_life.obj")
    reference = tmp_path / "reference"
    (reference / "meshes").mkdir(parents=True)
    shutil.copy(still_life, reference / "meshes" / "still_life.obj")
    (reference / "scene.json").write_text(json.dumps(scene))
    subprocess.run([str(WORKER), "render", str(reference / "scene.json"), "--out",
                    str(reference / "frames"), "--no-png"], check=True, capture_output=True, timeout=600)

    upload = farm.client.upload_assets([str(still_life)])
    job = farm.run_job(scene, strategy=strategy,
                       assets={"meshes/still_life.obj": upload.hashes[str(still_life)]})
    error = compare(reference / "frames", farm.store / str(job["id"]))
    assert error["frames"] == 8
    assert error["differing_pixels"] == 0


def test_a_second_upload_of_the_same_asset_sends_nothing(farm, tmp_path):
    mesh = tmp_path / "once.obj"
    mesh.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# sent once\n")
    before = uploads(farm)
    first = farm.client.upload_assets([str(mesh)])
    assert first.uploaded == [sha256(mesh.read_bytes())]
    second = farm.client.upload_assets([str(mesh)])
    assert second.uploaded == [] and second.hashes == first.hashes
    assert uploads(farm) == before + 1


def test_the_cli_uploads_the_obj_a_json_scene_names_once(farm, still_life, tmp_path):
    (tmp_path / "meshes").mkdir()
    # Bytes of its own, so that no other test has uploaded them.
    (tmp_path / "meshes" / "life.obj").write_bytes(still_life.read_bytes() + b"\n# cli test\n")
    scene = scene_with_mesh_file("./meshes/life.obj", 32, 24, 3)
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    before = uploads(farm)
    result = tcfarm_cli(farm, "submit", tmp_path / "scene.json", "--strategy", "exact", "--wait")
    assert result.returncode == 0, result.stderr
    assert "assets: 1 files, 1 uploaded" in result.stderr and "completed" in result.stdout
    again = tcfarm_cli(farm, "submit", tmp_path / "scene.json", "--wait")
    assert again.returncode == 0, again.stderr
    assert "assets: 1 files, 0 uploaded" in again.stderr
    assert uploads(farm) == before + 1


def test_the_cli_submits_an_obj_with_its_material_library(farm, still_life, tmp_path):
    result = tcfarm_cli(farm, "--json", "submit", still_life, "--wait")
    assert result.returncode == 0, result.stderr
    job = json.loads(result.stdout)
    assert job["state"] == "completed" and job["frames"]["count"] == 1
    # Without its library, the OBJ is refused naming the library.
    lonely = tmp_path / "lonely.obj"
    lonely.write_bytes(still_life.read_bytes())
    missing = tcfarm_cli(farm, "submit", lonely)
    assert missing.returncode == 1 and "still_life.mtl" in missing.stderr


def test_the_cli_refuses_a_scene_naming_a_file_outside_its_folder(farm, tmp_path):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "outside.obj").write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "scenes" / "scene.json").write_text(json.dumps(scene_with_mesh_file("../outside.obj")))
    result = tcfarm_cli(farm, "submit", tmp_path / "scenes" / "scene.json")
    assert result.returncode == 1
    assert "mesh file '../outside.obj' is not a relative path inside the scene's folder" in result.stderr
    (tmp_path / "scenes" / "scene.json").write_text(json.dumps(scene_with_mesh_file("absent.obj")))
    absent = tcfarm_cli(farm, "submit", tmp_path / "scenes" / "scene.json")
    assert absent.returncode == 1 and "cannot read mesh file 'absent.obj'" in absent.stderr
