"""trim stage: data/raw + annotations/segments.csv (+ data/segment_proposals) -> data/segments/index.parquet.

Each segment is a view on its downloaded video (pipeline/ingest/trim.py): the index gives its
clock, size and source; no video or audio is copied."""

from __future__ import annotations

import logging
import sys
from dataclasses import asdict
from pathlib import Path

import pipeline.ingest.media
import pipeline.ingest.segmentvideo
import pipeline.ingest.trim
from pipeline.core.errors import InputErrors
from pipeline.core.itemstage import StageReport, WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import ANNOTATIONS, RAW, SEGMENT_PROPOSALS, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint
from pipeline.ingest.catalog import INDEX, INDEX_VERSION, read_index, read_ledger, write_index
from pipeline.ingest.segments import plan_segments, remove_segment_copies
from pipeline.ingest.trim import PlanJob, TrimOptions, plan_job
from pipeline.pose.proposed import proposals_by_video

log = logging.getLogger("dance3d.trim")
CODE = code_fingerprint(pipeline.ingest.trim, pipeline.ingest.segmentvideo, pipeline.ingest.media,
                        "pipeline.ingest.segments")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "trim")
    opts = TrimOptions(fps=str(params.get("fps", "source")), max_side=int(params.get("max_side", 1280)))
    raw_dir, seg_dir = root / RAW, root / SEGMENTS
    ledger = read_ledger(raw_dir)
    available = {r["video_id"]: r for r in ledger.values() if r["status"] == "ok"}
    unannotated = str(params.get("unannotated", "skip"))
    proposed = proposals_by_video(root / SEGMENT_PROPOSALS) if unannotated == "proposals" else {}
    try:
        plan = plan_segments(root / ANNOTATIONS, {v: r["duration"] for v, r in available.items()},
                             known_videos={r["video_id"] for r in ledger.values() if r["video_id"]},
                             unannotated=unannotated, proposed=proposed)
    except InputErrors as exc:
        for error in exc.errors:
            log.error("%s", error)
        raise
    previous = read_index(seg_dir)
    items = []
    for spec in plan:
        fp = fingerprint(INDEX_VERSION, available[spec.video_id]["sha256"], spec.start, spec.end, asdict(opts), CODE)
        job = PlanJob(raw_dir / available[spec.video_id]["path"], spec, opts, fp)
        where = f"{ANNOTATIONS}:{spec.line}" if spec.line else spec.video_id
        items.append(WorkItem(spec.segment_id, fp, (), job, where))

    def up_to_date(item: WorkItem) -> bool:  # the fingerprints live in the index
        old = previous.get(item.item_id)
        return bool(old and old["fingerprint"] == item.fingerprint and (raw_dir / old["source"]).exists())

    def write(report: StageReport) -> None:  # before the failure ratio is checked: what was cut is kept
        rows = {**{s: previous[s] for s in report.skipped if s in previous}, **report.done}
        write_index(seg_dir, [rows[s.segment_id] for s in plan if s.segment_id in rows], params)
        log.info("index: %d segments, %d failed", len(rows), len(report.failures))

    if removed := remove_segment_copies(seg_dir):
        log.info("removed %d segment copies made before segments became views on data/raw", removed)
    run_item_stage("trim", items, plan_job, out_dirs=[seg_dir], params=params, up_to_date=up_to_date,
                   keep_files=frozenset({INDEX}), finish=write, light=True)  # plans: a probe each


def main() -> int:
    setup_logging()
    return run_stage("trim", run)


if __name__ == "__main__":
    sys.exit(main())
