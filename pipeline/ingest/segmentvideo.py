"""A segment as a view on its downloaded video: no copy is written.

Frame k of a segment shows the source at ``start + k / rate``: it is the latest source
frame shown before ``start + (k + 1/2) / rate`` (the rule of ffmpeg's ``fps`` filter, which
the earlier re-encoded segments used), scaled to the segment's size with swscale's bicubic
filter and turned upright. Source frames are decoded from the keyframe before ``start``;
only the frames a segment shows are converted, and where the reader keeps only some frames
(pose2d's keyframes), the decoder skips the non-reference frames none of them shows. The
segment has exactly ``frames`` frames: if the source ends early, its last frame is held.

Audio is cut from the source the same way (``audio_seek``: ffmpeg input options that seek to
``start`` and read the segment's duration).
"""

from __future__ import annotations

import functools
import logging
import threading
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Callable, Iterator, Mapping

import av
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.ingest.media import Frame, VideoInfo, _open, _reason, _rotate, decode_video, video_streams

log = logging.getLogger(__name__)
SEEK_MARGIN = 1.0  # seconds: seek this far before start (the keyframe before it is decoded from)
REDECODE_AHEAD = 2.0  # seconds: a second decode seeks rather than decode this far forward


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

    @classmethod
    def whole(cls, path: Path, info: VideoInfo) -> SegmentVideo:
        """The whole video as one segment, on its own clock (average rate) and at its own size."""
        return cls(Path(path), 0.0, Fraction(info.fps_fraction), info.frames, info.width, info.height,
                   info.has_audio, info.audio_stream)

    def audio_seek(self) -> list[str]:
        """ffmpeg input options (before ``-i source``) that read this segment's span (accurate seek)."""
        return ["-ss", f"{self.start:.6f}", "-t", f"{self.duration:.6f}"]

    def iter_frames(self, *, max_bad_packets: int = 25, keep: Callable[[int], bool] | None = None,
                    tap: Callable[[av.VideoFrame], None] | None = None, first: int = 0,
                    skip: bool = True, tap_all: bool = True) -> Iterator[Frame]:
        """The segment's frames, in order: Frame(k, k / rate, upright BGR image of width x height),
        from frame ``first`` on (seeking to it).

        With ``keep``, only the frames k it keeps are converted; the others' image is None and
        their ``picture`` converts them on demand. Then (unless ``skip`` is False or a ``tap``
        must see every frame) the decoder also skips the source frames that no kept frame shows
        and no other frame refers to (H.264's non-reference frames, often half of a stream): a
        frame not kept whose source frame was skipped converts from a second decode of the view
        (:class:`_Redecode`). ``tap`` sees every source frame decoded for the segment, in order
        (e.g. to find cuts); with ``tap_all`` False the decoder may still skip, and ``tap`` sees
        only the frames it decoded.
        """
        if self.frames < 1 or first >= self.frames:
            return
        rate = float(self.rate)
        half = 0.5 / rate
        emitted = first
        held = None  # (decoded frame, converted image or None, its time on the segment's clock)
        skips = _Skips() if keep is not None and skip and (tap is None or not tap_all) else None
        again = _Redecode(self) if skips is not None else None  # for frames the decoder skipped
        with _open(self.source) as container:
            streams = video_streams(container)
            if not streams:
                raise MediaError(self.source, "no video stream")
            vs = streams[0]
            vs.thread_type = "AUTO"
            origin = vs.start_time or 0
            begin = self.start + first / rate
            if begin > SEEK_MARGIN:
                target = origin + int((begin - SEEK_MARGIN) / vs.time_base)
                container.seek(target, stream=vs, backward=True, any_frame=False)
            source_rate = vs.guessed_rate or vs.average_rate
            step = 1.0 / float(source_rate) if source_rate else 1.0 / rate

            def clock(pts: int | None) -> float:
                return float(((pts if pts is not None else origin) - origin) * vs.time_base) - self.start

            def before(packet: av.Packet) -> None:
                # A packet whose frame no kept slot shows may be skipped if nothing refers to it.
                if packet.pts is None or packet.size == 0:
                    needed = True
                else:
                    tau = clock(packet.pts)
                    needed = _shows_a_kept_slot(tau, step * 1.25, rate, emitted, self.frames, keep)
                    if not needed:
                        skips.sent(packet.pts, tau)
                mode = "DEFAULT" if needed else "NONREF"
                if vs.codec_context.skip_frame != mode:
                    vs.codec_context.skip_frame = mode

            try:
                for decoded in decode_video(container, vs, self.source, max_bad_packets,
                                            before if skips is not None else None):
                    tau = clock(decoded.pts)
                    if skips is not None:
                        skips.came_out(decoded.pts)
                    if tau < first / rate - half:
                        continue  # before the segment
                    if tap is not None:
                        tap(decoded)
                    # Each slot whose window ends at or before this frame is shown by the held frame.
                    while held is not None and tau >= emitted / rate + half:
                        stale = skips is not None and skips.between(held[2], emitted / rate + half)
                        held, frame = self._shown(held, emitted, keep, again if stale else None)
                        yield frame
                        emitted += 1
                        if emitted == self.frames:
                            if skips is not None:
                                skips.report(self.source)
                            return
                    held = (decoded, None, tau)
            except av.error.FFmpegError as exc:
                raise MediaError(self.source, f"decoding stopped after {emitted} frames ({_reason(exc)})") from None
        if held is None:
            raise MediaError(self.source, f"no video frames at or after {begin:.3f} s")
        if emitted < self.frames:
            log.debug("%s: source ends %d frames early; its last frame is held", self.source, self.frames - emitted)
        while emitted < self.frames:
            stale = skips is not None and skips.between(held[2], emitted / rate + half)
            held, frame = self._shown(held, emitted, keep, again if stale else None)
            yield frame
            emitted += 1
        if skips is not None:
            skips.report(self.source)

    def _shown(self, held: tuple, k: int, keep: Callable[[int], bool] | None,
               again: _Redecode | None) -> tuple[tuple, Frame]:
        """``held`` (converted once, when a kept frame k shows it) and frame k: its picture, or
        (not kept) a way to convert it later; ``again``: frame k shows a source frame the decoder
        skipped, whose picture only a second decode gives."""
        time = float(k / self.rate)
        if keep is not None and not keep(k):
            later = functools.partial(again.picture, k) if again else functools.partial(self._picture, held)
            return held, Frame(k, time, None, later)
        if again is not None:
            return held, Frame(k, time, again.picture(k))
        held = self._convert(held)
        return held, Frame(k, time, held[1])

    def _picture(self, held: tuple) -> np.ndarray:
        return self._convert(held)[1]

    def _convert(self, held: tuple) -> tuple:
        frame, image, tau = held
        if image is not None:
            return held
        rotation = int(frame.rotation or 0)
        w, h = (self.height, self.width) if rotation % 180 else (self.width, self.height)
        rgb = frame.reformat(width=w, height=h, format="bgr24", interpolation="BICUBIC")
        return frame, _rotate(rgb.to_ndarray(), rotation), tau


def _shows_a_kept_slot(tau: float, duration: float, rate: float, first: int, frames: int,
                       keep: Callable[[int], bool]) -> bool:
    """Whether a source frame at ``tau`` shown for ``duration`` may be what a kept slot shows:
    some kept slot's window ends within (tau, tau + duration] (computed as iter_frames does)."""
    half = 0.5 / rate
    lo = max(first, int(np.floor(tau * rate - 0.5)))
    hi = min(frames - 1, int(np.ceil((tau + duration) * rate - 0.5)))
    return any(tau < k / rate + half <= tau + duration and keep(k) for k in range(lo, hi + 1)) or (
        hi == frames - 1 and keep(frames - 1))  # the last slot: a source that ends early holds its last frame


class _Skips:
    """The packets sent to the decoder while it was told to skip non-reference frames, less the
    frames that came out of them: what it skipped (by presentation time)."""

    def __init__(self) -> None:
        self.pending: dict[int, float] = {}
        self.skipped = 0

    def sent(self, pts: int, tau: float) -> None:
        self.pending[pts] = tau

    def came_out(self, pts: int | None) -> None:
        if pts is not None:
            self.pending.pop(pts, None)

    def between(self, after: float, before: float) -> bool:
        """Whether a frame shown after ``after`` and before ``before`` was skipped (frames come
        out in presentation order, so one not out by now never will be)."""
        gone = [pts for pts, tau in self.pending.items() if tau <= after]
        for pts in gone:  # older than the held frame: no slot can show them any more
            del self.pending[pts]
        self.skipped += len(gone)
        return any(after < tau < before for tau in self.pending.values())

    def report(self, source: Path) -> None:
        log.debug("%s: the decoder skipped %d frames that no kept frame shows", source,
                  self.skipped + len(self.pending))


class _Redecode:
    """Pictures of a view's frames decoded again without skipping: a second decoder that moves
    forward, and seeks when asked for a frame behind it or more than REDECODE_AHEAD seconds ahead."""

    def __init__(self, view: SegmentVideo) -> None:
        self.view = view
        self.frames: Iterator[Frame] | None = None
        self.at = -1
        self.wanted = -1
        self.lock = threading.Lock()  # the decoding thread and a pose thread may both ask

    def picture(self, k: int) -> np.ndarray:
        with self.lock:
            if self.frames is None or k <= self.at or (k - self.at) / float(self.view.rate) > REDECODE_AHEAD:
                self.frames = self.view.iter_frames(keep=lambda j: j == self.wanted, first=k, skip=False)
            self.wanted = k
            for frame in self.frames:
                self.at = frame.index
                if frame.index == k:
                    return frame.image
            raise MediaError(self.view.source, f"frame {k} of the view could not be decoded again")


def frames_of(video: Path | SegmentVideo, keep: Callable[[int], bool] | None = None) -> Iterator[Frame]:
    """Frames of a video file (every frame, its own timestamps) or of a segment view; ``keep``:
    which frames to convert to pictures (the others come with ``image`` None)."""
    from pipeline.ingest.media import iter_frames

    return video.iter_frames(keep=keep) if isinstance(video, SegmentVideo) else iter_frames(video, keep=keep)
