"""``manifests/sources.csv``: what to fetch. One row per video, or per channel, playlist or feed
(``kind=list``; discovery expands those into the catalogue)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

from pipeline.core.errors import InputError
from pipeline.core.ids import check_id
from pipeline.core.tables import read_csv

REQUIRED = ("url",)
OPTIONAL = ("video_id", "sha256", "channel", "style", "licence", "note", "kind")
KINDS = ("video", "list")  # empty: list when yt-dlp knows the url as a channel or playlist
_SHA256 = re.compile(r"[0-9a-f]{64}")


@dataclass(frozen=True)
class Source:
    line: int
    url: str                 # normalised: http(s)://, file:// (absolute), never a bare path
    video_id: str | None     # None: taken from the downloader's id
    url_error: str = ""      # why the url cannot be fetched (the row becomes a failed ledger row)
    sha256: str = ""         # expected sha256 of the downloaded file ("" : not checked)
    channel: str = ""
    style: str = ""
    licence: str = ""
    note: str = ""
    kind: str = ""           # "video", "list" or "" (decided from the url by discovery)
    entry: int = 0           # > 0: the entry-th video of the list on this line
    title: str = ""          # what the list said of the entry (the download's info wins)
    upload_date: str = ""
    tags: tuple[str, ...] = ()

    def where(self, sources_file: str | Path) -> str:
        """Where this source comes from, for messages: file:line, and the list entry."""
        return f"{sources_file}:{self.line}" + (f" entry {self.entry}" if self.entry else "")


def normalise_url(raw: str, base_dir: Path, allow_file_urls: bool) -> str:
    """http(s) URLs pass; local paths (relative to ``base_dir``) and file:// URLs become
    absolute file:// URLs when local files are allowed. Raises ValueError otherwise."""
    if not raw:
        raise ValueError("empty url")
    if "\x00" in raw or any(ch.isspace() for ch in raw):
        raise ValueError(f"url {raw!r} contains whitespace or NUL")
    parsed = urlparse(raw)
    scheme = parsed.scheme.lower()
    if scheme in ("http", "https"):
        if not parsed.netloc:
            raise ValueError(f"url {raw!r} has no host")
        return raw
    if scheme == "file" or scheme == "":
        if not allow_file_urls:
            raise ValueError(f"local file {raw!r} given but download.allow_file_urls is false")
        path = Path(parsed.path) if scheme == "file" else Path(raw)
        if not path.is_absolute():
            path = (base_dir / path).absolute()
        return path.as_uri()
    raise ValueError(f"url {raw!r} has unsupported scheme {scheme!r} (use http, https or file)")


def read_sources(path: Path, *, base_dir: Path, allow_file_urls: bool = True) -> list[Source]:
    """Parse and validate sources.csv; every problem names file and line."""
    rows = read_csv(path, REQUIRED, OPTIONAL)
    sources: list[Source] = []
    seen_ids: dict[str, int] = {}
    seen_urls: dict[str, int] = {}
    for row in rows:
        url, url_error = row.get("url"), ""
        try:
            url = normalise_url(url, base_dir, allow_file_urls)
        except ValueError as exc:  # one bad url is one failed video, not a rejected file
            url_error = f"{path}:{row.line}: {exc}"
        video_id = row.get("video_id") or None
        if video_id is not None:
            try:
                check_id(video_id, "video_id")
            except ValueError as exc:
                raise InputError(path, str(exc), row.line) from None
            if video_id in seen_ids:
                first = seen_ids[video_id]
                raise InputError(path, f"duplicate video_id {video_id!r} (first on line {first})", row.line)
            seen_ids[video_id] = row.line
        sha256 = row.get("sha256").lower()
        if sha256 and not _SHA256.fullmatch(sha256):
            raise InputError(path, f"sha256 {row.get('sha256')!r} is not 64 hexadecimal digits", row.line)
        kind = row.get("kind").lower()
        if kind not in ("",) + KINDS:
            raise InputError(path, f"kind {row.get('kind')!r} is not one of {', '.join(KINDS)} (or empty)", row.line)
        if kind == "list" and (video_id or sha256):
            raise InputError(path, "a list row (kind=list) names many videos: leave video_id and sha256 empty",
                             row.line)
        if url in seen_urls:
            raise InputError(path, f"duplicate url (first on line {seen_urls[url]})", row.line)
        seen_urls[url] = row.line
        sources.append(
            Source(
                line=row.line,
                url=url,
                video_id=video_id,
                url_error=url_error,
                sha256=sha256,
                channel=row.get("channel"),
                style=row.get("style"),
                licence=row.get("licence"),
                note=row.get("note"),
                kind=kind,
            )
        )
    return sources
