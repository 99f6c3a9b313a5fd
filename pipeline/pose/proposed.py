"""The propose_segments stage's proposals as the trim stage takes them. Apart from ``propose``,
which writes and reads them, so the segments floor below never imports the proposer above it."""

from __future__ import annotations

from pathlib import Path

from pipeline.core.storage import item_files
from pipeline.pose.propose import read_proposals


def proposals_by_video(folder: Path) -> dict[str, list[tuple[float, float, str]]]:
    """The propose_segments stage's proposals by video (start, end, why), as the trim stage takes
    them; none for a video it has not seen."""
    out = {}
    for path in item_files(folder):
        found = read_proposals(path)
        out[found["video_id"]] = [(s["start"], s["end"], f"proposed: {s['reason']}") for s in found["segments"]]
    return out
