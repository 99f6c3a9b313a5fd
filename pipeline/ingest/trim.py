"""Cut one dance segment out of a source video: frame-accurate, constant frame rate, with audio.

Frame k of a segment shows the source at ``start + k / fps`` (ffmpeg's accurate seek,
then the ``fps`` filter on the seek-relative clock). The segment gets exactly
``round((end - start) * fps)`` frames. Phone videos come out upright (ffmpeg autorotates
when transcoding). Alongside the H.264/AAC mp4 (for QC and playback) the segment's audio
is written losslessly as 16-bit PCM WAV at the source's sample rate, for the audio stage.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from pipeline.core.storage import atomic_path
from pipeline.ingest.media import VideoInfo, probe, run_ffmpeg
from pipeline.ingest.segments import SegmentSpec


@dataclass(frozen=True)
class TrimOptions:
    fps: str = "source"     # "source" or a rate like "30" / "30000/1001"
    max_side: int = 1280    # 0 keeps the size
    crf: int = 18
    preset: str = "veryfast"


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


def cut_segment(src: Path, video: VideoInfo, spec: SegmentSpec, mp4: Path, wav: Path | None,
                opts: TrimOptions) -> dict:
    """Write ``mp4`` (and ``wav`` when the video has audio and ``wav`` is given); return facts."""
    rate = segment_rate(opts, video)
    frames = int(round((spec.end - spec.start) * rate))
    if frames < 1:
        raise ValueError(f"segment {spec.segment_id} is shorter than one frame")
    duration = frames / rate
    width, height = output_size(video.width, video.height, opts.max_side)
    with_audio = video.has_audio and wav is not None
    exact = ["-fflags", "+bitexact", "-flags:v", "+bitexact", "-flags:a", "+bitexact", "-map_metadata", "-1"]
    with contextlib.ExitStack() as stack:
        tmp_mp4 = stack.enter_context(atomic_path(mp4))
        tmp_wav = stack.enter_context(atomic_path(wav)) if with_audio else None
        args = ["-ss", f"{spec.start:.6f}", "-i", str(src), "-t", f"{float(duration):.6f}",
                "-map", f"0:{video.video_stream}", *(["-map", f"0:{video.audio_stream}"] if video.has_audio else []),
                "-vf", f"fps={rate.numerator}/{rate.denominator},scale={width}:{height}:flags=bicubic",
                "-frames:v", str(frames), "-fps_mode", "cfr",
                "-c:v", "libx264", "-preset", opts.preset, "-crf", str(opts.crf), "-pix_fmt", "yuv420p",
                "-c:a", "aac", "-b:a", "192k", *exact, "-movflags", "+faststart", "-f", "mp4", str(tmp_mp4)]
        if with_audio:
            args += ["-map", f"0:{video.audio_stream}", "-t", f"{float(duration):.6f}", "-c:a", "pcm_s16le", *exact,
                     "-f", "wav", str(tmp_wav)]
        run_ffmpeg(args, subject=src)
        cut = probe(tmp_mp4)
    return {
        "segment_id": spec.segment_id,
        "video_id": spec.video_id,
        "start": spec.start,
        "end": spec.start + float(duration),
        "fps": float(rate),
        "fps_fraction": f"{rate.numerator}/{rate.denominator}",
        "frames": cut.frames,
        "width": cut.width,
        "height": cut.height,
        "has_audio": with_audio,
        "label": spec.label,
        "path": mp4.name,
        "wav_path": wav.name if with_audio else "",
    }


# --- the trim stage's worker -------------------------------------------------------------

@dataclass(frozen=True)
class CutJob:
    source: Path
    spec: SegmentSpec
    out_dir: Path
    opts: TrimOptions
    fingerprint: str


def cut_job(job: CutJob) -> dict:
    """Cut one segment; returns its row of the segment index."""
    row = cut_segment(job.source, probe(job.source), job.spec, job.out_dir / f"{job.spec.segment_id}.mp4",
                      job.out_dir / f"{job.spec.segment_id}.wav", job.opts)
    return {**row, "fingerprint": job.fingerprint}
