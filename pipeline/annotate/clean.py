"""Apply a manifest to a segment's tracks: every kept span becomes clips of one dancer.

Inside a span, gaps of up to ``max_gap`` missing frames are filled by linear
interpolation of the box, keypoints, feet and hands (and marked ``interpolated``); a longer gap
splits the span into separate clips. Clips shorter than ``min_clip_seconds`` are dropped
and counted. Clip ids are ``<segment_id>_<track_id>_<k>``, k counting a track's clips
from 0 in time order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.annotate.clipfile import Clip
from pipeline.annotate.manifests import Span
from pipeline.pose.trackfile import SegmentTracks

if TYPE_CHECKING:
    from pipeline.annotate.proposals import ProposalOptions


@dataclass(frozen=True)
class CleanOptions:
    max_gap: int = 12              # missing frames filled by interpolation inside a span
    min_clip_seconds: float = 2.0  # shorter clips are dropped


@dataclass
class CleanResult:
    clips: list[Clip]
    dropped_short: int
    interpolated_frames: int


def _fill(frames: np.ndarray, values: np.ndarray, full: np.ndarray) -> np.ndarray:
    flat = values.reshape(len(values), -1)
    out = np.column_stack([np.interp(full, frames, flat[:, c]) for c in range(flat.shape[1])])
    return out.reshape((len(full),) + values.shape[1:]).astype(np.float32)


def apply_manifest(tracks: SegmentTracks, spans: list[Span], opts: CleanOptions) -> CleanResult:
    tolerance = 0.5 / tracks.fps
    clips: list[Clip] = []
    dropped = 0
    interpolated = 0
    counters: dict[int, int] = {}
    for span in sorted((s for s in spans if s.keep), key=lambda s: (s.track_id, s.start)):
        rows = tracks.of(span.track_id)
        rows = rows[(tracks.time[rows] >= span.start - tolerance) & (tracks.time[rows] <= span.end + tolerance)]
        if not len(rows):
            continue
        frames = tracks.frame[rows]
        breaks = np.flatnonzero(np.diff(frames) - 1 > opts.max_gap) + 1
        for piece in np.split(np.arange(len(rows)), breaks):
            f = frames[piece]
            full = np.arange(f[0], f[-1] + 1)
            if len(full) / tracks.fps < opts.min_clip_seconds:
                dropped += 1
                continue
            k = counters.get(span.track_id, 0)
            counters[span.track_id] = k + 1
            mask = ~np.isin(full, f)
            interpolated += int(mask.sum())
            picked = rows[piece]
            hands = {} if tracks.hands is None else {"hands_world": _fill(f, tracks.hands_world[picked], full),
                                                     "hand_presence": _fill(f, tracks.hands[picked, :, 0, 2], full)}
            clips.append(Clip(f"{tracks.segment_id}_{span.track_id}_{k}", span.track_id, full,
                              _fill(f, tracks.box[picked], full), _fill(f, tracks.keypoints[picked], full), mask,
                              _fill(f, tracks.feet[picked], full), **hands))
    return CleanResult(clips, dropped, interpolated)


# --- the clean stage's worker ------------------------------------------------------------

@dataclass(frozen=True)
class CleanJob:
    tracks: Path
    manifest: Path | None   # None: the proposal is accepted (clean.unannotated: accept)
    out: Path
    opts: CleanOptions
    proposal_opts: "ProposalOptions"
    params: dict
    inputs: dict
    fingerprint: str


def clean_segment(job: CleanJob) -> dict:
    """Apply the segment's manifest (already checked by the stage) or its proposal; write the clips."""
    from pipeline.annotate.clipfile import write_clean
    from pipeline.annotate.manifests import parse_manifest
    from pipeline.annotate.proposals import propose
    from pipeline.pose.pose2dfile import SegmentInfo
    from pipeline.pose.trackfile import read_tracks

    tracks = read_tracks(job.tracks)
    if job.manifest is not None:
        spans, source = parse_manifest(job.manifest)[0], "manifest"
    else:
        spans, source = propose(tracks, job.proposal_opts), "proposal"
    result = apply_manifest(tracks, spans, job.opts)
    segment = SegmentInfo(tracks.segment_id, tracks.fps, tracks.frames_total, tracks.width, tracks.height)
    write_clean(job.out, result.clips, segment, spans_from=source, dropped_short=result.dropped_short,
                fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"clips": len(result.clips), "clip_frames": sum(len(c.frame) for c in result.clips),
            "dropped_short": result.dropped_short, "interpolated_frames": result.interpolated_frames,
            "source": source, "fps": tracks.fps}
