"""The dashboard end to end: a local farm serves it at /, headless Chromium opens it while
a real job runs and after it completes, and the page's DOM shows the job, charts with data
points and the loaded frame, traced-mask and change-mask images. The screenshot is kept as
tests/artifacts/dashboard.png."""
import html.parser
import io
import pathlib
import shutil
import subprocess
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from PIL import Image

from browser import chromium_binary
from farm_harness import ROOT, LocalFarm, small_scene

ARTIFACTS = ROOT / "tests" / "artifacts"
DASHBOARD = ROOT / "services" / "dashboard"
WIDTH, HEIGHT, FRAMES = 160, 120, 20


def chromium(url, profile, *mode):
    """Loads url in headless Chromium for 5 s of virtual time; returns stdout."""
    result = subprocess.run(
        [chromium_binary(), "--headless", "--no-sandbox", "--disable-gpu",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-first-run", f"--user-data-dir={profile}", "--window-size=1280,900",
         "--virtual-time-budget=5000", *mode, url],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


class Elements(html.parser.HTMLParser):
    """Every element's attributes, by id, and the job rows' ids."""

    def __init__(self, text):
        super().__init__()
        self.by_id = {}
        self.job_rows = set()
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.by_id[attrs["id"]] = attrs
        if tag == "tr" and "data-job-id" in attrs:
            self.job_rows.add(int(attrs["data-job-id"]))


def points(elements, chart):
    return int(elements.by_id[chart]["data-points"])


def fetch_png(url):
    with urllib.request.urlopen(url, timeout=10) as response:
        assert response.headers["Content-Type"] == "image/png"
        return np.asarray(Image.open(io.BytesIO(response.read())).convert("L"))


@pytest.fixture
def farm(tmp_path):
    if not (DASHBOARD / "node_modules" / "chart.js" / "dist" / "chart.umd.js").exists():
        pytest.fail("services/dashboard/node_modules is missing: run scripts/bootstrap")
    with LocalFarm(tmp_path, workers=2) as farm:
        farm.wait_for_workers(2)
        yield farm


def test_dashboard_shows_a_running_and_a_completed_job(farm, scenes_dir, tmp_path):
    with urllib.request.urlopen(farm.url + "/", timeout=10) as response:
        assert b"tcfarm" in response.read()
    with urllib.request.urlopen(farm.url + "/node_modules/chart.js/dist/chart.umd.js",
                                timeout=10) as response:
        assert response.status == 200

    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", WIDTH, HEIGHT, FRAMES)
    job = farm.client.submit(scene, name="paper_a_dashboard", strategy="search", bin_width=10)
    url = f"{farm.url}/#job={job['id']}"

    # While it runs (on a fast machine it may finish meanwhile): once it has a finished
    # frame, the page lists and selects it, charts that frame and loads its mask.
    deadline = time.monotonic() + 120
    while farm.client.job(job["id"])["frames"]["done"] < 1:
        assert time.monotonic() < deadline, "no frame finished in 120 s"
        time.sleep(0.02)
    live = Elements(chromium(url, tmp_path / "profile-live", "--dump-dom"))
    assert job["id"] in live.job_rows
    assert not live.by_id["job-detail"].get("hidden")
    assert points(live, "chart-traced") >= 1
    assert live.by_id["mask-image"].get("data-loaded") == "1"

    job = farm.client.wait(job["id"], timeout=300)
    assert job["state"] == "completed", job

    # The screenshot shows a frame inside a bin, whose mask traced only what moved.
    screenshot = tmp_path / "dashboard.png"
    chromium(f"{url}&frame=15", tmp_path / "profile-shot", f"--screenshot={screenshot}")
    assert screenshot.stat().st_size > 10_000
    ARTIFACTS.mkdir(exist_ok=True)
    shutil.copyfile(screenshot, ARTIFACTS / "dashboard.png")

    dom = chromium(url, tmp_path / "profile-dom", "--dump-dom")
    page = Elements(dom)
    assert job["id"] in page.job_rows
    assert "<b>trace CPU </b>" in dom  # the job's cost in CPU seconds, beside elapsed
    assert points(page, "chart-traced") == FRAMES
    assert points(page, "chart-coherence") == 2 * (FRAMES - 1)   # frame-to-frame, long-term
    assert points(page, "chart-cost") >= 3   # equation 3's curve, predicted and measured
    assert points(page, "chart-error") >= 3  # the spot checks' estimate and its interval
    for image in ("frame-image", "mask-image", "change-image"):
        assert page.by_id[image].get("data-loaded") == "1", (image, page.by_id[image])
    last = job["frames"]["end"]
    assert f"/frames/{last}/mask.png" in page.by_id["mask-image"]["data-src"]
    assert page.by_id["mask-image"]["src"].startswith("blob:")  # fetched, then shown
    assert page.by_id["sign-in"].get("hidden") is not None  # a farm without tokens asks none


def test_cost_chart_shows_what_autos_survey_predicted(farm, scenes_dir, tmp_path):
    flight = small_scene(scenes_dir / "paper_c_terrain_flyover.json", WIDTH, HEIGHT, FRAMES)
    job = farm.run_job(flight, strategy="auto")
    strategy = job["stats"]["strategy"]
    predicted = strategy["survey"]["predicted_traced_share"]
    dom = chromium(f"{farm.url}/#job={job['id']}", tmp_path / "profile", "--dump-dom")
    page = Elements(dom)
    # The summary shows the record's one prediction, the figure its reason gives.
    figure = f"{strategy['predicted_relative_cost']:.3f}"
    assert f"<b>predicted cost </b><span>{figure}</span>" in dom
    assert figure in strategy["reason"]
    by_dataset = [int(n) for n in page.by_id["chart-cost"]["data-points-by-dataset"].split(",")]
    # equation 3's curve, predicted, measured, then one point per width the survey weighed
    assert len(by_dataset) == 4
    assert by_dataset[3] == len(predicted) >= 2


def test_masks_are_the_traced_pixels_and_the_unchanged_ones(farm, scenes_dir):
    scene = small_scene(scenes_dir / "paper_a_one_sphere.json", WIDTH, HEIGHT, 12)
    job = farm.run_job(scene, strategy="search", bin_width=6)
    frames = f"{farm.url}/api/v1/jobs/{job['id']}/frames/"
    previous = None
    for frame, traced in enumerate(job["traced_per_frame"]):
        mask = fetch_png(f"{frames}{frame}/mask.png")
        change = fetch_png(f"{frames}{frame}/change.png")
        assert mask.shape == change.shape == (HEIGHT, WIDTH)
        assert set(np.unique(mask)) <= {0, 255} and set(np.unique(change)) <= {0, 255}
        assert int((mask == 255).sum()) == traced
        # The change mask compares the exact floats: where the 8-bit PNG changed, the
        # floats changed too, so it is black there (it may be black where 8 bits agree).
        rgb = np.asarray(Image.open(io.BytesIO(urllib.request.urlopen(
            f"{frames}{frame}.png", timeout=10).read())).convert("RGB"))
        if previous is None:
            assert (change == 255).all()
        else:
            png_changed = (rgb != previous).any(axis=2)
            assert not (png_changed & (change == 255)).any()
            assert (change == 0).any()
        previous = rgb
    with pytest.raises(urllib.error.HTTPError) as error:
        urllib.request.urlopen(f"{frames}{len(job['traced_per_frame'])}/mask.png", timeout=10)
    assert error.value.code == 400


READ_TOKEN = "dashboard-read-0123456789abcdef"
ADMIN_TOKEN = "dashboard-admin-0123456789abcdef"


def test_a_farm_with_tokens_asks_for_one_and_sends_it_on_every_request(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=1, api_tokens={ADMIN_TOKEN: "admin", READ_TOKEN: "read"}) as farm:
        farm.wait_for_workers(1)
        # The page itself is open; the API is not.
        with urllib.request.urlopen(farm.url + "/", timeout=10) as response:
            assert b"sign-in" in response.read()
        scene = small_scene(scenes_dir / "paper_a_one_sphere.json", WIDTH, HEIGHT, 6)
        job = farm.run_job(scene, strategy="search", bin_width=3)

        anonymous = Elements(chromium(f"{farm.url}/#job={job['id']}", tmp_path / "profile-anon", "--dump-dom"))
        assert anonymous.by_id["sign-in"].get("hidden") is None  # the form is shown
        assert anonymous.job_rows == set()
        assert anonymous.by_id["mask-image"].get("data-loaded") == "0"

        # A link with the token signs in: jobs, workers and every image come with it.
        dom = chromium(f"{farm.url}/#token={READ_TOKEN}&job={job['id']}", tmp_path / "profile-token", "--dump-dom")
        page = Elements(dom)
        assert page.by_id["sign-in"].get("hidden") is not None
        assert page.by_id["sign-out"].get("hidden") is None
        assert job["id"] in page.job_rows
        for image in ("frame-image", "mask-image", "change-image"):
            assert page.by_id[image].get("data-loaded") == "1", (image, page.by_id[image])
        assert READ_TOKEN not in dom  # not left in the page (nor in its address)

        wrong = Elements(chromium(f"{farm.url}/#token=unknown-0123456789abcdef", tmp_path / "profile-wrong",
                                  "--dump-dom"))
        assert wrong.by_id["sign-in"].get("hidden") is None
        assert wrong.job_rows == set()
