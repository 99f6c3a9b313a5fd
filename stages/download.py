"""download stage: manifests/sources.csv (+ data/catalog for its lists) -> data/raw/<video_id>.<ext>,
.info.json, ledger.parquet (pipeline/ingest/fetch.py, download.py)."""

from __future__ import annotations

import logging
import os
import shutil
import sys
from pathlib import Path

from pipeline.core.errors import RateLimitedError
from pipeline.core.failures import Failure, check_failure_ratio, now, write_failures
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CATALOG, RAW, SOURCES
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import remove_stale_temps
from pipeline.ingest.catalog import read_discovered, read_ledger, write_ledger
from pipeline.ingest.download import DownloadOptions, local_copies
from pipeline.ingest.fetch import Fetcher, expand_sources, is_done
from pipeline.ingest.sources import read_sources

log = logging.getLogger("dance3d.download")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "download")
    opts = DownloadOptions.from_params(params)
    raw_dir = root / RAW
    raw_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(raw_dir)
    previous = read_ledger(raw_dir)
    downloaded = {url for url, row in previous.items() if row["status"] == "ok"}
    sources = expand_sources(read_sources(root / SOURCES, base_dir=root, allow_file_urls=opts.allow_file_urls),
                             read_discovered(root / CATALOG), downloaded)
    rows = {s.url: previous[s.url] for s in sources if is_done(previous.get(s.url), raw_dir)}
    todo = [s for s in sources if s.url not in rows]
    log.info("%d sources: %d already downloaded, %d to fetch", len(sources), len(rows), len(todo))
    mirror = params.get("local_copies") or os.environ.get("DANCE3D_MEDIA") or ""
    copies = local_copies(Path(mirror) if mirror else None, {s.sha256 for s in todo if s.sha256})
    if copies:
        log.info("%d of %d sources are taken from local copies in %s", len(copies), len(todo), mirror)
    taken = {r["video_id"] for r in rows.values()} | {s.video_id for s in sources if s.video_id}
    fetcher = Fetcher(raw_dir, opts, taken, copies)
    failures: list[Failure] = []
    for source, row in fetcher.fetch_all(todo, int(params.get("workers", 1))):
        rows[source.url] = row
        if row["status"] == "failed":
            failures.append(Failure(source.where(SOURCES), "download", row["error_class"],
                                    f"{source.url}: {row['error_message']}", now()))
            log.warning("%s: %s: %s", source.where(SOURCES), source.url, row["error_message"])
        # after every item: nothing done is lost
        write_ledger(raw_dir, [rows[s.url] for s in sources if s.url in rows], params)
    write_ledger(raw_dir, [rows[s.url] for s in sources if s.url in rows], params)
    shutil.rmtree(raw_dir / ".incoming", ignore_errors=True)
    write_failures(raw_dir, "download", failures, total=len(sources))
    ok = sum(1 for r in rows.values() if r["status"] == "ok")
    log.info("ledger: %d ok, %d failed, of %d sources", ok, len(failures), len(sources))
    if fetcher.throttled:
        raise RateLimitedError(f"the site is rate limiting downloads ({ok} of {len(sources)} done); "
                               "wait a while (or raise download.sleep_interval) and re-run: finished videos are kept")
    check_failure_ratio("download", len(failures), len(sources), float(params.get("max_failure_ratio", 0.5)))


def main() -> int:
    setup_logging()
    return run_stage("download", run)


if __name__ == "__main__":
    sys.exit(main())
