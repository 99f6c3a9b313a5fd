"""Tracker on synthetic people: crossings, occlusion gaps, late entries, noise."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.pose.tracking import (
    UNTRACKED,
    TrackerOptions,
    assign_tracks,
    iou_matrix,
    oks_matrix,
)

# A standing skeleton in a unit box (x right, y down), COCO-17 order.
TEMPLATE = np.array([
    [0.50, 0.08], [0.54, 0.06], [0.46, 0.06], [0.58, 0.08], [0.42, 0.08], [0.65, 0.22], [0.35, 0.22],
    [0.72, 0.38], [0.28, 0.38], [0.75, 0.52], [0.25, 0.52], [0.60, 0.55], [0.40, 0.55],
    [0.60, 0.75], [0.40, 0.75], [0.60, 0.95], [0.40, 0.95],
])


def person(cx: float, cy: float, h: float, phase: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Box and keypoints of a person of height ``h`` centred at (cx, cy); arms swing with phase."""
    w = 0.45 * h
    kp = TEMPLATE.copy()
    kp[[9, 10], 1] += 0.1 * np.sin(phase)  # wrists move: keypoints are not rigid
    xy = np.column_stack([cx - w / 2 + kp[:, 0] * w, cy - h / 2 + kp[:, 1] * h])
    box = np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
    return box, np.column_stack([xy, np.full(17, 0.8)])


def run(people: dict[str, callable], n_frames: int, opts: TrackerOptions = TrackerOptions(), seed: int = 0):
    """people: name -> f(frame) giving (cx, cy, h) or None when not visible."""
    rng = np.random.default_rng(seed)
    frames, boxes, kps, truth = [], [], [], []
    for f in range(n_frames):
        for name, where in people.items():
            pos = where(f)
            if pos is None:
                continue
            box, kp = person(*pos, phase=f / 5)
            kp[:, :2] += rng.normal(0, 1.5, (17, 2))  # detector jitter
            frames.append(f), boxes.append(box + rng.normal(0, 1.0, 4)), kps.append(kp), truth.append(name)
    ids = assign_tracks(np.array(frames), np.array(boxes), np.array(kps), opts)
    return ids, np.array(truth)


def id_switches(ids: np.ndarray, truth: np.ndarray) -> int:
    """Times a person's assigned id changes (untracked detections ignored)."""
    switches = 0
    for name in np.unique(truth):
        seq = [i for i in ids[truth == name] if i != UNTRACKED]
        switches += sum(1 for a, b in zip(seq, seq[1:]) if a != b)
    return switches


def ids_of(ids: np.ndarray, truth: np.ndarray, name: str) -> set[int]:
    return {int(i) for i in ids[truth == name] if i != UNTRACKED}


def test_two_dancers_side_by_side_keep_their_ids() -> None:
    ids, truth = run({"a": lambda f: (200 + 30 * np.sin(f / 10), 300, 300),
                      "b": lambda f: (600 + 30 * np.cos(f / 10), 300, 300)}, 200)
    assert id_switches(ids, truth) == 0
    assert ids_of(ids, truth, "a") == {1} and ids_of(ids, truth, "b") == {2}


def test_people_crossing_paths_keep_their_ids() -> None:
    # Walking towards each other at slightly different depths (sizes), crossing at frame 50.
    ids, truth = run({"a": lambda f: (100 + 8 * f, 300, 320), "b": lambda f: (900 - 8 * f, 310, 280)}, 100)
    assert id_switches(ids, truth) == 0
    assert len(ids_of(ids, truth, "a")) == len(ids_of(ids, truth, "b")) == 1


def test_short_occlusion_gap_is_bridged() -> None:
    hidden = range(40, 55)  # 15 frames, under max_age
    ids, truth = run({"a": lambda f: None if f in hidden else (200 + 3 * f, 300, 300),
                      "b": lambda f: (700, 300, 300)}, 120)
    assert id_switches(ids, truth) == 0
    assert ids_of(ids, truth, "a") == {1}


def test_long_absence_starts_a_new_track() -> None:
    ids, truth = run({"a": lambda f: None if 30 <= f < 100 else (300, 300, 300)}, 150)
    assert ids_of(ids, truth, "a") == {1, 2}


def test_late_entering_person_gets_a_new_id_without_disturbing_others() -> None:
    ids, truth = run({"a": lambda f: (300, 300, 300), "late": lambda f: None if f < 60 else (700, 300, 280)}, 120)
    assert ids_of(ids, truth, "a") == {1}
    assert ids_of(ids, truth, "late") == {2}
    assert all(ids[truth == "late"] == 2)  # tentative frames get the id too


def test_one_frame_flicker_is_not_a_track() -> None:
    ids, truth = run({"a": lambda f: (300, 300, 300), "ghost": lambda f: (800, 200, 100) if f == 10 else None}, 30)
    assert set(ids[truth == "ghost"]) == {UNTRACKED}


def test_hard_case_crowd_crossing_stays_within_a_bound() -> None:
    # Four people, two pairs crossing at the same time, plus a gap: allow at most 2 switches.
    people = {
        "a": lambda f: (100 + 7 * f, 300, 300),
        "b": lambda f: (800 - 7 * f, 320, 290),
        "c": lambda f: (450, 100 + 5 * f, 250) if not 30 <= f < 36 else None,
        "d": lambda f: (250, 500, 260),
    }
    ids, truth = run(people, 100, seed=3)
    assert id_switches(ids, truth) <= 2


def test_unsorted_input_is_refused() -> None:
    with pytest.raises(ValueError, match="sorted by frame"):
        assign_tracks(np.array([1, 0]), np.zeros((2, 4)), np.zeros((2, 17, 3)))


def test_similarity_measures() -> None:
    a = np.array([[0, 0, 10, 10.0]])
    b = np.array([[5, 0, 15, 10.0], [20, 20, 30, 30.0]])
    assert iou_matrix(a, b) == pytest.approx(np.array([[1 / 3, 0.0]]))
    _, kp = person(100, 100, 200)
    far = kp.copy()
    far[:, 0] += 100
    sims = oks_matrix(kp[None], np.stack([kp, far]), np.array([90 * 200.0, 90 * 200.0]), 0.2)
    assert sims[0, 0] == pytest.approx(1.0) and sims[0, 1] < 0.01


def test_a_tracks_file_holds_only_the_ids_and_reads_back_joined_with_its_pose2d_file(tmp_path: Path) -> None:
    from pipeline.core.errors import InputError
    from pipeline.pose.pose2dfile import Poses, SegmentInfo, write_pose2d
    from pipeline.pose.trackfile import read_tracks, write_tracks

    n = 200
    frame = np.repeat(np.arange(n // 2), 2)
    rng = np.random.default_rng(0)
    poses = Poses(frame=frame, time=frame / 30.0, person=np.tile([0, 1], n // 2), box=rng.random((n, 4)) * 500,
                  box_score=np.full(n, 0.9), keypoints=rng.random((n, 17, 3)) * 500, detected=np.ones(n, bool),
                  feet=rng.random((n, 4, 3)), interpolated=frame % 3 != 0)
    segment = SegmentInfo("seg", 30.0, n // 2, 640, 360)
    pose2d, tracks = tmp_path / "data/pose2d/seg.parquet", tmp_path / "data/tracks/seg.parquet"
    write_pose2d(pose2d, poses, segment, fingerprint="p1", params={}, inputs={})
    ids = np.tile([1, 2], n // 2)
    write_tracks(tracks, pose2d, poses, ids, segment, fingerprint="t1", params={}, inputs={"pose2d": "p1"})
    assert tracks.stat().st_size < pose2d.stat().st_size / 20  # the ids, not the poses again
    back = read_tracks(tracks)
    assert back.ids == [1, 2] and back.fingerprint == "t1" and back.frames_total == n // 2
    np.testing.assert_allclose(back.keypoints, poses.keypoints, rtol=1e-6)
    np.testing.assert_allclose(back.feet, poses.feet, rtol=1e-6)
    assert np.array_equal(back.drawn, frame % 3 != 0)  # which rows were drawn between keyframes
    # A pose2d file written again after tracking is refused, not silently mis-numbered.
    write_pose2d(pose2d, poses, segment, fingerprint="p2", params={}, inputs={})
    with pytest.raises(InputError, match="another version.*dvc repro track"):
        read_tracks(tracks)
    pose2d.unlink()
    with pytest.raises(InputError, match="is missing"):
        read_tracks(tracks)


def test_a_box_that_swallows_two_dancers_for_a_moment_does_not_change_either_ones_id() -> None:
    # The duet's break at 10.8 s: the detector's box for the woman widens over her partner for two
    # frames, her track follows it and is lost, and she comes back under a new id.
    rng = np.random.default_rng(0)
    frames, boxes, kps, truth = [], [], [], []
    for f in range(120):
        people = {"man": person(200, 300, 300, f / 5), "woman": person(345, 300, 300, f / 5 + 1)}
        if f in (60, 61):  # one box over both, carrying the woman's keypoints; at 61 hers is found as well
            (a, _), (b, kp) = people["man"], people["woman"]
            people["woman"] = (np.r_[a[:2], b[2:]], kp) if f == 60 else people["woman"]
            if f == 61:
                people["both"] = (np.r_[a[:2] - [20, 0], b[2:]], kp)
        for name, (box, kp) in people.items():
            frames.append(f), boxes.append(box + rng.normal(0, 1.0, 4)), kps.append(kp), truth.append(name)
    ids = assign_tracks(np.array(frames), np.array(boxes), np.array(kps))
    truth = np.array(truth)
    assert ids_of(ids, truth, "man") == {1} and ids_of(ids, truth, "woman") == {2}


def test_the_qc_banner_says_which_frames_were_drawn_between_keyframes() -> None:
    from pipeline.pose.qc import draw_frame

    person = [(1, np.array([40, 40, 120, 300]), np.full((17, 3), 0.0))]

    def banner_width(drawn: bool) -> int:
        image = draw_frame(np.full((360, 640, 3), 255, np.uint8), 10, 0.4, person, 0.2, drawn=drawn)
        return int((image[-2].sum(1) == 0).sum())  # the banner's black box along the bottom row

    assert banner_width(True) > banner_width(False) + 40  # "frame 10   00:00.400   drawn"
