"""Track manifests: proposals, the checker's every error, and what clean makes of an edit."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.annotate.clipfile import read_clean
from pipeline.annotate.commands import check_manifests, seed_manifests
from pipeline.annotate.proposals import ProposalOptions
from pipeline.core.errors import InputErrors
from pipeline.pose.pose2dfile import Poses, SegmentInfo, write_pose2d
from pipeline.pose.trackfile import read_tracks
from pipeline.pose.trackfile import write_tracks as write_tracks_file
from tests.conftest import ffmpeg, run_stages, set_params, write_sources
from tests.pose.test_tracking import person

FPS = 24.0
HEADER = "track_id,start,end,keep,note,frames,mean_score,box_height,motion,reason\n"


def write_tracks(root: Path, seg_id: str, people: dict[int, list[int]], fps: float = FPS) -> Path:
    """A synthetic data/tracks file: track id -> the frames it is seen in (a dancer swaying)."""
    rows = []
    for track_id, frames in people.items():
        for f in frames:
            box, kp = person(300 + 200 * track_id + 40 * np.sin(f / 6), 400, 500, phase=f / 3)
            rows.append((f, track_id, box, kp))
    rows.sort(key=lambda r: (r[0], r[1]))
    n = len(rows)
    frame = np.array([r[0] for r in rows])
    poses = Poses(frame=frame, time=frame / fps, person=np.zeros(n), box=np.array([r[2] for r in rows]),
                  box_score=np.full(n, 0.9), keypoints=np.array([r[3] for r in rows]).reshape(n, 17, 3),
                  detected=np.ones(n, bool), feet=np.zeros((n, 4, 3)))
    path, pose2d = root / "data/tracks" / f"{seg_id}.parquet", root / "data/pose2d" / f"{seg_id}.parquet"
    frames_total = max(max(f) for f in people.values()) + 1
    segment = SegmentInfo(seg_id, fps, frames_total, 1280, 720)
    write_pose2d(pose2d, poses, segment, fingerprint="p1", params={}, inputs={})
    write_tracks_file(path, pose2d, poses, np.array([r[1] for r in rows]), segment, fingerprint="t1", params={},
                      inputs={"pose2d": "p1"})
    return path


def write_manifest_text(root: Path, seg_id: str, body: str, header: str = HEADER) -> Path:
    path = root / "manifests/tracks" / f"{seg_id}.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + body)
    return path


@pytest.fixture
def seg(project: Path) -> Path:
    # Track 1 over 0-9.958 s (frames 0-239), track 2 over 2-6 s (frames 48-143).
    write_tracks(project, "vid_000", {1: list(range(240)), 2: list(range(48, 144))})
    return project


def problems(root: Path, body: str, header: str = HEADER) -> list[str]:
    path = write_manifest_text(root, "vid_000", body, header)
    return [str(p).replace(str(path), "M") for p in check_manifests(root, [path], 2.0)]


def test_valid_manifest_has_no_problems(seg: Path) -> None:
    assert problems(seg, "1,0.000,9.958,yes,,,,,,\n2,2.000,5.958,no,audience,,,,,\n") == []


@pytest.mark.parametrize("body, expected", [
    ("7,0,1,yes,,,,,,\n1,0,9,yes,,,,,,\n2,2,5,no,,,,,,\n",
     "M:2: unknown track id 7 (tracks in vid_000: 1, 2)"),
    ("1,5,5,yes,,,,,,\n2,2,5,no,,,,,,\n", "M:2: start 5.000 s is not before end 5.000 s"),
    ("1,0,9,yes,,,,,,\n2,1.0,5,no,,,,,,\n", "M:3: span 1.000-5.000 s is outside track 2 (2.000-5.958 s)"),
    ("1,0,5,yes,,,,,,\n1,4,9,no,,,,,,\n2,2,5,no,,,,,,\n",
     "M:3: span 4.000-9.000 s of track 1 overlaps line 2 (0.000-5.000 s)"),
    ("1,0,9,maybe,,,,,,\n2,2,5,no,,,,,,\n", "M:2: keep must be yes or no, not 'maybe'"),
    ("1,0,9,yes,,,,,,\n1,0,9,yes,,,,,,\n2,2,5,no,,,,,,\n", "M:3: duplicate of line 2"),
    ("1,0,9,yes,,,,,,\nx,2,5,no,,,,,,\n", "M:3: track_id 'x' is not a whole number >= 0"),
    ("1,0:0:1.5,oops,yes,,,,,,\n2,2,5,no,,,,,,\n", "M:2: end: cannot read time 'oops' (use seconds like 12.5 or "
                                                   "HH:MM:SS.mmm)"),
])
def test_checker_errors_name_file_line_and_reason(seg: Path, body: str, expected: str) -> None:
    assert expected in problems(seg, body)


def test_missing_and_extra_header_columns(seg: Path) -> None:
    assert problems(seg, "1,0,9,yes\n", header="track_id,start,end,keep\n") == [
        "M:1: missing column(s) note, frames, mean_score, box_height, motion, reason in header "
        "['track_id', 'start', 'end', 'keep']"]
    (error,) = problems(seg, "1,0,9,yes,,,,,,,x\n", header=HEADER.strip() + ",colour\n")
    assert error.startswith("M:1: unknown column(s) colour")


def test_manifest_for_an_unknown_segment(seg: Path) -> None:
    path = write_manifest_text(seg, "ghost_000", "1,0,1,yes,,,,,,\n")
    (problem,) = check_manifests(seg, [path], 2.0)
    assert str(problem) == (f"{path}: manifest for an unknown segment: no {seg / 'data/tracks/ghost_000.parquet'} "
                            "(is the file name a tracked segment id?)")


def test_suspicious_but_valid_input_gives_warnings_only(seg: Path) -> None:
    found = problems(seg, "1,0,1,yes,,,,,,\n")
    assert found == ["M:2: warning: kept span is 1.00 s, shorter than clean.min_clip_seconds (2.0 s): "
                     "it will be dropped", "M: warning: track 2 has no row: it will be dropped"]


def test_check_command_exit_codes(seg: Path) -> None:
    write_manifest_text(seg, "vid_000", "1,0,9,yes,,,,,,\n2,2,5,no,,,,,,\n")
    ok = subprocess.run([sys.executable, "-m", "pipeline.cli", "--root", str(seg), "manifests", "check"],
                        capture_output=True, text=True)
    assert ok.returncode == 0 and ok.stdout.strip() == "0 errors, 0 warnings"
    write_manifest_text(seg, "vid_000", "1,0,9,yes,,,,,,\n9,2,5,no,,,,,,\n")
    bad = subprocess.run([sys.executable, "-m", "pipeline.cli", "--root", str(seg), "manifests", "check"],
                         capture_output=True, text=True)
    assert bad.returncode == 1
    assert "vid_000.csv:3: unknown track id 9" in bad.stdout


def clips_of(root: Path, seg_id: str = "vid_000") -> dict[str, tuple[int, int, int]]:
    """clip id -> (first frame, last frame, interpolated frames)."""
    clips = read_clean(root / "data/clean" / f"{seg_id}.parquet").clips
    return {c.clip_id: (int(c.frame.min()), int(c.frame.max()), int(c.interpolated.sum())) for c in clips}


def test_editing_a_manifest_changes_clean_output_exactly(seg: Path) -> None:
    write_manifest_text(seg, "vid_000", "1,0.000,9.958,yes,,,,,,\n2,2.000,5.958,yes,,,,,,\n")
    run_stages(seg, "clean")
    assert clips_of(seg) == {"vid_000_1_0": (0, 239, 0), "vid_000_2_0": (48, 143, 0)}
    # The annotator cuts track 1 in two around a swap at 3-5 s and rejects track 2.
    write_manifest_text(seg, "vid_000", "1,0.000,3.000,yes,,,,,,\n1,5.000,9.958,yes,,,,,,\n"
                                        "2,2.000,5.958,no,audience,,,,,\n")
    run_stages(seg, "clean")
    assert clips_of(seg) == {"vid_000_1_0": (0, 72, 0), "vid_000_1_1": (120, 239, 0)}


def test_short_gaps_are_filled_long_gaps_split_short_clips_drop(project: Path) -> None:
    # Seen 0-149 with a 5-frame hole at 50-54, then 180-199 (0.8 s), then 230-239 (a stub).
    frames = [f for f in range(150) if not 50 <= f < 55] + list(range(180, 200)) + list(range(230, 240))
    write_tracks(project, "vid_000", {1: frames})
    write_manifest_text(project, "vid_000", "1,0,9.958,yes,,,,,,\n")
    set_params(project, "clean", max_gap=12, min_clip_seconds=2.0)
    run_stages(project, "clean")
    assert clips_of(project) == {"vid_000_1_0": (0, 149, 5)}  # the 30-frame gaps split; short pieces drop
    (clip,) = read_clean(project / "data/clean/vid_000.parquet").clips
    assert sorted(clip.frame[clip.interpolated]) == [50, 51, 52, 53, 54]
    box = dict(zip(clip.frame.tolist(), clip.box))
    assert np.allclose(box[52], box[49] + (box[55] - box[49]) * 3 / 6, atol=1e-3)
    metrics = json.loads((project / "reports/clean.json").read_text())
    assert metrics["dropped_short_clips"] == 2  # 180-199 (0.8 s) and 230-239


def test_unannotated_segments_follow_the_param(seg: Path) -> None:
    set_params(seg, "clean", unannotated="skip")
    run_stages(seg, "clean")
    assert not (seg / "data/clean/vid_000.parquet").exists()
    set_params(seg, "clean", unannotated="accept")
    run_stages(seg, "clean")
    assert set(clips_of(seg)) == {"vid_000_1_0", "vid_000_2_0"}  # both sway: proposals keep them


def test_clean_refuses_an_invalid_manifest_naming_it(seg: Path) -> None:
    path = write_manifest_text(seg, "vid_000", "1,0,9,yes,,,,,,\n5,2,5,no,,,,,,\n")
    with pytest.raises(InputErrors, match=rf"{path}:3: unknown track id 5"):
        run_stages(seg, "clean")


def test_reseeding_never_overwrites_an_edited_manifest(seg: Path) -> None:
    written, kept = seed_manifests(seg, ProposalOptions())
    assert [p.name for p in written] == ["vid_000.csv"] and kept == []
    edited = written[0].read_text().replace(",yes,", ",no,")
    written[0].write_text(edited)
    written2, kept2 = seed_manifests(seg, ProposalOptions())
    assert written2 == [] and kept2 == written
    assert written[0].read_text() == edited


@pytest.fixture
def dancers_and_seated_group(tmp_path: Path, media_dir: Path) -> Path:
    """Two real dancers side by side above three seated musicians (static), 8 s, built with ffmpeg."""
    out = tmp_path / "stage.mp4"
    videos = media_dir / "videos"
    ffmpeg("-i", str(videos / "dance_single_music_musepose.mp4"), "-i", str(videos / "dance_solo_384x496_30fps.mp4"),
           "-i", str(videos / "musicians_trio_music_raga.mp4"), "-filter_complex",
           "[0:v]fps=24,scale=-2:496[a];[1:v]fps=24[b];[a][b]hstack=inputs=2[top];"
           "[2:v]fps=24,scale=664:-2[c];[top][c]vstack=inputs=2[v]",
           "-map", "[v]", "-map", "0:a", "-t", "8", "-c:v", "libx264", "-preset", "ultrafast", "-c:a", "aac", str(out))
    return out


def test_seeding_keeps_the_dancers_and_rejects_the_static_group(project: Path, dancers_and_seated_group: Path,
                                                                models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("stage", dancers_and_seated_group)])
    set_params(project, "trim", unannotated="whole")
    run_stages(project, "download", "trim", "pose2d", "track")
    (path,), _ = seed_manifests(project, ProposalOptions())
    tracks = read_tracks(project / "data/tracks/stage_000.parquet")
    centre_y = {t: float(np.median(tracks.box[tracks.of(t)][:, [1, 3]].mean(1))) for t in tracks.ids}
    manifest = list(csv.DictReader(line for line in path.read_text().splitlines() if not line.startswith("#")))
    dancers = {int(r["track_id"]) for r in manifest if centre_y[int(r["track_id"])] < 496}
    seated = {int(r["track_id"]) for r in manifest if centre_y[int(r["track_id"])] >= 496}
    assert len(dancers) == 2 and seated
    for row in manifest:
        if int(row["track_id"]) in dancers:
            assert row["keep"] == "yes", row
        else:
            assert row["keep"] == "no" and row["reason"], row
    assert any("nearly static" in r["reason"] or "legs not seen" in r["reason"]
               for r in manifest if int(r["track_id"]) in seated)
    # The musicians are found: the two in full in nearly every frame, and the one cut by the right
    # edge at times (the previous default, MoveNet with RTMDet at 0.5, never found her).
    centre_x, below = (tracks.box[:, 0] + tracks.box[:, 2]) / 2, (tracks.box[:, 1] + tracks.box[:, 3]) / 2 > 496
    seen = [len(np.unique(tracks.frame[below & (centre_x >= lo) & (centre_x < hi)])) / tracks.frames_total
            for lo, hi in ((0, 290), (290, 560), (560, 664))]
    assert seen[0] >= 0.95 and seen[1] >= 0.95 and seen[2] > 0.03, seen


def test_dancers_who_move_together_get_the_same_verdict_and_a_bystander_among_dancers_is_static() -> None:
    from pipeline.annotate.proposals import TrackStats, group_motion, reject_reason

    def track(k: int, motion: float) -> TrackStats:
        return TrackStats(k, 650, 0.0, 27.0, 0.8, 0.6, motion)

    opts = ProposalOptions()
    # A trio dancing one choreography: one of them a hair under the fixed threshold (0.0348 < 0.035).
    trio = [track(1, 0.0348), track(2, 0.037), track(3, 0.038)]
    assert [reject_reason(t, 0.6, opts, group_motion(trio, 0.6, opts)) for t in trio] == ["", "", ""]
    # A bystander among dancers is judged against them; a group that hardly moves is static as a whole.
    crew = [track(1, 0.10), track(2, 0.12), track(3, 0.011)]
    assert [bool(reject_reason(t, 0.6, opts, group_motion(crew, 0.6, opts))) for t in crew] == [False, False, True]
    seated = [track(1, 0.02), track(2, 0.021), track(3, 0.019)]
    verdicts = [reject_reason(t, 0.6, opts, group_motion(seated, 0.6, opts)) for t in seated]
    assert all("nearly static" in v and "the group's 0.020" in v for v in verdicts)


def test_the_clean_table_carries_what_lift_reads_and_not_the_world_landmarks() -> None:
    # BlazePose's 33 world landmarks were two thirds of every clean file and nothing after pose2d read them.
    from pipeline.annotate.clipfile import CLEAN_SCHEMA

    assert CLEAN_SCHEMA.names == ["clip_id", "track_id", "frame", "time", "box", "keypoints", "interpolated", "feet"]
