"""Proposed manifests: which tracks look like real dancers, and where a track seems to jump.

An annotator should mostly confirm. A track is proposed ``keep=no``, with the reason, when
it is too short, much smaller than the segment's main dancers, nearly static (against the
group too: dancers who move together get one verdict), poorly
seen (low keypoint confidence), or its legs are not seen (seated behind instruments, cut
off by the frame: no use for 3D dance, and the usual look of musicians and audience). A
kept track is cut in two where it jumps: a sudden large displacement, or a break in
keypoint similarity between neighbouring frames, which is what an id swap between two people looks like.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.annotate.manifests import Span
from pipeline.pose.trackfile import SegmentTracks
from pipeline.pose.tracking import oks_matrix


@dataclass(frozen=True)
class ProposalOptions:
    min_track_seconds: float = 2.0     # shorter tracks: keep=no (too short)
    min_relative_height: float = 0.5   # median box height below this share of the tallest main track: small
    min_motion: float = 0.035          # motion energy below this: static (audience, seated people) ...
    static_share: float = 0.5          # ... unless the main dancers move and this one moves at least this share as much
    min_score: float = 0.3             # mean keypoint confidence below this: poorly seen
    min_leg_score: float = 0.5         # mean confidence of hips, knees and ankles below this: legs not seen
    jump_ratio: float = 0.5            # centre moves more than this x box height in one step: cut
    swap_oks: float = 0.2              # keypoint similarity between neighbouring frames below this: cut
    kp_min_score: float = 0.2


@dataclass(frozen=True)
class TrackStats:
    track_id: int
    frames: int
    start: float
    end: float
    mean_score: float
    box_height: float   # median box height / frame height
    motion: float       # median over joints of the spread of their position over time / median box height
    leg_score: float = 1.0  # mean confidence of the hips, knees and ankles


def track_stats(tracks: SegmentTracks, track_id: int, kp_min_score: float = 0.2) -> TrackStats:
    rows = tracks.of(track_id)
    kps = tracks.keypoints[rows]
    heights = tracks.box[rows, 3] - tracks.box[rows, 1]
    median_h = float(np.median(heights))
    confident = kps[:, :, 2] >= kp_min_score
    spreads = []
    for j in range(17):
        pts = kps[confident[:, j], j, :2]
        if len(pts) >= 3:
            spreads.append(float(np.sqrt(pts.var(axis=0).sum())))
    # The median ignores a lone noisy joint (a jittering ankle behind a musician's instrument).
    motion = float(np.median(spreads)) / max(median_h, 1.0) if spreads else 0.0
    return TrackStats(track_id, len(rows), float(tracks.time[rows[0]]), float(tracks.time[rows[-1]]),
                      float(kps[:, :, 2].mean()), median_h / tracks.height, motion, float(kps[:, 11:, 2].mean()))


def jump_points(tracks: SegmentTracks, track_id: int, opts: ProposalOptions) -> list[int]:
    """Row positions (within the track) where a new piece should start."""
    rows = tracks.of(track_id)
    cuts = []
    for k in range(1, len(rows)):
        a, b = rows[k - 1], rows[k]
        if tracks.frame[b] - tracks.frame[a] > 2:
            continue  # across a gap the tracker already judged the match
        box_a, box_b = tracks.box[a], tracks.box[b]
        h = max(box_a[3] - box_a[1], box_b[3] - box_b[1], 1.0)
        centre_move = np.hypot(*((box_b[:2] + box_b[2:]) / 2 - (box_a[:2] + box_a[2:]) / 2))
        area = (box_b[2] - box_b[0]) * (box_b[3] - box_b[1])
        oks = oks_matrix(tracks.keypoints[a][None], tracks.keypoints[b][None], np.array([area]), opts.kp_min_score)
        if centre_move > opts.jump_ratio * h or oks[0, 0] < opts.swap_oks:
            cuts.append(k)
    return cuts


def main_tracks(stats: list[TrackStats], main_height: float, opts: ProposalOptions) -> list[TrackStats]:
    """The segment's main dancers: tracks long enough and not much smaller than the tallest."""
    return [s for s in stats if s.end - s.start >= opts.min_track_seconds
            and s.box_height >= opts.min_relative_height * main_height]


def group_motion(stats: list[TrackStats], main_height: float, opts: ProposalOptions) -> float:
    """The median motion of the segment's main dancers (NaN without any)."""
    main = main_tracks(stats, main_height, opts)
    return float(np.median([s.motion for s in main])) if main else float("nan")


def is_static(motion: float, group: float, opts: ProposalOptions) -> bool:
    """Below the fixed threshold, and either the main dancers hardly move either or this track
    moves much less than they do. A fixed threshold alone split a trio dancing one choreography
    (0.035, 0.037, 0.038 against 0.035): dancers who move together must get one verdict."""
    if motion >= opts.min_motion:
        return False
    return not group >= opts.min_motion or motion < opts.static_share * group  # NaN group: no main dancers


def reject_reason(stats: TrackStats, main_height: float, opts: ProposalOptions, group: float = float("nan")) -> str:
    """Why a track is not proposed as a dancer ('' when it is); ``group``: ``group_motion``."""
    reasons = []
    if stats.end - stats.start < opts.min_track_seconds:
        reasons.append(f"too short ({stats.end - stats.start:.1f} s < {opts.min_track_seconds} s)")
    if stats.box_height < opts.min_relative_height * main_height:
        reasons.append(f"small ({stats.box_height:.2f} of frame height vs {main_height:.2f} for the main dancers)")
    if is_static(stats.motion, group, opts):
        beside = f", the group's {group:.3f}" if np.isfinite(group) else ""
        reasons.append(f"nearly static (motion {stats.motion:.3f} < {opts.min_motion}{beside})")
    if stats.mean_score < opts.min_score:
        reasons.append(f"low keypoint confidence ({stats.mean_score:.2f} < {opts.min_score})")
    if stats.leg_score < opts.min_leg_score:
        reasons.append(f"legs not seen (seated or cut off: leg confidence {stats.leg_score:.2f} "
                       f"< {opts.min_leg_score})")
    return "; ".join(reasons)


def propose(tracks: SegmentTracks, opts: ProposalOptions = ProposalOptions()) -> list[Span]:
    """Proposed spans for every track of a segment."""
    stats = {t: track_stats(tracks, t, opts.kp_min_score) for t in tracks.ids}
    long_enough = [s.box_height for s in stats.values() if s.end - s.start >= opts.min_track_seconds]
    main_height = max(long_enough or [s.box_height for s in stats.values()] or [0.0])
    group = group_motion(list(stats.values()), main_height, opts)
    spans: list[Span] = []
    for track_id, st in stats.items():
        info = {"frames": st.frames, "mean_score": f"{st.mean_score:.2f}", "box_height": f"{st.box_height:.2f}",
                "motion": f"{st.motion:.3f}"}
        reason = reject_reason(st, main_height, opts, group)
        if reason:
            spans.append(Span(track_id, st.start, st.end, False, info={**info, "reason": reason}))
            continue
        rows = tracks.of(track_id)
        bounds = [0, *jump_points(tracks, track_id, opts), len(rows)]
        for k, (lo, hi) in enumerate(zip(bounds, bounds[1:])):
            start, end = float(tracks.time[rows[lo]]), float(tracks.time[rows[hi - 1]])
            if end <= start:
                continue
            why = "looks like a dancer"
            if len(bounds) > 2:
                why = f"cut at a sudden jump (possible id swap near {end:.3f} s): check" if hi < len(rows) else \
                    "after a sudden jump (possible id swap): check"
            spans.append(Span(track_id, start, end, True, info={**info, "reason": why}))
    return sorted(spans, key=lambda s: (s.track_id, s.start))
