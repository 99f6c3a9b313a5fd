"""discover stage: the channel, playlist and feed rows of manifests/sources.csv -> data/catalog/videos.parquet.

DVC runs it on every ``dvc repro`` (``always_changed``): a list can gain uploads without any
local file changing. An unchanged list writes a byte-identical catalogue, so nothing downstream
re-runs; a list that gained one video gives the download stage one video to fetch.
"""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from pipeline.core.errors import RateLimitedError
from pipeline.core.failures import Failure, check_failure_ratio, now, write_failures
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CATALOG, SOURCES
from pipeline.core.stage import run_stage, setup_logging
from pipeline.ingest.catalog import read_discovered, write_discovered
from pipeline.ingest.discover import DiscoverOptions, is_list_source, list_entries, merge, select
from pipeline.ingest.download import DownloadOptions
from pipeline.ingest.sources import read_sources

log = logging.getLogger("dance3d.discover")


def options(params: dict) -> tuple[DiscoverOptions, DownloadOptions]:
    section = params.get("discover") or {}
    return (
        DiscoverOptions(
            max_videos=int(section.get("max_videos", 0) or 0),
            date_after=str(section.get("date_after", "") or ""),
            date_before=str(section.get("date_before", "") or ""),
            min_duration=float(section.get("min_duration", 0) or 0),
            max_duration=float(section.get("max_duration", 0) or 0),
            title_include=str(section.get("title_include", "") or ""),
            title_exclude=str(section.get("title_exclude", "") or ""),
            stop_after_known=int(section.get("stop_after_known", 10)),
        ),
        # The same politeness as downloads: retries, back-off, pauses and time-outs.
        DownloadOptions.from_params(params.get("download") or {}),
    )


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    params = stage_params(all_params, "discover")
    opts, net = options(all_params)
    sources = read_sources(root / SOURCES, base_dir=root, allow_file_urls=net.allow_file_urls)
    lists = [s for s in sources if is_list_source(s)]
    catalog_dir = root / CATALOG
    catalog_dir.mkdir(parents=True, exist_ok=True)
    previous = read_discovered(catalog_dir)
    taken = {s.video_id for s in sources if s.video_id} | {r["video_id"] for rows in previous.values() for r in rows}
    found: dict[str, list[dict]] = {}
    failures: list[Failure] = []
    throttled = ""
    for n, feed in enumerate(lists):
        before = previous.get(feed.url, [])
        if throttled or feed.url_error:
            found[feed.url] = before  # keep what earlier runs found
            if feed.url_error:
                failures.append(Failure(feed.where(SOURCES), "discover", "invalid_url", feed.url_error, now()))
            continue
        if n and net.sleep_interval:
            time.sleep(net.sleep_interval)
        started = time.perf_counter()
        try:
            entries = list(list_entries(feed.url, net, {r["url"] for r in before}, opts.stop_after_known))
        except RateLimitedError as exc:
            throttled = str(exc)
            found[feed.url] = before
            continue
        except RuntimeError as exc:
            found[feed.url] = before
            failures.append(Failure(feed.where(SOURCES), "discover", "discover_error", f"{feed.url}: {exc}", now()))
            log.warning("%s: %s: %s", feed.where(SOURCES), feed.url, exc)
            continue
        rows = merge(before, feed, entries, taken)
        found[feed.url] = rows
        log.info("%s: %s: %d entries listed in %.1f s, %d new, %d in the catalogue",
                 feed.where(SOURCES), feed.url, len(entries), time.perf_counter() - started,
                 len(rows) - len(before), len(rows))
    out = []
    for feed in lists:
        rows = select(found.get(feed.url, []), opts)
        out.extend({**r, "list_line": feed.line} for r in rows)
    dropped = sorted(set(previous) - {f.url for f in lists})
    if dropped:
        log.info("%d list(s) no longer in %s are dropped from the catalogue: %s", len(dropped), SOURCES,
                 ", ".join(dropped))
    write_discovered(catalog_dir, out, params)
    write_failures(catalog_dir, "discover", failures, total=len(lists))
    chosen = sum(r["selected"] for r in out)
    log.info("catalogue: %d videos from %d lists, %d selected by the discover filters", len(out), len(lists), chosen)
    if throttled:
        raise RateLimitedError(f"the site is rate limiting discovery ({throttled}); wait a while (or raise "
                               "download.sleep_interval) and re-run: lists already found are kept")
    check_failure_ratio("discover", len(failures), len(lists), float(params.get("max_failure_ratio", 0.5)))


def main() -> int:
    setup_logging()
    return run_stage("discover", run)


if __name__ == "__main__":
    sys.exit(main())
