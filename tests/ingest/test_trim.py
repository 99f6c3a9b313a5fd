"""Segments are views on their downloaded video: frame-accurate, constant frame rate, audio
cut from the source; the trim stage writes only the index."""

from __future__ import annotations

import subprocess
import wave
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from pipeline.core.errors import MediaError
from pipeline.ingest.catalog import read_index
from pipeline.ingest.media import ffmpeg_exe, iter_frames, probe
from pipeline.ingest.segments import SegmentSpec
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.ingest.trim import TrimOptions, output_size, plan_segment, segment_view
from tests.conftest import ffmpeg, make_test_video, set_params


def _frames(path: Path, indices: set[int]) -> dict[int, np.ndarray]:
    return {f.index: f.image.astype(np.float32) for f in iter_frames(path) if f.index in indices}


def _ffmpeg_frames(src: Path, start: float, frames: int, rate: str, size: tuple[int, int]) -> np.ndarray:
    """What the re-encoding trim used to select: ffmpeg's accurate seek, then its fps filter and bicubic scale."""
    w, h = size
    raw = subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-ss", f"{start:.6f}", "-i", str(src),
                          "-vf", f"fps={rate},scale={w}:{h}:flags=bicubic", "-frames:v", str(frames),
                          "-f", "rawvideo", "-pix_fmt", "bgr24", "-"], capture_output=True, check=True).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, h, w, 3).astype(np.float32)


def test_a_segment_has_the_requested_frames_on_a_constant_clock_and_its_audio(tmp_path: Path,
                                                                            dance_clip: Path) -> None:
    video = probe(dance_clip)
    row = plan_segment(dance_clip, video, SegmentSpec("dance_000", "dance", 2.3, 7.1), TrimOptions(max_side=480))
    assert row["frames"] == round(4.8 * 24) and row["end"] == pytest.approx(2.3 + 115 / 24)
    assert (row["width"], row["height"], row["has_audio"], row["source"]) == (270, 480, True, dance_clip.name)
    view = SegmentVideo.from_index(dance_clip.parent, row)
    frames = list(view.iter_frames())
    assert [f.index for f in frames] == list(range(115))
    assert np.allclose([f.time for f in frames], np.arange(115) / 24)
    assert {f.image.shape for f in frames} == {(480, 270, 3)}
    wav = tmp_path / "a.wav"
    ffmpeg(*view.audio_seek(), "-i", str(view.source), "-map", "0:a:0", "-c:a", "pcm_s16le", str(wav))
    with wave.open(str(wav)) as w:
        assert w.getframerate() == 44100
        assert w.getnframes() / 44100 == pytest.approx(115 / 24, abs=1 / 24)


def test_segment_frame_k_is_the_source_frame_at_start_plus_k_over_fps(dance_clip: Path) -> None:
    video = probe(dance_clip)
    view = segment_view(dance_clip, video, SegmentSpec("dance_000", "dance", 2.5, 4.0), TrimOptions(max_side=0))
    seg = {f.index: f.image.astype(np.float32) for f in view.iter_frames() if f.index in (0, 20)}
    src = _frames(dance_clip, {59, 60, 61, 79, 80, 81})  # source frame 60 = segment frame 0
    for k, expected in ((0, 60), (20, 80)):
        errors = {i: float(np.abs(seg[k] - src[i]).mean()) for i in (expected - 1, expected, expected + 1)}
        assert min(errors, key=errors.get) == expected, errors
        assert errors[expected] == 0  # the very pixels: nothing is re-encoded


def test_rate_conversion_and_downscale_select_what_ffmpeg_selects(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=3, fps="30000/1001", size="640x360")
    row = plan_segment(src, probe(src), SegmentSpec("v_000", "v", 0.5, 2.5), TrimOptions(fps="25", max_side=320))
    assert (row["width"], row["height"], row["fps_fraction"], row["frames"]) == (320, 180, "25/1", 50)
    ours = np.stack([f.image for f in SegmentVideo.from_index(tmp_path, row).iter_frames()]).astype(np.float32)
    theirs = _ffmpeg_frames(src, 0.5, 50, "25", (320, 180))
    assert len(theirs) == len(ours) == 50
    per_frame = np.abs(ours - theirs).mean(axis=(1, 2, 3))
    # The same source frames (a neighbour differs by far more): only YUV-to-BGR rounding differs.
    assert per_frame.max() < 2.0, per_frame


def test_an_upsampled_segment_repeats_frames_and_a_late_start_seeks(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=6, fps="10", size="160x120", audio=False)
    row = plan_segment(src, probe(src), SegmentSpec("v_000", "v", 4.0, 5.0), TrimOptions(fps="20"))
    frames = [f.image for f in SegmentVideo.from_index(tmp_path, row).iter_frames()]
    source = [f.image for f in iter_frames(src)][40:50]
    assert len(frames) == 20 and not row["has_audio"]
    for k, image in enumerate(frames):  # slot k shows the latest source frame before (k + 1/2) / 20 s
        assert np.array_equal(image, source[k // 2]), k


def test_a_segment_past_the_end_of_its_source_holds_the_last_frame(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=2, fps="25", size="160x120", audio=False)
    view = SegmentVideo(src, 1.0, Fraction(25), 40, 160, 120)  # 1.6 s from 1.0 s: 0.6 s past the end
    frames = [f.image for f in view.iter_frames()]
    assert len(frames) == 40 and all(np.array_equal(f, frames[24]) for f in frames[25:])


def test_a_rotated_phone_video_gives_upright_segment_frames(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=2, fps="25", size="320x180", audio=False)
    rotated = tmp_path / "rotated.mp4"
    ffmpeg("-display_rotation", "90", "-i", str(src), "-c", "copy", str(rotated))
    row = plan_segment(rotated, probe(rotated), SegmentSpec("r_000", "r", 0.0, 1.0), TrimOptions())
    assert (row["width"], row["height"]) == (180, 320)
    first = next(SegmentVideo.from_index(tmp_path, row).iter_frames()).image
    assert first.shape == (320, 180, 3)
    assert np.abs(first.astype(float) - next(iter_frames(rotated)).image).mean() < 1.0


def test_a_source_that_cannot_be_decoded_at_the_start_fails_planning_naming_it(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=2, fps="25", size="160x120", audio=False)
    info = probe(src)
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(src.read_bytes()[:2000])
    with pytest.raises(MediaError, match="broken.mp4"):
        plan_segment(broken, info, SegmentSpec("b_000", "b", 0.5, 1.5), TrimOptions())


def test_output_size_is_even_and_bounded() -> None:
    assert output_size(1080, 1920, 1280) == (720, 1280)
    assert output_size(333, 201, 0) == (334, 202)
    assert output_size(300, 200, 1280) == (300, 200)


def _demo_project(project: Path, media_dir: Path, annotations: str) -> None:
    videos = media_dir / "videos"
    (project / "manifests/sources.csv").write_text(
        "video_id,url\n"
        f"dance,{(videos / 'dance_single_music_musepose.mp4').as_uri()}\n"
        f"solo,{videos / 'dance_solo_384x496_30fps.mp4'}\n"
    )
    (project / "annotations/segments.csv").write_text("video_id,start,end\n" + annotations)


def test_trim_stage_indexes_views_and_skips_up_to_date_segments(project: Path, media_dir: Path) -> None:
    from stages import download, trim

    _demo_project(project, media_dir, "dance,1,3\ndance,5,6.5\nsolo,0,2\n")
    set_params(project, "trim", unannotated="skip", max_side=480)
    download.run(project)
    seg_dir = project / "data/segments"
    seg_dir.mkdir(parents=True)
    (seg_dir / "dance_000.mp4").write_bytes(b"a copy made by index version 1")
    trim.run(project)
    index = list(read_index(seg_dir).values())
    assert [(r["segment_id"], r["frames"], r["has_audio"], r["source"]) for r in index] == [
        ("dance_000", 48, True, "dance.mp4"), ("dance_001", 36, True, "dance.mp4"), ("solo_000", 60, False, "solo.mp4")]
    assert sorted(p.name for p in seg_dir.iterdir() if not p.name.startswith("_")) == ["index.parquet"]

    # Drop one segment, keep the others: the index loses its row, the others are not planned again.
    (project / "annotations/segments.csv").write_text("video_id,start,end\ndance,1,3\nsolo,0,2\n")
    trim.run(project)
    again = read_index(seg_dir)
    assert list(again) == ["dance_000", "solo_000"]
    assert again["dance_000"] == index[0] and again["solo_000"] == index[2]


def test_trim_stage_refuses_invalid_annotations_naming_every_line(project: Path, media_dir: Path) -> None:
    from pipeline.core.errors import InputErrors
    from stages import download, trim

    _demo_project(project, media_dir, "dance,3,1\nghost,0,1\n")
    download.run(project)
    with pytest.raises(InputErrors) as err:
        trim.run(project)
    assert [e.line for e in err.value.errors] == [2, 3]
    assert not (project / "data/segments/index.parquet").exists()


def _b_frame_video(path: Path, rate: str, setpts: str = "PTS") -> Path:
    """A test pattern with B-frames (x264's veryfast: about half the frames are referred to by none),
    a keyframe every 2 s; ``setpts`` may make its clock irregular."""
    ffmpeg("-f", "lavfi", "-i", f"testsrc2=size=160x120:rate={rate}:duration=4", "-vf", f"setpts={setpts}",
           "-fps_mode", "passthrough", "-c:v", "libx264", "-preset", "veryfast", "-g", rate.split("/")[0],
           "-pix_fmt", "yuv420p", str(path))
    return path


@pytest.mark.parametrize(("rate", "setpts", "view_rate", "start"), [
    ("24", "PTS", Fraction(24), 0.0),                        # the source's own clock
    ("30", "PTS", Fraction(30), 1.3),                        # a late start: decoded from the keyframe before
    ("60", "PTS", Fraction(30), 0.4),                        # every other source frame, slots on a frame's edge
    ("24", "PTS", Fraction(30), 0.0),                        # upsampled: some source frames shown twice
    ("30", "PTS+0.012*mod(N\\,3)/TB", Fraction(30), 0.2),  # an irregular clock
])
def test_frames_a_view_does_not_keep_look_the_same_whether_or_not_the_decoder_skipped_them(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, rate: str, setpts: str, view_rate: Fraction,
        start: float) -> None:
    src = _b_frame_video(tmp_path / "b.mp4", rate, setpts)
    view = SegmentVideo(src, start, view_rate, 60, 160, 120)
    every = [f.image for f in view.iter_frames()]
    with caplog.at_level("DEBUG", logger="pipeline.ingest.segmentvideo"):
        kept = list(view.iter_frames(keep=lambda k: k % 3 == 0))
    assert [f.index for f in kept] == list(range(60))
    assert [f.image is not None for f in kept] == [k % 3 == 0 for k in range(60)]
    for k, frame in enumerate(kept):  # kept or not, each shows the very pixels of a full decode
        assert np.array_equal(frame.shown(), every[k]), k
    skipped = [r.message for r in caplog.records if "skipped" in r.message]
    assert skipped and int(skipped[0].split("skipped ")[1].split()[0]) > 0, skipped  # work saved


def test_a_view_can_start_at_a_later_frame_on_the_same_clock(tmp_path: Path) -> None:
    src = _b_frame_video(tmp_path / "b.mp4", "30")
    view = SegmentVideo(src, 0.5, Fraction(30), 90, 160, 120)
    every = [f.image for f in view.iter_frames()]
    later = list(view.iter_frames(first=50))
    assert [f.index for f in later] == list(range(50, 90))
    assert all(np.array_equal(f.image, every[f.index]) for f in later)
