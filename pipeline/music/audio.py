"""Audio: EBU R128 loudness normalisation and music features on the motion's clock.

Alignment rule: features are computed from the audio resampled to fps x 512 Hz (12288 Hz
at the default 24 fps) with a hop of 512 samples and centred frames, so feature frame k is
centred at exactly k / fps s on the segment clock, the same instant as motion frame k.
There is no drift: the hop is an exact 1/fps s, not a rounded 44100/fps. Beats are tracked
on full-resolution audio (``beats.py``) and placed on that grid from their exact times.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import librosa
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.core.storage import atomic_path
from pipeline.ingest.media import ffmpeg_exe
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.music.beats import DEFAULT_TRACKER, Beats, beat_flags, track_beats

FPS = 24
HOP = 512
FEATURE_SR = FPS * HOP  # 12288 Hz
OUTPUT_SR = 44100


@dataclass(frozen=True)
class LoudnessOptions:
    target_lufs: float = -23.0
    true_peak: float = -2.0
    loudness_range: float = 7.0  # only a floor: a wider input range is kept (linear gain, never compression)


@dataclass(frozen=True)
class LoudnessReport:
    """What normalisation did to one file (EBU R128 figures from ffmpeg's loudnorm)."""

    input_i: float      # integrated loudness, LUFS
    input_lra: float    # loudness range, LU
    input_tp: float     # true peak, dBTP
    output_i: float
    output_lra: float
    output_tp: float
    mode: str           # "linear" (one gain for the whole file) or "dynamic"
    target_i: float     # the target actually used: lower than asked when the true-peak ceiling limits the gain
    peak_limited: bool  # the gain was limited by the true-peak ceiling, so output_i is below the asked target

    def as_dict(self) -> dict:
        return {k: (round(v, 2) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


def normalise_loudness(src: Path, out: Path, opts: LoudnessOptions, audio_stream: int | None = None,
                       input_options: Sequence[str] = ()) -> LoudnessReport:
    """EBU R128 two-pass *linear* normalisation with ffmpeg-normalize to 44.1 kHz 16-bit audio:
    FLAC when ``out`` ends in ``.flac`` (lossless, about half the size of WAV), else WAV.

    Linear on purpose: dynamic mode compresses the music, which changes onset strengths
    and therefore beats. A loudness range above ``opts.loudness_range`` is kept, and when
    the true-peak ceiling does not allow the full gain, the target is lowered (and the
    report says so) instead of compressing. ``audio_stream`` selects the stream
    explicitly (files may carry cover art or several tracks). ``input_options`` go before the
    input in both passes (e.g. ``-ss``/``-t``: a segment of a longer file).
    """
    from ffmpeg_normalize import FFmpegNormalize

    os.environ["FFMPEG_PATH"] = ffmpeg_exe()  # ffmpeg-normalize finds the wheel's ffmpeg through this
    codec, container = ("flac", "flac") if Path(out).suffix == ".flac" else ("pcm_s16le", "wav")
    with atomic_path(Path(out)) as tmp:
        normaliser = FFmpegNormalize(
            normalization_type="ebu", target_level=opts.target_lufs, true_peak=opts.true_peak,
            loudness_range_target=opts.loudness_range, keep_lra_above_loudness_range_target=True,
            auto_lower_loudness_target=True, dynamic=False, sample_rate=OUTPUT_SR, audio_codec=codec,
            video_disable=True, subtitle_disable=True, metadata_disable=True, chapters_disable=True,
            audio_streams=[audio_stream] if audio_stream is not None else None, output_format=container,
            extension=container, keep_bit_depth=False, extra_input_options=list(input_options) or None,
            # FLAC: 16 bit as the WAV; a fixed block size, since loudnorm hands over frames longer
            # than a FLAC block may be (88184 samples on the demo clip: "invalid block size").
            extra_output_options=["-sample_fmt", "s16", "-frame_size", "4608"] if codec == "flac" else None)
        normaliser.add_media_file(str(src), str(tmp))
        try:
            normaliser.run_normalization()
        except Exception as exc:  # ffmpeg-normalize raises its own error types
            raise MediaError(src, f"loudness normalisation failed: {exc}") from None
        stats = [s for s in normaliser.media_files[0].get_stats()]
    if not stats or not stats[0].get("ebu_pass1") or not stats[0].get("ebu_pass2"):
        raise MediaError(src, "loudness normalisation gave no EBU R128 statistics")
    first, second = stats[0]["ebu_pass1"], stats[0]["ebu_pass2"]
    input_i, input_tp = float(first["input_i"]), float(first["input_tp"])
    # the same rule as ffmpeg-normalize's auto_lower_loudness_target, to report what was used
    target = min(opts.target_lufs, input_i - input_tp + opts.true_peak - 0.1)
    return LoudnessReport(
        input_i=input_i, input_lra=float(first["input_lra"]), input_tp=input_tp,
        output_i=float(second["output_i"]), output_lra=float(second["output_lra"]),
        output_tp=float(second["output_tp"]), mode=str(second.get("normalization_type", "")),
        target_i=round(target, 2), peak_limited=bool(target < opts.target_lufs))


@dataclass
class AudioFeatures:
    frames: int
    fps: float
    mfcc: np.ndarray       # frames x 39: MFCC-13, delta, delta-delta
    chroma: np.ndarray     # frames x 12
    onset: np.ndarray      # frames: onset strength
    beat: np.ndarray       # frames: 1 on the frame nearest to each beat, else 0
    beat_times: np.ndarray  # seconds on the segment clock (exact, from the full-resolution tracker)
    downbeat_times: np.ndarray
    beats_per_bar: int
    tempo: float           # beats per minute
    extra: dict            # optional feature sets, name -> frames x d


def feature_rate(fps: float) -> int:
    """The sample rate whose hop of HOP samples is exactly one motion frame."""
    rate = fps * HOP
    if abs(rate - round(rate)) > 1e-9:
        raise ValueError(f"fps {fps} x hop {HOP} is not a whole sample rate")
    return int(round(rate))


def read_mono(path: Path) -> tuple[np.ndarray, int]:
    """A sound file decoded once at its own rate, channels averaged (as ``librosa.load`` does)."""
    import soundfile

    y, sr = soundfile.read(str(path), dtype="float32", always_2d=True)
    return y.mean(axis=1), int(sr)


def load_for_features(path: Path, fps: float = FPS) -> np.ndarray:
    y, _ = librosa.load(str(path), sr=feature_rate(fps), mono=True)
    return y


def features_of_file(path: Path, fps: float = FPS, extra_sets: tuple[str, ...] = ()) -> AudioFeatures:
    """Features of any file ffmpeg reads, with the default tracker's beats: what the audio stage
    computes, for music outside the corpus (``dance3d sample``)."""
    from pipeline.music.beats import RNN_SR

    y, _ = librosa.load(str(path), sr=RNN_SR, mono=True)
    low = librosa.resample(y, orig_sr=RNN_SR, target_sr=feature_rate(fps), res_type="soxr_hq")
    return compute_features(low, extra_sets, fps, track_beats(y, RNN_SR))


def compute_features(y: np.ndarray, extra_sets: tuple[str, ...] = (), fps: float = FPS,
                     beats: Beats | None = None) -> AudioFeatures:
    """Features of mono audio at ``feature_rate(fps)``; frame k is centred at k / fps s.

    ``beats``: from ``track_beats`` on full-resolution audio (``read_mono``); when absent
    librosa's tracker runs on ``y`` itself, upsampled (fine for tests, less exact for real music).
    """
    sr = feature_rate(fps)
    if len(y) < HOP:
        raise ValueError("audio shorter than one feature frame")
    n_fft = 2048
    mfcc = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=13, n_fft=n_fft, hop_length=HOP)
    width = min(9, mfcc.shape[1] - (1 - mfcc.shape[1] % 2))
    if width >= 3:
        delta = librosa.feature.delta(mfcc, width=width)
        delta2 = librosa.feature.delta(mfcc, order=2, width=width)
    else:
        delta = delta2 = np.zeros_like(mfcc)
    onset = librosa.onset.onset_strength(y=y, sr=sr, hop_length=HOP)
    chroma = librosa.feature.chroma_stft(y=y, sr=sr, n_fft=n_fft, hop_length=HOP)
    frames = mfcc.shape[1]
    beats = beats if beats is not None else track_beats(y, sr, "librosa")
    beat = beat_flags(beats.times, frames, fps)
    extra = {}
    if "mel80" in extra_sets:  # Transflower-style: 80-band log-mel at the motion rate
        mel = librosa.feature.melspectrogram(y=y, sr=sr, n_fft=n_fft, hop_length=HOP, n_mels=80)
        extra["mel80"] = librosa.power_to_db(mel).T[:frames]
    if "beat_mfcc40" in extra_sets:  # DanceNet3D-style: per-beat MFCC-40 + chroma, held over each beat
        mfcc40 = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=40, n_fft=n_fft, hop_length=HOP)
        beat_frames = np.unique(np.clip(np.rint(beats.times * fps).astype(int), 0, frames))
        bounds = librosa.util.fix_frames(beat_frames, x_min=0, x_max=frames)
        synced = librosa.util.sync(np.vstack([mfcc40, chroma]), bounds, aggregate=np.mean)
        per_frame = np.zeros((frames, synced.shape[0]))
        for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            per_frame[a:b] = synced[:, i]
        extra["beat_mfcc40"] = per_frame
    return AudioFeatures(
        frames=frames, fps=float(fps),
        mfcc=np.vstack([mfcc, delta, delta2]).T.astype(np.float32),
        chroma=chroma.T.astype(np.float32),
        onset=onset[:frames].astype(np.float32),
        beat=beat,
        beat_times=np.asarray(beats.times, np.float64),
        downbeat_times=np.asarray(beats.downbeats, np.float64),
        beats_per_bar=int(beats.beats_per_bar),
        tempo=float(beats.tempo),
        extra={k: v.astype(np.float32) for k, v in extra.items()},
    )


# --- the audio stage's worker ------------------------------------------------------------

@dataclass(frozen=True)
class AudioJob:
    segment: SegmentVideo  # the segment's audio is read from its source
    out_audio: Path      # 44.1 kHz, EBU R128, FLAC
    out_features: Path
    loudness: LoudnessOptions
    extra_sets: tuple[str, ...]
    fps: float
    params: dict
    inputs: dict
    fingerprint: str
    tracker: str = DEFAULT_TRACKER


def audio_segment(job: AudioJob) -> dict:
    from pipeline.music.featurefile import features_table, write_features

    seg = job.segment
    loudness = normalise_loudness(seg.source, job.out_audio, job.loudness, seg.audio_stream, seg.audio_seek())
    y, sr = read_mono(job.out_audio)  # decoded once: the tracker and the features resample it as they need
    beats = track_beats(y, sr, job.tracker)
    low = librosa.resample(y, orig_sr=sr, target_sr=feature_rate(job.fps), res_type="soxr_hq")
    f = compute_features(low, tuple(job.extra_sets), job.fps, beats)
    meta = {"segment_id": job.out_features.stem, "fps": job.fps, "tempo": f.tempo, "loudness": loudness.as_dict(),
            "beat_times": [round(t, 6) for t in f.beat_times],
            "downbeat_times": [round(t, 6) for t in f.downbeat_times], "beats_per_bar": f.beats_per_bar,
            "beat_tracker": beats.tracker, "beat_tracker_detail": beats.description,
            "downbeat_method": beats.downbeat_method,
            "alignment": f"frame k is centred at k/{job.fps:g} s: audio resampled to {feature_rate(job.fps)} Hz, "
                         f"hop {HOP}, centred frames; beat flags at the frame nearest to each exact beat time"}
    table = features_table(f.frames, job.fps, f.mfcc, f.chroma, f.onset, f.beat, f.extra)
    write_features(job.out_features, table, meta, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"frames": f.frames, "tempo": f.tempo, "loudness": loudness.as_dict()}
