"""download stage with the real yt-dlp: local files, a local HTTP server, failures, resume."""

from __future__ import annotations

import http.server
import json
import threading
from dataclasses import asdict
from pathlib import Path
from typing import Iterator

import pytest

from pipeline.core.errors import RateLimitedError
from pipeline.core.failures import StageFailed, read_failures
from pipeline.core.storage import sha256_file
from pipeline.ingest.catalog import read_ledger
from stages import download
from tests.conftest import Mirror, set_params


def ledger(project: Path) -> dict[str, dict]:
    return {r["video_id"] or r["url"]: r for r in read_ledger(project / "data/raw").values()}


def write_sources(project: Path, rows: str) -> None:
    (project / "manifests/sources.csv").write_text("video_id,url,channel,style,licence,note\n" + rows)


def test_file_urls_and_local_paths_download_with_a_full_ledger(project: Path, media_dir: Path) -> None:
    clip = media_dir / "videos/dance_single_music_musepose.mp4"
    solo = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    write_sources(project, f"dance,{clip.as_uri()},MusePose,kids,MIT,\n,{solo},,,,no id given\n")
    download.run(project)
    rows = ledger(project)
    dance = rows["dance"]
    assert dance["status"] == "ok" and dance["path"] == "dance.mp4"
    assert dance["sha256"] == sha256_file(clip)
    assert (dance["fps"], dance["duration"], dance["width"], dance["height"]) == (24.0, 12.0, 1080, 1920)
    assert dance["has_audio"] is True
    assert (dance["channel"], dance["style"], dance["licence"]) == ("MusePose", "kids", "MIT")
    assert (project / "data/raw/dance.info.json").exists()
    solo_row = rows["dance_solo_384x496_30fps"]  # id taken from yt-dlp
    assert solo_row["status"] == "ok" and solo_row["has_audio"] is False
    assert not (project / "data/raw/.incoming").exists()


def test_second_run_downloads_nothing(project: Path, media_dir: Path) -> None:
    clip = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    write_sources(project, f"solo,{clip.as_uri()},,,,\n")
    download.run(project)
    video = project / "data/raw/solo.mp4"
    stamp = video.stat().st_mtime_ns
    first = ledger(project)
    download.run(project)
    assert video.stat().st_mtime_ns == stamp
    assert ledger(project) == first


def test_missing_file_and_malformed_url_are_failed_rows_not_crashes(project: Path, media_dir: Path) -> None:
    clip = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    write_sources(project, f"good,{clip},,,,\ngone,{project / 'deleted.mp4'},,,,\nbad,htp:/nowhere,,,,\n")
    set_params(project, "download", max_failure_ratio=1.0, retries=1)
    download.run(project)
    rows = ledger(project)
    assert rows["good"]["status"] == "ok"
    assert rows["gone"]["status"] == "failed" and rows["gone"]["error_class"] == "not_found"
    assert "deleted.mp4" in rows["gone"]["error_message"] and "No such file" in rows["gone"]["error_message"]
    assert rows["bad"]["error_class"] == "invalid_url"
    assert rows["bad"]["error_message"].endswith(
        "sources.csv:4: url 'htp:/nowhere' has unsupported scheme 'htp' (use http, https or file)")
    failures = [asdict(f) for f in read_failures(project / "data/raw")]
    assert [f["item"] for f in failures] == ["manifests/sources.csv:3", "manifests/sources.csv:4"]
    summary = json.loads((project / "reports/failures_download.json").read_text())
    assert summary == {"items": 3, "failed": 2, "failed_share": 0.6667,
                       "by_error_class": {"not_found": 1, "invalid_url": 1}}


def test_stage_fails_past_the_failure_ratio_but_keeps_what_it_did(project: Path, media_dir: Path) -> None:
    clip = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    write_sources(project, f"good,{clip},,,,\ngone,missing.mp4,,,,\n")
    set_params(project, "download", max_failure_ratio=0.2, retries=1)
    with pytest.raises(StageFailed, match=r"1 of 2 items failed"):
        download.run(project)
    assert ledger(project)["good"]["status"] == "ok"


class _Server:
    """A local HTTP server whose responses a test scripts: a list of status codes, then 200."""

    def __init__(self, payload: bytes, statuses: list[int]) -> None:
        self.payload, self.statuses, self.requests = payload, list(statuses), 0
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
                server.requests += 1
                status = server.statuses.pop(0) if server.statuses else 200
                if status != 200:
                    self.send_error(status)
                    return
                self.send_response(200)
                self.send_header("Content-Type", "video/mp4")
                self.send_header("Content-Length", str(len(server.payload)))
                self.end_headers()
                self.wfile.write(server.payload)

            def log_message(self, *args) -> None:
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()


@pytest.fixture
def http_server(media_dir: Path) -> Iterator[callable]:
    servers: list[_Server] = []

    def start(statuses: list[int]) -> _Server:
        servers.append(_Server((media_dir / "videos/dance_solo_384x496_30fps.mp4").read_bytes(), statuses))
        return servers[-1]

    yield start
    for server in servers:
        server.httpd.shutdown()


def test_http_download_retries_transient_errors(project: Path, http_server) -> None:
    server = http_server([503, 503])
    write_sources(project, f"solo,{server.url}/solo.mp4,,,,\n")
    set_params(project, "download", retries=4, backoff_seconds=0.01)
    download.run(project)
    row = ledger(project)["solo"]
    assert row["status"] == "ok" and row["attempts"] >= 2


def test_rate_limiting_stops_politely_and_keeps_finished_work(project: Path, media_dir: Path, http_server) -> None:
    server = http_server([429] * 50)
    clip = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    write_sources(project, f"local,{clip},,,,\nremote,{server.url}/a.mp4,,,,\nlater,{server.url}/b.mp4,,,,\n")
    set_params(project, "download", workers=1)
    with pytest.raises(RateLimitedError, match="rate limiting downloads .* re-run"):
        download.run(project)
    rows = ledger(project)
    assert rows["local"]["status"] == "ok"
    assert rows["remote"]["status"] == "throttled" and rows["remote"]["error_class"] == "rate_limited"
    assert rows["later"]["status"] == "skipped"
    assert server.requests <= 3  # it did not hammer the site


def _demo_sources_served(media_dir: Path, corrupt: str = "") -> tuple[Mirror, str]:
    """A local server standing in for the demo's public host, and the demo's sources.csv pointed at it."""
    from urllib.parse import urlparse

    from pipeline.ingest.sources import read_sources
    from tests.conftest import PROJECT

    demo = read_sources(PROJECT / "manifests/sources.csv", base_dir=PROJECT)
    by_sha = {sha256_file(p): p for p in sorted((media_dir / "videos").glob("*.mp4"))}
    files = {urlparse(s.url).path: by_sha[s.sha256].read_bytes() for s in demo}
    for s in demo:
        if s.video_id == corrupt:
            files[urlparse(s.url).path] = files[urlparse(s.url).path][:-1000]  # a truncated transfer
    server = Mirror(files)
    text = (PROJECT / "manifests/sources.csv").read_text().replace("https://raw.githubusercontent.com", server.url)
    return server, text


def test_the_demo_sources_download_from_their_public_urls_checksum_verified(project: Path, media_dir: Path,
                                                                            monkeypatch) -> None:
    monkeypatch.delenv("DANCE3D_MEDIA", raising=False)  # no local copies: the online path
    server, text = _demo_sources_served(media_dir)
    (project / "manifests/sources.csv").write_text(text)
    download.run(project)
    rows = ledger(project)
    assert [rows[v]["status"] for v in ("musepose_dance", "taiji", "raga_trio", "solo_dance")] == ["ok"] * 4
    assert len(set(server.requests)) == 4  # every clip came from the (stand-in) public host
    assert rows["taiji"]["sha256"] == "34fa7a96a905a0934116b2f867fd72043a725346cc36897ab34660cf383d4581"
    server.httpd.shutdown()


def test_a_download_with_another_checksum_is_a_failed_row(project: Path, media_dir: Path, monkeypatch) -> None:
    monkeypatch.delenv("DANCE3D_MEDIA", raising=False)
    server, text = _demo_sources_served(media_dir, corrupt="taiji")
    (project / "manifests/sources.csv").write_text(text)
    set_params(project, "download", max_failure_ratio=1.0)
    download.run(project)
    rows = ledger(project)
    assert rows["taiji"]["status"] == "failed" and rows["taiji"]["error_class"] == "checksum"
    assert "not the 34fa7a96" in rows["taiji"]["error_message"]
    assert not (project / "data/raw/taiji.mp4").exists()
    assert rows["musepose_dance"]["status"] == "ok"
    server.httpd.shutdown()


def test_local_copies_with_the_same_checksum_replace_the_network(project: Path, media_dir: Path,
                                                                 monkeypatch) -> None:
    from tests.conftest import PROJECT

    monkeypatch.setenv("DANCE3D_MEDIA", str(media_dir))
    text = (PROJECT / "manifests/sources.csv").read_text().replace("https://raw.githubusercontent.com",
                                                                   "http://127.0.0.1:9")  # nothing listens there
    (project / "manifests/sources.csv").write_text(text)
    download.run(project)
    rows = ledger(project)
    assert all(r["status"] == "ok" for r in rows.values())
    assert rows["musepose_dance"]["url"].startswith("http://127.0.0.1:9/TMElyralab/MusePose/")
    assert rows["musepose_dance"]["sha256"] == sha256_file(media_dir / "videos/dance_single_music_musepose.mp4")


def test_a_malformed_sha256_names_file_and_line(project: Path) -> None:
    from pipeline.core.errors import InputError

    write_sources(project, "")
    (project / "manifests/sources.csv").write_text("video_id,url,sha256\nx,https://example.org/x.mp4,abc\n")
    with pytest.raises(InputError, match=r"sources\.csv:2: sha256 'abc' is not 64 hexadecimal digits"):
        download.run(project)
