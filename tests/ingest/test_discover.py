"""discover stage with the real yt-dlp: an RSS feed on a local HTTP server, filters, incremental re-runs."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from pipeline.core.errors import InputError
from pipeline.core.storage import item_files
from pipeline.ingest.catalog import read_discovered, read_index, read_ledger
from pipeline.ingest.discover import DiscoverOptions, is_list_url, select
from pipeline.ingest.sources import read_sources
from stages import discover, download, pose2d, propose_segments, trim
from tests.conftest import Mirror, make_test_video, set_params

FEED_HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<rss version="2.0" xmlns:itunes="http://www.itunes.com/dtds/podcast-1.0.dtd">
<channel><title>Local Dance Crew</title><link>{base}/</link><description>test channel</description>
"""


def feed(base: str, items: list[tuple[str, str, str, str]]) -> bytes:
    """An RSS 2.0 feed whose items (guid, title, RFC 822 date, itunes duration) link to {base}/v/<guid>.mp4."""
    body = "".join(
        f"<item><title>{title}</title><link>{base}/v/{guid}.mp4</link><guid>{guid}</guid>"
        f"<pubDate>{date}</pubDate><itunes:duration>{duration}</itunes:duration></item>\n"
        for guid, title, date, duration in items)
    return (FEED_HEAD.format(base=base) + body + "</channel></rss>\n").encode()


ITEMS = [
    ("routine-a", "Routine A (full dance)", "Mon, 02 Mar 2026 10:00:00 +0000", "00:02"),
    ("routine-b", "Routine B (full dance)", "Tue, 03 Mar 2026 10:00:00 +0000", "00:02"),
    ("vlog-c", "Behind the scenes vlog", "Wed, 04 Mar 2026 10:00:00 +0000", "00:02"),
]
STAGES = (discover, download, propose_segments, trim, pose2d)
NEW_ITEM = ("routine-d", "Routine D (full dance)", "Thu, 05 Mar 2026 10:00:00 +0000", "00:02")


@pytest.fixture()
def channel(project: Path, tmp_path: Path) -> Mirror:
    """A site with one feed and its clips; sources.csv names only the feed."""
    files = {}
    for n, (guid, *_rest) in enumerate(ITEMS + [NEW_ITEM]):
        clip = tmp_path / f"{guid}.mp4"
        make_test_video(clip, seconds=2.0, fps="25", size="160x120", pattern=["testsrc", "smptebars", "rgbtestsrc",
                                                                             "testsrc2"][n])
        files[f"/v/{guid}.mp4"] = clip.read_bytes()
    site = Mirror(files)
    site.files["/feed.xml"] = feed(site.url, ITEMS)
    (project / "manifests/sources.csv").write_text(
        "url,kind,style,licence,note\n"
        f"{site.url}/feed.xml,list,hip-hop,CC BY 4.0,the crew's channel\n")
    return site


def test_a_feed_row_is_discovered_then_downloaded_with_its_metadata(project: Path, channel: Mirror) -> None:
    discover.run(project)
    lists = read_discovered(project / "data/catalog")
    rows = lists[f"{channel.url}/feed.xml"]
    assert [r["video_id"] for r in rows] == ["routine-a", "routine-b", "vlog-c"]
    assert [r["position"] for r in rows] == [0, 1, 2]
    first = rows[0]
    assert (first["title"], first["channel"], first["upload_date"], first["duration"]) == (
        "Routine A (full dance)", "Local Dance Crew", "20260302", 2.0)
    assert (first["style"], first["licence"], first["list_line"], first["selected"]) == (
        "hip-hop", "CC BY 4.0", 2, True)
    assert first["url"] == f"{channel.url}/v/routine-a.mp4"  # the guid is not left smuggled in the url

    download.run(project)
    ledger = {r["video_id"]: r for r in read_ledger(project / "data/raw").values()}
    assert sorted(ledger) == ["routine-a", "routine-b", "vlog-c"]
    assert all(r["status"] == "ok" for r in ledger.values())
    assert (ledger["routine-b"]["style"], ledger["routine-b"]["upload_date"]) == ("hip-hop", "20260303")


def test_a_second_run_after_the_feed_gains_an_entry_processes_only_that_entry(project: Path, channel: Mirror,
                                                                             models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    set_params(project, "trim", unannotated="whole")
    started = time.perf_counter()
    for stage in STAGES:
        stage.run(project)
    first_run = time.perf_counter() - started
    catalogue = (project / "data/catalog/videos.parquet").read_bytes()
    segments = read_index(project / "data/segments")
    discover.run(project)  # the feed is unchanged: the same bytes, so DVC re-runs nothing downstream
    assert (project / "data/catalog/videos.parquet").read_bytes() == catalogue

    outputs = [*(project / "data/raw").glob("*.mp4"), *item_files(project / "data/pose2d"),
               *item_files(project / "data/segment_proposals")]
    stamps = {p: p.stat().st_mtime_ns for p in outputs}
    channel.requests.clear()
    channel.files["/feed.xml"] = feed(channel.url, [NEW_ITEM] + ITEMS)  # newest first, as channels list
    started = time.perf_counter()
    for stage in STAGES:
        stage.run(project)
    second_run = time.perf_counter() - started

    rows = read_discovered(project / "data/catalog")[f"{channel.url}/feed.xml"]
    assert [r["video_id"] for r in rows] == ["routine-a", "routine-b", "vlog-c", "routine-d"]  # order kept
    assert {p for p in channel.requests if p.startswith("/v/")} == {"/v/routine-d.mp4"}  # sniffed, then fetched
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # downloads, proposals, 2D poses untouched
    assert (project / "data/pose2d/routine-d_000.parquet").exists()
    after = read_index(project / "data/segments")
    assert sorted(after) == ["routine-a_000", "routine-b_000", "routine-d_000", "vlog-c_000"]
    assert {k: after[k] for k in segments} == segments  # the old segments are untouched
    print(f"discover to pose2d: 3 feed videos {first_run:.2f} s; the one new entry {second_run:.2f} s")


def test_filters_choose_entries_and_say_why_without_the_network(project: Path, channel: Mirror) -> None:
    discover.run(project)
    set_params(project, "discover", title_exclude="vlog", max_videos=1)
    channel.requests.clear()
    channel.files.pop("/feed.xml")  # the site is gone: filters still apply to what was found
    set_params(project, "download", retries=1)
    set_params(project, "discover", max_failure_ratio=1.0)
    discover.run(project)
    rows = read_discovered(project / "data/catalog")[f"{channel.url}/feed.xml"]
    assert [(r["video_id"], r["selected"], r["reason"]) for r in rows] == [
        ("routine-a", True, ""),
        ("routine-b", False, "past discover.max_videos (1)"),
        ("vlog-c", False, "title matches discover.title_exclude"),
    ]
    download.run(project)
    assert [r["video_id"] for r in read_ledger(project / "data/raw").values()] == ["routine-a"]


def test_date_and_duration_filters() -> None:
    rows = [{"title": "a", "upload_date": "20260101", "duration": 30.0},
            {"title": "b", "upload_date": "20260601", "duration": 600.0},
            {"title": "c", "upload_date": "", "duration": None}]
    chosen = select(rows, DiscoverOptions(date_after="20260201", max_duration=300))
    assert [(r["selected"], r["reason"]) for r in chosen] == [
        (False, "uploaded 20260101, before discover.date_after 20260201"),
        (False, "600 s, longer than discover.max_duration"),
        (True, ""),  # the listing gave neither: it passes
    ]


def test_a_feed_that_fails_is_one_failure_and_keeps_what_was_found(project: Path, channel: Mirror) -> None:
    discover.run(project)
    channel.files["/feed.xml"] = b"<html><body>maintenance</body></html>"
    set_params(project, "download", retries=1)
    set_params(project, "discover", max_failure_ratio=1.0)
    discover.run(project)
    assert len(read_discovered(project / "data/catalog")[f"{channel.url}/feed.xml"]) == 3
    import json
    failures = json.loads((project / "reports/failures_discover.json").read_text())
    assert failures["failed"] == 1


def test_list_rows_are_recognised_and_checked(project: Path) -> None:
    assert is_list_url("https://www.youtube.com/@somecrew")
    assert is_list_url("https://www.youtube.com/playlist?list=PL0123456789")
    assert not is_list_url("https://www.youtube.com/watch?v=dQw4w9WgXcQ")
    assert not is_list_url("https://example.org/clip.mp4")
    assert not is_list_url("file:///data/videos/clip.mp4")  # a local file is one video, without asking yt-dlp
    path = project / "manifests/sources.csv"
    path.write_text("url,kind,video_id\nhttps://example.org/feed.xml,list,crew\n")
    with pytest.raises(InputError, match=r"sources.csv:2: a list row \(kind=list\) names many videos"):
        read_sources(path, base_dir=project)
    path.write_text("url,kind\nhttps://example.org/feed.xml,channel\n")
    with pytest.raises(InputError, match=r"sources.csv:2: kind 'channel' is not one of video, list"):
        read_sources(path, base_dir=project)


def test_status_counts_what_discovery_found(project: Path, channel: Mirror) -> None:
    from pipeline.status import summarise

    discover.run(project)
    assert "discover: 1 channels/playlists/feeds, 3 videos listed, 3 selected by the filters" in summarise(project)
