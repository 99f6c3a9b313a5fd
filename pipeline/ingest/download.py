"""Fetch one source with the yt-dlp Python API and describe the result as a ledger row."""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import re
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pipeline.core.errors import MediaError, RateLimitedError
from pipeline.core.ids import check_id, slug_id
from pipeline.core.storage import sha256_file
from pipeline.ingest.media import ffmpeg_exe, probe
from pipeline.ingest.sources import Source

log = logging.getLogger(__name__)

STATUSES = ("ok", "failed", "throttled", "skipped")
_MEDIA_SUFFIXES = {".mp4", ".mkv", ".webm", ".mov", ".avi", ".m4v", ".flv", ".ogg", ".ogv", ".mp3", ".wav", ".m4a"}

_EMPTY = re.compile(r"Did not get any data blocks|downloaded file is empty", re.I)
_RATE_LIMIT = re.compile(r"HTTP Error 429|Too Many Requests|Sign in to confirm|rate.?limit", re.I)
_UNAVAILABLE = re.compile(r"Private video|Video unavailable|has been removed|account .* terminated|not available", re.I)
_NOT_FOUND = re.compile(r"No such file|HTTP Error 404|Not Found", re.I)
_UNSUPPORTED = re.compile(r"Unsupported URL|unsupported url scheme|is not a valid URL", re.I)
_TRANSIENT = re.compile(
    r"timed out|Temporary failure|Connection (reset|refused|aborted)|HTTP Error 5\d\d|IncompleteRead", re.I)


@dataclass
class LedgerRow:
    """One row of ``data/raw/ledger.parquet`` (one per source)."""

    url: str
    video_id: str
    status: str
    error_class: str = ""
    error_message: str = ""
    path: str = ""            # relative to the raw folder
    info_path: str = ""
    size: int = 0
    sha256: str = ""
    fps: float = 0.0
    duration: float = 0.0
    width: int = 0
    height: int = 0
    has_audio: bool = False
    title: str = ""
    channel: str = ""
    uploader: str = ""
    upload_date: str = ""
    licence: str = ""
    style: str = ""
    tags: list[str] = field(default_factory=list)
    attempts: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class DownloadOptions:
    retries: int = 3              # our attempts for transient errors (yt-dlp retries inside each)
    backoff_seconds: float = 2.0
    sleep_interval: float = 0.0   # pause before each download, to be polite
    format: str = "bv*[height<=1080]+ba/b[height<=1080]/bv*+ba/b"
    allow_file_urls: bool = True
    socket_timeout: float = 30.0

    @staticmethod
    def from_params(params: dict) -> "DownloadOptions":
        """From params.yaml's ``download`` section (the discover stage reads it too: the same politeness)."""
        return DownloadOptions(
            retries=int(params.get("retries", 3)),
            backoff_seconds=float(params.get("backoff_seconds", 2.0)),
            sleep_interval=float(params.get("sleep_interval", 0.0)),
            format=str(params.get("format", DownloadOptions.format)),
            allow_file_urls=bool(params.get("allow_file_urls", True)),
            socket_timeout=float(params.get("socket_timeout", 30.0)),
        )


def classify_error(message: str) -> str:
    """Map a downloader message to a stable error class for the ledger."""
    if _RATE_LIMIT.search(message):
        return "rate_limited"
    if _UNSUPPORTED.search(message):
        return "unsupported_url"
    if _EMPTY.search(message):
        return "empty"
    if _NOT_FOUND.search(message):
        return "not_found"
    if _UNAVAILABLE.search(message):
        return "unavailable"
    if _TRANSIENT.search(message):
        return "network"
    return "download_error"


def _clean(message: str) -> str:
    message = re.sub(r"\x1b\[[0-9;]*m", "", message)
    return message.removeprefix("ERROR: ").strip()


class _YtdlpLog:
    """Route yt-dlp's chatter to logging instead of the terminal."""

    def debug(self, msg: str) -> None:
        log.debug(msg)

    def info(self, msg: str) -> None:
        log.debug(msg)

    def warning(self, msg: str) -> None:
        log.info("yt-dlp: %s", msg)

    def error(self, msg: str) -> None:
        log.debug("yt-dlp: %s", msg)


def local_copies(folder: Path | None, wanted: set[str]) -> dict[str, Path]:
    """Files under ``folder`` whose sha256 is in ``wanted``: sha256 -> path (a local mirror of sources)."""
    found: dict[str, Path] = {}
    if not folder or not wanted or not Path(folder).is_dir():
        return found
    for path in sorted(Path(folder).rglob("*")):
        if path.is_file() and path.suffix.lower() in _MEDIA_SUFFIXES:
            digest = sha256_file(path)
            if digest in wanted:
                found.setdefault(digest, path)
    return found


def staging_dir(raw_dir: Path, url: str) -> Path:
    return raw_dir / ".incoming" / hashlib.sha256(url.encode()).hexdigest()[:16]


def _ytdlp_options(dest: Path, opts: DownloadOptions) -> dict[str, Any]:
    return {
        "outtmpl": str(dest / "%(id)s.%(ext)s"),
        "format": opts.format,
        "merge_output_format": "mp4",
        "writeinfojson": True,
        "enable_file_urls": opts.allow_file_urls,
        "ffmpeg_location": ffmpeg_exe(),
        "noplaylist": True,
        "quiet": True,
        "no_warnings": True,
        "noprogress": True,
        "logger": _YtdlpLog(),
        "retries": 3,
        "fragment_retries": 3,
        "socket_timeout": opts.socket_timeout,
        "sleep_interval": opts.sleep_interval or None,
        "restrictfilenames": True,
        "color": {"stderr": "no_color", "stdout": "no_color"},
    }


def download_source(source: Source, raw_dir: Path, opts: DownloadOptions,
                    taken_ids: set[str] = frozenset(), local_copy: Path | None = None) -> LedgerRow:
    """Download ``source`` into ``raw_dir`` as ``<video_id>.<ext>`` + ``<video_id>.info.json``.

    ``local_copy``: a local file with the source's sha256, fetched instead of the network
    (the ledger still names the source's URL). A source with a sha256 whose download has
    another checksum fails. Never raises for a bad source: the returned row says what
    went wrong. Raises RateLimitedError when the site throttles us, so the caller can stop politely.
    """
    row = LedgerRow(url=source.url, video_id=source.video_id or "", status="failed",
                    channel=source.channel, licence=source.licence, style=source.style)
    if source.url_error:
        row.error_class, row.error_message = "invalid_url", source.url_error
        return row
    stage = staging_dir(raw_dir, source.url)
    info: dict[str, Any] | None = None
    url = local_copy.absolute().as_uri() if local_copy else source.url
    ytdlp_opts = dataclasses.replace(opts, allow_file_urls=True) if local_copy else opts
    import yt_dlp  # here: a stage with nothing to download need not import it

    for attempt in range(1, max(1, opts.retries) + 1):
        row.attempts = attempt
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir(parents=True)
        try:
            with yt_dlp.YoutubeDL(_ytdlp_options(stage, ytdlp_opts)) as ydl:
                info = ydl.extract_info(url, download=True)
            break
        except Exception as exc:  # yt-dlp raises several unrelated types
            message = _clean(str(exc))
            row.error_class = classify_error(message)
            row.error_message = f"the source is empty (0 bytes): {message}" if row.error_class == "empty" else message
            if row.error_class == "rate_limited":
                shutil.rmtree(stage, ignore_errors=True)
                row.status = "throttled"
                raise RateLimitedError(f"{source.url}: rate limited ({message})") from None
            if row.error_class != "network" or attempt == opts.retries:
                shutil.rmtree(stage, ignore_errors=True)
                return row
            time.sleep(opts.backoff_seconds * 2 ** (attempt - 1))
    assert info is not None
    try:
        return _finish(row, info, stage, raw_dir, taken_ids, source)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _finish(row: LedgerRow, info: dict[str, Any], stage: Path, raw_dir: Path, taken_ids: set[str],
            listed: Source) -> LedgerRow:
    """``listed``: the source row, whose sha256 is checked and whose list metadata fills what the site's info lacks."""
    expected_sha256 = listed.sha256
    downloads = info.get("requested_downloads") or [{}]
    media = Path(downloads[0].get("filepath") or "")
    if not media.is_file():
        row.error_class, row.error_message = "download_error", "yt-dlp reported success but wrote no file"
        return row
    digest = sha256_file(media)
    if expected_sha256 and digest != expected_sha256:
        row.error_class = "checksum"
        row.error_message = f"the downloaded file has sha256 {digest}, not the {expected_sha256} that sources.csv names"
        return row
    video_id = row.video_id or slug_id(str(info.get("id") or media.stem))
    if not row.video_id and video_id in taken_ids:
        video_id = f"{video_id}-{hashlib.sha256(row.url.encode()).hexdigest()[:6]}"
    row.video_id = check_id(video_id, "video_id")
    row.title = str(info.get("title") or "") or listed.title
    row.uploader = str(info.get("uploader") or "")
    row.channel = row.channel or str(info.get("channel") or info.get("uploader") or "")
    row.upload_date = str(info.get("upload_date") or "") or listed.upload_date
    row.tags = [str(t) for t in (info.get("tags") or [])] or list(listed.tags)
    try:
        video = probe(media)
    except MediaError as exc:
        row.error_class, row.error_message = "media", f"downloaded file is not a usable video: {exc.reason}"
        return row
    target = raw_dir / f"{row.video_id}{media.suffix}"
    info_target = raw_dir / f"{row.video_id}.info.json"
    infojson = next(stage.glob("*.info.json"), None)
    if infojson is not None:
        infojson.replace(info_target)
        row.info_path = info_target.name
    media.replace(target)  # same filesystem: atomic
    row.path = target.name
    row.size = target.stat().st_size
    row.sha256 = digest
    row.fps, row.duration = video.fps, video.duration
    row.width, row.height, row.has_audio = video.width, video.height, video.has_audio
    row.status, row.error_class, row.error_message = "ok", "", ""
    return row
