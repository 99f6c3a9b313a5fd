"""The review page's trim mode: its API (proposals, checked saves, stale writes, the raw video) and a real browser."""

from __future__ import annotations

import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from pipeline.annotate.proposals import ProposalOptions
from pipeline.annotate.review.server import ReviewApp, serve
from pipeline.pose.propose import Proposal, Proposals, ProposeOptions, Shot, Timeline, write_proposals
from stages import download
from tests.annotate.test_review import _chromium, call, open_page
from tests.conftest import PROJECT, make_test_video

OTHER_LINES = ("# Dance segments per video (a comment the annotator wrote)\n"
               "video_id,start,end,label,note\n"
               "other,1.0,4.0,hip-hop,another video's row\n")


@pytest.fixture
def trim_site(tmp_path: Path):
    root = tmp_path / "p"
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    for name in ("vid", "other"):
        make_test_video(tmp_path / f"{name}.mp4", seconds=12, fps="24", size="320x180")
    (root / "manifests/sources.csv").write_text(f"video_id,url\nvid,{tmp_path / 'vid.mp4'}\n"
                                               f"other,{tmp_path / 'other.mp4'}\n")
    download.run(root)
    (root / "annotations/segments.csv").write_text(OTHER_LINES)
    seconds = 12
    dance = np.array([2 <= k < 10 for k in range(seconds)])
    tl = Timeline(12.0, [2.0, 10.0], np.where(dance, -20.0, -80.0), np.where(dance, 0.9, 0.1),
                  np.where(dance, 0.1, 0.6), np.ones(seconds), np.where(dance, 0.2, 0.01))
    found = Proposals([Proposal(2.0, 10.0, "music (harmonic 0.90), 1 person moving")],
                      [Shot(0.0, 2.0, "no dance", "no music (silence, speech or noise)"),
                       Shot(2.0, 10.0, "dance", "music"), Shot(10.0, 12.0, "no dance", "nobody seen")])
    (root / "data/segment_proposals").mkdir(parents=True)
    write_proposals(root / "data/segment_proposals/vid.parquet", "vid", tl, found, ProposeOptions(), {}, "x")
    (root / "secret.txt").write_text("not for the web")
    server = serve(ReviewApp(root, ProposalOptions(), 2.0), "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield root, f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_videos_are_listed_with_their_rows_and_proposals(trim_site) -> None:
    _, url = trim_site
    listed = {v["id"]: v for v in json.loads(call(f"{url}/api/videos")[1])}
    assert (listed["vid"]["status"], listed["vid"]["rows"], listed["vid"]["proposals"]) == ("proposed", 0, 1)
    assert (listed["other"]["status"], listed["other"]["rows"]) == ("annotated", 1)


def test_a_video_without_rows_shows_its_proposals_as_rows(trim_site) -> None:
    _, url = trim_site
    video = json.loads(call(f"{url}/api/videos/vid")[1])
    assert video["has_rows"] is False and video["duration"] == 12.0 and video["fps"] == 24.0
    assert [(r["start"], r["end"]) for r in video["rows"]] == [(2.0, 10.0)]
    assert video["cuts"] == [2.0, 10.0] and [s["verdict"] for s in video["shots"]] == ["no dance", "dance", "no dance"]
    assert sum(s["dance"] for s in video["seconds"]) == 8


def test_saving_replaces_only_the_videos_rows(trim_site) -> None:
    root, url = trim_site
    video = json.loads(call(f"{url}/api/videos/vid")[1])
    rows = [{"start": 6.0, "end": 10.0, "label": "dance", "note": ""},
            {"start": 2.0, "end": 6.0, "label": "dance", "note": "=cmd|x"}]
    status, body, _ = call(f"{url}/api/videos/vid", "PUT", {"version": video["version"], "rows": rows})
    assert status == 200, body
    assert (root / "annotations/segments.csv").read_text() == OTHER_LINES + (
        "vid,2.000,6.000,dance,'=cmd|x\n"   # in start order; a formula is neutralised
        "vid,6.000,10.000,dance,\n")
    again = json.loads(call(f"{url}/api/videos/vid")[1])
    assert again["has_rows"] is True and again["version"] == json.loads(body)["version"]


def test_an_invalid_save_names_the_row_and_writes_nothing(trim_site) -> None:
    root, url = trim_site
    video = json.loads(call(f"{url}/api/videos/vid")[1])
    rows = [{"start": 2.0, "end": 7.0}, {"start": 6.0, "end": 13.0}]
    status, body, _ = call(f"{url}/api/videos/vid", "PUT", {"version": video["version"], "rows": rows})
    payload = json.loads(body)
    assert status == 422 and payload["error"] == "not saved: the segments have errors"
    problems = {p["row"]: p["text"] for p in payload["problems"]}
    assert problems == {1: "annotations/segments.csv:5: segment 6.000-13.000 s passes the end of vid (12.000 s)"}
    assert (root / "annotations/segments.csv").read_text() == OTHER_LINES
    rows = [{"start": 2.0, "end": 7.0}, {"start": 6.0, "end": 9.0}]
    payload = json.loads(call(f"{url}/api/videos/vid", "PUT", {"version": video["version"], "rows": rows})[1])
    assert [p["row"] for p in payload["problems"]] == [1] and "overlaps line 4" in payload["problems"][0]["text"]


def test_a_stale_save_is_refused(trim_site) -> None:
    root, url = trim_site
    video = json.loads(call(f"{url}/api/videos/vid")[1])
    path = root / "annotations/segments.csv"
    path.write_text(OTHER_LINES + "vid,0.0,1.0,,typed in a spreadsheet meanwhile\n")
    status, body, _ = call(f"{url}/api/videos/vid", "PUT", {"version": video["version"], "rows": video["rows"]})
    assert status == 409 and "changed on disk" in json.loads(body)["error"]
    assert path.read_text().endswith("meanwhile\n")


def test_the_raw_video_is_served_with_ranges_and_nothing_else_is(trim_site) -> None:
    root, url = trim_site
    raw = (root / "data/raw/vid.mp4").read_bytes()
    status, body, headers = call(f"{url}/raw/vid", headers={"Range": "bytes=0-99"})
    assert status == 206 and body == raw[:100] and headers["Content-Type"] == "video/mp4"
    for path in ("/raw/ghost", "/raw/..%2fsecret.txt", "/api/videos/ghost", "/trim/../secret.txt",
                 "/raw/ledger.parquet"):
        status, body, _ = call(url + path)
        assert status == 404 and b"not for the web" not in body


@pytest.mark.slow
def test_browser_split_delete_add_save_and_an_inline_error(trim_site, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    root, url = trim_site
    browser = _chromium()
    try:
        wait = open_page(browser, f"{url}/trim/vid", 1)  # the proposal
        wait.until(lambda b: b.execute_script("return document.querySelector('#video').readyState") >= 1)
        body = browser.find_element(By.TAG_NAME, "body")

        def seek(t: float) -> None:
            browser.execute_script(f"document.querySelector('#video').currentTime = {t}")
            wait.until(lambda b: abs(b.execute_script("return document.querySelector('#video').currentTime") - t)
                       < 1e-3)

        def rows() -> list[tuple[str, str]]:
            return [(r.find_element(By.CSS_SELECTOR, "[data-field=start]").get_attribute("value"),
                     r.find_element(By.CSS_SELECTOR, "[data-field=end]").get_attribute("value"))
                    for r in browser.find_elements(By.CSS_SELECTOR, "#rows tbody tr")]

        seek(6.0)
        body.send_keys("s")                      # split the proposal at 6 s
        assert rows() == [("2.000", "6.000"), ("6.000", "10.000")]
        browser.find_element(By.CSS_SELECTOR, "#rows tbody tr[data-index='1'] td.reason").click()
        body.send_keys(Keys.DELETE)              # delete its second half
        seek(0.5)
        body.send_keys("a")                      # add a segment at 0.5 s ...
        seek(1.5)
        body.send_keys("]")                      # ... and end it at 1.5 s
        assert rows() == [("0.500", "1.500"), ("2.000", "6.000")]
        browser.find_element(By.ID, "annotator").send_keys("Bo")  # the name field in the header
        browser.find_element(By.ID, "save").click()
        wait.until(lambda b: b.find_element(By.ID, "state").text == "saved")
        saved = (root / "annotations/segments.csv").read_text()
        assert saved == OTHER_LINES + "vid,0.500,1.500,dance,\nvid,2.000,6.000,,\n"
        assert ",annotations/segments.csv,Bo," in (root / "manifests/review_log.csv").read_text()

        start = browser.find_element(By.CSS_SELECTOR, "#rows tbody tr[data-index='1'] [data-field=start]")
        start.send_keys(Keys.CONTROL, "a")
        start.send_keys("1.0", Keys.TAB)         # now it overlaps the first segment (a change re-renders)
        browser.find_element(By.TAG_NAME, "body").send_keys(Keys.CONTROL, "s")
        wait.until(lambda b: b.find_element(By.ID, "state").text == "not saved: the segments have errors")
        reason = browser.find_element(By.CSS_SELECTOR, "#rows tbody tr.has-error td.reason").text
        assert "overlaps line 4" in reason
        assert (root / "annotations/segments.csv").read_text() == saved
        artifacts = Path(os.environ.get("DANCE3D_ARTIFACTS", tmp_path))
        artifacts.mkdir(parents=True, exist_ok=True)
        browser.save_screenshot(str(artifacts / "review_trim_page.png"))
    finally:
        browser.quit()
