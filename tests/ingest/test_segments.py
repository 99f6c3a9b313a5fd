"""annotations/segments.csv: planning and every validation error, with file:line: reason."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.core.errors import InputErrors
from pipeline.ingest.segments import plan_segments

DURATIONS = {"vid": 30.0, "other": 10.0}
HEADER = "video_id,start,end,label,note\n"


def plan(tmp_path: Path, body: str, **kwargs):
    path = tmp_path / "segments.csv"
    path.write_text(HEADER + body)
    return plan_segments(path, DURATIONS, **kwargs)


def errors_of(tmp_path: Path, body: str, **kwargs) -> list[str]:
    with pytest.raises(InputErrors) as err:
        plan(tmp_path, body, **kwargs)
    return [f"{e.line}: {e.reason}" for e in err.value.errors]


def test_segments_are_numbered_by_start_time(tmp_path: Path) -> None:
    segs = plan(tmp_path, "vid,20,25,b,\nvid,00:00:01.500,10,a,\n")
    assert [(s.segment_id, s.start, s.end, s.label, s.line) for s in segs] == [
        ("vid_000", 1.5, 10.0, "a", 3), ("vid_001", 20.0, 25.0, "b", 2)]


def test_unannotated_videos_follow_the_policy(tmp_path: Path) -> None:
    assert [s.segment_id for s in plan(tmp_path, "vid,0,5,,\n", unannotated="skip")] == ["vid_000"]
    whole = plan(tmp_path, "vid,0,5,,\n", unannotated="whole")
    assert [(s.segment_id, s.start, s.end) for s in whole] == [("other_000", 0.0, 10.0), ("vid_000", 0.0, 5.0)]


def test_an_end_a_hair_past_the_video_is_clamped(tmp_path: Path) -> None:
    (seg,) = plan(tmp_path, "other,5,10.03,,\n")
    assert seg.end == 10.0


def test_unknown_video(tmp_path: Path) -> None:
    assert errors_of(tmp_path, "ghost,0,1,,\n") == ["2: unknown video 'ghost' (not in manifests/sources.csv)"]


def test_a_video_whose_download_failed_is_skipped_not_an_error(tmp_path: Path) -> None:
    segs = plan(tmp_path, "vid,0,1,,\nbroken,0,1,,\n", known_videos={"vid", "broken"})
    assert [s.segment_id for s in segs] == ["vid_000"]


def test_end_not_after_start(tmp_path: Path) -> None:
    assert errors_of(tmp_path, "vid,5,5,,\n") == ["2: end 5.000 s is not after start 5.000 s"]


def test_overlapping_segments(tmp_path: Path) -> None:
    assert errors_of(tmp_path, "vid,0,10,,\nvid,9,12,,\n") == [
        "3: segment 9.000-12.000 s overlaps line 2 (0.000-10.000 s) of the same video"]


def test_times_past_the_end_of_the_video(tmp_path: Path) -> None:
    assert errors_of(tmp_path, "other,5,11,,\n") == ["2: segment 5.000-11.000 s passes the end of other (10.000 s)"]


def test_unparseable_time(tmp_path: Path) -> None:
    (error,) = errors_of(tmp_path, "vid,1.2.3,4,,\n")
    assert error.startswith("2: cannot read time '1.2.3'")


def test_bad_id(tmp_path: Path) -> None:
    (error,) = errors_of(tmp_path, "../vid,0,4,,\n")
    assert error.startswith("2: video_id '../vid' is not a safe identifier")


def test_every_problem_is_reported_at_once_with_the_file(tmp_path: Path) -> None:
    path = tmp_path / "segments.csv"
    path.write_text(HEADER + "vid,3,2,,\nghost,0,1,,\nvid,x,2,,\n")
    with pytest.raises(InputErrors) as err:
        plan_segments(path, DURATIONS)
    lines = str(err.value).splitlines()
    assert len(lines) == 3
    assert all(line.startswith(f"{path}:") for line in lines)
