"""manifests/sources.csv validation."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.core.errors import InputError
from pipeline.ingest.sources import read_sources

HEADER = "video_id,url,channel,style,licence,note\n"


def write(tmp_path: Path, body: str, header: str = HEADER) -> Path:
    path = tmp_path / "sources.csv"
    path.write_text(header + body)
    return path


def test_local_paths_and_file_urls_become_absolute_file_urls(tmp_path: Path) -> None:
    path = write(tmp_path, "a,clips/a.mp4,,,,\nb,file:///data/b.mp4,,,,\n,https://example.org/v?id=1,ch,pop,CC-BY,\n")
    a, b, c = read_sources(path, base_dir=tmp_path)
    assert a.url == (tmp_path / "clips/a.mp4").as_uri()
    assert b.url == "file:///data/b.mp4"
    assert (c.url, c.video_id, c.channel, c.licence) == ("https://example.org/v?id=1", None, "ch", "CC-BY")


def test_missing_column_names_the_header_line(tmp_path: Path) -> None:
    path = write(tmp_path, "x,y\n", header="video_id,channel\n")
    with pytest.raises(InputError, match=r"sources\.csv:1: missing column\(s\) url"):
        read_sources(path, base_dir=tmp_path)


def test_duplicate_video_id(tmp_path: Path) -> None:
    path = write(tmp_path, "a,x.mp4,,,,\na,y.mp4,,,,\n")
    with pytest.raises(InputError, match=r"sources\.csv:3: duplicate video_id 'a' \(first on line 2\)"):
        read_sources(path, base_dir=tmp_path)


def test_duplicate_url(tmp_path: Path) -> None:
    path = write(tmp_path, "a,x.mp4,,,,\nb,x.mp4,,,,\n")
    with pytest.raises(InputError, match=r"sources\.csv:3: duplicate url \(first on line 2\)"):
        read_sources(path, base_dir=tmp_path)


def test_unsafe_id_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, "../x,x.mp4,,,,\n")
    with pytest.raises(InputError, match=r"sources\.csv:2: video_id '\.\./x' is not a safe identifier"):
        read_sources(path, base_dir=tmp_path)


@pytest.mark.parametrize("url, reason", [
    ("ftp://host/x.mp4", "unsupported scheme 'ftp'"),
    ("https://", "has no host"),
    ("javascript:alert(1)", "unsupported scheme 'javascript'"),
])
def test_bad_urls_are_kept_as_row_errors(tmp_path: Path, url: str, reason: str) -> None:
    path = write(tmp_path, f"a,{url},,,,\nb,ok.mp4,,,,\n")
    bad, good = read_sources(path, base_dir=tmp_path)
    assert "sources.csv:2: " in bad.url_error and reason in bad.url_error
    assert good.url_error == ""


def test_local_files_can_be_disabled(tmp_path: Path) -> None:
    path = write(tmp_path, "a,x.mp4,,,,\n")
    (source,) = read_sources(path, base_dir=tmp_path, allow_file_urls=False)
    assert "allow_file_urls is false" in source.url_error
