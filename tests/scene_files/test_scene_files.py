"""The shared corpus (cases.json) against the Python client's scene_files: for each scene,
the files `tcfarm submit` uploads are the files the coordinator reads (scene_files_test.cpp
holds the coordinator to the same list). The dashboard's submit.js is held to it by
submit_js.test.mjs, run here with node's test runner."""
import json
import pathlib
import shutil
import subprocess

import pytest

from farm_harness import ROOT  # puts the client on the path

from tcfarm.scene_files import SceneFileError, scene_files

CORPUS = ROOT / "tests" / "scene_files"
CASES = json.loads((CORPUS / "cases.json").read_text())


@pytest.mark.parametrize("case", CASES, ids=[case["name"] for case in CASES])
def test_the_client_uploads_what_the_coordinator_reads(case):
    scene = CORPUS / case["name"] / case["scene"]
    if case.get("rejected"):
        with pytest.raises(SceneFileError):
            scene_files(scene)
        return
    found = scene_files(scene)
    listed = set(found.assets) | {scene.name}  # a JSON scene travels as the submission itself
    assert sorted(listed) == sorted(case["files"])
    for relative, local in found.assets.items():
        assert pathlib.Path(local) == scene.parent / relative


def test_the_dashboard_uploads_what_the_coordinator_reads():
    node = shutil.which("node")
    if node is None:
        pytest.fail("node is missing: run scripts/bootstrap")
    result = subprocess.run([node, "--test", str(CORPUS / "submit_js.test.mjs")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"# pass {len(CASES)}" in result.stdout, result.stdout
