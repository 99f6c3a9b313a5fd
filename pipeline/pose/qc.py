"""QC videos for annotators: boxes, skeletons and big id labels in stable per-id colours,
the frame number and the timecode annotators type into manifests (and "drawn" on frames the
2D models did not look at: drawn between two keyframes), and the segment's audio.

Frames are read from the segment's view on its downloaded video, drawn and piped to ffmpeg
one at a time (H.264 yuv420p, faststart: plays in any browser); memory does not grow with the
segment's length. QC videos are for annotators, so they are made when someone asks: the review
page and ``dance3d qc`` render a segment's on first request (``qc_video``), and the track stage
renders them all only with ``track.qc_videos: true``.
"""

from __future__ import annotations

import colorsys
import subprocess
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.core.storage import atomic_path
from pipeline.core.timecode import format_time
from pipeline.ingest.media import ffmpeg_exe
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.pose.pose2dfile import HAND_PARENTS, MIN_PRESENCE

# COCO-17 limbs, drawn between keypoint pairs.
SKELETON = ((15, 13), (13, 11), (16, 14), (14, 12), (11, 12), (5, 11), (6, 12), (5, 6), (5, 7), (6, 8),
            (7, 9), (8, 10), (1, 2), (0, 1), (0, 2), (1, 3), (2, 4), (3, 5), (4, 6))
# Feet, when the pose data has them: keypoints 17-20 = left heel, right heel, left toe, right toe.
FOOT_BONES = ((15, 17), (15, 19), (17, 19), (16, 18), (16, 20), (18, 20))
UNTRACKED_COLOUR = (160, 160, 160)
# A hand's 21 points (MediaPipe's order): each finger from the wrist, and across the knuckles.
HAND_BONES = tuple((p, j) for j, p in enumerate(HAND_PARENTS) if p >= 0) + ((5, 9), (9, 13), (13, 17))


def id_colour(track_id: int) -> tuple[int, int, int]:
    """A stable, well-separated BGR colour per id (golden-ratio hue steps)."""
    if track_id < 0:
        return UNTRACKED_COLOUR
    hue = (track_id * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(hue, 0.85, 1.0)
    return int(b * 255), int(g * 255), int(r * 255)


def draw_frame(image: np.ndarray, frame: int, time: float, people: list[tuple], kp_min_score: float,
               drawn: bool = False) -> np.ndarray:
    """Draw ``people`` = [(track_id, box[4], keypoints[17x3] or [21x3] with the feet[, hands[2x21x3]]), ...]
    and the banner (``drawn``: the poses were drawn between two keyframes, not posed by the models)."""
    h, w = image.shape[:2]
    unit = max(h, w) / 720.0
    thick = max(1, int(round(2 * unit)))
    for track_id, box, kps, *hands in people:
        colour = id_colour(track_id)
        for hand in hands[0] if hands else ():
            if hand[0, 2] >= MIN_PRESENCE:  # sure hands only: thin bones in the person's colour, white joints
                for a, b in HAND_BONES:
                    cv2.line(image, (int(hand[a, 0]), int(hand[a, 1])), (int(hand[b, 0]), int(hand[b, 1])), colour,
                             max(1, thick // 2), cv2.LINE_AA)
                for x, y, _ in hand:
                    cv2.circle(image, (int(x), int(y)), max(1, thick // 2), (255, 255, 255), -1, cv2.LINE_AA)
        x1, y1, x2, y2 = (int(round(v)) for v in box)
        cv2.rectangle(image, (x1, y1), (x2, y2), colour, thick if track_id >= 0 else 1, cv2.LINE_AA)
        for a, b in SKELETON + (FOOT_BONES if len(kps) > 17 else ()):
            if kps[a, 2] >= kp_min_score and kps[b, 2] >= kp_min_score:
                cv2.line(image, (int(kps[a, 0]), int(kps[a, 1])), (int(kps[b, 0]), int(kps[b, 1])),
                         colour, thick, cv2.LINE_AA)
        for x, y, s in kps:
            if s >= kp_min_score:
                cv2.circle(image, (int(x), int(y)), thick + 1, colour, -1, cv2.LINE_AA)
        label = str(track_id) if track_id >= 0 else "?"
        scale = 1.4 * unit
        (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, scale, thick + 1)
        ty = max(th + 6, y1 - 6)  # above the box, or just inside it at the top edge
        cv2.rectangle(image, (x1, ty - th - 6), (x1 + tw + 8, ty + 4), colour, -1)
        cv2.putText(image, label, (x1 + 4, ty), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thick + 1, cv2.LINE_AA)
    # Bottom-left, so it never hides the id label of someone near the top edge.
    banner = f"frame {frame}   {format_time(time)}" + ("   drawn" if drawn else "")
    scale = 0.8 * unit
    (tw, th), _ = cv2.getTextSize(banner, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    cv2.rectangle(image, (0, h - th - 16), (tw + 16, h), (0, 0, 0), -1)
    cv2.putText(image, banner, (8, h - 8), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), thick, cv2.LINE_AA)
    return image


def render_qc(segment: SegmentVideo, fps: float, frames: np.ndarray, track_ids: np.ndarray, boxes: np.ndarray,
              keypoints: np.ndarray, out: Path, *, kp_min_score: float = 0.2,
              crf: int = 23, preset: str = "veryfast", feet: np.ndarray | None = None,
              drawn: np.ndarray | None = None, hands: np.ndarray | None = None) -> None:
    """Write the QC video of ``segment`` with the given detections (one row per person per frame;
    ``drawn``: which rows were drawn between keyframes; ``hands``: N x 2 x 21 x 3, drawn where sure)."""
    by_frame: dict[int, list[tuple]] = defaultdict(list)
    for i in range(len(frames)):
        kps = keypoints[i].reshape(17, 3)
        if feet is not None:
            kps = np.vstack([kps, feet[i].reshape(4, 3)])
        person = (int(track_ids[i]), boxes[i], kps)
        by_frame[int(frames[i])].append(person if hands is None else (*person, hands[i]))
    drawn_frames = set(np.asarray(frames)[np.asarray(drawn, bool)].tolist()) if drawn is not None else set()
    stream = segment.iter_frames()
    first = next(stream, None)
    if first is None:
        raise MediaError(segment.source, "segment has no frames to draw")
    h, w = first.image.shape[:2]
    with atomic_path(out) as tmp:
        cmd = [ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-y",
               "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", f"{w}x{h}", "-r", f"{fps:.6f}", "-i", "pipe:0"]
        if segment.has_audio:
            audio = f"1:{segment.audio_stream}" if segment.audio_stream is not None else "1:a:0"
            cmd += [*segment.audio_seek(), "-i", str(segment.source), "-map", "0:v:0", "-map", audio,
                    "-c:a", "aac", "-b:a", "128k", "-shortest"]
        cmd += ["-c:v", "libx264", "-preset", preset, "-crf", str(crf), "-pix_fmt", "yuv420p",
                "-fflags", "+bitexact", "-flags:v", "+bitexact", "-flags:a", "+bitexact", "-map_metadata", "-1",
                "-movflags", "+faststart", "-f", "mp4", str(tmp)]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            for frame in _chain(first, stream):
                number = int(round(frame.time * fps))
                image = draw_frame(frame.image, number, frame.time, by_frame.get(number, []), kp_min_score,
                                   number in drawn_frames)
                proc.stdin.write(image.tobytes())
            proc.stdin.close()
        except BrokenPipeError:
            pass
        finally:
            err = proc.stderr.read().decode(errors="replace")
            code = proc.wait()
        if code != 0:
            raise MediaError(out, f"ffmpeg could not encode the QC video: {err.strip()[-300:]}")


def _chain(first, rest):
    yield first
    yield from rest


def qc_video(root: Path, segment_id: str, *, kp_min_score: float = 0.2) -> Path:
    """``data/qc/<segment_id>.mp4``, rendered from the segment's tracks unless it is already newer than them."""
    from pipeline.core.paths import QC, RAW, SEGMENTS, TRACKS
    from pipeline.ingest.catalog import read_index
    from pipeline.pose.trackfile import read_tracks

    tracks_file = Path(root) / TRACKS / f"{segment_id}.parquet"
    out = Path(root) / QC / f"{segment_id}.mp4"
    if not tracks_file.exists():
        raise MediaError(tracks_file, "no tracks for this segment (run the track stage first)")
    if out.exists() and out.stat().st_mtime_ns >= tracks_file.stat().st_mtime_ns:
        return out
    row = read_index(Path(root) / SEGMENTS).get(segment_id)
    if row is None:
        raise MediaError(Path(root) / SEGMENTS, f"segment {segment_id} is not in the index")
    tracks = read_tracks(tracks_file)
    render_qc(SegmentVideo.from_index(Path(root) / RAW, row), tracks.fps, tracks.frame, tracks.track_id, tracks.box,
              tracks.keypoints, out, kp_min_score=kp_min_score, feet=tracks.feet, drawn=tracks.drawn,
              hands=tracks.hands)
    return out
