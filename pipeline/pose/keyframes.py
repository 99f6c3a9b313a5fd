"""2D on keyframes: the models pose every k-th frame, and the frames between are interpolated.

A dancer's 2D keypoints change smoothly over a few frames at 24-60 fps, while the pose models
cost the same on every frame: running them on every k-th frame (``pose2d.fps``, the keyframes'
rate) and drawing each person's keypoints, feet and box linearly between two
keyframes divides the models' work by k. A person is followed from one keyframe to the next by
their boxes' overlap; a person seen on only one of the two keyframes is held from it over the
half of the gap nearer to it.
A joint is as confident in between as it is on the less confident of its two keyframes.
Where the two keyframes' people differ (someone came or went: :func:`people_change`), the frames
between are looked at: the detector runs on each, and the boxes that are none of the people on both
keyframes (:func:`newcomers`) are posed there, while those people are still drawn.
(Measured against posing every frame in ``benchmarks/pose2d_fastpath.py``; docs/pipeline/pose2d.md, "2D speed".)
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterator, Mapping

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.pose.boxes import iou_matrix

MIN_IOU = 0.2  # two keyframes' boxes overlapping less than this are not the same person
CHANGE_MIN_HEIGHT = 0.3  # people_change: a person this tall (share of the tallest) coming or going counts


def keyframe_step(source_fps: float, pose_fps: float) -> int:
    """Every how many frames the models run so they run at least ``pose_fps`` times a second
    (0: every frame). 24 fps at 12: every 2nd; 30 at 12: every 2nd; 60 at 12: every 5th."""
    if pose_fps <= 0 or source_fps <= 0:
        return 1
    return max(1, math.floor(source_fps / pose_fps + 1e-9))


def match_people(a: np.ndarray, b: np.ndarray, min_iou: float = MIN_IOU) -> list[tuple[int, int]]:
    """Pairs (i, j) of boxes ``a[i]`` and ``b[j]`` (N x 4) that are one person: the assignment of
    greatest total overlap, pairs under ``min_iou`` dropped."""
    if not len(a) or not len(b):
        return []
    iou = iou_matrix(np.asarray(a, np.float64), np.asarray(b, np.float64))
    rows, cols = linear_sum_assignment(-iou)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if iou[i, j] >= min_iou]


def people_change(a: Any, b: Any, min_height: float = CHANGE_MIN_HEIGHT) -> bool:
    """Whether someone is on only one of two keyframes' people (they came in or went out of sight,
    or the ``top_k`` largest changed), at least ``min_height`` of the tallest person's height:
    there, drawing the frames between would guess. (Smaller people who flicker in and out, mostly
    weak boxes far behind a dancer, do not count.)"""
    pairs = match_people(a.boxes, b.boxes)
    if len(pairs) == max(len(a.scores), len(b.scores)):
        return False
    heights = [people.boxes[:, 3] - people.boxes[:, 1] for people in (a, b)]
    tallest = max(float(h.max(initial=0.0)) for h in heights)
    lone = np.concatenate([np.delete(heights[0], [i for i, _ in pairs]), np.delete(heights[1], [j for _, j in pairs])])
    return bool((lone >= min_height * tallest).any())


def drawn_boxes(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(F x M x 4) the boxes of the people on both keyframes (boxes ``a`` and ``b``), drawn each
    fraction ``w`` (F) of the way from ``a`` to ``b``."""
    pairs = match_people(a, b)
    ia, ib = [i for i, _ in pairs], [j for _, j in pairs]
    w = np.asarray(w, np.float64).reshape(-1, 1, 1)
    start, end = np.asarray(a, np.float64)[ia].reshape(-1, 4), np.asarray(b, np.float64)[ib].reshape(-1, 4)
    return start[None] * (1 - w) + end[None] * w


def newcomers(found: np.ndarray, drawn: np.ndarray) -> np.ndarray:
    """Indices of the boxes ``found`` on a frame between keyframes that are none of the people
    ``drawn`` there (:func:`drawn_boxes`): one found box per drawn person, matched by overlap."""
    taken = {j for _, j in match_people(drawn, found)}
    return np.array([k for k in range(len(found)) if k not in taken], int)


def lerp_points(a: np.ndarray, b: np.ndarray, w: float | np.ndarray) -> np.ndarray:
    """(..., 3) points a fraction ``w`` of the way from ``a`` to ``b``: x and y drawn linearly, the
    score the smaller of the two."""
    w = np.asarray(w, np.float64)
    out = a * (1 - w) + b * w
    out[..., 2] = np.minimum(a[..., 2], b[..., 2])
    return out


def drawn_between(points: np.ndarray, step: int) -> np.ndarray:
    """One person's per-frame points (T x ... x 3) as the keyframes would give them: every
    ``step``-th frame and the last kept, the frames between drawn by :func:`lerp_points` (what
    ``dance3d eval world --pose-fps`` feeds the lifter)."""
    points = np.asarray(points, np.float64)
    if step <= 1 or len(points) < 3:
        return points.copy()
    keys = np.unique(np.r_[np.arange(0, len(points), max(1, step)), len(points) - 1])
    after = np.clip(np.searchsorted(keys, np.arange(len(points))), 1, len(keys) - 1)
    a, b = keys[after - 1], keys[after]
    w = ((np.arange(len(points)) - a) / np.maximum(b - a, 1)).reshape((-1,) + (1,) * (points.ndim - 1))
    out = lerp_points(points[a], points[b], w)
    out[keys] = points[keys]
    return out


def in_between(a: Any, b: Any, slots: list[tuple[int, float]], top_k: int = 0,
               posed: Mapping[int, Any] | None = None) -> Iterator[Any]:
    """The frames ``slots`` ((frame, time), between keyframes ``a`` and ``b``) as interpolated
    ``FramePoses``: a person on both keyframes drawn between them; one on only one keyframe held
    from it over the half of the gap nearer to it (they were among the ``top_k`` largest there but
    not on the other, or came in or went out of sight), unless the frame is in ``posed`` (frame ->
    the ``FramePoses`` of the newcomers posed on it): then those posed people take their place;
    people in the order of their boxes' area, largest first, at most ``top_k`` (0: all)."""
    pairs = match_people(a.boxes, b.boxes)
    ia = np.array([i for i, _ in pairs], int)
    ib = np.array([j for _, j in pairs], int)
    only_a = np.setdiff1d(np.arange(len(a.scores)), ia)
    only_b = np.setdiff1d(np.arange(len(b.scores)), ib)
    for frame, time in slots:
        w = (frame - a.frame) / (b.frame - a.frame)
        alone, near = (only_a, a) if w <= 0.5 else (only_b, b)
        held_over = True  # the lone people: held from the nearer keyframe ...
        if posed is not None and frame in posed:
            near, held_over = posed[frame], False  # ... or the newcomers, as posed on this frame
            alone = np.arange(len(near.scores))
        boxes = np.concatenate([a.boxes[ia] * (1 - w) + b.boxes[ib] * w, near.boxes[alone]])
        scores = np.concatenate([np.minimum(a.scores[ia], b.scores[ib]), near.scores[alone]])
        keypoints = np.concatenate([lerp_points(a.keypoints[ia], b.keypoints[ib], w), near.keypoints[alone]])
        feet = np.concatenate([lerp_points(a.feet[ia], b.feet[ib], w), near.feet[alone]])
        drawn = np.r_[np.ones(len(ia), bool), np.full(len(alone), held_over)]
        area = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
        order = np.argsort(-area, kind="stable")[: top_k or None]
        hands = {}
        if getattr(a, "hands", None) is not None:  # a hand's points drawn as the body's, its metric shape too
            points = np.concatenate([lerp_points(a.hands[ia], b.hands[ib], w), near.hands[alone]])
            world = np.concatenate([a.hands_world[ia] * (1 - w) + b.hands_world[ib] * w, near.hands_world[alone]])
            hands = {"hands": points[order].astype(np.float32), "hands_world": world[order].astype(np.float32)}
        yield dataclasses.replace(
            a, frame=frame, time=time, boxes=boxes[order].astype(np.float32),
            scores=scores[order].astype(np.float32), keypoints=keypoints[order].astype(np.float32),
            feet=feet[order].astype(np.float32),
            detected=~drawn[order], interpolated=drawn[order], **hands)


def held(a: Any, slots: list[tuple[int, float]]) -> Iterator[Any]:
    """Frames after the last keyframe of a video whose length is not known in advance: its
    poses held (a segment's last frame is always a keyframe, so segments never need this)."""
    for frame, time in slots:
        yield dataclasses.replace(a, frame=frame, time=time, detected=False, interpolated=True)
