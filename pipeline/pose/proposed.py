"""The propose_segments stage's proposals file as later readers take it (trim, the review page,
``dance3d status``): its schema and reader live here, apart from ``propose``, which writes them, so a
reader never imports the proposer and the pose models behind it."""

from __future__ import annotations

from pathlib import Path

from pipeline.core.storage import item_files, read_meta, read_rows

SCHEMA_VERSION = 1


def read_proposals(path: Path) -> dict:
    """The metadata of a proposals file: video_id, duration, cuts, segments, shots (and the per-second table)."""
    meta = read_meta(path)
    return {**{k: meta[k] for k in ("video_id", "duration", "cuts", "segments", "shots")}, "seconds": read_rows(path)}


def proposals_by_video(folder: Path) -> dict[str, list[tuple[float, float, str]]]:
    """The propose_segments stage's proposals by video (start, end, why), as the trim stage takes
    them; none for a video it has not seen."""
    out = {}
    for path in item_files(folder):
        found = read_proposals(path)
        out[found["video_id"]] = [(s["start"], s["end"], f"proposed: {s['reason']}") for s in found["segments"]]
    return out
