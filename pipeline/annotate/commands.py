"""The annotator's commands: seed proposal manifests, check manifests."""

from __future__ import annotations

import logging
from dataclasses import fields
from pathlib import Path

from pipeline.annotate.manifests import Problem, check_manifest_file, write_manifest
from pipeline.annotate.proposals import ProposalOptions, propose
from pipeline.core.paths import TRACK_MANIFESTS, TRACKS
from pipeline.core.storage import item_files
from pipeline.pose.trackfile import read_tracks

log = logging.getLogger(__name__)


def proposal_options(params: dict) -> ProposalOptions:
    section = params.get("proposals") or {}
    known = {f.name for f in fields(ProposalOptions)}
    return ProposalOptions(**{k: v for k, v in section.items() if k in known})


def tracked_segments(root: Path) -> list[str]:
    return [p.stem for p in item_files(root / TRACKS)]


def seed_manifests(root: Path, opts: ProposalOptions) -> tuple[list[Path], list[Path]]:
    """Write a proposal manifest for every tracked segment without one; never overwrite.

    Returns (written, kept) paths.
    """
    written, kept = [], []
    for seg_id in tracked_segments(root):
        path = root / TRACK_MANIFESTS / f"{seg_id}.csv"
        if path.exists():
            kept.append(path)
            continue
        tracks = read_tracks(root / TRACKS / f"{seg_id}.parquet")
        write_manifest(path, propose(tracks, opts), tracks.fingerprint)
        written.append(path)
    return written, kept


def check_manifests(root: Path, files: list[Path] | None, min_clip_seconds: float) -> list[Problem]:
    """Problems of the given manifests (default: all in manifests/tracks), errors and warnings."""
    folder = root / TRACK_MANIFESTS
    if not files:
        files = sorted(folder.glob("*.csv")) if folder.exists() else []
    problems: list[Problem] = []
    for path in files:
        problems.extend(check_manifest_file(Path(path), root / TRACKS, min_clip_seconds)[1])
    return problems


def refuse_invalid_manifests(root: Path, min_clip_seconds: float) -> None:
    """What the clean stage does first: `dance3d manifests check`, logging warnings, and refusing
    invalid manifests with every error named (file, line, reason)."""
    import logging

    from pipeline.core.errors import InputError, InputErrors

    log = logging.getLogger("dance3d.clean")
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


def clean_metrics(root: Path, skipped: list[str]) -> dict:
    """reports/clean.json (headline in metrics/): every segment's current clean output (new and up to date) summed."""
    from pipeline.annotate.clipfile import read_clean
    from pipeline.core.paths import CLEAN
    from pipeline.core.storage import item_files

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
    return {"segments_from_manifests": sources["manifest"], "segments_from_proposals": sources["proposal"],
            "segments_skipped": len(skipped), "clips": clips, "clip_minutes": round(minutes, 3),
            "interpolated_frame_share": round(interpolated / clip_frames, 4) if clip_frames else 0.0,
            "dropped_short_clips": dropped}
