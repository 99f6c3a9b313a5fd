"""Media layer: probing matches the known facts of the shared videos; bad files fail clearly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.core.errors import MediaError
from pipeline.ingest.media import count_frames, iter_frames, probe
from tests.conftest import ffmpeg, make_test_video

# Facts from shared/media/MEDIA.md (ffprobe): duration s, fps, width, height, has_audio, sample rate.
MEDIA_FACTS = {
    "dance_single_music_musepose.mp4": (12.0, 24.0, 1080, 1920, True, 44100),
    "musicians_trio_music_raga.mp4": (10.02, 25.0, 768, 576, True, 48000),
    "performance_audience_music_whitehouse.mp4": (26.73, 29.97, 640, 360, True, 44100),
    "movement_single_speech_taiji.mp4": (17.21, 23.976, 1280, 720, True, 44100),
    "dance_solo_384x496_30fps.mp4": (18.2, 30.0, 384, 496, False, None),
}


@pytest.mark.parametrize("name", sorted(MEDIA_FACTS))
def test_probe_matches_the_documented_facts(media_dir: Path, name: str) -> None:
    duration, fps, width, height, has_audio, rate = MEDIA_FACTS[name]
    info = probe(media_dir / "videos" / name)
    assert info.fps == pytest.approx(fps, abs=0.001)
    # MEDIA.md gives the container duration to 2 decimals; the video stream may end a frame earlier.
    assert info.duration == pytest.approx(duration, abs=1.0 / fps + 0.01)
    assert (info.width, info.height) == (width, height)
    assert info.has_audio is has_audio
    assert info.sample_rate == rate
    assert info.codec == "h264"
    assert info.rotation == 0
    assert info.frames == count_frames(media_dir / "videos" / name)


def test_frames_stream_with_their_timestamps(dance_clip: Path) -> None:
    info = probe(dance_clip)
    count = 0
    for frame in iter_frames(dance_clip):
        assert frame.time == pytest.approx(frame.index / info.fps, abs=1e-6)
        assert frame.image.shape == (info.height, info.width, 3)
        count += 1
    assert count == info.frames == 288


def test_rotated_phone_video_comes_out_upright(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=0.4, size="160x96", audio=False)
    rotated = tmp_path / "rotated.mp4"
    ffmpeg("-display_rotation", "90", "-i", str(src), "-c", "copy", str(rotated))
    upright = tmp_path / "upright.mp4"  # ffmpeg applies the display matrix when it transcodes
    ffmpeg("-i", str(rotated), "-c:v", "libx264", "-preset", "ultrafast", "-qp", "0", str(upright))

    info = probe(rotated)
    assert info.rotation == 90
    assert (info.width, info.height) == (96, 160)
    ours = next(iter_frames(rotated)).image.astype(float)
    reference = next(iter_frames(upright)).image.astype(float)
    assert ours.shape == reference.shape == (160, 96, 3)
    assert np.abs(ours - reference).mean() < 3.0
    # The opposite turn would be clearly wrong: the check can fail.
    wrong = np.rot90(np.rot90(ours))
    assert np.abs(wrong - reference).mean() > 20.0


def test_variable_frame_rate_keeps_true_timestamps(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "cfr.mp4", seconds=1.0, fps="30", audio=False)
    vfr = tmp_path / "vfr.mp4"
    # Keep frames 0,1, 5,6, 10,11, ... with their original times: irregular gaps.
    ffmpeg("-i", str(src), "-vf", "select='lt(mod(n\\,5)\\,2)'", "-fps_mode", "vfr",
           "-c:v", "libx264", "-preset", "ultrafast", str(vfr))
    times = [f.time for f in iter_frames(vfr)]
    expected = [n / 30 for n in range(30) if n % 5 < 2]
    assert times == pytest.approx(expected, abs=1e-3)


def test_zero_byte_file_is_named_with_the_reason(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(MediaError, match=r"empty\.mp4: file is empty \(0 bytes\)"):
        probe(empty)


def test_truncated_video_without_index_is_unreadable(tmp_path: Path, dance_clip: Path) -> None:
    # This file keeps its index (moov) at the end, so a cut copy has none.
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(dance_clip.read_bytes()[:1_500_000])
    with pytest.raises(MediaError, match=r"cut\.mp4: not a readable media file"):
        probe(cut)


def test_truncated_faststart_video_is_detected_from_its_index(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=2.0)
    fast = tmp_path / "fast.mp4"
    ffmpeg("-i", str(src), "-c", "copy", "-movflags", "+faststart", str(fast))
    data = fast.read_bytes()
    cut = tmp_path / "half.mp4"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(MediaError, match=r"half\.mp4: file is truncated"):
        probe(cut)


def test_audio_only_file_has_no_video_stream(media_dir: Path) -> None:
    with pytest.raises(MediaError, match="no video stream \\(audio-only file\\)"):
        probe(media_dir / "music/music_vibe_ace_kevin_macleod.ogg")


def test_garbage_bytes_are_not_media(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"this is not a video" * 100)
    with pytest.raises(MediaError, match=r"junk\.mp4: not a readable media file"):
        probe(junk)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MediaError, match=r"nope\.mp4: file not found"):
        probe(tmp_path / "nope.mp4")
