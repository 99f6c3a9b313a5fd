"""A segment as a view on its downloaded video: no copy is written.

Frame k of a segment shows the source at ``start + k / rate``: it is the latest source
frame shown before ``start + (k + 1/2) / rate`` (the rule of ffmpeg's ``fps`` filter, which
the earlier re-encoded segments used), scaled to the segment's size with swscale's bicubic
filter and turned upright. Source frames are decoded from the keyframe before ``start``;
only the frames a segment shows are converted. The segment has exactly ``frames`` frames:
if the source ends early, its last frame is held.

Audio is cut from the source the same way (``audio_seek``: ffmpeg input options that seek to
``start`` and read the segment's duration).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Callable, Iterator, Mapping

import av
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.ingest.media import Frame, _open, _reason, _rotate, decode_video, video_streams

log = logging.getLogger(__name__)
SEEK_MARGIN = 1.0  # seconds: seek this far before start (the keyframe before it is decoded from)


@dataclass(frozen=True)
class SegmentVideo:
    """Where a segment's frames come from, and the clock and size they are given."""

    source: Path        # the downloaded video
    start: float        # seconds on the source's clock (from its first video frame)
    rate: Fraction      # segment frame rate
    frames: int         # exactly this many frames
    width: int          # upright output size
    height: int
    has_audio: bool = False
    audio_stream: int | None = None

    @property
    def duration(self) -> float:
        return float(self.frames / self.rate)

    @classmethod
    def from_index(cls, raw_dir: Path, row: Mapping) -> SegmentVideo:
        """The view that a row of the segment index describes (``source`` names a file in ``raw_dir``)."""
        return cls(Path(raw_dir) / row["source"], float(row["start"]), Fraction(row["fps_fraction"]),
                   int(row["frames"]), int(row["width"]), int(row["height"]), bool(row["has_audio"]),
                   row.get("audio_stream"))

    def audio_seek(self) -> list[str]:
        """ffmpeg input options (before ``-i source``) that read this segment's span (accurate seek)."""
        return ["-ss", f"{self.start:.6f}", "-t", f"{self.duration:.6f}"]

    def iter_frames(self, *, max_bad_packets: int = 25, keep: Callable[[int], bool] | None = None,
                    tap: Callable[[av.VideoFrame], None] | None = None) -> Iterator[Frame]:
        """The segment's frames, in order: Frame(k, k / rate, upright BGR image of width x height);
        with ``keep``, only the frames k it keeps are converted (the others' image is None);
        ``tap`` sees every source frame decoded for the segment, in order (e.g. to find cuts)."""
        if self.frames < 1:
            return
        half = 0.5 / float(self.rate)
        emitted = 0
        held = None  # (decoded frame, converted image or None)
        with _open(self.source) as container:
            streams = video_streams(container)
            if not streams:
                raise MediaError(self.source, "no video stream")
            vs = streams[0]
            vs.thread_type = "AUTO"
            origin = vs.start_time or 0
            if self.start > SEEK_MARGIN:
                target = origin + int((self.start - SEEK_MARGIN) / vs.time_base)
                container.seek(target, stream=vs, backward=True, any_frame=False)
            try:
                for decoded in decode_video(container, vs, self.source, max_bad_packets):
                    pts = decoded.pts if decoded.pts is not None else origin
                    tau = float((pts - origin) * vs.time_base) - self.start
                    if tau < -half:
                        continue  # before the segment
                    if tap is not None:
                        tap(decoded)
                    # Each slot whose window ends at or before this frame is shown by the held frame.
                    while held is not None and tau >= emitted / float(self.rate) + half:
                        held, frame = self._shown(held, emitted, keep)
                        yield frame
                        emitted += 1
                        if emitted == self.frames:
                            return
                    held = (decoded, None)
            except av.error.FFmpegError as exc:
                raise MediaError(self.source, f"decoding stopped after {emitted} frames ({_reason(exc)})") from None
        if held is None:
            raise MediaError(self.source, f"no video frames at or after {self.start:.3f} s")
        if emitted < self.frames:
            log.debug("%s: source ends %d frames early; its last frame is held", self.source, self.frames - emitted)
        while emitted < self.frames:
            held, frame = self._shown(held, emitted, keep)
            yield frame
            emitted += 1

    def _shown(self, held: tuple, k: int, keep: Callable[[int], bool] | None) -> tuple[tuple, Frame]:
        """``held`` (converted once, when a kept frame k shows it) and frame k: its picture, or
        (not kept) a way to convert it later."""
        time = float(k / self.rate)
        if keep is not None and not keep(k):
            return held, Frame(k, time, None, functools.partial(self._picture, held))
        held = self._convert(held)
        return held, Frame(k, time, held[1])

    def _picture(self, held: tuple) -> np.ndarray:
        return self._convert(held)[1]

    def _convert(self, held: tuple) -> tuple:
        frame, image = held
        if image is not None:
            return held
        rotation = int(frame.rotation or 0)
        w, h = (self.height, self.width) if rotation % 180 else (self.width, self.height)
        rgb = frame.reformat(width=w, height=h, format="bgr24", interpolation="BICUBIC")
        return frame, _rotate(rgb.to_ndarray(), rotation)


def frames_of(video: Path | SegmentVideo, keep: Callable[[int], bool] | None = None) -> Iterator[Frame]:
    """Frames of a video file (every frame, its own timestamps) or of a segment view; ``keep``:
    which frames to convert to pictures (the others come with ``image`` None)."""
    from pipeline.ingest.media import iter_frames

    return video.iter_frames(keep=keep) if isinstance(video, SegmentVideo) else iter_frames(video, keep=keep)
