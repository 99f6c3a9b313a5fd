"""Draw a 3D skeleton clip with the segment's audio to an mp4: front and side views of the
camera-frame pose, or (world motion) an oblique view over a floor grid and a top view, with the
root's trail and the feet in contact marked, so travel and foot sliding show at a glance."""

from __future__ import annotations

import subprocess
from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.core.storage import atomic_path
from pipeline.core.timecode import format_time
from pipeline.ingest.media import ffmpeg_exe
from pipeline.motion.mocap.skeleton import FOOT_BONES, H36M_BONES

LEFT = {4, 5, 6, 11, 12, 13, 17, 19}
RIGHT = {1, 2, 3, 14, 15, 16, 18, 20}


def _colour(a: int, b: int) -> tuple[int, int, int]:
    if b in LEFT:
        return (255, 160, 40)   # left side: blue-ish (BGR)
    if b in RIGHT:
        return (40, 80, 255)    # right side: red-ish
    return (230, 230, 230)


def _draw_bones(image: np.ndarray, pts: np.ndarray) -> None:
    """H36M-17 bones, and the feet when ``pts`` has 21 joints."""
    for a, b in H36M_BONES + (FOOT_BONES if len(pts) == 21 else ()):
        cv2.line(image, tuple(int(v) for v in pts[a]), tuple(int(v) for v in pts[b]), _colour(a, b), 3, cv2.LINE_AA)


def draw_pose(joints: np.ndarray, size: int = 480, extent: float = 1.1) -> np.ndarray:
    """Two panels: front (camera x, y) and side (camera z, y), root-relative metres, y down."""
    canvas = np.full((size, 2 * size, 3), 24, np.uint8)
    scale = size / (2 * extent)
    views = ((0, 1, 0), (2, 1, size))  # (horizontal axis, vertical axis, panel x offset)
    for h_axis, v_axis, offset in views:
        pts = np.stack([joints[:, h_axis] * scale + size / 2 + offset, joints[:, v_axis] * scale + size / 2], -1)
        _draw_bones(canvas, pts)
        for p in pts:
            cv2.circle(canvas, (int(p[0]), int(p[1])), 4, (255, 255, 255), -1, cv2.LINE_AA)
    cv2.line(canvas, (size, 0), (size, size), (90, 90, 90), 1)
    cv2.putText(canvas, "front", (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (200, 200, 200), 1, cv2.LINE_AA)
    cv2.putText(canvas, "side", (size + 10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (200, 200, 200), 1, cv2.LINE_AA)
    return canvas


_GRID = np.arange(-3.0, 3.01, 0.5)


def _oblique(points: np.ndarray, centre: np.ndarray, azimuth: float = 35.0, elevation: float = 25.0) -> np.ndarray:
    """World points (y up) -> 2D (right, down) seen from above and to the side, orthographic."""
    p = points - centre
    a, e = np.radians(azimuth), np.radians(elevation)
    x = p[..., 0] * np.cos(a) - p[..., 2] * np.sin(a)
    depth = p[..., 0] * np.sin(a) + p[..., 2] * np.cos(a)
    y = p[..., 1] * np.cos(e) - depth * np.sin(e)
    return np.stack([x, -y], -1)


def _draw_smpl(image: np.ndarray, pts: np.ndarray) -> None:
    """The SMPL tree's bones (its first ``len(pts)`` joints), thin and yellow, and its joints as dots."""
    from pipeline.motion.smpl.skeleton import PARENTS

    for j, p in enumerate(PARENTS[: len(pts)]):
        if p >= 0:
            cv2.line(image, tuple(int(v) for v in pts[p]), tuple(int(v) for v in pts[j]), (0, 230, 255), 1,
                     cv2.LINE_AA)
    for q in pts:
        cv2.circle(image, (int(q[0]), int(q[1])), 2, (0, 230, 255), -1, cv2.LINE_AA)


def _draw_hands(image: np.ndarray, hands: np.ndarray, colour: tuple[int, int, int] = (240, 240, 240)) -> None:
    """Each hand's 21 points (2 x 21 x 3 projected: NaN where none) as thin fingers, white by default."""
    from pipeline.pose.pose2dfile import HAND_PARENTS

    for hand in hands:
        if not np.isfinite(hand).all():
            continue
        for j, p in enumerate(HAND_PARENTS):
            if p >= 0:
                cv2.line(image, tuple(int(v) for v in hand[p]), tuple(int(v) for v in hand[j]), colour, 1,
                         cv2.LINE_AA)


def draw_world(joints: np.ndarray, contact: np.ndarray, trail: np.ndarray, centre: np.ndarray,
               size: int = 480, extent: float = 1.6, smpl: np.ndarray | None = None,
               hands: np.ndarray | None = None, smpl_hands: np.ndarray | None = None) -> np.ndarray:
    """Two panels of world motion (y up, floor y = 0): an oblique view with the floor grid, and
    the floor seen from above. Feet in contact are green discs; the root's recent path is the
    orange trail. ``smpl`` (24 x 3): the SMPL skeleton's joints, drawn in yellow over the world's;
    ``hands`` (2 x 21 x 3, NaN where none): the hands' fingers, in white; ``smpl_hands`` (the same):
    SMPL-H's fingers by forward kinematics, in yellow."""
    scale = size / (2 * extent)
    floor_c = np.array([centre[0], 0.0, centre[2]])
    views = (lambda p: _oblique(p, floor_c + [0.0, 0.9, 0.0]) * scale + size / 2,
             lambda p: (p[..., [0, 2]] - floor_c[[0, 2]]) * scale * 0.6 + size / 2)
    panels = []
    for project in views:
        panel = np.full((size, size, 3), 24, np.uint8)
        lo, hi = _GRID[0], _GRID[-1]
        for g in _GRID:
            for line in (np.array([[g, 0, lo], [g, 0, hi]]), np.array([[lo, 0, g], [hi, 0, g]])):
                a, b = project(line + [floor_c[0], 0, floor_c[2]])
                cv2.line(panel, tuple(int(v) for v in a), tuple(int(v) for v in b), (60, 60, 60), 1, cv2.LINE_AA)
        if len(trail) > 1:
            path = project(trail * [1, 0, 1])
            cv2.polylines(panel, [path.astype(np.int32)], False, (0, 170, 255), 2, cv2.LINE_AA)
        for foot, ankle in enumerate((6, 3)):
            if contact[foot]:
                # under the middle of the foot when heels and toes are known, else under the ankle
                place = joints[[17 + foot, 19 + foot]].mean(0) if len(joints) == 21 else joints[ankle]
                spot = project(place * [1, 0, 1])
                cv2.circle(panel, (int(spot[0]), int(spot[1])), 8, (60, 220, 60), -1, cv2.LINE_AA)
        pts = project(joints)
        _draw_bones(panel, pts)
        if smpl is not None:
            _draw_smpl(panel, project(smpl))
        if hands is not None:
            _draw_hands(panel, project(hands))
        if smpl_hands is not None:
            _draw_hands(panel, project(smpl_hands), (0, 230, 255))
        panels.append(panel)
    canvas = np.concatenate(panels, axis=1)
    cv2.line(canvas, (size, 0), (size, size), (90, 90, 90), 1)
    cv2.putText(canvas, "world (floor grid 0.5 m)", (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (200, 200, 200), 1,
                cv2.LINE_AA)
    cv2.putText(canvas, "from above: path, feet in contact", (size + 10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                (200, 200, 200), 1, cv2.LINE_AA)
    return canvas


def encode_mp4(frames: Iterable[np.ndarray], out: Path, width: int, height: int, fps: float, *,
               audio: Path | None = None, audio_start: float = 0.0, what: str = "the 3D render") -> None:
    """Write BGR frames (``height`` x ``width`` each) to ``out`` as H.264 mp4 at ``fps``, with
    ``audio`` from ``audio_start`` s when it exists (cut to the video's length)."""
    with atomic_path(out) as tmp:
        cmd = [ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-y", "-f", "rawvideo",
               "-pix_fmt", "bgr24", "-s", f"{width}x{height}", "-r", f"{fps:.6f}", "-i", "pipe:0"]
        if audio is not None and Path(audio).exists():
            cmd += ["-ss", f"{audio_start:.6f}", "-i", str(audio), "-map", "0:v", "-map", "1:a", "-c:a", "aac",
                    "-shortest"]
        cmd += ["-c:v", "libx264", "-preset", "veryfast", "-crf", "23", "-pix_fmt", "yuv420p",
                "-movflags", "+faststart", "-f", "mp4", str(tmp)]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            for frame in frames:
                proc.stdin.write(frame.tobytes())
            proc.stdin.close()
        except BrokenPipeError:
            pass
        err = proc.stderr.read().decode(errors="replace")
        if proc.wait() != 0:
            raise MediaError(out, f"ffmpeg could not encode {what}: {err.strip()[-300:]}")


def render_clip(joints: np.ndarray, times: np.ndarray, fps: float, out: Path, *, audio: Path | None = None,
                title: str = "", contact: np.ndarray | None = None, smpl: np.ndarray | None = None,
                hands: np.ndarray | None = None, smpl_hands: np.ndarray | None = None) -> None:
    """Write ``out`` (H.264 mp4); ``audio`` (the segment's wav) is cut to the clip's times.
    ``joints``: T x 17 x 3, or 21 with the heels and toes. With ``contact`` (T x 2), ``joints``
    are world motion and are drawn with ``draw_world``, and ``smpl`` (T x 24 x 3), ``hands`` and
    ``smpl_hands`` (T x 2 x 21 x 3) over them."""
    size = 480
    centre = joints[:, 0].mean(0)

    def frames() -> Iterator[np.ndarray]:
        for k, (pose, t) in enumerate(zip(joints, times)):
            frame = draw_pose(pose, size) if contact is None else draw_world(
                pose, contact[k], joints[max(0, k - int(4 * fps)): k + 1, 0], centre, size,
                smpl=None if smpl is None else smpl[k], hands=None if hands is None else hands[k],
                smpl_hands=None if smpl_hands is None else smpl_hands[k])
            cv2.putText(frame, f"{title}  {format_time(float(t))}", (10, size - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                        (255, 255, 255), 1, cv2.LINE_AA)
            yield frame

    encode_mp4(frames(), out, 2 * size, size, fps, audio=audio, audio_start=float(times[0]))
