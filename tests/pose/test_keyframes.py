"""2D on keyframes: the models pose every k-th frame, the frames between are drawn from them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.ingest.segmentvideo import SegmentVideo, frames_of
from pipeline.pose.keyframes import drawn_between, held, in_between, keyframe_step, match_people, people_change
from pipeline.pose.pose2d import FramePoses, Pose2dOptions, collect_poses, estimate_segment
from pipeline.pose.pose2dfile import Poses


def person(x: float, score: float = 0.9, height: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    box = np.array([x, 0, x + height / 2, height], np.float32)
    kp = np.zeros((17, 3), np.float32)
    kp[:, 0], kp[:, 1], kp[:, 2] = x + 10 + np.arange(17), 5 + 10 * np.arange(17), score
    return box, kp


def keyframe(frame: int, people: list[tuple[np.ndarray, np.ndarray]]) -> FramePoses:
    n = len(people)
    boxes = np.array([b for b, _ in people], np.float32).reshape(n, 4)
    kps = np.array([k for _, k in people], np.float32).reshape(n, 17, 3)
    feet = kps[:, :4].copy()
    world = np.repeat(np.arange(33, dtype=np.float32)[None, :, None] * np.ones(3, np.float32), n, 0)
    return FramePoses(frame, frame / 30, boxes, np.full(n, 0.8, np.float32), kps, True, feet, world)


@pytest.mark.parametrize(("source", "pose", "step"), [(24, 12, 2), (30, 12, 2), (60, 12, 5), (25, 8, 3),
                                                      (30, 0, 1), (10, 12, 1)])
def test_the_keyframe_step_poses_at_least_the_asked_rate(source: float, pose: float, step: int) -> None:
    assert keyframe_step(source, pose) == step


def test_people_are_followed_from_keyframe_to_keyframe_by_their_boxes_not_their_rank() -> None:
    a = np.array([[0, 0, 100, 200], [300, 0, 400, 200]], np.float32)
    b = np.array([[310, 0, 410, 200], [5, 0, 105, 200], [900, 0, 950, 100]], np.float32)
    assert sorted(match_people(a, b)) == [(0, 1), (1, 0)]
    assert match_people(a, np.array([[600, 0, 700, 200]], np.float32)) == []  # nobody overlaps: no pair


def test_someone_on_only_one_of_two_keyframes_is_a_change_of_people() -> None:
    one, other = person(0), person(400)
    assert not people_change(keyframe(0, [one, other]), keyframe(3, [person(10), person(405)]))  # both moved a bit
    assert people_change(keyframe(0, [one]), keyframe(3, [one, other]))                          # someone came
    assert people_change(keyframe(0, [one, other]), keyframe(3, [other]))                        # someone went
    assert people_change(keyframe(0, [one]), keyframe(3, [person(300)]))   # no overlap: another person, or a leap
    assert not people_change(keyframe(0, []), keyframe(3, []))
    far = person(800, height=40.0)  # a fifth of the dancers' height, far behind them
    assert not people_change(keyframe(0, [one, other]), keyframe(3, [one, other, far]))


def test_frames_between_two_keyframes_are_drawn_linearly_at_the_weaker_keyframes_confidence_or_held() -> None:
    near_a, far_a = person(0, height=300), person(400, score=0.5)
    a = keyframe(0, [near_a, far_a])
    b = keyframe(3, [person(430, score=0.9), person(30, height=300), person(1000, height=150)])  # a third, smaller
    b.keypoints[1, 0, 2] = 0.1                                                        # the nose unsure at b
    got = list(in_between(a, b, [(1, 1 / 30), (2, 2 / 30)]))
    assert [f.frame for f in got] == [1, 2] and all(f.interpolated and not f.detected for f in got)
    first, second = got
    assert len(first.scores) == 2 and len(second.scores) == 3     # the one seen only at b: held from b, nearer it
    assert np.array_equal(second.keypoints[2], b.keypoints[2])
    assert len(list(in_between(a, b, [(2, 2 / 30)], top_k=2))[0].scores) == 2  # no more than the top k
    assert np.allclose(second.keypoints[0, :, 0], near_a[1][:, 0] + 20)  # two thirds of the way, largest first
    assert np.allclose(second.keypoints[1, :, 0], far_a[1][:, 0] + 20)
    assert second.keypoints[0, 0, 2] == pytest.approx(0.1)          # as sure as the less sure keyframe
    assert np.allclose(second.keypoints[1, 1:, 2], 0.5)
    assert np.allclose(second.boxes[0], [20, 0, 170, 300])
    assert np.allclose(second.world[:2], a.world)
    tail = list(held(b, [(4, 4 / 30)]))
    assert tail[0].frame == 4 and tail[0].interpolated and np.array_equal(tail[0].keypoints, b.keypoints)


def test_a_segment_view_converts_only_the_frames_asked_for(dance_clip: Path) -> None:
    view = SegmentVideo(dance_clip, 1.0, 24, 10, 540, 960)
    images = [f.image is not None for f in frames_of(view, keep=lambda k: k % 4 == 0 or k == 9)]
    assert images == [True, False, False, False, True, False, False, False, True, True]


def test_posing_keyframes_only_gives_every_frame_and_the_keyframes_exactly_as_posing_every_frame(
        dance_clip: Path, default_models) -> None:
    models, _ = default_models
    view = SegmentVideo(dance_clip, 2.0, 24, 50, 1080, 1920)  # 50 frames: step 3 leaves the last one off the grid
    every = collect_poses(estimate_segment(view, 24.0, models.detector, models.pose,
                                           Pose2dOptions()))[0]
    fast, frames = collect_poses(estimate_segment(view, 24.0, models.detector, models.pose,
                                                  Pose2dOptions(fps=8)))
    assert frames == 50 and np.array_equal(fast.frame, every.frame)
    posed = ~fast.interpolated
    assert np.array_equal(np.flatnonzero(posed), np.flatnonzero((fast.frame % 3 == 0) | (fast.frame == 49)))
    assert np.array_equal(fast.keypoints[posed], every.keypoints[posed])
    assert np.array_equal(fast.feet[posed], every.feet[posed])
    moved = np.linalg.norm(fast.keypoints[~posed, :, :2] - every.keypoints[~posed, :, :2], axis=-1)
    sure = np.minimum(fast.keypoints[~posed, :, 2], every.keypoints[~posed, :, 2]) >= 0.5
    height = np.median(every.box[:, 3] - every.box[:, 1])
    assert np.median(moved[sure]) < 0.02 * height                    # drawn where the models would put them
    assert isinstance(Poses.from_table(fast.table()).interpolated, np.ndarray)


def test_where_someone_comes_into_sight_between_keyframes_the_frames_between_are_posed(
        media_dir: Path, default_models, tmp_path: Path) -> None:
    from tests.conftest import ffmpeg

    models, _ = default_models
    clip = tmp_path / "card_then_dancer.mp4"  # frames 0-9 an empty card, 10-23 the dancer (24 fps)
    ffmpeg("-f", "lavfi", "-i", "color=c=0x203060:s=270x480:r=24:d=1", "-ss", "2", "-t", "1",
           "-i", str(media_dir / "videos/dance_single_music_musepose.mp4"), "-filter_complex",
           "[1:v]scale=270:480,fps=24,trim=end_frame=14,setsar=1[d];[0:v]trim=end_frame=10,setsar=1[c];"
           "[c][d]concat=n=2:v=1:a=0,format=yuv420p[v]",
           "-map", "[v]", "-c:v", "libx264", "-preset", "veryfast", "-crf", "12", str(clip))
    view = SegmentVideo(clip, 0.0, 24, 24, 270, 480)  # B-frames: frames between keyframes may be skipped

    def run(fps: float = 8, **options) -> Poses:
        return collect_poses(estimate_segment(view, 24.0, models.detector, models.pose,
                                              Pose2dOptions(fps=fps, **options)))[0]

    every, changes, drawn = run(fps=0), run(), run(pose_changes=False)
    assert set(every.frame) == set(range(10, 24))  # the dancer from frame 10 on: keyframes 9 and 12 differ
    posed = changes.frame[~changes.interpolated]
    assert {10, 11} <= set(posed) and not {13, 14} & set(posed)  # only the frames between 9 and 12
    assert np.array_equal(changes.frame, every.frame)
    assert np.array_equal(changes.keypoints[np.isin(changes.frame, [10, 11])],
                          every.keypoints[np.isin(every.frame, [10, 11])])
    assert 10 not in set(drawn.frame)  # drawn instead: held from keyframe 9, where nobody was


def test_one_persons_track_drawn_from_keyframes_keeps_the_keyframes_and_the_last_frame() -> None:
    t = np.arange(8, dtype=np.float64)
    points = np.stack([t ** 2, 2 * t, np.where(t == 4, 0.2, 0.9)], -1)[:, None, :]  # one joint, curving
    drawn = drawn_between(points, 3)
    kept = [0, 3, 6, 7]
    assert np.array_equal(drawn[kept], points[kept])
    assert drawn[4, 0, 0] == pytest.approx(9 + (36 - 9) / 3)    # a straight line between frames 3 and 6
    assert drawn[4, 0, 2] == pytest.approx(0.9)                  # its own score is not seen: the keyframes'
    assert np.array_equal(drawn_between(points, 1), points)


def test_a_carried_box_frames_the_moved_keypoints_as_the_detector_framed_them() -> None:
    from pipeline.pose.pose2d import box_framing, carried_boxes

    _, kp = person(100)                                   # keypoints span x 110-126, y 5-165
    detected = np.array([[90, -20, 150, 200]], np.float32)  # the detector's box: wider below than above
    framing = box_framing(detected, kp[None], 0.2, 0.15)
    moved = kp.copy()
    moved[:, 0] += 40                                      # she steps 40 px right
    moved[:, 1] = 5 + 2 * (moved[:, 1] - 5)                # and looks twice as tall
    box = carried_boxes(moved[None], 1000, 1000, 0.2, 0.15, framing)[0]
    assert np.allclose(box, [130, 0, 190, 395], atol=1e-3)  # clipped at the top; 2 x 35 px below the feet
    plain = carried_boxes(moved[None], 1000, 1000, 0.2, 0.15)[0]
    assert np.allclose(plain, [150 - 0.15 * 16, 0, 166 + 0.15 * 16, 325 + 0.15 * 320], atol=1e-3)

