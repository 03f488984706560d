"""A job's PNG previews go through the view it was submitted with; its EXR frames are the
traced values whatever the view."""
import json

import pytest

from farm_harness import LocalFarm, compare, small_scene, tcfarm_cli, wait_until
from tcfarm.client import ApiError


def finished(farm, job_id):
    """The frame finisher compressed the job's EXRs and wrote its previews."""
    return (farm.store / str(job_id) / ".finished").exists()


def test_a_neutral_view_changes_the_previews_and_not_the_exrs(tmp_path, scenes_dir):
    scene = small_scene(scenes_dir / "paper_b_twelve_spheres.json", 64, 48, frames=3)
    scene_path = tmp_path / "twelve.json"
    scene_path.write_text(json.dumps(scene))
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        standard = farm.run_job(scene, strategy="exact")
        submitted = tcfarm_cli(farm, "--json", "submit", scene_path, "--strategy", "exact",
                               "--view", "khr-pbr-neutral", "--exposure", "0.5", "--wait")
        assert submitted.returncode == 0, submitted.stderr
        neutral = json.loads(submitted.stdout.strip().splitlines()[-1])
        assert neutral["state"] == "completed", neutral
        assert (standard["view"], standard["exposure"]) == ("standard", 0)
        assert (neutral["view"], neutral["exposure"]) == ("khr-pbr-neutral", 0.5)
        assert farm.client.job(neutral["id"])["view"] == "khr-pbr-neutral"
        status = tcfarm_cli(farm, "status", neutral["id"])
        assert "previews: view khr-pbr-neutral, exposure +0.5 EV" in status.stdout, status.stdout

        # Asked for before the finisher wrote them, previews are made on request; after,
        # they are the finisher's files: through the job's view either way.
        early = {job["id"]: farm.client.frame(job["id"], 1) for job in (standard, neutral)}
        wait_until(lambda: finished(farm, standard["id"]) and finished(farm, neutral["id"]),
                   "the frame finisher", timeout=120)
        for frame in range(3):
            png = {job["id"]: farm.client.frame(job["id"], frame) for job in (standard, neutral)}
            assert png[neutral["id"]] != png[standard["id"]], frame
            if frame == 1:
                assert png == early
        # The EXRs' pixels (their headers hold the date they were written).
        same = compare(farm.store / str(standard["id"]), farm.store / str(neutral["id"]))
        assert (same["frames"], same["differing_pixels"]) == (3, 0), same


@pytest.mark.parametrize("field, value", [("view", "filmic"), ("view", 2), ("exposure", 40),
                                          ("exposure", "1")])
def test_a_bad_view_or_exposure_is_refused_naming_it(tmp_path, scenes_dir, field, value):
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 16, 12, frames=1)
    with LocalFarm(tmp_path, workers=0) as farm:
        with pytest.raises(ApiError) as error:
            farm.client.submit(scene, **{field: value})
    assert (error.value.status, error.value.code, error.value.pointer) == (400, "invalid_field", f"/{field}")
    assert "expected" in str(error.value)
