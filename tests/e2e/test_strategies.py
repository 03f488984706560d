"""Beyond the paper, end to end: exact (validity horizons), guarded, auto, and error
measured against brute force, through real processes, sockets and HTTP."""
import json
import os

import pytest

from deforming_scenes import deforming_set
from farm_harness import LocalFarm, compare, render_reference, small_scene
from tcfarm.client import ApiError

# A thin object crossing the screen between two frames that are otherwise equal (the
# paper's pathological case), and a light that flickers.
THIN_AND_FLICKER = {
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [3, 4, 8],
                "intensity": {"keyframes": [{"frame": 0, "value": [100, 100, 100]},
                                            {"frame": 6, "value": [100, 100, 100]},
                                            {"frame": 7, "value": [30, 30, 30]},
                                            {"frame": 8, "value": [100, 100, 100]}]}}],
    "materials": {"wall": {"diffuse": [0.7, 0.7, 0.65]}, "rod": {"diffuse": [0.9, 0.2, 0.1]}},
    "shapes": [
        {"type": "quad", "corner": [-8, -6, -4], "edge_u": [16, 0, 0], "edge_v": [0, 12, 0],
         "material": "wall"},
        {"type": "sphere", "center": [0, 0, 0], "radius": 0.06, "material": "rod",
         "motion": {"keyframes": [{"frame": 0, "value": [-30, 0.5, 0]},
                                  {"frame": 1, "value": [-30, 0.5, 0]},
                                  {"frame": 9, "value": [30, 0.5, 0]},
                                  {"frame": 10, "value": [30, 0.5, 0]}]}}],
    "background": [0.1, 0.1, 0.2],
    "render": {"width": 96, "height": 72, "frames": {"start": 0, "count": 11}},
}


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("farm"), workers=2) as farm:
        farm.wait_for_workers(2)
        yield farm


def reference_of(scene, tmp_path_factory, name):
    return render_reference(scene, tmp_path_factory.mktemp(name))


@pytest.mark.parametrize("name", ["paper_a_one_sphere", "paper_b_twelve_spheres"])
def test_exact_is_bit_identical_on_the_paper_animations(farm, scenes_dir, tmp_path_factory,
                                                         name):
    scene = small_scene(scenes_dir / f"{name}.json", 128, 96, 21)
    reference = reference_of(scene, tmp_path_factory, name)
    job = farm.run_job(scene, strategy="exact", bin_width=21)
    error = compare(reference, farm.store / str(job["id"]))
    assert error["differing_pixels"] == 0
    assert job["traced_pixel_ratio"] < 0.5
    print(f"{name} exact: traced ratio {job['traced_pixel_ratio']:.4f}")
    # Unasked, exact renders its last frame brute force as well: that frame, the most
    # copied into, is compared bit for bit, and it prices brute force for the job's cost
    # (exact's own full frames carry horizons and would overprice it).
    reference_check = job["stats"]["error"]["reference"]
    assert reference_check["frames_compared"] == 1
    assert reference_check["pixels_differing"] == 0
    cost = job["stats"]["cost"]
    assert cost["brute_estimate_from"] == "reference frames"
    # Priced in CPU seconds of the tracing threads, which waiting for shared cores does
    # not inflate; elapsed time is priced beside it.
    stats = job["stats"]
    assert cost["measured_relative_cost_basis"] == "trace cpu seconds"
    assert cost["measured_trace_relative_cost"] == pytest.approx(
        stats["trace_cpu_seconds"] / cost["brute_trace_cpu_seconds_estimate"])
    # The job's cost counts its checks as well: the reference frame, the spot checks.
    assert cost["measured_relative_cost"] == pytest.approx(
        (stats["trace_cpu_seconds"] + stats["verify_trace_cpu_seconds"]) / cost["brute_trace_cpu_seconds_estimate"])
    assert cost["measured_relative_cost_wall"] == pytest.approx(
        (stats["trace_seconds"] + stats["verify_trace_seconds"]) / cost["brute_trace_seconds_estimate"])
    assert 0 < stats["trace_cpu_seconds"] <= stats["trace_seconds"] * os.cpu_count() * 1.05 + 0.05


def moved(scene, offset):
    """The paper scene moved by offset: camera, point lights and shapes' own places."""
    scene = json.loads(json.dumps(scene))
    shift = lambda point: [p + o for p, o in zip(point, offset)]  # noqa: E731
    scene["camera"]["position"] = shift(scene["camera"]["position"])
    scene["camera"]["look_at"] = shift(scene["camera"]["look_at"])
    for light in scene["lights"]:
        light["position"] = shift(light["position"])
    for shape in scene["shapes"]:
        for key in ("center", "corner"):
            if key in shape:
                shape[key] = shift(shape[key])
    return scene


def test_far_from_the_origin_exact_equals_brute_force_and_the_image_holds(
        farm, scenes_dir, tmp_path_factory):
    # 164 pixels a row: packets of 8 rays straddle the view's axis.
    scene = small_scene(scenes_dir / "paper_b_twelve_spheres.json", 164, 120, 12)
    far = moved(scene, [3e4, 3e4, 3e4])
    reference = reference_of(far, tmp_path_factory, "far")
    exact = farm.run_job(far, strategy="exact", bin_width=12)
    assert compare(reference, farm.store / str(exact["id"]))["differing_pixels"] == 0
    # And it is the scene at the origin, up to float rounding of the move itself.
    near = compare(reference_of(scene, tmp_path_factory, "near"), reference)
    assert near["psnr_db"] is None or near["psnr_db"] > 60, near


def test_exact_sees_thin_fast_objects_and_flickering_lights(farm, tmp_path_factory):
    reference = reference_of(THIN_AND_FLICKER, tmp_path_factory, "thin")
    exact = farm.run_job(THIN_AND_FLICKER, strategy="exact", bin_width=11)
    assert compare(reference, farm.store / str(exact["id"]))["differing_pixels"] == 0
    # The paper's search misses the object between equal bin ends: that is the flaw.
    search = farm.run_job(THIN_AND_FLICKER, strategy="search", bin_width=11)
    assert compare(reference, farm.store / str(search["id"]))["differing_pixels"] > 0


def test_guarded_errs_less_than_search(farm, tmp_path_factory):
    reference = reference_of(THIN_AND_FLICKER, tmp_path_factory, "guarded")
    search = farm.run_job(THIN_AND_FLICKER, strategy="search", bin_width=11)
    guarded = farm.run_job(THIN_AND_FLICKER, strategy="guarded", bin_width=11)
    search_error = compare(reference, farm.store / str(search["id"]))["differing_pixels"]
    guarded_error = compare(reference, farm.store / str(guarded["id"]))["differing_pixels"]
    assert guarded_error < search_error


def test_exact_on_a_static_scene_traces_one_frame(farm):
    scene = json.loads(json.dumps(THIN_AND_FLICKER))
    scene["shapes"] = scene["shapes"][:1]
    scene["lights"][0]["intensity"] = [100, 100, 100]
    job = farm.run_job(scene, strategy="exact", bin_width=11)
    assert job["pixels_traced"] == 96 * 72


def test_auto_picks_exact_for_a_still_camera_and_guarded_for_a_flight(farm, scenes_dir):
    spheres = small_scene(scenes_dir / "paper_a_one_sphere.json", 64, 48, 9)
    flight = small_scene(scenes_dir / "paper_c_terrain_flyover.json", 64, 48, 9)
    assert farm.run_job(spheres, strategy="auto")["stats"]["strategy"]["name"] == "exact"
    job = farm.run_job(flight, strategy="auto")
    strategy = job["stats"]["strategy"]
    assert strategy["name"] == "guarded"
    # Its one prediction is the survey's for the width it runs with: the traced share priced
    # at 1.3 (kGuardedCostPerTracedShare), at most brute force's 1.
    share = strategy["survey"]["predicted_traced_share"][str(strategy["bin_width"])]
    assert strategy["predicted_relative_cost"] == pytest.approx(min(1.0, share * 1.3))
    assert "predicted_relative_cost" not in job["stats"]["cost"]


def test_auto_surveys_a_flight_and_renders_as_guarded_with_the_width_it_chose(farm, scenes_dir):
    flight = small_scene(scenes_dir / "paper_c_terrain_flyover.json", 96, 72, 24)
    job = farm.run_job(flight, strategy="auto")
    strategy = job["stats"]["strategy"]
    survey = strategy["survey"]
    assert survey["frames"] == 24
    predicted = {int(width): share for width, share in survey["predicted_traced_share"].items()}
    assert sorted(predicted) == list(range(2, 17))
    assert strategy["bin_width"] == min(predicted, key=lambda width: (predicted[width], width))
    # The survey was the coarse pass: the frames and the traced count are guarded's own.
    guarded = farm.run_job(flight, strategy="guarded", bin_width=strategy["bin_width"])
    assert job["pixels_traced"] == guarded["pixels_traced"]
    assert compare(farm.store / str(guarded["id"]), farm.store / str(job["id"]))["differing_pixels"] == 0


def test_verification_reports_what_compare_counts(farm, scenes_dir, tmp_path_factory):
    scene = small_scene(scenes_dir / "paper_b_twelve_spheres.json", 96, 72, 19)
    reference = reference_of(scene, tmp_path_factory, "verify")
    job = farm.run_job(scene, strategy="search", bin_width=10, verify={"frames": "all"})
    measured = compare(reference, farm.store / str(job["id"]))
    reported = job["stats"]["error"]["reference"]
    assert reported["frames_compared"] == 19
    assert reported["pixels_differing"] == measured["differing_pixels"]
    assert reported["ssim"] <= 1.0
    spot = job["stats"]["error"]["spot_checks"]
    assert spot["pixels_checked"] == 0  # every frame verified in full: no estimate needed
    sampled = farm.run_job(scene, strategy="search", bin_width=10)
    assert "reference" not in sampled["stats"]["error"]  # search verifies only when asked
    assert sampled["stats"]["cost"]["brute_estimate_from"] == "frames traced in full"
    spot = sampled["stats"]["error"]["spot_checks"]
    assert 0 < spot["pixels_checked"] <= 0.02 * 19 * 96 * 72
    low, high = spot["ci95_percent"]
    assert low <= spot["estimated_error_percent"] <= high


def test_bad_verification_requests_are_rejected(farm, scenes_dir):
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 32, 24, 3)
    for verify, pointer in (({"frames": "some"}, "/verify/frames"),
                            ({"sample": 0}, "/verify/sample"), ("yes", "/verify")):
        with pytest.raises(ApiError) as error:
            farm.client.submit(scene, verify=verify)
        assert error.value.status == 400 and error.value.pointer == pointer
    with pytest.raises(ApiError) as error:
        farm.client.submit(scene, spot_check_share=0.5)
    assert error.value.pointer == "/spot_check_share"


@pytest.mark.parametrize("mirror", [False, True], ids=["before a still wall", "in a mirror"])
def test_exact_is_bit_identical_on_deforming_meshes(farm, tmp_path_factory, mirror):
    """A skinned arm bending and a morphing blob with its shadow: whichever worker poses a
    frame, in whatever order, exact's frames are brute force's, bit for bit, and the still
    set around the character is copied."""
    scene = deforming_set(mirror=mirror)
    reference = reference_of(scene, tmp_path_factory, "deforming")
    job = farm.run_job(scene, strategy="exact", bin_width=12)
    assert compare(reference, farm.store / str(job["id"]))["differing_pixels"] == 0
    print(f"deforming ({'mirror' if mirror else 'wall'}) exact: traced ratio {job['traced_pixel_ratio']:.4f}")
    assert job["traced_pixel_ratio"] < 0.6
