"""Discovery: expand channel, playlist and feed rows of sources.csv into one catalogue row per video.

yt-dlp's flat extraction lists a channel or feed without fetching each video. The catalogue
keeps every entry ever discovered, in the order first seen, so a re-run appends only new
uploads and nothing already downloaded changes position or id. Filters (count, dates,
durations, title patterns) choose which entries the download stage fetches; they are
re-applied on every run, so changing them needs no network.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import logging
import re
import time
from dataclasses import dataclass, replace
from typing import Any, Iterable, Iterator

from pipeline.core.errors import RateLimitedError
from pipeline.core.ids import slug_id
from pipeline.core.paths import SOURCES
from pipeline.ingest.download import DownloadOptions, _clean, _YtdlpLog, classify_error
from pipeline.ingest.sources import Source

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DiscoverOptions:
    max_videos: int = 0           # per list: at most this many selected entries (0: no limit)
    date_after: str = ""          # YYYYMMDD: only uploads on or after this day ("" : no limit)
    date_before: str = ""         # YYYYMMDD: only uploads on or before this day
    min_duration: float = 0.0     # seconds (0: no limit)
    max_duration: float = 0.0
    title_include: str = ""       # regular expression (case-insensitive) a title must match
    title_exclude: str = ""       # regular expression a title must not match
    stop_after_known: int = 10    # a re-run stops listing after this many already-known entries in a row

    @staticmethod
    def from_params(section: dict) -> "DiscoverOptions":
        """From params.yaml's ``discover`` section (empty values: no limit)."""
        return DiscoverOptions(
            max_videos=int(section.get("max_videos", 0) or 0),
            date_after=str(section.get("date_after", "") or ""),
            date_before=str(section.get("date_before", "") or ""),
            min_duration=float(section.get("min_duration", 0) or 0),
            max_duration=float(section.get("max_duration", 0) or 0),
            title_include=str(section.get("title_include", "") or ""),
            title_exclude=str(section.get("title_exclude", "") or ""),
            stop_after_known=int(section.get("stop_after_known", 10)))


@dataclass(frozen=True)
class Entry:
    """One video of a list, as the site describes it without fetching the video."""

    url: str
    entry_id: str = ""
    title: str = ""
    channel: str = ""
    upload_date: str = ""         # YYYYMMDD or ""
    duration: float | None = None
    tags: tuple[str, ...] = ()
    licence: str = ""


def is_list_url(url: str) -> bool:
    """True when yt-dlp knows ``url`` as a channel or playlist (YouTube, Vimeo, TikTok ...).

    A feed on any other site (RSS, Atom, XSPF) is not recognisable from its URL: mark its
    row with ``kind=list`` in sources.csv. The first call compiles yt-dlp's URL patterns (0.3 s).
    """
    if not url.lower().startswith(("http://", "https://")):
        return False  # a local file is one video
    import yt_dlp.extractor  # here: a stage with nothing to fetch need not import yt-dlp

    for ie in yt_dlp.extractor.gen_extractor_classes():
        if ie.ie_key() != "Generic" and ie.suitable(url):
            return ie._RETURN_TYPE in ("playlist", "any")
    return False


def is_list_source(source: Source, lists: Iterable[str] = (), videos: Iterable[str] = ()) -> bool:
    """Whether ``source`` is a channel, playlist or feed: its ``kind``, else whether it is among the
    ``lists`` already discovered or the ``videos`` already downloaded, else what yt-dlp knows of its URL."""
    if source.kind:
        return source.kind == "list"
    if source.url in lists or source.url in videos:
        return source.url in lists
    return not source.url_error and is_list_url(source.url)


def _date(info: dict[str, Any]) -> str:
    if info.get("upload_date"):
        return str(info["upload_date"])
    stamp = info.get("timestamp") or info.get("release_timestamp")
    if stamp:
        return dt.datetime.fromtimestamp(float(stamp), dt.timezone.utc).strftime("%Y%m%d")
    return ""


def _entry(raw: dict[str, Any], feed: dict[str, Any]) -> Entry | None:
    from yt_dlp.utils import unsmuggle_url

    url, smuggled = unsmuggle_url(str(raw.get("url") or raw.get("webpage_url") or ""), {})
    if not url:
        return None
    duration = raw.get("duration")
    return Entry(
        url=url,
        entry_id=str(raw.get("id") or smuggled.get("force_videoid") or ""),
        title=str(raw.get("title") or ""),
        channel=str(raw.get("channel") or raw.get("uploader") or feed.get("channel") or feed.get("uploader")
                    or feed.get("title") or ""),
        upload_date=_date(raw),
        duration=float(duration) if duration is not None else None,
        tags=tuple(str(t) for t in (raw.get("tags") or ())),
        licence=str(raw.get("license") or ""),
    )


def _ytdlp_options(opts: DownloadOptions) -> dict[str, Any]:
    return {
        "extract_flat": "in_playlist",
        "lazy_playlist": True,
        "enable_file_urls": opts.allow_file_urls,
        "quiet": True,
        "no_warnings": True,
        "noprogress": True,
        "logger": _YtdlpLog(),
        "socket_timeout": opts.socket_timeout,
        "sleep_interval_requests": opts.sleep_interval or None,
        "color": {"stderr": "no_color", "stdout": "no_color"},
    }


def list_entries(url: str, opts: DownloadOptions, known: set[str] = frozenset(),
                 stop_after_known: int = 10) -> Iterator[Entry]:
    """The list's entries in the site's order, read lazily.

    With ``known`` urls, listing stops after ``stop_after_known`` known entries in a row:
    channels list newest first, so a re-run reads one page, not the whole channel.
    Raises RateLimitedError when the site throttles us, RuntimeError for any other failure.
    """
    import yt_dlp

    for attempt in range(1, max(1, opts.retries) + 1):
        try:
            with yt_dlp.YoutubeDL(_ytdlp_options(opts)) as ydl:
                info = ydl.extract_info(url, download=False, process=False)
                if info.get("_type") not in ("playlist", "multi_video"):
                    raise RuntimeError("not a channel, playlist or feed (yt-dlp sees one video): "
                                       "remove kind=list from its row")
                run = 0
                for raw in info.get("entries") or ():
                    entry = _entry(raw or {}, info)
                    if entry is None:
                        continue
                    run = run + 1 if entry.url in known else 0
                    if known and run >= stop_after_known:
                        return
                    yield entry
            return
        except RuntimeError:
            raise
        except Exception as exc:  # yt-dlp raises several unrelated types
            message = _clean(str(exc))
            kind = classify_error(message)
            if kind == "rate_limited":
                raise RateLimitedError(f"{url}: rate limited ({message})") from None
            if kind != "network" or attempt >= opts.retries:
                raise RuntimeError(message) from None
            time.sleep(opts.backoff_seconds * 2 ** (attempt - 1))


def merge(previous: list[dict], feed: Source, found: Iterable[Entry], taken_ids: set[str]) -> list[dict]:
    """``previous`` rows of this list, then the new entries of ``found`` in the site's order.

    Known urls keep their row (and so their video id); new ones get an id that no other
    video has (``taken_ids`` is updated).
    """
    rows = [dict(r) for r in previous]
    seen = {r["url"] for r in rows}
    for entry in found:
        if entry.url in seen:
            continue
        seen.add(entry.url)
        rows.append(catalogue_row(feed, entry, _unique_id(entry, taken_ids)))
    for position, row in enumerate(rows):
        row["position"] = position
    return rows


def _unique_id(entry: Entry, taken: set[str]) -> str:
    base = slug_id(entry.entry_id or entry.url.rstrip("/").rsplit("/", 1)[-1].rsplit(".", 1)[0])
    video_id = base if base not in taken else f"{base[:93]}-{hashlib.sha256(entry.url.encode()).hexdigest()[:6]}"
    taken.add(video_id)
    return video_id


def catalogue_row(feed: Source, entry: Entry, video_id: str) -> dict:
    return {"list_url": feed.url, "list_line": feed.line, "position": 0, "url": entry.url, "video_id": video_id,
            "title": entry.title, "channel": entry.channel or feed.channel, "upload_date": entry.upload_date,
            "duration": entry.duration, "tags": list(entry.tags), "licence": entry.licence or feed.licence,
            "style": feed.style, "selected": True, "reason": ""}


def select(rows: list[dict], opts: DiscoverOptions) -> list[dict]:
    """Mark each row of one list selected or not, with the reason; the cap counts selected rows in order.

    A filter whose field the site did not give (no date, no duration) lets the entry pass.
    """
    include = re.compile(opts.title_include, re.I) if opts.title_include else None
    exclude = re.compile(opts.title_exclude, re.I) if opts.title_exclude else None
    chosen = 0
    out = []
    for row in rows:
        reason = ""
        date, duration = row.get("upload_date") or "", row.get("duration")
        if opts.date_after and date and date < opts.date_after:
            reason = f"uploaded {date}, before discover.date_after {opts.date_after}"
        elif opts.date_before and date and date > opts.date_before:
            reason = f"uploaded {date}, after discover.date_before {opts.date_before}"
        elif opts.min_duration and duration is not None and duration < opts.min_duration:
            reason = f"{duration:g} s, shorter than discover.min_duration"
        elif opts.max_duration and duration is not None and duration > opts.max_duration:
            reason = f"{duration:g} s, longer than discover.max_duration"
        elif include and not include.search(row.get("title") or ""):
            reason = "title does not match discover.title_include"
        elif exclude and exclude.search(row.get("title") or ""):
            reason = "title matches discover.title_exclude"
        elif opts.max_videos and chosen >= opts.max_videos:
            reason = f"past discover.max_videos ({opts.max_videos})"
        chosen += not reason
        out.append({**row, "selected": not reason, "reason": reason})
    return out


def entry_sources(feed: Source, rows: list[dict]) -> list[Source]:
    """The selected rows of one list as download sources (the list's line, its entry number)."""
    return [replace(feed, url=r["url"], video_id=r["video_id"], entry=r["position"] + 1,
                    channel=r["channel"], licence=r["licence"], title=r["title"], upload_date=r["upload_date"],
                    tags=tuple(r["tags"] or ()), kind="video", sha256="", url_error="")
            for r in rows if r["selected"]]


@dataclass
class Discovery:
    """What listing every list found: its rows by list URL, the lists that failed, and the
    rate-limit message that stopped listing ('' when none did)."""

    found: dict[str, list[dict]]
    failures: list[tuple[Source, str, str]]  # (list row, error class, message)
    throttled: str = ""


def discover_lists(lists: list[Source], previous: dict[str, list[dict]], opts: DiscoverOptions,
                   net: DownloadOptions, taken: set[str]) -> Discovery:
    """List every list row politely (a pause between lists, a stop at the first rate limit); a list
    that fails or is not reached keeps what earlier runs found."""
    out = Discovery({}, [])
    for n, feed in enumerate(lists):
        before = previous.get(feed.url, [])
        out.found[feed.url] = before
        if out.throttled or feed.url_error:
            if feed.url_error:
                out.failures.append((feed, "invalid_url", feed.url_error))
            continue
        if n and net.sleep_interval:
            time.sleep(net.sleep_interval)
        started = time.perf_counter()
        try:
            entries = list(list_entries(feed.url, net, {r["url"] for r in before}, opts.stop_after_known))
        except RateLimitedError as exc:
            out.throttled = str(exc)
            continue
        except RuntimeError as exc:
            out.failures.append((feed, "discover_error", f"{feed.url}: {exc}"))
            log.warning("%s: %s: %s", feed.where(SOURCES), feed.url, exc)
            continue
        rows = merge(before, feed, entries, taken)
        out.found[feed.url] = rows
        log.info("%s: %s: %d entries listed in %.1f s, %d new, %d in the catalogue",
                 feed.where(SOURCES), feed.url, len(entries), time.perf_counter() - started,
                 len(rows) - len(before), len(rows))
    return out
