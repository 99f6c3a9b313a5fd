"""The download stage's work over every source: which are done, what the channel and playlist
rows expand to, and the polite parallel loop that stops the moment a site rate-limits us.
(``download.download_source`` fetches one source.)"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

from pipeline.core.errors import RateLimitedError
from pipeline.core.executor import run_items
from pipeline.core.paths import CATALOG, SOURCES
from pipeline.ingest.discover import entry_sources, is_list_source
from pipeline.ingest.download import DownloadOptions, LedgerRow, download_source
from pipeline.ingest.sources import Source

log = logging.getLogger("dance3d.download")


def is_done(row: dict | None, raw_dir: Path) -> bool:
    """A ledger row whose download is there, whole."""
    if not row or row["status"] != "ok" or not row["path"]:
        return False
    media = raw_dir / row["path"]
    return media.is_file() and media.stat().st_size == row["size"]


def expand_sources(sources: list[Source], discovered: dict[str, list[dict]],
                   downloaded: Iterable[str] = ()) -> list[Source]:
    """Video rows as they are; each list row replaced by its selected catalogue entries, in order.
    A URL ``discovered`` is a list and one already ``downloaded`` a video, without asking yt-dlp.

    A video listed twice (a direct row and a list, or two lists) is fetched once, for its first row.
    """
    out: list[Source] = []
    seen: set[str] = set()
    for source in sources:
        if not is_list_source(source, discovered, downloaded):
            expanded = [source]
        elif source.url in discovered:
            expanded = entry_sources(source, discovered[source.url])
        else:
            log.warning("%s: %s is a channel, playlist or feed that is not in %s yet: run the discover stage",
                        source.where(SOURCES), source.url, CATALOG)
            expanded = []
        for s in expanded:
            if s.url not in seen:
                seen.add(s.url)
                out.append(s)
    return out


def _row(source: Source, status: str, error_class: str, message: str) -> dict:
    return LedgerRow(url=source.url, video_id=source.video_id or "", status=status, error_class=error_class,
                     error_message=message, channel=source.channel, licence=source.licence,
                     style=source.style).as_dict()


class Fetcher:
    """Downloads sources in parallel threads; after one rate-limited answer every source not yet
    started is skipped (``throttled`` says so), so a throttling site is not hammered."""

    def __init__(self, raw_dir: Path, opts: DownloadOptions, taken: set[str], copies: dict[str, Path]) -> None:
        self.raw_dir, self.opts, self.copies = raw_dir, opts, copies
        self.taken = set(taken)
        self._stop = threading.Event()
        self._lock = threading.Lock()

    @property
    def throttled(self) -> bool:
        return self._stop.is_set()

    def fetch(self, source: Source) -> dict:
        if self._stop.is_set():
            return _row(source, "skipped", "rate_limited", "not attempted: the site was rate limiting us")
        try:
            with self._lock:
                snapshot = set(self.taken)
            row = download_source(source, self.raw_dir, self.opts, snapshot, local_copy=self.copies.get(source.sha256))
        except RateLimitedError as exc:
            self._stop.set()
            return _row(source, "throttled", "rate_limited", str(exc))
        with self._lock:
            self.taken.add(row.video_id)
        return row.as_dict()

    def fetch_all(self, todo: list[Source], workers: int) -> Iterator[tuple[Source, dict]]:
        """(source, ledger row) as each finishes; a bug in one is one failed row, never a crash."""
        for outcome in run_items(self.fetch, todo, workers=workers, kind="thread", desc="download", unit="video"):
            source: Source = outcome.item
            yield source, outcome.value if outcome.ok else _row(source, "failed", outcome.error_class,
                                                                outcome.error_message)
