"""The review server on a shared machine: a token off loopback, writes only from its own page,
and every save attributed to its annotator."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.annotate.review.access import choose_token
from tests.annotate.test_review import _chromium, call, open_page, review_site
from tests.conftest import PROJECT

TOKEN = "s3cret-token-for-the-team_0123"


@pytest.fixture
def team_site(tmp_path: Path):
    with review_site(tmp_path, TOKEN) as site:
        yield site


def signed_in(url: str) -> dict:
    """Headers of a browser that opened the token URL (the cookie) on this server's page (the origin)."""
    return {"Cookie": f"dance3d_review={TOKEN}", "Origin": url}


@pytest.mark.parametrize("path", ["/", "/segment/vid_000", "/trim", "/static/app.js", "/static/style.css",
                                  "/api/segments", "/api/segments/vid_000", "/qc/vid_000.mp4", "/api/videos",
                                  "/raw/vid"])
def test_without_the_token_every_route_is_401_and_says_how_to_get_in(team_site, path: str) -> None:
    _, url = team_site
    status, body, _ = call(url + path)
    assert status == 401 and b"?token=" in body


def test_the_token_url_sets_an_http_only_strict_cookie_and_leaves_the_token_out_of_the_address(team_site) -> None:
    import http.client
    from urllib.parse import urlparse

    _, url = team_site
    connection = http.client.HTTPConnection(urlparse(url).netloc)
    connection.request("GET", f"/segment/vid_000?token={TOKEN}")
    response = connection.getresponse()
    cookie = response.getheader("Set-Cookie")
    assert response.status == 303 and response.getheader("Location") == "/segment/vid_000"
    assert cookie.startswith(f"dance3d_review={TOKEN}") and "HttpOnly" in cookie and "SameSite=Strict" in cookie
    status, body, _ = call(f"{url}/api/segments", headers={"Cookie": f"dance3d_review={TOKEN}"})
    assert status == 200 and json.loads(body)[0]["id"] == "vid_000"


@pytest.mark.parametrize("headers", [{"Cookie": "dance3d_review=wrong-token-of-the-same-size!"},
                                     {"Cookie": 'dance3d_review="unterminated; other'},
                                     {"Cookie": f"other={TOKEN}"}])
def test_a_wrong_or_malformed_cookie_is_refused(team_site, headers: dict) -> None:
    _, url = team_site
    assert call(f"{url}/api/segments", headers=headers)[0] == 401


def test_a_wrong_token_in_the_address_is_refused(team_site) -> None:
    _, url = team_site
    status, _, headers = call(f"{url}/?token=not-the-token-at-all")
    assert status == 401 and "Set-Cookie" not in headers


def test_writes_from_another_site_are_refused_even_with_the_cookie(team_site) -> None:
    root, url = team_site
    auth = signed_in(url)
    segment = json.loads(call(f"{url}/api/segments/vid_000", headers=auth)[1])
    body = {"version": segment["version"], "rows": segment["rows"], "annotator": "Mallory"}
    for origin in ("http://evil.example", None):
        headers = {"Cookie": auth["Cookie"], **({"Origin": origin} if origin else {})}
        assert call(f"{url}/api/segments/vid_000", "PUT", body, headers)[0] == 403
        assert call(f"{url}/api/segments/vid_000", "POST", body, headers)[0] == 403
    assert not (root / "manifests/tracks/vid_000.csv").exists()
    assert call(f"{url}/api/segments/vid_000", "PUT", body, auth)[0] == 200


def test_each_save_names_its_annotator_and_a_stale_save_says_who_changed_the_file(team_site) -> None:
    root, url = team_site
    auth = signed_in(url)
    segment = json.loads(call(f"{url}/api/segments/vid_000", headers=auth)[1])
    first = {"version": segment["version"], "rows": segment["rows"], "annotator": "Ana"}
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", first, auth)
    assert status == 200
    log = (root / "manifests/review_log.csv").read_text().splitlines()
    assert log[0] == "time,file,annotator,version"
    assert log[1].split(",")[1:] == ["manifests/tracks/vid_000.csv", "Ana", json.loads(body)["version"]]
    rows = segment["rows"]
    rows[0]["note"] = "Bo's edit"
    status, body, _ = call(f"{url}/api/segments/vid_000", "PUT", {"version": segment["version"], "rows": rows,
                                                                  "annotator": "Bo"}, auth)
    assert status == 409 and "saved by Ana at " in json.loads(body)["error"]


def test_on_loopback_without_token_nothing_changes(tmp_path: Path) -> None:
    assert choose_token("127.0.0.1", asked=False) is None and choose_token("::1", asked=False) is None
    assert choose_token("0.0.0.0", asked=False) and choose_token("192.168.1.5", asked=False)
    assert choose_token("127.0.0.1", asked=True)


def test_the_start_up_line_prints_the_address_with_the_token(tmp_path: Path) -> None:
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    env = {**os.environ, "DANCE3D_REVIEW_TOKEN": TOKEN}
    server = subprocess.Popen([sys.executable, "-m", "pipeline.cli", "--root", str(root), "review", "--token",
                               "--port", "0"], stdout=subprocess.PIPE, text=True, env=env, cwd=PROJECT)
    try:
        first = server.stdout.readline()
    finally:
        server.terminate()
        server.wait(10)
    assert first.startswith("dance3d review: http://127.0.0.1:") and first.rstrip().endswith(
        f"/?token={TOKEN}  (clean tracks)")


@pytest.mark.slow
def test_browser_logs_in_through_the_token_url_and_saves_under_its_name(team_site, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    root, url = team_site
    browser = _chromium()
    try:
        wait = open_page(browser, f"{url}/segment/vid_000?token={TOKEN}", 2)
        assert browser.current_url == f"{url}/segment/vid_000"  # the token left the address bar
        header = browser.find_element(By.TAG_NAME, "header").text
        assert "dance3d review · tracks · vid_000" in header and "trim ·" not in header
        browser.find_element(By.ID, "annotator").send_keys("Ana")
        browser.find_element(By.CSS_SELECTOR, "#rows tbody tr[data-index='1'] td.reason").click()
        browser.find_element(By.ID, "toggle").click()
        browser.find_element(By.ID, "save").click()
        wait.until(lambda b: b.find_element(By.ID, "state").text == "saved")
    finally:
        browser.quit()
    assert ",Ana," in (root / "manifests/review_log.csv").read_text()
