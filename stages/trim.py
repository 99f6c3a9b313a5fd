"""trim stage: data/raw + annotations/segments.csv -> data/segments/<segment_id>.mp4 (+ .wav), index.parquet."""

from __future__ import annotations

import logging
import sys
from dataclasses import asdict
from pathlib import Path

import pyarrow as pa

import pipeline.ingest.media
import pipeline.ingest.trim
from pipeline.core.errors import InputErrors
from pipeline.core.executor import run_items
from pipeline.core.failures import Failure, check_failure_ratio, now, write_failures
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import ANNOTATIONS, RAW, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, remove_stale_temps, write_parquet
from pipeline.ingest.catalog import INDEX, read_index, read_ledger
from pipeline.ingest.media import probe
from pipeline.ingest.segments import SegmentSpec, plan_segments
from pipeline.ingest.trim import TrimOptions, cut_segment

log = logging.getLogger("dance3d.trim")
CODE = code_fingerprint(pipeline.ingest.trim, pipeline.ingest.media)

SCHEMA_VERSION = 1
INDEX_SCHEMA = pa.schema(
    [
        ("segment_id", pa.string()), ("video_id", pa.string()), ("start", pa.float64()), ("end", pa.float64()),
        ("fps", pa.float64()), ("fps_fraction", pa.string()), ("frames", pa.int32()),
        ("width", pa.int32()), ("height", pa.int32()), ("has_audio", pa.bool_()), ("label", pa.string()),
        ("path", pa.string()), ("wav_path", pa.string()), ("fingerprint", pa.string()),
    ]
)


def _cut(job: tuple) -> dict:
    src, spec, out_dir, opts, fp = job
    video = probe(src)
    row = cut_segment(src, video, spec, out_dir / f"{spec.segment_id}.mp4", out_dir / f"{spec.segment_id}.wav", opts)
    return {**row, "fingerprint": fp}


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
    seg_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(seg_dir)
    previous = read_index(seg_dir)
    rows: dict[str, dict] = {}
    jobs = []
    for spec in plan:
        src = raw_dir / available[spec.video_id]["path"]
        fp = fingerprint(SCHEMA_VERSION, available[spec.video_id]["sha256"], spec.start, spec.end, asdict(opts), CODE)
        old = previous.get(spec.segment_id)
        if old and old["fingerprint"] == fp and (seg_dir / old["path"]).exists():
            rows[spec.segment_id] = old
        else:
            jobs.append((src, spec, seg_dir, opts, fp))
    _remove_stale(seg_dir, {s.segment_id for s in plan})
    log.info("%d segments planned: %d up to date, %d to cut", len(plan), len(rows), len(jobs))
    failures = []
    executor = "ray" if params.get("executor") == "ray" else "process"
    for outcome in run_items(_cut, jobs, workers=int(params.get("workers", 1)), kind=executor, desc="trim",
                             unit="segment", ray_options=params.get("ray") or {}):
        spec: SegmentSpec = outcome.item[1]
        if outcome.ok:
            rows[spec.segment_id] = outcome.value
        else:
            where = f"{ANNOTATIONS}:{spec.line}" if spec.line else spec.video_id
            message = f"{where}: {outcome.error_message}"
            failures.append(Failure(spec.segment_id, "trim", outcome.error_class, message, now()))
            log.warning("%s: %s", spec.segment_id, outcome.error_message)
    ordered = [rows[s.segment_id] for s in plan if s.segment_id in rows]
    write_parquet(pa.Table.from_pylist(ordered, schema=INDEX_SCHEMA), seg_dir / INDEX,
                  schema_version=SCHEMA_VERSION, params=params)
    write_failures(seg_dir, "trim", failures, total=len(plan))
    log.info("index: %d segments, %d failed", len(ordered), len(failures))
    check_failure_ratio("trim", len(failures), len(plan), float(params.get("max_failure_ratio", 0.2)))


def _remove_stale(seg_dir: Path, keep: set[str]) -> None:
    """Segments no longer annotated must not feed later stages."""
    for path in sorted(seg_dir.glob("*.mp4")) + sorted(seg_dir.glob("*.wav")):
        if path.stem not in keep:
            log.info("removing %s: no longer in %s", path.name, ANNOTATIONS)
            path.unlink()


def main() -> int:
    setup_logging()
    return run_stage("trim", run)


if __name__ == "__main__":
    sys.exit(main())
