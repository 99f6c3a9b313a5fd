"""The review page: its API (round trips, checks, stale writes, traversal) and a real browser."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from pipeline.annotate.proposals import ProposalOptions
from pipeline.annotate.review.server import ReviewApp, serve
from tests.annotate.test_annotation import write_tracks
from tests.conftest import PROJECT, make_test_video, skip_or_fail


@contextlib.contextmanager
def review_site(tmp_path: Path, token: str | None = None):
    """A project with two tracks of vid_000 and its QC video, its review page served on a free port."""
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    write_tracks(root, "vid_000", {1: list(range(240)), 2: list(range(48, 144))})
    (root / "data/qc").mkdir(parents=True)
    make_test_video(root / "data/qc/vid_000.mp4", seconds=10, fps="24", size="320x180")
    server = serve(ReviewApp(root, ProposalOptions(), 2.0, token=token), "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield root, f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def site(tmp_path: Path):
    with review_site(tmp_path) as (root, url):
        (root / "secret.txt").write_text("not for the web")
        yield root, url


def call(url: str, method: str = "GET", body: dict | None = None, headers: dict | None = None):
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(url, data=data, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(request) as response:
            return response.status, response.read(), dict(response.headers)
    except urllib.error.HTTPError as err:
        return err.code, err.read(), dict(err.headers)


def test_segment_list_and_statuses(site) -> None:
    root, url = site
    status, body, _ = call(f"{url}/api/segments")
    assert status == 200 and json.loads(body) == [{"id": "vid_000", "status": "unannotated", "errors": 0}]


def test_unedited_manifest_round_trips_byte_for_byte(site) -> None:
    root, url = site
    path = root / "manifests/tracks/vid_000.csv"
    path.parent.mkdir(parents=True)
    original = ("# a comment the annotator wrote\n"
                "track_id,start,end,keep,note,frames,mean_score,box_height,motion,reason\n"
                "1,0.0,9.958,yes,,,,,,\n2,2,5.958,no,audience,,,,,\n")
    path.write_text(original)
    segment = json.loads(call(f"{url}/api/segments/vid_000")[1])
    unedited = {"version": segment["version"], "rows": segment["rows"]}
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", unedited)
    assert status == 200 and json.loads(body)["unchanged"] is True
    assert path.read_text() == original


def test_saving_a_proposal_writes_a_valid_manifest(site) -> None:
    root, url = site
    segment = json.loads(call(f"{url}/api/segments/vid_000")[1])
    assert segment["has_manifest"] is False and segment["version"] == ""
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", {"version": "", "rows": segment["rows"]})
    assert status == 200
    text = (root / "manifests/tracks/vid_000.csv").read_text()
    assert "# tracks fingerprint: t1" in text and "1,0.000,9.958,yes" in text
    assert json.loads(call(f"{url}/api/segments")[1])[0]["status"] == "proposal"


def test_an_invalid_edit_is_refused_with_the_checkers_messages(site) -> None:
    root, url = site
    segment = json.loads(call(f"{url}/api/segments/vid_000")[1])
    rows = segment["rows"] + [{"track_id": 7, "start": 1, "end": 2, "keep": True, "note": ""}]
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", {"version": "", "rows": rows})
    payload = json.loads(body)
    assert status == 422 and payload["error"] == "not saved: the manifest has errors"
    assert any(p["text"].startswith("manifests/tracks/vid_000.csv:") and "unknown track id 7" in p["text"]
               for p in payload["problems"])
    assert not (root / "manifests/tracks/vid_000.csv").exists()


def test_a_stale_overwrite_is_refused(site) -> None:
    root, url = site
    segment = json.loads(call(f"{url}/api/segments/vid_000")[1])
    call(f"{url}/api/segments/vid_000", "PUT", {"version": "", "rows": segment["rows"]})
    path = root / "manifests/tracks/vid_000.csv"
    edited_elsewhere = path.read_text().replace(",yes,", ",no,", 1)
    path.write_text(edited_elsewhere)  # someone edits the file while the page is open
    rows = segment["rows"]
    rows[0]["note"] = "mine"
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", {"version": segment["version"] or "loaded-earlier",
                                                                  "rows": rows})
    assert status == 409 and "changed on disk" in json.loads(body)["error"]
    assert path.read_text() == edited_elsewhere


@pytest.mark.parametrize("path", ["/../secret.txt", "/static/../../secret.txt", "/qc/../../secret.txt",
                                  "/qc/%2e%2e%2fsecret.mp4", "/api/segments/..%2f..%2fsecret", "/secret.txt",
                                  "/data/tracks/vid_000.parquet", "/api/segments/ghost_000", "/qc/ghost_000.mp4",
                                  "/static/app.py", "/segment/../../etc/passwd"])
def test_nothing_outside_the_page_data_and_manifests_is_served(site, path: str) -> None:
    _, url = site
    status, body, _ = call(url + path)
    assert status == 404 and b"not for the web" not in body


def test_qc_video_supports_range_requests(site) -> None:
    root, url = site
    size = (root / "data/qc/vid_000.mp4").stat().st_size
    status, body, headers = call(f"{url}/qc/vid_000.mp4", headers={"Range": "bytes=100-199"})
    assert status == 206 and len(body) == 100 and headers["Content-Range"] == f"bytes 100-199/{size}"
    assert body == (root / "data/qc/vid_000.mp4").read_bytes()[100:200]


def test_a_missing_qc_video_is_rendered_from_the_download_on_first_request(site) -> None:
    from pipeline.ingest.catalog import write_index
    from pipeline.ingest.media import probe

    root, url = site
    (root / "data/qc/vid_000.mp4").unlink()
    (root / "data/raw").mkdir(parents=True)
    make_test_video(root / "data/raw/vid.mp4", seconds=12, fps="24", size="1280x720")
    write_index(root / "data/segments", [{
        "segment_id": "vid_000", "video_id": "vid", "start": 1.0, "end": 11.0, "fps": 24.0, "fps_fraction": "24/1",
        "frames": 240, "width": 640, "height": 360, "has_audio": True, "audio_stream": 1, "label": "",
        "source": "vid.mp4", "fingerprint": "x"}], {})
    status, body, headers = call(f"{url}/qc/vid_000.mp4")
    assert status == 200 and headers["Content-Type"] == "video/mp4"
    qc = probe(root / "data/qc/vid_000.mp4")
    assert (qc.frames, qc.width, qc.height, qc.has_audio) == (240, 640, 360, True)
    assert body == (root / "data/qc/vid_000.mp4").read_bytes()


def _chromium():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    binary, driver = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
    if not (binary.exists() and driver.exists()):
        skip_or_fail("Chromium and chromedriver are not installed (Debian: apt-get install chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = str(binary)
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--window-size=1400,1000", "--autoplay-policy=no-user-gesture-required"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(str(driver)), options=options)


def open_page(browser, url: str, rows: int):
    """Load a review page and wait until its table has ``rows`` rows; the wait, for what follows."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    browser.get(url)
    wait = WebDriverWait(browser, 20)
    wait.until(lambda b: len(b.find_elements(By.CSS_SELECTOR, "#rows tbody tr")) == rows)
    return wait


@pytest.mark.slow
def test_browser_edit_save_round_trip(site, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    root, url = site
    browser = _chromium()
    try:
        wait = open_page(browser, f"{url}/segment/vid_000", 2)
        wait.until(lambda b: b.execute_script("return document.querySelector('#video').readyState") >= 1)
        # Move the playhead to 6.000 s and end track 1's span there with the ']' key.
        browser.execute_script("document.querySelector('#video').currentTime = 6.0")
        wait.until(lambda b: abs(b.execute_script("return document.querySelector('#video').currentTime") - 6.0) < 1e-3)
        browser.find_element(By.CSS_SELECTOR, "#rows tbody tr[data-index='0'] td.reason").click()
        browser.find_element(By.TAG_NAME, "body").send_keys("]")
        # Reject track 2 with the button.
        browser.find_element(By.CSS_SELECTOR, "#rows tbody tr[data-index='1'] td.reason").click()
        browser.find_element(By.ID, "toggle").click()
        browser.find_element(By.ID, "save").click()
        # The first save asks the annotator's name once (kept in the browser, logged with each save).
        wait.until(lambda b: b.switch_to.alert).send_keys("Ana")
        browser.switch_to.alert.accept()
        wait.until(lambda b: b.find_element(By.ID, "state").text == "saved")
        assert browser.find_element(By.ID, "annotator").get_attribute("value") == "Ana"
        artifacts = Path(os.environ.get("DANCE3D_ARTIFACTS", tmp_path))
        artifacts.mkdir(parents=True, exist_ok=True)
        browser.save_screenshot(str(artifacts / "review_page.png"))
    finally:
        browser.quit()
    lines = [ln for ln in (root / "manifests/tracks/vid_000.csv").read_text().splitlines() if not ln.startswith("#")]
    rows = [ln.split(",")[:4] for ln in lines[1:]]
    assert rows == [["1", "0.000", "6.000", "yes"], ["2", "2.000", "5.958", "no"]]
    assert ",manifests/tracks/vid_000.csv,Ana," in (root / "manifests/review_log.csv").read_text()
