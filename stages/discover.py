"""discover stage: the channel, playlist and feed rows of manifests/sources.csv -> data/catalog/videos.parquet
(pipeline/ingest/discover.py).

DVC runs it on every ``dvc repro`` (``always_changed``): a list can gain uploads without any
local file changing. An unchanged list writes a byte-identical catalogue, so nothing downstream
re-runs; a list that gained one video gives the download stage one video to fetch.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from pipeline.core.errors import RateLimitedError
from pipeline.core.failures import Failure, check_failure_ratio, now, write_failures
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CATALOG, RAW, SOURCES
from pipeline.core.stage import run_stage, setup_logging
from pipeline.ingest.catalog import read_discovered, read_ledger, write_discovered
from pipeline.ingest.discover import DiscoverOptions, discover_lists, is_list_source, select
from pipeline.ingest.download import DownloadOptions
from pipeline.ingest.sources import read_sources

log = logging.getLogger("dance3d.discover")


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    params = stage_params(all_params, "discover")
    opts = DiscoverOptions.from_params(params)
    net = DownloadOptions.from_params(all_params.get("download") or {})  # the downloads' politeness
    sources = read_sources(root / SOURCES, base_dir=root, allow_file_urls=net.allow_file_urls)
    catalog_dir = root / CATALOG
    catalog_dir.mkdir(parents=True, exist_ok=True)
    previous = read_discovered(catalog_dir)
    # Lists already discovered, and videos already downloaded, are known without asking yt-dlp.
    videos = {url for url, row in read_ledger(root / RAW).items() if row["status"] == "ok"}
    lists = [s for s in sources if is_list_source(s, previous, videos)]
    taken = {s.video_id for s in sources if s.video_id} | {r["video_id"] for rows in previous.values() for r in rows}
    found = discover_lists(lists, previous, opts, net, taken)
    out = [{**r, "list_line": feed.line} for feed in lists for r in select(found.found.get(feed.url, []), opts)]
    dropped = sorted(set(previous) - {f.url for f in lists})
    if dropped:
        log.info("%d list(s) no longer in %s are dropped from the catalogue: %s", len(dropped), SOURCES,
                 ", ".join(dropped))
    write_discovered(catalog_dir, out, params)
    failures = [Failure(feed.where(SOURCES), "discover", kind, message, now())
                for feed, kind, message in found.failures]
    write_failures(catalog_dir, "discover", failures, total=len(lists))
    chosen = sum(r["selected"] for r in out)
    log.info("catalogue: %d videos from %d lists, %d selected by the discover filters", len(out), len(lists), chosen)
    if found.throttled:
        raise RateLimitedError(f"the site is rate limiting discovery ({found.throttled}); wait a while (or raise "
                               "download.sleep_interval) and re-run: lists already found are kept")
    check_failure_ratio("discover", len(failures), len(lists), float(params.get("max_failure_ratio", 0.5)))


def main() -> int:
    setup_logging()
    return run_stage("discover", run)


if __name__ == "__main__":
    sys.exit(main())
