"""trim stage: data/raw + annotations/segments.csv -> data/segments/<segment_id>.mp4 (+ .wav), index.parquet."""

from __future__ import annotations

import logging
import sys
from dataclasses import asdict
from pathlib import Path

import pipeline.ingest.media
import pipeline.ingest.trim
from pipeline.core.errors import InputErrors
from pipeline.core.itemstage import StageReport, WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import ANNOTATIONS, RAW, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint
from pipeline.ingest.catalog import INDEX, INDEX_VERSION, read_index, read_ledger, write_index
from pipeline.ingest.segments import plan_segments
from pipeline.ingest.trim import CutJob, TrimOptions, cut_job

log = logging.getLogger("dance3d.trim")
CODE = code_fingerprint(pipeline.ingest.trim, pipeline.ingest.media)


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "trim")
    opts = TrimOptions(fps=str(params.get("fps", "source")), max_side=int(params.get("max_side", 1280)),
                       crf=int(params.get("crf", 18)), preset=str(params.get("preset", "veryfast")))
    raw_dir, seg_dir = root / RAW, root / SEGMENTS
    ledger = read_ledger(raw_dir)
    available = {r["video_id"]: r for r in ledger.values() if r["status"] == "ok"}
    try:
        plan = plan_segments(root / ANNOTATIONS, {v: r["duration"] for v, r in available.items()},
                             known_videos={r["video_id"] for r in ledger.values() if r["video_id"]},
                             unannotated=str(params.get("unannotated", "skip")))
    except InputErrors as exc:
        for error in exc.errors:
            log.error("%s", error)
        raise
    previous = read_index(seg_dir)
    items = []
    for spec in plan:
        fp = fingerprint(INDEX_VERSION, available[spec.video_id]["sha256"], spec.start, spec.end, asdict(opts), CODE)
        job = CutJob(raw_dir / available[spec.video_id]["path"], spec, seg_dir, opts, fp)
        where = f"{ANNOTATIONS}:{spec.line}" if spec.line else spec.video_id
        items.append(WorkItem(spec.segment_id, fp, (seg_dir / f"{spec.segment_id}.mp4",), job, where))

    def up_to_date(item: WorkItem) -> bool:  # the fingerprints live in the index, not in the videos
        old = previous.get(item.item_id)
        return bool(old and old["fingerprint"] == item.fingerprint and (seg_dir / old["path"]).exists())

    def write(report: StageReport) -> None:  # before the failure ratio is checked: what was cut is kept
        rows = {**{s: previous[s] for s in report.skipped if s in previous}, **report.done}
        write_index(seg_dir, [rows[s.segment_id] for s in plan if s.segment_id in rows], params)
        log.info("index: %d segments, %d failed", len(rows), len(report.failures))

    run_item_stage("trim", items, cut_job, out_dirs=[seg_dir], params=params, up_to_date=up_to_date,
                   keep_files=frozenset({INDEX}), finish=write)


def main() -> int:
    setup_logging()
    return run_stage("trim", run)


if __name__ == "__main__":
    sys.exit(main())
