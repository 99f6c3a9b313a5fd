"""Plan one dance segment of a source video: a frame-accurate, constant-rate view, not a copy.

Frame k of a segment shows the source at ``start + k / fps``; the segment has exactly
``round((end - start) * fps)`` frames (fewer only when the source ends sooner), at the
source's rate or ``trim.fps``, downscaled to ``trim.max_side``. Nothing is re-encoded: the
index row says where the frames come from, and every later stage reads them from the
downloaded file through ``SegmentVideo`` (pipeline/ingest/segmentvideo.py), audio included.
Phone videos come out upright. Planning decodes the segment's first frame, so a source
that cannot be read there fails here, naming the file, not in a later stage.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from pipeline.core.errors import MediaError
from pipeline.ingest.media import VideoInfo, probe
from pipeline.ingest.segments import SegmentSpec
from pipeline.ingest.segmentvideo import SegmentVideo


@dataclass(frozen=True)
class TrimOptions:
    fps: str = "source"     # "source" or a rate like "30" / "30000/1001"
    max_side: int = 1280    # 0 keeps the size


def segment_rate(opts: TrimOptions, video: VideoInfo) -> Fraction:
    text = video.fps_fraction if str(opts.fps) == "source" else str(opts.fps)
    rate = Fraction(text).limit_denominator(1001 * 1000)
    if rate <= 0:
        raise ValueError(f"trim.fps must be positive, not {opts.fps!r}")
    return rate


def output_size(width: int, height: int, max_side: int) -> tuple[int, int]:
    """Size after downscaling so the longer side is at most ``max_side``; even numbers (yuv420p)."""
    scale = min(1.0, max_side / max(width, height)) if max_side else 1.0
    def even(x: float) -> int:
        return max(2, int(x / 2 + 0.5) * 2)

    return even(width * scale), even(height * scale)


def segment_view(src: Path, video: VideoInfo, spec: SegmentSpec, opts: TrimOptions) -> SegmentVideo:
    """The view of ``spec`` on ``src``: its clock, frame count and size."""
    rate = segment_rate(opts, video)
    end = min(spec.end, video.duration) if video.duration > 0 else spec.end
    frames = int(round((end - spec.start) * rate))
    if frames < 1:
        raise ValueError(f"segment {spec.segment_id} is shorter than one frame")
    width, height = output_size(video.width, video.height, opts.max_side)
    return SegmentVideo(Path(src), spec.start, rate, frames, width, height, video.has_audio, video.audio_stream)


def plan_segment(src: Path, video: VideoInfo, spec: SegmentSpec, opts: TrimOptions) -> dict:
    """The segment's row of the index, after checking that its first frame decodes."""
    view = segment_view(src, video, spec, opts)
    first = next(view.iter_frames(), None)
    if first is None or first.image.shape[:2] != (view.height, view.width):
        raise MediaError(src, f"cannot decode segment {spec.segment_id} at {spec.start:.3f} s")
    return {
        "segment_id": spec.segment_id,
        "video_id": spec.video_id,
        "start": spec.start,
        "end": spec.start + view.duration,
        "fps": float(view.rate),
        "fps_fraction": f"{view.rate.numerator}/{view.rate.denominator}",
        "frames": view.frames,
        "width": view.width,
        "height": view.height,
        "has_audio": view.has_audio,
        "audio_stream": view.audio_stream,
        "label": spec.label,
        "source": Path(src).name,
    }


# --- the trim stage's worker -------------------------------------------------------------

@dataclass(frozen=True)
class PlanJob:
    source: Path
    spec: SegmentSpec
    opts: TrimOptions
    fingerprint: str


def plan_job(job: PlanJob) -> dict:
    """Plan one segment; returns its row of the segment index."""
    return {**plan_segment(job.source, probe(job.source), job.spec, job.opts), "fingerprint": job.fingerprint}
