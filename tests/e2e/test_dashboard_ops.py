"""The dashboard's daily actions, clicked in headless Chromium against a real farm: delete
with its confirmation, retry, priority, filtering and paging among 1,000 jobs, the per-frame
strip, the job's events, and live events from the farm's stream, without a reload."""
import json
import socket
import threading

import pytest

from browser import Browser
from farm_harness import ROOT, LocalFarm, small_scene

ARTIFACTS = ROOT / "tests" / "artifacts"


def tiny(scenes_dir, frames=2):
    return small_scene(scenes_dir / "paper_a_one_sphere.json", 16, 16, frames)


def row_ids(page):
    return page.evaluate("[...document.querySelectorAll('#jobs tbody tr')].map((r) => Number(r.dataset.jobId))")


def wait_for_page_note(page, text):
    """Waits until the pager says `text`; a timeout shows what it says instead."""
    try:
        page.wait_for(f"document.getElementById('page-note').textContent === {json.dumps(text)}")
    except AssertionError:
        assert page.text("#page-note") == text, page.evaluate("JSON.stringify(state.filters) + ' offset ' + state.offset")


def message_of_kind(page, kind):
    page.wait_for(f"document.getElementById('action-message').dataset.kind === {json.dumps(kind)}")
    return page.text("#action-message")


def test_delete_asks_for_confirmation_and_frees_the_store(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=1) as farm:
        farm.wait_for_workers(1)
        job = farm.run_job(tiny(scenes_dir, frames=4), name="to delete")
        other = farm.run_job(tiny(scenes_dir), name="kept")
        folder = farm.store / str(job["id"])
        assert folder.is_dir()
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("!document.getElementById('action-delete').disabled")
            page.click("#action-delete")
            page.wait_for("!document.getElementById('delete-confirm').hidden")
            question = page.text("#delete-question")
            assert question.startswith(f"Delete job {job['id']} “to delete” (completed, 4 frames written)"), question
            page.click("#delete-no")  # changed my mind
            assert page.evaluate("document.getElementById('delete-confirm').hidden")
            page.pump(0.5)
            assert farm.client.job(job["id"])["state"] == "completed" and folder.is_dir()

            page.click("#action-delete")
            page.click("#delete-yes")
            message = message_of_kind(page, "ok")
            assert message.startswith(f"Deleted job {job['id']}; freed "), message
            assert not folder.exists()
            page.wait_for(f"!document.querySelector('tr[data-job-id=\"{job['id']}\"]')")
            assert row_ids(page) == [other["id"]]
            assert page.evaluate("document.getElementById('job-detail').hidden")
            assert page.exceptions == []


def test_retry_and_priority_from_the_page(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny(scenes_dir), name="again")
        farm.client.cancel(job["id"])
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("!document.getElementById('action-retry').disabled")
            page.click("#action-retry")
            assert message_of_kind(page, "ok") == f"Job {job['id']} is queued again."
            assert farm.client.job(job["id"])["state"] in ("queued", "running")
            page.wait_for("document.getElementById('action-retry').disabled")

            page.type("#action-priority-value", "-50")
            page.click("#action-priority")
            assert message_of_kind(page, "ok") == f"Job {job['id']} now has priority -50."
            assert farm.client.job(job["id"])["priority"] == -50
            page.wait_for(f"document.querySelector('tr[data-job-id=\"{job['id']}\"] td:nth-child(8)').textContent === '-50'")

            # Out of range: the farm refuses, and the page says so in the farm's words.
            page.type("#action-priority-value", "500")
            page.click("#action-priority")
            message = message_of_kind(page, "error")
            assert message.startswith(f"Could not change the priority of job {job['id']}: "), message
            assert "priority" in message and "500" in message and "[" in message
            assert farm.client.job(job["id"])["priority"] == -50
            assert page.exceptions == []


JOBS = 1000


@pytest.fixture(scope="module")
def thousand(tmp_path_factory, scenes_dir):
    """A farm without workers and 1,000 jobs: "take-0001".."take-1000", every fourth a guarded
    one, every tenth canceled."""
    with LocalFarm(tmp_path_factory.mktemp("thousand"), workers=0) as farm:
        scene = tiny(scenes_dir)
        ids = []
        for index in range(1, JOBS + 1):
            job = farm.client.submit(scene, name=f"take-{index:04d}",
                                     strategy="guarded" if index % 4 == 0 else "search", bin_width=2)
            if index % 10 == 0:
                farm.client.cancel(job["id"])
            ids.append(job["id"])
        yield farm, ids


def test_any_job_among_a_thousand_is_found_by_filter_search_and_paging(thousand, tmp_path):
    farm, ids = thousand
    with Browser(tmp_path / "profile") as page:
        page.goto(farm.url + "/")
        wait_for_page_note(page, "showing 1–20 of 1000")
        assert row_ids(page) == ids[::-1][:20]
        page.click("#page-next")
        wait_for_page_note(page, "showing 21–40 of 1000")
        assert row_ids(page) == ids[::-1][20:40]
        page.click("#page-prev")
        wait_for_page_note(page, "showing 1–20 of 1000")

        # The oldest job, by its name.
        page.type("#filter-name", "TAKE-0001")
        wait_for_page_note(page, "showing 1–1 of 1")
        assert row_ids(page) == [ids[0]]
        page.click(f"tr[data-job-id=\"{ids[0]}\"]")
        page.wait_for(f"document.getElementById('job-title').textContent === 'Job {ids[0]}: take-0001'")

        # Canceled guarded jobs: every 20th.
        page.type("#filter-name", "")
        page.choose("#filter-state", "canceled")
        page.choose("#filter-strategy", "guarded")
        wait_for_page_note(page, "showing 1–20 of 50")
        expected = [job_id for index, job_id in enumerate(ids, 1) if index % 20 == 0][::-1]
        assert row_ids(page) == expected[:20]
        assert set(page.evaluate("[...document.querySelectorAll('#jobs tbody .state')].map((s) => s.textContent)")) == {"canceled"}
        page.click("#page-next")
        page.click("#page-next")
        wait_for_page_note(page, "showing 41–50 of 50")
        assert row_ids(page) == expected[40:]
        assert page.evaluate("document.getElementById('page-next').disabled")
        page.type("#filter-name", "take-09")  # with a name too
        wait_for_page_note(page, "showing 1–5 of 5")
        assert page.evaluate("[...document.querySelectorAll('#jobs tbody .name-col')].map((c) => c.textContent)") == \
            ["take-0980", "take-0960", "take-0940", "take-0920", "take-0900"]
        page.screenshot(ARTIFACTS / "dashboard-filtered.png", full_page=False)
        assert page.exceptions == []


def test_frames_events_and_live_updates_without_a_reload(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny(scenes_dir, frames=6), name="live", strategy="search", bin_width=3)
        with Browser(tmp_path / "profile") as page:
            page.goto(f"{farm.url}/#job={job['id']}")
            page.wait_for("document.getElementById('connection').dataset.stream === 'live'")
            page.wait_for("document.querySelectorAll('#frame-strip .cell').length === 6")
            assert set(page.evaluate("[...document.querySelectorAll('#frame-strip .cell')].map((c) => c.dataset.state)")) \
                <= {"queued", "tracing"}
            page.wait_for("document.querySelector('#events li[data-type=\"submitted\"]') !== null")
            page.evaluate("window.notReloaded = true")

            # Something happens on the farm: the page hears of it from the stream.
            farm.client.update(job["id"], name="live, renamed")
            page.wait_for("document.querySelector('#events li[data-type=\"renamed\"]') !== null", timeout=10)
            assert page.evaluate("document.querySelector('#events li[data-type=\"renamed\"]').dataset.via") == "stream"
            page.wait_for("document.getElementById('job-title').textContent.endsWith('live, renamed')", timeout=10)

            farm.add_worker()  # the job runs: frames written, then completed, all live
            page.wait_for("document.querySelector('#events li[data-type=\"completed\"]') !== null", timeout=120)
            page.wait_for("[...document.querySelectorAll('#frame-strip .cell')].every((c) => c.dataset.state === 'written')")
            assert page.evaluate("window.notReloaded") is True
            types = page.evaluate("[...document.querySelectorAll('#events li')].map((li) => li.dataset.type)")
            assert types[0] == "completed" and types[-1] == "submitted"  # newest first
            assert "frames_written" in types and "started" in types
            # A cell is a frame: a click shows it.
            page.click("#frame-strip .cell[data-frame=\"2\"]")
            page.wait_for("document.getElementById('mask-image').dataset.frame === '2' && "
                          "document.getElementById('mask-image').dataset.loaded === '1'")
            page.screenshot(ARTIFACTS / "dashboard-events.png")
            assert page.exceptions == []


class DroppingProxy:
    """A TCP proxy in front of the farm whose connections can all be cut at once, as a
    network that fails for a moment cuts them."""

    def __init__(self, upstream_port):
        self.upstream = ("127.0.0.1", upstream_port)
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.open = []
        self.lock = threading.Lock()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            server = socket.create_connection(self.upstream)
            with self.lock:
                self.open += [client, server]
            for source, sink in ((client, server), (server, client)):
                threading.Thread(target=self._pump, args=(source, sink), daemon=True).start()

    @staticmethod
    def _pump(source, sink):
        try:
            while True:
                data = source.recv(65536)
                if not data:
                    break
                sink.sendall(data)
        except OSError:
            pass
        finally:
            for end in (source, sink):
                try:
                    end.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def drop(self):
        with self.lock:
            cut, self.open = self.open, []
        for end in cut:
            try:
                end.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def close(self):
        self.listener.close()
        self.drop()


def test_the_event_stream_comes_back_after_the_connection_drops(tmp_path, scenes_dir):
    with LocalFarm(tmp_path, workers=0) as farm:
        job = farm.client.submit(tiny(scenes_dir), name="first")
        proxy = DroppingProxy(int(farm.url.rsplit(":", 1)[1]))
        try:
            with Browser(tmp_path / "profile") as page:
                page.goto(f"http://127.0.0.1:{proxy.port}/#job={job['id']}")
                page.wait_for("document.getElementById('connection').dataset.stream === 'live'")
                page.wait_for("document.querySelector('#events li[data-type=\"submitted\"]') !== null")
                page.evaluate("window.notReloaded = true")
                proxy.drop()
                farm.client.update(job["id"], name="second")  # while the page is cut off
                page.wait_for("document.getElementById('connection').dataset.stream !== 'live'", timeout=5)
                page.wait_for("document.getElementById('connection').dataset.stream === 'live'", timeout=20)
                page.wait_for("document.querySelector('#events li[data-type=\"renamed\"]') !== null", timeout=10)
                farm.client.update(job["id"], name="third")  # and after: live again, from the stream
                page.wait_for("document.querySelectorAll('#events li[data-type=\"renamed\"]').length === 2", timeout=10)
                assert page.evaluate("document.querySelector('#events li[data-type=\"renamed\"]').dataset.via") == "stream"
                page.wait_for("document.getElementById('job-title').textContent.endsWith('third')", timeout=10)
                page.pump(1)
                assert page.evaluate("document.querySelectorAll('#events li[data-type=\"renamed\"]').length") == 2
                assert page.evaluate("window.notReloaded") is True
                assert page.exceptions == []
        finally:
            proxy.close()
