"""Media layer: probe videos and stream their frames with PyAV; run the wheel's ffmpeg.

Probing reads container and stream fields through PyAV (libav*), never ffmpeg's
human-readable log. Frames are decoded one packet at a time, so memory does not grow
with video length. Rotated (phone) videos come out upright; every frame carries its
own presentation time, so variable-frame-rate input keeps correct timestamps.
"""

from __future__ import annotations

import functools
import logging
import subprocess
from dataclasses import asdict, dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Callable, Iterator, Sequence

import av
import numpy as np

from pipeline.core.errors import MediaError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class VideoInfo:
    """What the pipeline needs to know about a video file."""

    path: str
    container: str
    codec: str
    duration: float          # seconds
    fps: float               # average frame rate
    fps_fraction: str        # the same rate as an exact fraction, e.g. "24000/1001"
    frames: int              # frames in the stream (from the index, else counted)
    width: int               # upright width (after applying rotation)
    height: int              # upright height
    rotation: int            # display rotation stored in the file, degrees counter-clockwise
    has_audio: bool
    audio_codec: str | None
    sample_rate: int | None
    audio_channels: int | None
    video_stream: int = 0    # container stream indices, for selecting streams explicitly
    audio_stream: int | None = None

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Frame:
    index: int               # 0-based decode order
    time: float              # seconds from the stream's first frame
    image: np.ndarray | None  # HxWx3 uint8 BGR, upright (None: a frame the reader did not ask to see)
    picture: Callable[[], np.ndarray] | None = field(default=None, repr=False, compare=False)
    # ... whose image this converts on demand (the decoded frame is kept until the Frame is dropped)

    def shown(self) -> np.ndarray:
        """The frame's picture, converting it now if it was not asked for."""
        return self.image if self.image is not None else self.picture()


def ffmpeg_exe() -> str:
    """The ffmpeg binary shipped by the imageio-ffmpeg wheel (or $IMAGEIO_FFMPEG_EXE)."""
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_exe()


def run_ffmpeg(args: Sequence[str], *, subject: str | Path) -> None:
    """Run ffmpeg with ``args`` (no shell); raise MediaError naming ``subject`` on failure."""
    cmd = [ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-y", *map(str, args)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        tail = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()][-3:]
        raise MediaError(subject, "ffmpeg failed: " + (" | ".join(tail) or f"exit code {proc.returncode}"))


def _open(path: Path) -> av.container.InputContainer:
    path = Path(path)
    if not path.exists():
        raise MediaError(path, "file not found")
    if path.stat().st_size == 0:
        raise MediaError(path, "file is empty (0 bytes)")
    try:
        return av.open(str(path))
    except av.error.FFmpegError as exc:
        raise MediaError(path, f"not a readable media file ({_reason(exc)})") from None


def _reason(exc: Exception) -> str:
    return getattr(exc, "strerror", None) or str(exc)


def _upright(width: int, height: int, rotation: int) -> tuple[int, int]:
    return (height, width) if rotation % 180 else (width, height)


def video_streams(container) -> list:
    """Real video streams: cover art (an attached picture) is not video."""
    return [s for s in container.streams.video if not (s.disposition & av.stream.Disposition.attached_pic)]


def probe(path: str | Path) -> VideoInfo:
    """Probe a video. Raises MediaError (file + reason) for anything unusable."""
    path = Path(path)
    with _open(path) as container:
        streams = video_streams(container)
        if not streams:
            kind = "audio-only file" if container.streams.audio else "no audio or video streams"
            raise MediaError(path, f"no video stream ({kind})")
        vs = streams[0]
        audio = container.streams.audio[0] if container.streams.audio else None
        rate = vs.average_rate or vs.guessed_rate or vs.base_rate
        if not rate:
            raise MediaError(path, "video stream has no frame rate")
        rate = Fraction(rate.numerator, rate.denominator).limit_denominator(1001 * 1000)
        if vs.duration is not None and vs.time_base is not None:
            duration = float(vs.duration * vs.time_base)
        elif container.duration is not None:
            duration = container.duration / av.time_base
        else:
            duration = 0.0
        _check_complete(path, vs)
        first = _first_frame(container, vs, path)
        rotation = int(first.rotation or 0) % 360
        frames = int(vs.frames or 0)
        first_size = (first.width, first.height)
        container_name = container.format.name
        codec = vs.codec_context.name
        video_index = vs.index
        audio_facts = (
            (audio.codec_context.name, audio.codec_context.sample_rate, audio.codec_context.channels, audio.index)
            if audio is not None else (None, None, None, None)
        )
    if frames <= 0:
        frames = count_frames(path)
    if duration <= 0:
        duration = frames / float(rate)
    width, height = _upright(*first_size, rotation)
    audio_codec, sample_rate, channels, audio_index = audio_facts
    return VideoInfo(
        path=str(path),
        container=container_name,
        codec=codec,
        duration=round(duration, 6),
        fps=float(rate),
        fps_fraction=f"{rate.numerator}/{rate.denominator}",
        frames=frames,
        width=width,
        height=height,
        rotation=rotation,
        has_audio=audio_codec is not None,
        audio_codec=audio_codec,
        sample_rate=sample_rate,
        audio_channels=channels,
        video_stream=video_index,
        audio_stream=audio_index,
    )


def _check_complete(path: Path, stream) -> None:
    """A file cut short after its index (moov first) still opens; its index then points past EOF."""
    entries = stream.index_entries
    if not len(entries):
        return
    last = entries[len(entries) - 1]
    size = path.stat().st_size
    if last.pos + last.size > size:
        raise MediaError(path, f"file is truncated: its index needs {last.pos + last.size} bytes, the file has {size}")


def _first_frame(container, stream, path: Path):
    try:
        for frame in container.decode(stream):
            return frame
    except av.error.FFmpegError as exc:
        raise MediaError(path, f"cannot decode the first video frame ({_reason(exc)})") from None
    raise MediaError(path, "video stream has no decodable frames (truncated file?)")


def count_frames(path: str | Path) -> int:
    """Count video packets without decoding (for containers without a frame count)."""
    with _open(Path(path)) as container:
        vs = video_streams(container)[0]
        return sum(1 for packet in container.demux(vs) if packet.size)


def _rotate(image: np.ndarray, rotation: int) -> np.ndarray:
    # The display matrix says how far to turn the picture counter-clockwise to show it.
    k = (rotation // 90) % 4
    return np.ascontiguousarray(np.rot90(image, k)) if k else image


def _bgr(frame: av.VideoFrame) -> np.ndarray:
    return _rotate(frame.to_ndarray(format="bgr24"), int(frame.rotation or 0))


def decode_video(container, stream, path: Path, max_bad_packets: int = 25,
                 before: Callable[[av.Packet], None] | None = None) -> Iterator[av.VideoFrame]:
    """Decoded frames of ``stream`` in order (``before`` sees each packet before it is decoded).
    A corrupt packet is skipped with a warning; more than ``max_bad_packets`` of them raise
    MediaError. Demuxing errors propagate (av's)."""
    bad = 0
    for packet in container.demux(stream):
        if before is not None:
            before(packet)
        try:
            decoded = packet.decode()
        except av.error.FFmpegError as exc:
            bad += 1
            log.warning("%s: skipped a corrupt packet (%s)", path, _reason(exc))
            if bad > max_bad_packets:
                raise MediaError(path, f"too many corrupt packets ({bad}); last: {_reason(exc)}") from None
            continue
        yield from decoded


def iter_frames(path: str | Path, *, max_bad_packets: int = 25,
                keep: Callable[[int], bool] | None = None) -> Iterator[Frame]:
    """Stream upright BGR frames with their timestamps (``keep``: which frame indices to convert
    to pictures; the others come with ``image`` None, decoded but not converted).

    A corrupt packet in the middle of a file is skipped with a warning (the frame is
    simply missing, its neighbours keep their true times); more than ``max_bad_packets``
    of them raise MediaError.
    """
    path = Path(path)
    with _open(path) as container:
        streams = video_streams(container)
        if not streams:
            raise MediaError(path, "no video stream")
        vs = streams[0]
        vs.thread_type = "AUTO"
        start = vs.start_time or 0
        index = 0
        try:
            for frame in decode_video(container, vs, path, max_bad_packets):
                pts = frame.pts if frame.pts is not None else start
                time = float((pts - start) * vs.time_base)
                if keep is None or keep(index):
                    yield Frame(index, time, _bgr(frame))
                else:
                    yield Frame(index, time, None, functools.partial(_bgr, frame))
                index += 1
        except av.error.FFmpegError as exc:
            raise MediaError(path, f"decoding stopped after {index} frames ({_reason(exc)})") from None
