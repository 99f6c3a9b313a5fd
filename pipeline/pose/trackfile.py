"""Reading a ``data/tracks/<segment_id>.parquet`` file into arrays."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from pipeline.core.storage import read_meta


@dataclass(frozen=True)
class SegmentTracks:
    segment_id: str
    fps: float
    frames_total: int      # frames in the segment
    width: int
    height: int
    frame: np.ndarray      # N int, sorted
    time: np.ndarray       # N float
    track_id: np.ndarray   # N int (-1: not a real track)
    box: np.ndarray        # N x 4
    keypoints: np.ndarray  # N x 17 x 3
    fingerprint: str

    def of(self, track_id: int) -> np.ndarray:
        """Row indices of one track, in frame order."""
        return np.flatnonzero(self.track_id == track_id)

    @property
    def ids(self) -> list[int]:
        return sorted(int(t) for t in np.unique(self.track_id) if t >= 0)


def load_tracks(path: Path) -> SegmentTracks:
    table = pq.read_table(path)
    meta = read_meta(path)
    return SegmentTracks(
        segment_id=meta.get("segment_id") or Path(path).stem,
        fps=float(meta["fps"]),
        frames_total=int(meta["frames"]),
        width=int(meta["width"]),
        height=int(meta["height"]),
        frame=table.column("frame").to_numpy().astype(np.int64),
        time=table.column("time").to_numpy(),
        track_id=table.column("track_id").to_numpy().astype(np.int64),
        box=np.asarray(table.column("box").combine_chunks().flatten(), np.float32).reshape(-1, 4),
        keypoints=np.asarray(table.column("keypoints").combine_chunks().flatten(), np.float32).reshape(-1, 17, 3),
        fingerprint=str(meta.get("fingerprint", "")),
    )
