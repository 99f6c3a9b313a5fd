"""clean stage: data/tracks + manifests/tracks -> data/clean/<segment_id>.parquet (one row per clip frame;
pipeline/annotate/clean.py), metrics/clean.json (headline) and reports/clean.json."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pipeline.annotate.clean
import pipeline.annotate.clipfile
import pipeline.annotate.manifests
import pipeline.annotate.proposals
from pipeline.annotate.clean import CleanJob, CleanOptions, clean_segment
from pipeline.annotate.clipfile import SCHEMA_VERSION
from pipeline.annotate.commands import clean_metrics, proposal_options, refuse_invalid_manifests, tracked_segments
from pipeline.core.errors import InputError
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.metrics import write_metrics
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CLEAN, TRACK_MANIFESTS, TRACKS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, read_meta, sha256_file

log = logging.getLogger("dance3d.clean")
UNANNOTATED = ("accept", "skip")
CODE = code_fingerprint(pipeline.annotate.clean, pipeline.annotate.clipfile, pipeline.annotate.manifests,
                        pipeline.annotate.proposals, "pipeline.pose.tracking", "pipeline.pose.pose2dfile")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "clean")
    all_params = load_params(root / "params.yaml")
    opts = CleanOptions(max_gap=int(params.get("max_gap", 12)),
                        min_clip_seconds=float(params.get("min_clip_seconds", 2.0)))
    policy = str(params.get("unannotated", "accept"))
    if policy not in UNANNOTATED:
        raise InputError(root / "params.yaml", f"clean.unannotated must be one of {UNANNOTATED}, not {policy!r}")
    proposal_opts = proposal_options(all_params)
    segments = tracked_segments(root)
    refuse_invalid_manifests(root, opts.min_clip_seconds)
    items, skipped = [], []
    for seg_id in segments:
        tracks_file = root / TRACKS / f"{seg_id}.parquet"
        manifest = root / TRACK_MANIFESTS / f"{seg_id}.csv"
        if not manifest.exists():
            if policy == "skip":
                skipped.append(seg_id)
                continue
            manifest = None
        inputs = {"tracks": read_meta(tracks_file).get("fingerprint", ""),
                  "manifest": sha256_file(manifest) if manifest else f"proposal:{proposal_opts}"}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / CLEAN / f"{seg_id}.parquet"
        job = CleanJob(tracks_file, manifest, out, opts, proposal_opts, params, inputs, fp)
        items.append(WorkItem(seg_id, fp, (out,), job))
    if skipped:
        log.info("skipping %d segments without a manifest (clean.unannotated: skip): %s", len(skipped),
                 ", ".join(skipped))
    run_item_stage("clean", items, clean_segment, out_dirs=[root / CLEAN], params=params, light=True)
    write_metrics(root, "clean", clean_metrics(root, skipped))


def main() -> int:
    setup_logging()
    return run_stage("clean", run)


if __name__ == "__main__":
    sys.exit(main())
