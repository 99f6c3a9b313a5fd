"""clean stage: data/tracks + manifests/tracks -> data/clean/<segment_id>.parquet (one row per clip frame)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pipeline.annotate.clean
import pipeline.annotate.clipfile
import pipeline.annotate.manifests
import pipeline.annotate.proposals
from pipeline.annotate.clean import CleanJob, CleanOptions, clean_segment
from pipeline.annotate.clipfile import SCHEMA_VERSION, read_clean
from pipeline.annotate.commands import check_manifests, proposal_options, tracked_segments
from pipeline.core.errors import InputError, InputErrors
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CLEAN, METRICS, TRACK_MANIFESTS, TRACKS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import (
    code_fingerprint,
    fingerprint,
    item_files,
    read_meta,
    sha256_file,
    write_json,
)

log = logging.getLogger("dance3d.clean")
UNANNOTATED = ("accept", "skip")
CODE = code_fingerprint(pipeline.annotate.clean, pipeline.annotate.clipfile, pipeline.annotate.manifests,
                        pipeline.annotate.proposals)


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
    _refuse_invalid_manifests(root, opts.min_clip_seconds)
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
    _write_metrics(root, skipped)


def _refuse_invalid_manifests(root: Path, min_clip_seconds: float) -> None:
    """The clean stage runs `dance3d manifests check` and refuses invalid manifests, naming them."""
    errors: list[InputError] = []
    for problem in check_manifests(root, None, min_clip_seconds):
        if problem.warning:
            log.warning("%s", problem)
        else:
            errors.append(InputError(problem.path, problem.message, problem.line))
    if errors:
        for error in errors:
            log.error("%s", error)
        raise InputErrors(errors)


def _write_metrics(root: Path, skipped: list[str]) -> None:
    """metrics/clean.json summarises every segment's current output (new and up to date)."""
    clips = clip_frames = dropped = interpolated = 0
    sources = {"manifest": 0, "proposal": 0}
    minutes = 0.0
    for path in item_files(root / CLEAN):
        clean = read_clean(path)
        frames = sum(len(c.frame) for c in clean.clips)
        clips += len(clean.clips)
        clip_frames += frames
        interpolated += int(sum(c.interpolated.sum() for c in clean.clips))
        minutes += frames / clean.segment.fps / 60
        sources[clean.spans_from] += 1
        dropped += clean.dropped_short
    metrics = {"segments_from_manifests": sources["manifest"], "segments_from_proposals": sources["proposal"],
               "segments_skipped": len(skipped), "clips": clips, "clip_minutes": round(minutes, 3),
               "interpolated_frame_share": round(interpolated / clip_frames, 4) if clip_frames else 0.0,
               "dropped_short_clips": dropped}
    write_json(root / METRICS / "clean.json", metrics)


def main() -> int:
    setup_logging()
    return run_stage("clean", run)


if __name__ == "__main__":
    sys.exit(main())
