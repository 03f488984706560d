"""The dashboard used as a person uses it: headless Chromium, driven over the DevTools
protocol (tests/browser.py), clicks its buttons, fills its forms and chooses files, against
a real local farm. Screenshots at 1280 and 420 px wide are kept in tests/artifacts/."""
import base64
import hashlib
import json
import sys

import pytest

from browser import Browser
from farm_harness import ROOT, LocalFarm, small_scene, tcfarm_cli

sys.path.insert(0, str(ROOT / "tests" / "gltf"))
import make_gltf  # noqa: E402

ARTIFACTS = ROOT / "tests" / "artifacts"
DASHBOARD = ROOT / "services" / "dashboard"


@pytest.fixture(autouse=True)
def dashboard_installed():
    if not (DASHBOARD / "node_modules" / "chart.js" / "dist" / "chart.umd.js").exists():
        pytest.fail("services/dashboard/node_modules is missing: run scripts/bootstrap")


def tiny_scene(scenes_dir, frames=2, size=16):
    return small_scene(scenes_dir / "paper_a_one_sphere.json", size, size, frames)


def js(value):
    return json.dumps(value)


def no_page_errors(page):
    assert page.exceptions == [], page.exceptions


# --- layout ----------------------------------------------------------------------------------

def test_the_page_fits_1280_and_420_pixels_wide(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        scene = small_scene(scenes_dir / "paper_a_one_sphere.json", 160, 120, 12)
        job = farm.run_job(scene, name="a sphere, verified", strategy="search", bin_width=6,
                           verify={"sample": 2})
        farm.client.submit(tiny_scene(scenes_dir), name="a job with a much longer name than fits a phone")
        for width in (1280, 420):
            with Browser(tmp_path / f"profile-{width}", width=width, height=900) as page:
                page.goto(f"{farm.url}/#job={job['id']}&frame=7")
                page.wait_for("document.getElementById('mask-image').dataset.loaded === '1' && "
                              "document.getElementById('change-image').dataset.loaded === '1'")
                page.wait_for("document.querySelectorAll('#jobs tbody tr').length === 2")
                page.pump(0.5)  # charts drawn
                scroll_width = page.evaluate("document.documentElement.scrollWidth")
                assert scroll_width <= width, f"{scroll_width} px of content in a {width} px window"
                # The buttons a person needs are there and on screen at this width.
                for button in ("#action-cancel", "#action-delete", "#action-priority", "#page-next"):
                    assert page.evaluate(f"document.querySelector({js(button)}).getBoundingClientRect().right") <= width
                no_page_errors(page)
                page.screenshot(ARTIFACTS / f"dashboard-{width}.png")


# --- the error panel -----------------------------------------------------------------------------

def test_the_error_panel_says_not_measured_yet_until_a_measurement_exists(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:  # no worker: nothing is measured
        job = farm.client.submit(tiny_scene(scenes_dir, frames=4), strategy="search", bin_width=2,
                                 verify={"frames": "all"})
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("document.getElementById('error-note').textContent !== ''")
            note = page.text("#error-note")
            assert "spot checks: not measured yet" in note, note
            assert "referee's unseen sample: none traced yet" in note, note
            for not_a_result in ("CI", "0/0", "PSNR", "SSIM", "51"):
                assert not_a_result not in note, note
            assert page.evaluate("document.getElementById('chart-error').dataset.pointsByDataset") == "0,0,0"
            assert "traced ratio not measured yet" in page.text("#job-summary")

            # Once a worker comes, the figures arrive on the page, without a reload.
            farm.add_worker()
            page.wait_for("document.getElementById('error-note').textContent.includes('PSNR')", timeout=60)
            note = page.text("#error-note")
            assert "against brute force (4/4 frames)" in note and "not measured yet" not in note, note
            # The referee's unseen sample: what it traced of the worker's values, and found.
            page.wait_for("document.getElementById('error-note').textContent.includes(' wrong, ')", timeout=60)
            note = page.text("#error-note")
            assert "referee's unseen sample: 10.00 % of every worker's pixels" in note, note
            assert " 0 wrong, " in note and "a worker altering 16 px a frame: 1 in " in note, note
            no_page_errors(page)


# --- images ------------------------------------------------------------------------------------

def test_a_mask_not_written_yet_is_tried_again_instead_of_shown_broken(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny_scene(scenes_dir, frames=3), strategy="search", bin_width=2)
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}&frame=1")
            page.wait_for("Number(document.getElementById('mask-image').dataset.retries || 0) >= 2")
            caption = page.text("#mask-image-caption")
            assert "the traced mask of frame 1 not written yet: trying again" in caption, caption
            # Nothing broken on screen: no image source was set that failed to load.
            for image in ("frame-image", "mask-image", "change-image"):
                assert page.evaluate(f"document.getElementById({js(image)}).getAttribute('src')") is None
            farm.add_worker()
            page.wait_for("document.getElementById('mask-image').dataset.loaded === '1'", timeout=60)
            assert page.evaluate("document.getElementById('mask-image').dataset.frame") == "1"
            assert page.text("#mask-image-caption") == "(frame 1)"
            assert page.evaluate("document.getElementById('mask-image').naturalWidth") == 16
            no_page_errors(page)


# --- submitting ----------------------------------------------------------------------------------

def submit_through_the_form(page, fields):
    """Fills the form's fields ({selector: value}; a <select> is chosen, the rest typed),
    clicks submit, waits for the farm's answer and returns the new job's id."""
    for selector, value in fields.items():
        if page.evaluate(f"document.querySelector({js(selector)}).tagName") == "SELECT":
            page.choose(selector, value)
        else:
            page.type(selector, value)
    before = page.evaluate("document.getElementById('submit-status').dataset.job || ''")
    page.click("#submit-button")
    page.wait_for(f"document.getElementById('submit-status').dataset.kind === 'ok' && "
                  f"document.getElementById('submit-status').dataset.job !== {js(before)}")
    return int(page.evaluate("document.getElementById('submit-status').dataset.job"))


def test_a_json_scene_submitted_through_the_form_runs_with_the_chosen_options(tmp_path, scenes_dir):
    scene_path = tmp_path / "tiny sphere.json"
    scene_path.write_text(json.dumps(tiny_scene(scenes_dir, frames=6)))
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        with Browser(tmp_path / "profile") as page:
            page.goto(farm.url + "/")
            page.click("#submit-panel summary")
            page.set_files("#submit-scene", [scene_path])
            page.wait_for("document.querySelector('#submit-strategy option[value=search]') !== null")
            job_id = submit_through_the_form(page, {
                "#submit-name": "from the form", "#submit-strategy": "search", "#submit-bin-width": "2",
                "#submit-frame-start": "1", "#submit-frame-end": "4", "#submit-priority": "-20",
                "#submit-verify": "all", "#submit-view": "khr-pbr-neutral", "#submit-exposure": "0.5"})
            assert page.text("#submit-status") == f"submitted job {job_id}"
            # The page selects the new job and shows it.
            page.wait_for(f"document.getElementById('job-title').textContent === 'Job {job_id}: from the form'")
            job = farm.client.wait(job_id, timeout=120)
            assert job["state"] == "completed", job
            assert (job["name"], job["strategy"], job["bin_width"], job["priority"]) == ("from the form", "search", 2, -20)
            assert job["frames"]["start"] == 1 and job["frames"]["end"] == 4
            assert job["stats"]["error"]["reference"]["frames_requested"] == 4
            assert (job["view"], job["exposure"]) == ("khr-pbr-neutral", 0.5)
            no_page_errors(page)


def test_a_gltf_with_its_buffer_and_image_is_uploaded_and_rendered(tmp_path):
    shot = tmp_path / "shot"
    shot.mkdir()
    gltf = make_gltf.textured_turntable("file")
    document = json.loads(gltf.gltf_text())
    (shot / "turntable.bin").write_bytes(base64.b64decode(document["buffers"][0]["uri"].split(",", 1)[1]))
    document["buffers"][0]["uri"] = "turntable.bin"
    (shot / "turntable.gltf").write_text(json.dumps(document))
    (shot / "floor.png").write_bytes(make_gltf.floor_png())
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        with Browser(tmp_path / "profile") as page:
            page.goto(farm.url + "/")
            page.click("#submit-panel summary")
            page.set_files("#submit-scene", [shot / "turntable.gltf"])
            # Without its files, the form says which one it lacks before anything is sent.
            page.wait_for("document.getElementById('submit-status').dataset.kind === 'error'")
            assert 'references buffer "turntable.bin": choose it' in page.text("#submit-status")
            page.set_files("#submit-files", [shot / "turntable.bin", shot / "floor.png"])
            page.wait_for("document.getElementById('submit-status').textContent.startsWith('references 2 files')")
            assert page.evaluate("document.getElementById('submit-import').hidden") is False
            job_id = submit_through_the_form(page, {
                "#submit-size": "48x36", "#submit-fps": "12", "#submit-frame-start": "0",
                "#submit-frame-end": "2", "#submit-strategy": "exact"})
            assert "3 files, 3 uploaded" in page.text("#submit-status")
            job = farm.client.wait(job_id, timeout=120)
            assert job["state"] == "completed", job
            assert (job["width"], job["height"], job["frames"]["count"]) == (48, 36, 3)
            for name in ("turntable.bin", "floor.png", "turntable.gltf"):
                digest = hashlib.sha256((shot / name).read_bytes()).hexdigest()
                assert (farm.store / "assets" / digest).exists(), name
            # The same files again: the farm has them all, nothing is uploaded twice.
            submit_through_the_form(page, {})
            assert "3 files, 0 uploaded, the rest already on the farm" in page.text("#submit-status")
            no_page_errors(page)


def test_the_job_page_lists_what_the_import_added(tmp_path):
    """A glTF without a camera or lights gets defaults, and the job page says so in its words."""
    bare = make_gltf.Gltf()
    bare.node(name="quad", mesh=bare.mesh([{"positions": make_gltf.quad(1.0), "indices": [0, 1, 2, 0, 2, 3]}]))
    path = tmp_path / "bare.gltf"
    path.write_text(bare.gltf_text())
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=0) as farm:
        result = tcfarm_cli(farm, "submit", path, "--size", "8x6")
        assert result.returncode == 0, result.stderr
        job = farm.client.jobs()[0]
        record = farm.client.job(job["id"])
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("!document.getElementById('job-warnings').hidden")
            shown = page.text("#job-warnings")
            for warning in record["warnings"]:
                assert warning["code"] in shown and warning["message"] in shown, (shown, warning)
            assert "default_light" in shown and "the file has no light" in shown, shown
            assert "default_camera" in shown and "the file has no camera" in shown, shown
            no_page_errors(page)


def test_a_scene_the_farm_refuses_is_explained_in_its_words(tmp_path, scenes_dir):
    bad = tiny_scene(scenes_dir)
    bad["shapes"][0]["radius"] = -1
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    with LocalFarm(tmp_path, workers=0) as farm:
        with Browser(tmp_path / "profile") as page:
            page.goto(farm.url + "/")
            page.click("#submit-panel summary")
            page.set_files("#submit-scene", [path])
            page.click("#submit-button")
            page.wait_for("document.getElementById('submit-status').dataset.kind === 'error'")
            status = page.text("#submit-status")
            assert status.startswith("The farm refused the job: "), status
            assert "(at /scene/shapes/0/radius) [invalid_scene]" in status, status
            assert farm.client.jobs() == []


def test_the_pages_sha256_agrees_with_hashlib_where_there_is_no_webcrypto(tmp_path):
    # A farm reached over plain http beyond loopback gives the page no crypto.subtle: the
    # page's own SHA-256, fed a piece at a time, must name files as the farm does.
    sizes = [0, 3, 55, 56, 63, 64, 65, 1000, (4 << 20) + 17]
    files = []
    for size in sizes:
        path = tmp_path / f"data-{size}.bin"
        path.write_bytes(bytes((i * 7 + size) % 251 for i in range(size)))
        files.append(path)
    with LocalFarm(tmp_path, workers=0) as farm:
        with Browser(tmp_path / "profile") as page:
            page.goto(farm.url + "/")
            page.set_files("#submit-files", files)
            digests = page.evaluate("Promise.all([...document.getElementById('submit-files').files]"
                                    ".map(sha256OfFileInPieces))")
    assert digests == [hashlib.sha256(path.read_bytes()).hexdigest() for path in files]


# --- actions -------------------------------------------------------------------------------------

def test_cancel_from_the_page(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny_scene(scenes_dir), name="to cancel")
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("!document.getElementById('action-cancel').disabled")
            assert page.evaluate("document.getElementById('action-delete').disabled")  # active: cancel first
            page.click("#action-cancel")
            page.wait_for("document.getElementById('action-message').dataset.kind === 'ok'")
            assert page.text("#action-message") == f"Canceled job {job['id']}."
            assert farm.client.job(job["id"])["state"] == "canceled"
            page.wait_for(f"document.querySelector('tr[data-job-id=\"{job['id']}\"] .state').textContent === 'canceled'")
            page.wait_for("document.getElementById('action-cancel').disabled")
            # Cancelling again is refused by the farm; the page says why in its words.
            page.evaluate("document.getElementById('action-cancel').disabled = false")
            page.click("#action-cancel")
            page.wait_for("document.getElementById('action-message').dataset.kind === 'error'")
            message = page.text("#action-message")
            assert message.startswith(f"Could not cancel job {job['id']}: job {job['id']} is already canceled"), message
            assert message.endswith("[job_finished]"), message
            no_page_errors(page)


# --- tokens --------------------------------------------------------------------------------------

READ_TOKEN = "dashboard-read-0123456789abcdef"
ADMIN_TOKEN = "dashboard-admin-0123456789abcdef"


def test_with_tokens_the_page_signs_in_remembers_and_acts_with_the_tokens_role(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0, api_tokens={ADMIN_TOKEN: "admin", READ_TOKEN: "read"}) as farm:
        job = farm.client.submit(tiny_scene(scenes_dir), name="guarded")
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("!document.getElementById('sign-in').hidden")
            assert "This farm needs an API token." in page.text("#sign-in-message")
            page.type("#token-input", READ_TOKEN)
            page.click("#sign-in button[type=submit]")
            page.wait_for(f"document.querySelector('tr[data-job-id=\"{job['id']}\"]') !== null")
            assert page.evaluate("localStorage.getItem('tcfarm-api-token')") == READ_TOKEN
            # The event stream, refused before, is opened with the token at once.
            page.wait_for("document.getElementById('connection').dataset.stream === 'live'", timeout=3)
            # A read token may look, not act: the farm's refusal, in its words.
            page.wait_for("!document.getElementById('action-cancel').disabled")
            page.click("#action-cancel")
            page.wait_for("document.getElementById('action-message').dataset.kind === 'error'")
            assert "needs a token of role submit or above" in page.text("#action-message")
            assert "[forbidden]" in page.text("#action-message")
            assert farm.client.job(job["id"])["state"] in ("queued", "running")  # not canceled

            # Remembered: a new visit signs in by itself. Then an admin token acts.
            page.reload()
            page.wait_for(f"document.querySelector('tr[data-job-id=\"{job['id']}\"]') !== null")
            assert page.evaluate("document.getElementById('sign-in').hidden")
            page.click("#sign-out")
            page.wait_for("!document.getElementById('sign-in').hidden")
            assert page.evaluate("localStorage.getItem('tcfarm-api-token')") is None
            page.type("#token-input", ADMIN_TOKEN)
            page.click("#token-remember")  # this tab only
            page.click("#sign-in button[type=submit]")
            page.wait_for("!document.getElementById('action-cancel').disabled")
            assert page.evaluate("localStorage.getItem('tcfarm-api-token')") is None
            assert page.evaluate("sessionStorage.getItem('tcfarm-api-token')") == ADMIN_TOKEN
            page.click("#action-cancel")
            page.wait_for("document.getElementById('action-message').dataset.kind === 'ok'")
            assert farm.client.job(job["id"])["state"] == "canceled"
            assert ADMIN_TOKEN not in page.evaluate("document.documentElement.outerHTML")
            no_page_errors(page)


def test_the_pages_strategies_are_the_farms(tmp_path):
    with LocalFarm(tmp_path, workers=0) as farm:
        served = farm.client.strategies()
        with Browser(tmp_path / "profile") as page:
            page.goto(farm.url + "/")
            page.wait_for("document.querySelectorAll('#submit-strategy option').length > 1")
            for select in ("#submit-strategy", "#filter-strategy"):
                values = page.evaluate(f"Array.from(document.querySelectorAll({js(select + ' option')}), "
                                       "(option) => option.value)")
                assert values == [""] + served["strategies"], (select, values)
            assert page.text("#submit-strategy option[value='']") == f"the farm's default ({served['default']})"
            no_page_errors(page)
