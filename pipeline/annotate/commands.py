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
