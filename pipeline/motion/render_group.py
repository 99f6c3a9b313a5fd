"""Draw a segment's scene: the video frame beside the floor seen from above, every dancer of the
segment where the ground stage put them, with their recent path; planted feet as green dots.

A look at what the group windows hold: whether the dancers stand where the video shows them
(left to right, front to back), whether their paths jump, whether their feet stay put.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from pipeline.core.timecode import format_time
from pipeline.motion.mocap.skeleton import FOOT_BONES, H36M_BONES
from pipeline.motion.render3d import encode_mp4

PANEL = 480
TRAIL_SECONDS = 4.0
# One colour per dancer (BGR), as distinct as a dark background allows.
PALETTE = ((80, 200, 255), (255, 160, 60), (120, 230, 120), (240, 110, 240), (90, 120, 255), (230, 230, 90),
           (200, 200, 200), (60, 180, 180))


def floor_extent(clips: list) -> tuple[np.ndarray, float]:
    """The centre (x, z) and half-size (m) of the square of floor that holds every dancer's path."""
    points = np.concatenate([c.joints[:, 0, [0, 2]] for c in clips]) if clips else np.zeros((1, 2))
    lo, hi = points.min(0), points.max(0)
    return (lo + hi) / 2, max(1.5, float((hi - lo).max()) / 2 + 0.8)


def draw_floor(clips: list, frame: int, fps: float, centre: np.ndarray, half: float, size: int = PANEL) -> np.ndarray:
    """The floor from above (x right, z toward the camera at the bottom): a 0.5 m grid, each
    dancer's skeleton, their path over the last ``TRAIL_SECONDS`` and their planted points."""
    panel = np.full((size, size, 3), 24, np.uint8)
    scale = size / (2 * half)

    def to_px(xz: np.ndarray) -> np.ndarray:
        return ((xz - centre) * scale + size / 2).astype(np.int32)

    for g in np.arange(np.floor((centre.min() - half) * 2) / 2, centre.max() + half + 0.5, 0.5):
        for line in (np.array([[g, centre[1] - half], [g, centre[1] + half]]),
                     np.array([[centre[0] - half, g], [centre[0] + half, g]])):
            a, b = to_px(line)
            cv2.line(panel, tuple(map(int, a)), tuple(map(int, b)), (55, 55, 55), 1, cv2.LINE_AA)
    for k, clip in enumerate(clips):
        colour = PALETTE[k % len(PALETTE)]
        rows = np.flatnonzero(clip.frame <= frame)
        if not len(rows) or clip.frame[rows[-1]] != frame:
            continue  # this dancer is not in the scene at this frame
        now = rows[-1]
        recent = rows[clip.frame[rows] > frame - TRAIL_SECONDS * fps]
        if len(recent) > 1:
            cv2.polylines(panel, [to_px(clip.joints[recent, 0][:, [0, 2]])], False, colour, 1, cv2.LINE_AA)
        pose = clip.joints[now] if clip.feet is None else np.concatenate([clip.joints[now], clip.feet[now]])
        pts = to_px(pose[:, [0, 2]])
        for a, b in H36M_BONES + (FOOT_BONES if len(pose) == 21 else ()):
            cv2.line(panel, tuple(map(int, pts[a])), tuple(map(int, pts[b])), colour, 2, cv2.LINE_AA)
        if clip.planted is not None and clip.feet is not None:
            for p in np.flatnonzero(clip.planted[now]):
                cv2.circle(panel, tuple(map(int, pts[17 + p])), 4, (60, 220, 60), -1, cv2.LINE_AA)
        cv2.putText(panel, str(clip.track_id), tuple(map(int, pts[0] + [8, -8])), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                    colour, 1, cv2.LINE_AA)
    cv2.putText(panel, "floor from above (grid 0.5 m; camera below)", (10, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                (200, 200, 200), 1, cv2.LINE_AA)
    return panel


def _fit(image: np.ndarray, height: int) -> np.ndarray:
    return cv2.resize(image, (max(1, round(image.shape[1] * height / image.shape[0])), height),
                      interpolation=cv2.INTER_AREA)


def render_group(video, clips: list, fps: float, out: Path, *, audio: Path | None = None, title: str = "") -> None:
    """Write ``out`` (H.264 mp4) from a segment's video (``SegmentVideo``) and its world clips
    (``worldfile.read_world``, on the ``fps`` grid of the segment clock): at each grid frame, the
    video frame at that time beside ``draw_floor``."""
    centre, half = floor_extent(clips)
    last = max((int(c.frame[-1]) for c in clips), default=-1)
    frames = video.iter_frames()
    current, upcoming = next(frames, None), next(frames, None)
    first = None if current is None else _fit(current.image, PANEL)
    width = (first.shape[1] if first is not None else PANEL) + PANEL
    width += width % 2
    def canvases() -> Iterator[np.ndarray]:
        nonlocal current, upcoming
        for k in range(last + 1):
            t = k / fps
            while upcoming is not None and upcoming.time <= t + 1e-6:  # the last video frame at or before t
                current, upcoming = upcoming, next(frames, None)
            picture = np.zeros((PANEL, width - PANEL, 3), np.uint8)
            if current is not None:
                image = _fit(current.image, PANEL)
                picture[:, : image.shape[1]] = image[:, : width - PANEL]
            canvas = np.concatenate([picture, draw_floor(clips, k, fps, centre, half)], axis=1)
            cv2.putText(canvas, f"{title}  {format_time(t)}", (10, PANEL - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                        (255, 255, 255), 1, cv2.LINE_AA)
            yield canvas

    encode_mp4(canvases(), out, width, PANEL, fps, audio=audio, what="the group render")
