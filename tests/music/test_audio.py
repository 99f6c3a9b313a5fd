"""Audio: EBU R128 normalisation and 24 fps features with exact alignment."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyloudnorm
import pytest
import soundfile as sf

from pipeline.music.audio import FEATURE_SR, FPS, LoudnessOptions, compute_features, feature_rate, normalise_loudness
from tests.conftest import ffmpeg


def click_track(bpm: float, seconds: float, sr: int = FEATURE_SR, first: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Short decaying 1 kHz clicks at ``bpm``; returns the audio and the click times."""
    y = np.zeros(int(seconds * sr), np.float32)
    times = np.arange(first, seconds - 0.1, 60.0 / bpm)
    n = np.arange(int(0.03 * sr))
    click = np.sin(2 * np.pi * 1000 * n / sr) * np.exp(-n / (0.005 * sr))
    for t in times:
        i = int(round(t * sr))
        y[i: i + len(click)] += click[: len(y) - i]
    return y, times


def test_beat_flags_land_within_a_frame_of_the_clicks() -> None:
    y, clicks = click_track(120, 30)
    f = compute_features(y)
    assert f.tempo == pytest.approx(120, rel=0.03)
    beat_frames = np.flatnonzero(f.beat)
    # every beat is within one frame of a click, and nearly every click after the first few has a beat
    for frame in beat_frames:
        assert np.min(np.abs(clicks * FPS - frame)) <= 1.0
    assert len(beat_frames) >= 0.9 * len(clicks[4:])


@pytest.mark.parametrize("fps", [24, 20, 30, 60])
def test_features_stay_on_the_grid_over_ten_minutes_at_any_rate(fps: int) -> None:
    seconds = 600
    y, clicks = click_track(100, seconds, sr=feature_rate(fps))
    f = compute_features(y, fps=fps)
    assert f.frames == 1 + len(y) // 512 == seconds * fps + 1  # frame k centred at k/fps s, no drift by design
    beats = np.flatnonzero(f.beat)

    def offsets(frames: np.ndarray) -> np.ndarray:  # signed distance (frames) to the nearest click
        click_frames = clicks * fps
        return np.array([fr - click_frames[np.argmin(np.abs(click_frames - fr))] for fr in frames])

    early, late = offsets(beats[5:60]) / fps, offsets(beats[-60:]) / fps  # seconds
    assert np.abs(early).max() <= 0.0625 and np.abs(late).max() <= 0.0625  # 1.5 frames at 24 fps
    assert abs(late.mean() - early.mean()) < min(1 / fps, 0.02)  # no drift between the first and the tenth minute
    onsets = np.flatnonzero(f.onset > 0.5 * f.onset.max())
    last_click_frame = clicks[-1] * fps
    assert np.min(np.abs(onsets - last_click_frame)) <= 1.0
    assert f.mfcc.shape == (f.frames, 39) and f.chroma.shape == (f.frames, 12)


def test_optional_feature_sets() -> None:
    y, _ = click_track(120, 10)
    f = compute_features(y, ("mel80", "beat_mfcc40"))
    assert f.extra["mel80"].shape == (f.frames, 80)
    assert f.extra["beat_mfcc40"].shape == (f.frames, 52)


def loudness(path: Path) -> float:
    y, sr = sf.read(path)
    return pyloudnorm.Meter(sr).integrated_loudness(y)


@pytest.mark.parametrize("clip", ["musicians_trio_music_raga.mp4", "dance_single_music_musepose.mp4"])
def test_quiet_and_loud_clips_come_out_at_the_target_loudness(tmp_path: Path, media_dir: Path, clip: str) -> None:
    out = tmp_path / "norm.wav"
    normalise_loudness(media_dir / "videos" / clip, out, LoudnessOptions(target_lufs=-23.0))
    assert sf.info(out).samplerate == 44100
    assert loudness(out) == pytest.approx(-23.0, abs=1.0)


@pytest.mark.parametrize("clip, start", [("musicians_trio_music_raga.mp4", "6.0"),
                                         ("dance_single_music_musepose.mp4", "1.0")])
def test_a_segment_of_a_longer_file_is_measured_and_normalised_alone_into_flac(tmp_path: Path, media_dir: Path,
                                                                            clip: str, start: str) -> None:
    # 4 s read straight from the video: -ss/-t go before the input in both passes.
    clip = media_dir / "videos" / clip
    out = tmp_path / "norm.flac"
    report = normalise_loudness(clip, out, LoudnessOptions(target_lufs=-23.0), audio_stream=1,
                                input_options=["-ss", start, "-t", "4.0"])
    info = sf.info(out)
    assert (info.format, info.samplerate) == ("FLAC", 44100)
    assert info.duration == pytest.approx(4.0, abs=0.03)
    alone = tmp_path / "alone.wav"
    ffmpeg("-ss", start, "-t", "4.0", "-i", str(clip), "-map", "0:a:0", "-c:a", "pcm_s16le", str(alone))
    assert report.input_i == pytest.approx(ebur128(alone)["I"], abs=0.3)  # measured on the segment only
    assert loudness(out) == pytest.approx(-23.0, abs=1.0)
    wav = tmp_path / "norm.wav"
    normalise_loudness(clip, wav, LoudnessOptions(target_lufs=-23.0), 1, ["-ss", start, "-t", "4.0"])
    assert np.array_equal(sf.read(out)[0], sf.read(wav)[0])  # FLAC is lossless
    assert out.stat().st_size < 0.75 * wav.stat().st_size


def test_cover_art_stream_is_ignored(tmp_path: Path, media_dir: Path) -> None:
    out = tmp_path / "norm.wav"
    normalise_loudness(media_dir / "music/music_vibe_ace_kevin_macleod.ogg", out, LoudnessOptions(), audio_stream=0)
    info = sf.info(out)
    assert info.samplerate == 44100 and info.duration == pytest.approx(61.46, abs=0.1)


def ebur128(path: Path) -> dict[str, float]:
    """Integrated loudness (I, LUFS) and loudness range (LRA, LU), measured by ffmpeg's ebur128."""
    import re
    import subprocess

    from pipeline.ingest.media import ffmpeg_exe

    log = subprocess.run([ffmpeg_exe(), "-hide_banner", "-nostats", "-i", str(path), "-af", "ebur128", "-f", "null",
                          "-"], capture_output=True, text=True, check=True).stderr
    summary = log[log.rindex("Summary:"):]
    return {key: float(re.search(rf"{key}:\s+(-?[\d.]+)", summary).group(1)) for key in ("I", "LRA")}


def test_a_wide_loudness_range_is_kept_linear_not_compressed(tmp_path: Path, media_dir: Path) -> None:
    # 15 s of music at full level, then the next 15 s 20 dB quieter: LRA far above the 7 LU target
    wide = tmp_path / "wide.wav"
    ffmpeg("-i", str(media_dir / "music/music_vibe_ace_kevin_macleod.ogg"), "-map", "0:a", "-t", "30", "-af",
           "volume='if(lt(t,15),1,0.1)':eval=frame", "-ar", "44100", str(wide))
    before = ebur128(wide)
    assert before["LRA"] > 14
    report = normalise_loudness(wide, tmp_path / "out.wav", LoudnessOptions(target_lufs=-23.0, loudness_range=7.0))
    after = ebur128(tmp_path / "out.wav")
    assert report.mode == "linear"
    assert after["LRA"] == pytest.approx(before["LRA"], abs=1.0)
    if report.peak_limited:  # the metrics say why the target was not reached
        assert after["I"] == pytest.approx(report.target_i, abs=1.0) and report.target_i < -23.0
    else:
        assert after["I"] == pytest.approx(-23.0, abs=1.0)


def test_a_gain_limited_by_the_true_peak_is_reported_not_compressed(tmp_path: Path, media_dir: Path) -> None:
    # a quiet clip with one loud click: reaching -14 LUFS linearly would push the click past -2 dBTP
    quiet = tmp_path / "quiet.wav"
    ffmpeg("-i", str(media_dir / "music/music_vibe_ace_kevin_macleod.ogg"), "-map", "0:a", "-t", "20", "-af",
           "volume=0.05", "-ar", "44100", str(quiet))
    y, sr = sf.read(quiet)
    y[sr * 5: sr * 5 + 200] = 0.9
    sf.write(quiet, y, sr)
    report = normalise_loudness(quiet, tmp_path / "out.wav", LoudnessOptions(target_lufs=-14.0, true_peak=-2.0))
    assert report.mode == "linear" and report.peak_limited and report.target_i < -14.0
    assert ebur128(tmp_path / "out.wav")["I"] == pytest.approx(report.target_i, abs=1.0)
