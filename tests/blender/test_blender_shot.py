"""A shot made in Blender, exported as glTF with the exporter's defaults, rendered by Cycles
and by tcfarm: the directly lit diffuse surfaces agree in mean luminance within 10 %.

The exporter writes Blender's watts as photometric units (a 3 W/m^2 sun as 2049 lx, a 500 W
point as 27176 cd), and Cycles' lamps emit what their watts say (a P W point P / (4 pi)
W/sr, a sun of S an irradiance of S): tcfarm must turn the photometric units back into what
Cycles renders for the shot to agree. Side-by-side frames (Cycles | tcfarm) are kept in
tests/artifacts/blender/."""
import json
import math
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import compare_shot  # noqa: E402
from required_tool import require_tool  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
ARTIFACTS = HERE.parent / "artifacts" / "blender"


def run_in_blender(script, out):
    """Runs a script of this folder inside Blender, headless; its stdout."""
    blender = shutil.which("blender")
    require_tool(blender, "no blender: run scripts/bootstrap (installs Debian's blender)")
    ran = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1",
                          "--python", str(HERE / script), "--", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert ran.returncode == 0, ran.stdout[-3000:] + ran.stderr[-3000:]
    return ran.stdout


def test_cycles_lamps_emit_what_their_watts_say(tmp_path):
    printed = run_in_blender("cycles_light_units.py", tmp_path)
    units = json.loads(printed.split("cycles_light_units ", 1)[1].splitlines()[0])
    assert units["point"]["ratio_to_p_over_4pi"] == pytest.approx(1, abs=0.01), units
    assert units["sun"]["ratio_to_strength"] == pytest.approx(1, abs=0.01), units


def test_cycles_and_tcfarm_light_the_shot_alike(worker_binary, tmp_path):
    run_in_blender("make_shot.py", tmp_path)
    lights = json.loads((tmp_path / "shot.gltf").read_text())["extensions"]["KHR_lights_punctual"]["lights"]
    intensity = {light["name"]: light["intensity"] for light in lights}
    assert intensity == pytest.approx({"Sun": 683 * 3, "Point": 683 * 500 / (4 * math.pi)}), intensity
    result = compare_shot.compare(tmp_path, worker_binary, ARTIFACTS)
    print({name: result[name] for name in ("Floor", "Ball", "Suzanne", "lit_diffuse")})
    ratio = result["lit_diffuse"]["ratio"]
    assert abs(ratio - 1) <= compare_shot.TOLERANCE, (
        f"tcfarm's directly lit floor and ball are {ratio:.4g} times as bright as Cycles' "
        f"(see {result['side_by_side']})")


def test_the_comparison_sees_the_lit_scale_not_shadows_or_edges():
    """Without Blender: a frame 8 % brighter passes and one 12 % brighter fails, though both
    add an ambient term in the shadow and get every edge pixel wrong."""
    shot = {"pass_index": {"Floor": 1, "Ball": 3, "Panel": 4}, "emissive": ["Panel"]}
    index = np.ones((40, 40))
    index[10:20, 10:20] = 3
    index[30:, 30:] = 4
    cycles = np.full((40, 40, 3), 0.5)
    cycles[:, :5] = 0  # a shadow on the floor
    cycles[index == 4] = 9  # the emissive panel
    for scale, passes in ((1.08, True), (1.12, False)):
        tcfarm = cycles * scale
        tcfarm[:, :5] = 0.025  # an ambient term where Cycles is black
        ring = np.zeros((40, 40), bool)
        ring[9:21, 9:21] = True
        ring[11:19, 11:19] = False
        tcfarm[ring] = 100  # the ball's edge and the floor's along it, antialiased another way
        tcfarm[index == 4] = 1
        figures = compare_shot.compare_images(shot, cycles, tcfarm, index)
        assert (abs(figures["lit_diffuse"]["ratio"] - 1) <= compare_shot.TOLERANCE) == passes, figures
        assert figures["lit_diffuse"]["ratio"] == pytest.approx(scale), figures
        assert "Panel" not in figures
