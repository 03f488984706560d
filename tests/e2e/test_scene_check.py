"""A scene the farm would refuse is refused before its bytes travel, and uploads no job
names do not stay: POST /api/v1/scenes/check, `tcfarm submit` asking it first, and the
store's janitor removing orphan assets, against a real coordinator."""
import base64
import hashlib
import json
import pathlib
import sys
import urllib.error
import urllib.request

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "gltf"))
import make_gltf  # noqa: E402
from farm_harness import LocalFarm, tcfarm_cli, wait_until

GRACE_SECONDS = 2


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    # No workers: the jobs stay queued, naming their assets, which is all these tests need.
    with LocalFarm(tmp_path_factory.mktemp("check-farm"), workers=0,
                   coordinator_args=("--asset-orphan-grace-s", str(GRACE_SECONDS))) as farm:
        yield farm


def stored_assets(farm):
    folder = farm.store / "assets"
    return {path.name for path in folder.iterdir() if not path.name.startswith(".")} if folder.exists() else set()


def check(farm, body):
    """POST /api/v1/scenes/check: (status, JSON answer)."""
    request = urllib.request.Request(f"{farm.url}/api/v1/scenes/check", data=json.dumps(body).encode(),
                                     method="POST", headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def inline(name, data):
    return {"scene_file": name, "scene_file_data": base64.b64encode(data).decode()}


def test_an_html_page_named_glb_is_refused_by_submit_before_any_upload(farm, tmp_path):
    shot = tmp_path / "shot.glb"
    shot.write_text("<!DOCTYPE html>\n<html><head><title>Sign in</title></head></html>\n")
    before = stored_assets(farm)
    uploads = farm.metric("tcfarm_asset_uploads_total")
    result = tcfarm_cli(farm, "submit", shot)
    assert result.returncode != 0
    assert ('shot.glb: this is an HTML page (it starts with "<!DOCTYPE html"), not a glTF file; expected a '
            'binary glTF (starts with "glTF") or glTF JSON') in result.stderr, result.stderr
    assert not stored_assets(farm) - before
    assert farm.metric("tcfarm_asset_uploads_total") == uploads
    assert all(job["name"] != "shot.glb" for job in farm.client.jobs())


def test_a_json_scene_that_is_html_is_refused_saying_so(farm, tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text("<html><body>502 Bad Gateway</body></html>\n")
    result = tcfarm_cli(farm, "submit", scene)
    assert result.returncode != 0
    assert 'this is an HTML page (it starts with "<html"), not a tcfarm JSON scene' in result.stderr, result.stderr


def test_a_good_glb_passes_the_check_and_is_submitted(farm, tmp_path):
    quad = make_gltf.red_quad().write(tmp_path / "quad.glb")
    result = tcfarm_cli(farm, "--json", "submit", quad)
    assert result.returncode == 0, result.stderr
    job = json.loads(result.stdout.strip().splitlines()[-1])
    assert job["name"] == "quad.glb"
    assert hashlib.sha256(quad.read_bytes()).hexdigest() in stored_assets(farm)


def test_the_check_answers_what_the_import_gives_with_its_warnings(farm):
    document = json.loads(make_gltf.red_quad().gltf_text())
    document["extensionsUsed"] = ["EXT_not_known_here"]
    status, answer = check(farm, {**inline("quad.gltf", json.dumps(document).encode()),
                                  "import": {"size": [32, 24]}, "frames": {"start": 0, "end": 0}})
    assert status == 200, answer
    assert answer["ok"] is True and answer["complete"] is True
    assert (answer["width"], answer["height"]) == (32, 24)
    assert answer["frames"] == {"start": 0, "end": 0}
    assert len(answer["warnings"]) == 1 and "EXT_not_known_here" in answer["warnings"][0]["message"]
    # The structure a job record gives its warnings.
    assert answer["warnings"][0]["code"] == "extension_not_implemented"
    assert answer["warnings"][0]["pointer"] == "/extensionsUsed/0"


def test_the_check_refuses_what_the_submit_refuses(farm):
    status, answer = check(farm, inline("shot.glb", b"PK\x03\x04 a zip, not a scene"))
    assert status == 400
    assert answer["error"]["code"] == "invalid_scene"
    assert "this is a ZIP archive" in answer["error"]["message"]
    # The same field errors as a submission's, before the scene.
    status, answer = check(farm, {**inline("quad.glb", make_gltf.red_quad().glb_bytes()), "bin_width": 1})
    assert status == 400 and answer["error"]["pointer"] == "/bin_width"
    status, answer = check(farm, {"scene": {"render": {}}})
    assert status == 400 and answer["error"]["pointer"].startswith("/scene/render")


def test_the_check_stores_nothing_not_even_an_embedded_texture(farm):
    before = stored_assets(farm)
    status, answer = check(farm, inline("printed.glb", make_gltf.textured_quad("data").glb_bytes()))
    assert status == 200 and answer["complete"] is True, answer
    assert not stored_assets(farm) - before


def test_without_its_uploads_the_check_judges_the_scene_file_alone(farm):
    document = json.loads(make_gltf.red_quad().gltf_text())
    document["buffers"][0]["uri"] = "quad.bin"
    not_uploaded = {"quad.bin": hashlib.sha256(b"not uploaded yet").hexdigest()}
    status, answer = check(farm, {**inline("quad.gltf", json.dumps(document).encode()), "assets": not_uploaded})
    assert status == 200, answer
    assert answer["complete"] is False and answer["missing_assets"] == ["quad.bin"]
    document["extensionsRequired"] = document["extensionsUsed"] = ["EXT_not_implemented_here"]
    status, answer = check(farm, {**inline("quad.gltf", json.dumps(document).encode()), "assets": not_uploaded})
    assert status == 400 and "EXT_not_implemented_here" in answer["error"]["message"], answer


def test_the_janitor_removes_orphan_uploads_and_keeps_what_a_job_names(farm, tmp_path):
    orphan = b"uploaded for a submission that never came"
    orphan_hash = hashlib.sha256(orphan).hexdigest()
    farm.client.put_asset(_write(tmp_path / "orphan.bin", orphan))
    assert orphan_hash in stored_assets(farm)
    quad = make_gltf.red_quad().write(tmp_path / "kept.glb")
    result = tcfarm_cli(farm, "submit", quad)
    assert result.returncode == 0, result.stderr
    kept_hash = hashlib.sha256(quad.read_bytes()).hexdigest()
    removed = farm.metric("tcfarm_store_orphan_assets_removed_total")
    # Counted once removed: the count is the later of the two.
    wait_until(lambda: farm.metric("tcfarm_store_orphan_assets_removed_total") >= removed + 1,
               "the orphan asset to be removed", timeout=30)
    assert orphan_hash not in stored_assets(farm)
    assert farm.metric("tcfarm_store_orphan_asset_bytes_removed_total") >= len(orphan)
    # Past the grace period, the asset the queued job names is still there.
    assert kept_hash in stored_assets(farm)


def _write(path, data):
    path.write_bytes(data)
    return path
