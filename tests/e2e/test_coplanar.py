"""Coplanar surfaces through the farm: whichever strategy traces a pixel, a ray that meets
two faces at the same distance sees the one the brute-force renderer sees. exact (and auto,
which picks it here) must equal brute force bit for bit; search and guarded may copy
wrongly by design, but every pixel they trace must equal brute force's."""
import copy
import json
import subprocess

import numpy as np
import pytest
from PIL import Image

from farm_harness import WORKER, LocalFarm, compare

FLOOR = {"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0],
         "material": "floor"}


def quad(corner, size, material, speed=None):
    shape = {"type": "quad", "corner": corner, "edge_u": [0, 0, size], "edge_v": [size, 0, 0],
             "material": material}
    if speed is not None:
        shape["motion"] = {"polynomial": [[0, speed], [0], [0]]}
    return shape


# The scene a user met the bug with: a red quad sliding on the floor, in its plane.
SLIDING_QUAD = {
    "camera": {"position": [0, 2, 8], "look_at": [0, 1, 0]},
    "lights": [{"type": "point", "position": [4, 6, 3], "intensity": [30, 30, 30]},
               {"type": "directional", "direction": [-1, -2, -1], "intensity": [0.3, 0.3, 0.3]}],
    "materials": {"red": {"diffuse": [0.8, 0.1, 0.1], "specular": [0.3, 0.3, 0.3], "shininess": 32},
                  "blue": {"diffuse": [0.1, 0.2, 0.8]},
                  "floor": {"diffuse": [0.6, 0.6, 0.6]},
                  "mirror": {"diffuse": [0.05, 0.05, 0.05], "reflectivity": 0.9}},
    "shapes": [FLOOR, quad([-3, 0, -1], 2, "red", speed=0.2)],
    "background": [0.1, 0.1, 0.2],
    "render": {"width": 160, "height": 120, "frames": {"start": 0, "count": 24},
               "samples_per_pixel": 1, "max_depth": 5},
}


def variant(shapes, width=96, height=72, frames=16):
    scene = copy.deepcopy(SLIDING_QUAD)
    scene["shapes"] = shapes
    scene["render"].update(width=width, height=height, frames={"start": 0, "count": frames})
    return scene


SCENES = {
    "sliding_quad": SLIDING_QUAD,
    "still_quad_and_a_moving_one": variant(
        [FLOOR, quad([-1.3, 0, -1.1], 2.3, "blue"), quad([-3, 0, 0.5], 1.5, "red", speed=0.3)]),
    "two_moving_coplanar_quads": variant(
        [FLOOR, quad([-3, 0, -1], 2, "red", speed=0.3), quad([1, 0, -1.5], 2.5, "blue", speed=-0.3)]),
    "coplanar_triangles_of_one_mesh": variant(
        [{"type": "mesh", "material": "floor",
          "vertices": [[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4],
                       [-3, 0, -3.3], [3.1, 0, -2.9], [0.2, 0, 3.7]],
          "triangles": [[0, 1, 2], [0, 2, 3], [4, 5, 6], [6, 5, 4]]},
         {"type": "sphere", "center": [-2, 0.6, 1], "radius": 0.6, "material": "red",
          "motion": {"polynomial": [[0, 0.3], [0], [0]]}}]),
    "a_tie_seen_in_a_mirror": variant(
        [FLOOR, quad([-3, 0, -1], 2, "red", speed=0.4),
         {"type": "quad", "corner": [-6, 0, -3], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0.5],
          "material": "mirror"}]),
}


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("farm"), workers=2) as farm:
        farm.wait_for_workers(2)
        yield farm


def render_reference(scene, directory):
    """Brute force through the standalone renderer: EXR for bits, PNG beside it."""
    (directory / "scene.json").write_text(json.dumps(scene))
    subprocess.run([str(WORKER), "render", str(directory / "scene.json"), "--out",
                    str(directory / "frames")], check=True, capture_output=True, timeout=600)
    return directory / "frames"


@pytest.fixture(scope="module")
def references(tmp_path_factory):
    return {name: render_reference(scene, tmp_path_factory.mktemp(name))
            for name, scene in SCENES.items()}


def png(path):
    return np.asarray(Image.open(path).convert("RGB"))


@pytest.mark.parametrize("name", sorted(SCENES))
@pytest.mark.parametrize("strategy", ["exact", "auto", "brute"])
def test_exact_and_brute_equal_the_reference_on_coplanar_faces(farm, references, name, strategy):
    job = farm.run_job(SCENES[name], strategy=strategy, bin_width=8)
    error = compare(references[name], farm.store / str(job["id"]))
    assert error["differing_pixels"] == 0, (name, strategy, error)
    print(f"{name} {strategy}: traced-pixel ratio {job['traced_pixel_ratio']:.3f}, 0 pixels differ")


@pytest.mark.parametrize("name", ["sliding_quad", "two_moving_coplanar_quads"])
@pytest.mark.parametrize("strategy", ["search", "guarded"])
def test_traced_pixels_equal_the_reference_on_coplanar_faces(farm, references, name, strategy,
                                                              tmp_path):
    scene = SCENES[name]
    job = farm.run_job(scene, strategy=strategy, bin_width=8)
    traced_wrong = traced = 0
    for frame in range(scene["render"]["frames"]["count"]):
        mask_path = tmp_path / f"mask{frame}.png"
        mask_path.write_bytes(farm.client._request(
            "GET", f"/api/v1/jobs/{job['id']}/frames/{frame}/mask.png", raw=True))
        traced_here = np.asarray(Image.open(mask_path).convert("L")) > 127
        ours_path = tmp_path / f"frame{frame}.png"  # the preview as users get it
        ours_path.write_bytes(farm.client._request("GET", f"/api/v1/jobs/{job['id']}/frames/{frame}.png", raw=True))
        ours = png(ours_path)
        reference = png(references[name] / f"frame_{frame:04d}.png")
        differs = (ours != reference).any(axis=2)
        traced += int(traced_here.sum())
        traced_wrong += int((differs & traced_here).sum())
    assert traced > 0
    assert traced_wrong == 0, f"{traced_wrong} of {traced} traced pixels differ from brute force"
    print(f"{name} {strategy}: {traced} traced pixels, all equal to brute force's")
