"""download stage: manifests/sources.csv (+ data/catalog for its lists) -> data/raw/<video_id>.<ext>,
.info.json, ledger.parquet."""

from __future__ import annotations

import logging
import os
import shutil
import sys
import threading
from pathlib import Path

from pipeline.core.errors import RateLimitedError
from pipeline.core.executor import run_items
from pipeline.core.failures import Failure, check_failure_ratio, now, write_failures
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CATALOG, RAW, SOURCES
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import remove_stale_temps
from pipeline.ingest.catalog import read_discovered, read_ledger, write_ledger
from pipeline.ingest.discover import entry_sources, is_list_source
from pipeline.ingest.download import DownloadOptions, LedgerRow, download_source, local_copies
from pipeline.ingest.sources import Source, read_sources

log = logging.getLogger("dance3d.download")

def _is_done(row: dict | None, raw_dir: Path) -> bool:
    if not row or row["status"] != "ok" or not row["path"]:
        return False
    media = raw_dir / row["path"]
    return media.is_file() and media.stat().st_size == row["size"]


def _write_ledger(raw_dir: Path, sources: list[Source], rows: dict[str, dict], params: dict) -> None:
    write_ledger(raw_dir, [rows[s.url] for s in sources if s.url in rows], params)


def expand_sources(root: Path, sources: list[Source]) -> list[Source]:
    """Video rows as they are; each list row replaced by its selected catalogue entries, in order.

    A video listed twice (a direct row and a list, or two lists) is fetched once, for its first row.
    """
    discovered = read_discovered(root / CATALOG)
    out: list[Source] = []
    seen: set[str] = set()
    for source in sources:
        if not is_list_source(source):
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


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "download")
    opts = DownloadOptions.from_params(params)
    sources = expand_sources(root, read_sources(root / SOURCES, base_dir=root, allow_file_urls=opts.allow_file_urls))
    raw_dir = root / RAW
    raw_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(raw_dir)
    previous = read_ledger(raw_dir)
    rows = {s.url: previous[s.url] for s in sources if _is_done(previous.get(s.url), raw_dir)}
    todo = [s for s in sources if s.url not in rows]
    log.info("%d sources: %d already downloaded, %d to fetch", len(sources), len(rows), len(todo))
    taken = {r["video_id"] for r in rows.values()} | {s.video_id for s in sources if s.video_id}
    mirror = params.get("local_copies") or os.environ.get("DANCE3D_MEDIA") or ""
    copies = local_copies(Path(mirror) if mirror else None, {s.sha256 for s in todo if s.sha256})
    if copies:
        log.info("%d of %d sources are taken from local copies in %s", len(copies), len(todo), mirror)
    stop = threading.Event()
    lock = threading.Lock()

    def fetch(source: Source) -> dict:
        if stop.is_set():
            return LedgerRow(url=source.url, video_id=source.video_id or "", status="skipped",
                             error_class="rate_limited", error_message="not attempted: the site was rate limiting us",
                             channel=source.channel, licence=source.licence, style=source.style).as_dict()
        try:
            with lock:
                snapshot = set(taken)
            row = download_source(source, raw_dir, opts, snapshot, local_copy=copies.get(source.sha256))
        except RateLimitedError as exc:
            stop.set()
            return LedgerRow(url=source.url, video_id=source.video_id or "", status="throttled",
                             error_class="rate_limited", error_message=str(exc),
                             channel=source.channel, licence=source.licence, style=source.style).as_dict()
        with lock:
            taken.add(row.video_id)
        return row.as_dict()

    failures: list[Failure] = []
    for outcome in run_items(fetch, todo, workers=int(params.get("workers", 1)), kind="thread",
                             desc="download", unit="video"):
        source: Source = outcome.item
        if outcome.ok:
            row = outcome.value
        else:  # a bug, not a bad source: still one row, never a crash
            row = LedgerRow(url=source.url, video_id=source.video_id or "", status="failed",
                            error_class=outcome.error_class, error_message=outcome.error_message).as_dict()
        rows[source.url] = row
        if row["status"] == "failed":
            failures.append(Failure(source.where(SOURCES), "download", row["error_class"],
                                    f"{source.url}: {row['error_message']}", now()))
            log.warning("%s: %s: %s", source.where(SOURCES), source.url, row["error_message"])
        _write_ledger(raw_dir, sources, rows, params)  # after every item: nothing done is lost
    _write_ledger(raw_dir, sources, rows, params)
    shutil.rmtree(raw_dir / ".incoming", ignore_errors=True)
    write_failures(raw_dir, "download", failures, total=len(sources))
    ok = sum(1 for r in rows.values() if r["status"] == "ok")
    log.info("ledger: %d ok, %d failed, of %d sources", ok, len(failures), len(sources))
    if stop.is_set():
        raise RateLimitedError(
            f"the site is rate limiting downloads ({ok} of {len(sources)} done); "
            "wait a while (or raise download.sleep_interval) and re-run: finished videos are kept"
        )
    check_failure_ratio("download", len(failures), len(sources), float(params.get("max_failure_ratio", 0.5)))


def main() -> int:
    setup_logging()
    return run_stage("download", run)


if __name__ == "__main__":
    sys.exit(main())
