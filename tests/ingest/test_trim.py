"""Cutting segments: frame-accurate, constant frame rate, audio kept; the trim stage end to end."""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest

from pipeline.ingest.catalog import read_index
from pipeline.ingest.media import iter_frames, probe
from pipeline.ingest.segments import SegmentSpec
from pipeline.ingest.trim import TrimOptions, cut_segment, output_size
from tests.conftest import make_test_video, set_params


def _frames(path: Path, indices: set[int]) -> dict[int, np.ndarray]:
    return {f.index: f.image.astype(np.float32) for f in iter_frames(path) if f.index in indices}


def test_cut_has_the_requested_duration_audio_and_constant_rate(tmp_path: Path, dance_clip: Path) -> None:
    video = probe(dance_clip)
    spec = SegmentSpec("dance_000", "dance", 2.3, 7.1)
    row = cut_segment(dance_clip, video, spec, tmp_path / "s.mp4", tmp_path / "s.wav", TrimOptions(max_side=0))
    cut = probe(tmp_path / "s.mp4")
    assert abs(cut.duration - 4.8) <= 1 / 24
    assert row["frames"] == cut.frames == round(4.8 * 24)
    assert cut.has_audio and row["has_audio"]
    times = [f.time for f in iter_frames(tmp_path / "s.mp4")]
    assert np.allclose(np.diff(times), 1 / 24, atol=1e-6)  # CFR: every step is exactly one frame
    with wave.open(str(tmp_path / "s.wav")) as wav:
        assert wav.getframerate() == 44100
        assert wav.getnframes() / 44100 == pytest.approx(cut.frames / 24, abs=1 / 24)


def test_segment_frame_k_shows_the_source_at_start_plus_k_over_fps(tmp_path: Path, dance_clip: Path) -> None:
    video = probe(dance_clip)
    spec = SegmentSpec("dance_000", "dance", 2.5, 4.0)  # source frame 60 = segment frame 0
    cut_segment(dance_clip, video, spec, tmp_path / "s.mp4", None, TrimOptions(max_side=0, crf=10))
    seg = _frames(tmp_path / "s.mp4", {0, 20})
    src = _frames(dance_clip, {59, 60, 61, 79, 80, 81})
    for k, expected in ((0, 60), (20, 80)):
        errors = {i: float(np.abs(seg[k] - src[i]).mean()) for i in (expected - 1, expected, expected + 1)}
        assert min(errors, key=errors.get) == expected, errors


def test_rate_conversion_and_downscale(tmp_path: Path) -> None:
    src = make_test_video(tmp_path / "src.mp4", seconds=3, fps="30000/1001", size="640x360")
    video = probe(src)
    spec = SegmentSpec("v_000", "v", 0.5, 2.5)
    row = cut_segment(src, video, spec, tmp_path / "s.mp4", tmp_path / "s.wav",
                      TrimOptions(fps="25", max_side=320))
    cut = probe(tmp_path / "s.mp4")
    assert (cut.width, cut.height, cut.fps, cut.frames) == (320, 180, 25.0, 50)
    assert row["fps_fraction"] == "25/1"


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


def test_trim_stage_cuts_indexes_and_skips_up_to_date_segments(project: Path, media_dir: Path) -> None:
    from stages import download, trim

    _demo_project(project, media_dir, "dance,1,3\ndance,5,6.5\nsolo,0,2\n")
    set_params(project, "trim", unannotated="skip", max_side=480)
    download.run(project)
    trim.run(project)
    seg_dir = project / "data/segments"
    index = list(read_index(seg_dir).values())
    assert [(r["segment_id"], r["frames"], r["has_audio"]) for r in index] == [
        ("dance_000", 48, True), ("dance_001", 36, True), ("solo_000", 60, False)]
    assert (seg_dir / "dance_001.wav").exists() and not (seg_dir / "solo_000.wav").exists()
    before = {p.name: p.stat().st_mtime_ns for p in seg_dir.glob("*.mp4")}

    # Drop one segment, keep the others: only the index changes, nothing is re-cut.
    (project / "annotations/segments.csv").write_text("video_id,start,end\ndance,1,3\nsolo,0,2\n")
    trim.run(project)
    after = {p.name: p.stat().st_mtime_ns for p in seg_dir.glob("*.mp4")}
    assert after == {k: v for k, v in before.items() if k != "dance_001.mp4"}
    assert not (seg_dir / "dance_001.wav").exists()


def test_trim_stage_refuses_invalid_annotations_naming_every_line(project: Path, media_dir: Path) -> None:
    from pipeline.core.errors import InputErrors
    from stages import download, trim

    _demo_project(project, media_dir, "dance,3,1\nghost,0,1\n")
    download.run(project)
    with pytest.raises(InputErrors) as err:
        trim.run(project)
    assert [e.line for e in err.value.errors] == [2, 3]
    assert not (project / "data/segments/index.parquet").exists()
