"""Pose-aware online multi-person tracking, in the spirit of LightTrack / OC-SORT.

Each frame, every live track predicts its box with a constant-velocity model. The cost
of pairing a track with a detection is ``1 - (w * IoU + (1 - w) * OKS)`` between the
prediction and the detection (box overlap and keypoint similarity); the Hungarian method
(scipy) picks the cheapest pairs, and pairs costing more than ``max_cost`` are refused.
A detection left over starts a tentative track; a track becomes real after ``min_hits``
matches (and then keeps its earlier detections too, since a segment is processed whole);
a track not matched for ``max_age`` frames ends, so people who are hidden briefly get
their id back. Detections of tracks that never became real get track id -1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.pose.boxes import iou_matrix
from pipeline.pose.pose2dfile import COCO_SIGMAS

UNTRACKED = -1


@dataclass(frozen=True)
class TrackerOptions:
    iou_weight: float = 0.5      # w in the similarity w * IoU + (1 - w) * OKS
    max_cost: float = 0.75       # pairs with 1 - similarity above this are never matched
    min_hits: int = 3            # matches before a track gets an id
    max_age: int = 24            # frames a lost track waits to be re-associated
    kp_min_score: float = 0.2    # keypoints below this confidence are ignored by OKS
    velocity_smoothing: float = 0.6  # weight of the newest velocity estimate
    stitch_gap: int = 12         # a track starting this close to another's end, where that one stood, continues it
    stitch_iou: float = 0.5      # ... when its first boxes overlap the other's last sure ones this much


def oks_matrix(kp_a: np.ndarray, kp_b: np.ndarray, areas: np.ndarray, min_score: float) -> np.ndarray:
    """Object keypoint similarity between poses (Na x 17 x 3) and (Nb x 17 x 3).

    ``areas`` (Nb) are the detection boxes' areas, the scale of OKS. Only keypoints
    confident in both poses count; a pair with none shares similarity 0.
    """
    if not len(kp_a) or not len(kp_b):
        return np.zeros((len(kp_a), len(kp_b)))
    d2 = ((kp_a[:, None, :, :2] - kp_b[None, :, :, :2]) ** 2).sum(-1)
    k2 = (2 * COCO_SIGMAS) ** 2
    e = d2 / (2 * np.maximum(areas, 1.0)[None, :, None] * k2[None, None, :])
    both = (kp_a[:, None, :, 2] >= min_score) & (kp_b[None, :, :, 2] >= min_score)
    counts = both.sum(-1)
    sims = (np.exp(-e) * both).sum(-1)
    return np.where(counts > 0, sims / np.maximum(counts, 1), 0.0)


@dataclass
class _Track:
    box: np.ndarray
    keypoints: np.ndarray
    last_frame: int
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(4))
    hits: int = 1
    detections: list[int] = field(default_factory=list)
    track_id: int = UNTRACKED

    def predict(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        dt = frame - self.last_frame
        box = self.box + self.velocity * dt
        shift = (self.velocity[:2] + self.velocity[2:]) / 2 * dt
        keypoints = self.keypoints.copy()
        keypoints[:, :2] += shift
        return box, keypoints

    def update(self, box: np.ndarray, keypoints: np.ndarray, frame: int, index: int, alpha: float) -> None:
        dt = max(1, frame - self.last_frame)
        self.velocity = alpha * (box - self.box) / dt + (1 - alpha) * self.velocity
        self.box, self.keypoints, self.last_frame = box, keypoints, frame
        self.hits += 1
        self.detections.append(index)


def assign_tracks(frames: np.ndarray, boxes: np.ndarray, keypoints: np.ndarray,
                  opts: TrackerOptions = TrackerOptions()) -> np.ndarray:
    """Track ids (int32, -1 = not part of any real track) for detections sorted by frame.

    ``frames`` (N), ``boxes`` (N x 4) and ``keypoints`` (N x 17 x 3) describe every
    detection of a segment. Ids are 1, 2, ... in the order the tracks become real.
    """
    from scipy.optimize import linear_sum_assignment  # here: clean's up-to-date check reaches this module

    ids = np.full(len(frames), UNTRACKED, np.int32)
    if not len(frames):
        return ids
    if np.any(np.diff(frames) < 0):
        raise ValueError("detections must be sorted by frame")
    live: list[_Track] = []
    next_id = 1
    starts = np.flatnonzero(np.r_[True, np.diff(frames) != 0])
    ends = np.r_[starts[1:], len(frames)]
    for start, end in zip(starts, ends):
        frame = int(frames[start])
        live = [t for t in live if frame - t.last_frame <= opts.max_age]
        det_idx = np.arange(start, end)
        det_boxes, det_kps = boxes[start:end].astype(np.float64), keypoints[start:end].astype(np.float64)
        matched_dets: set[int] = set()
        if live:
            predicted = [t.predict(frame) for t in live]
            pred_boxes = np.stack([p[0] for p in predicted])
            pred_kps = np.stack([p[1] for p in predicted])
            areas = (det_boxes[:, 2] - det_boxes[:, 0]) * (det_boxes[:, 3] - det_boxes[:, 1])
            similarity = (opts.iou_weight * iou_matrix(pred_boxes, det_boxes)
                          + (1 - opts.iou_weight) * oks_matrix(pred_kps, det_kps, areas, opts.kp_min_score))
            cost = 1.0 - similarity
            rows, cols = linear_sum_assignment(np.where(cost <= opts.max_cost, cost, 1e6))
            for r, c in zip(rows, cols):
                if cost[r, c] > opts.max_cost:
                    continue
                track = live[r]
                track.update(det_boxes[c], det_kps[c], frame, int(det_idx[c]), opts.velocity_smoothing)
                matched_dets.add(c)
                if track.track_id == UNTRACKED and track.hits >= opts.min_hits:
                    track.track_id = next_id
                    next_id += 1
                    ids[track.detections] = track.track_id  # its tentative past too
                elif track.track_id != UNTRACKED:
                    ids[det_idx[c]] = track.track_id
        for c in range(len(det_idx)):
            if c not in matched_dets:
                track = _Track(det_boxes[c], det_kps[c], frame, detections=[int(det_idx[c])])
                if opts.min_hits <= 1:
                    track.track_id = next_id
                    next_id += 1
                    ids[track.detections] = track.track_id
                live.append(track)
    return stitch_tracks(frames, boxes, ids, opts.stitch_gap, opts.stitch_iou)


def _median_box(boxes: np.ndarray) -> np.ndarray:
    return np.median(boxes, axis=0)[None]


def stitch_tracks(frames: np.ndarray, boxes: np.ndarray, ids: np.ndarray, max_gap: int = 12, min_iou: float = 0.5,
                  tail: int = 3) -> np.ndarray:
    """Ids with broken tracks joined: a track B that starts within ``max_gap`` frames of a track
    A's end (A ending at most ``tail`` frames after B starts), whose first boxes overlap A's last
    sure ones (before B began and before A's last ``tail`` frames) by ``min_iou``, is A. A's
    detections from B's start on are dropped: they are what broke it (a box that swallowed two
    dancers, or another person's). Seen in the shared duet: for two frames the woman's box grew
    over her partner, her track followed it and was lost, and she came back under a new id."""
    ids = ids.copy()
    real = ids >= 0
    spans = {int(t): [int(frames[ids == t].min()), int(frames[ids == t].max())] for t in np.unique(ids[real])}
    for b in sorted(spans, key=lambda t: spans[t][0]):
        if b not in spans:
            continue
        b_start = spans[b][0]
        b_rows = np.flatnonzero(ids == b)[:5]
        best, best_iou = None, min_iou
        for a, (a_start, a_end) in spans.items():
            if a == b or a_start >= b_start or not b_start - max_gap <= a_end <= b_start + tail:
                continue
            sure = np.flatnonzero((ids == a) & (frames < min(b_start, a_end - tail + 1)))[-5:]
            if not len(sure):
                continue
            overlap = float(iou_matrix(_median_box(boxes[sure]), _median_box(boxes[b_rows]))[0, 0])
            if overlap >= best_iou:
                best, best_iou = a, overlap
        if best is not None:
            ids[(ids == best) & (frames >= b_start)] = UNTRACKED
            ids[ids == b] = best
            spans[best][1] = spans.pop(b)[1]
    return ids


# --- the track stage's worker ------------------------------------------------------------

@dataclass(frozen=True)
class TrackJob:
    pose2d: Path
    out: Path
    qc_out: Path | None   # None: no QC video
    video: SegmentVideo   # the segment, for the QC video
    opts: TrackerOptions
    params: dict
    fingerprint: str


def track_segment(job: TrackJob) -> dict:
    from pipeline.pose.pose2dfile import read_pose2d
    from pipeline.pose.qc import render_qc
    from pipeline.pose.trackfile import write_tracks

    pose2d = read_pose2d(job.pose2d)
    poses = pose2d.poses
    ids = assign_tracks(poses.frame, poses.box, poses.keypoints, job.opts)
    write_tracks(job.out, job.pose2d, poses, ids, pose2d.segment, fingerprint=job.fingerprint, params=job.params,
                 inputs={"pose2d": pose2d.fingerprint})
    if job.qc_out is not None:
        render_qc(job.video, pose2d.segment.fps, poses.frame, ids, poses.box, poses.keypoints, job.qc_out,
                  kp_min_score=job.opts.kp_min_score, feet=poses.feet, drawn=poses.interpolated_mask(),
                  hands=poses.hands)
    real = ids[ids >= 0]
    return {"tracks": int(len(np.unique(real))), "untracked": int((ids < 0).sum())}
