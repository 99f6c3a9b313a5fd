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
    return FramePoses(frame, frame / 30, boxes, np.full(n, 0.8, np.float32), kps, True, feet)


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
    assert [f.frame for f in got] == [1, 2] and all(np.all(f.interpolated) and not np.any(f.detected) for f in got)
    first, second = got
    assert len(first.scores) == 2 and len(second.scores) == 3     # the one seen only at b: held from b, nearer it
    assert np.array_equal(second.keypoints[2], b.keypoints[2])
    assert len(list(in_between(a, b, [(2, 2 / 30)], top_k=2))[0].scores) == 2  # no more than the top k
    assert np.allclose(second.keypoints[0, :, 0], near_a[1][:, 0] + 20)  # two thirds of the way, largest first
    assert np.allclose(second.keypoints[1, :, 0], far_a[1][:, 0] + 20)
    assert second.keypoints[0, 0, 2] == pytest.approx(0.1)          # as sure as the less sure keyframe
    assert np.allclose(second.keypoints[1, 1:, 2], 0.5)
    assert np.allclose(second.boxes[0], [20, 0, 170, 300])
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



class _FrameNumberDetector:
    """A detector that reads the frame number off the frame (its grey level is 64 + 8 k): one dancer always,
    a second from frame ``arrives`` on."""

    def __init__(self, arrives: int) -> None:
        self.arrives = arrives

    def preprocess(self, image: np.ndarray) -> np.ndarray:
        return image

    def infer(self, image: np.ndarray):
        from pipeline.pose.models.detector import Detections

        frame = int(round((float(image.mean()) - 64) / 8))
        boxes = [[10 + frame, 10, 60 + frame, 110]] + ([[150, 20, 200, 120]] if frame >= self.arrives else [])
        return Detections(np.array(boxes, np.float32), np.full(len(boxes), 0.9, np.float32))

    def detect(self, image: np.ndarray):
        return self.infer(image)


class _CountingPose:
    """A pose model that puts 17 confident joints down each box's middle and counts the boxes it posed."""

    def __init__(self) -> None:
        self.posed: list[tuple[int, float]] = []  # (frame, box x1)

    def estimate(self, image: np.ndarray, boxes: np.ndarray):
        from pipeline.pose.models.pose import PoseBatch

        boxes = np.asarray(boxes, np.float32).reshape(-1, 4)
        frame = int(round((float(image.mean()) - 64) / 8))
        self.posed += [(frame, float(b[0])) for b in boxes]
        kp = np.zeros((len(boxes), 17, 3), np.float32)
        kp[:, :, 0] = (boxes[:, None, 0] + boxes[:, None, 2]) / 2
        kp[:, :, 1] = boxes[:, None, 1] + (boxes[:, None, 3] - boxes[:, None, 1]) * np.linspace(0.05, 0.95, 17)
        kp[:, :, 2] = 0.9
        return PoseBatch.body_only(kp)


def _numbered_clip(path: Path, frames: int) -> Path:
    """A lossless clip whose frame k is grey level 64 + 8 k, too bright to be brightened (so a fake
    model can tell the frames apart)."""
    import av

    with av.open(str(path), "w") as out:
        stream = out.add_stream("ffv1", rate=24)
        stream.width, stream.height, stream.pix_fmt = 240, 160, "bgr0"
        for k in range(frames):
            picture = av.VideoFrame.from_ndarray(np.full((160, 240, 3), 64 + 8 * k, np.uint8), format="bgr24")
            for packet in stream.encode(picture):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return path


def test_where_someone_comes_between_keyframes_only_they_are_posed_and_the_others_drawn(tmp_path: Path) -> None:
    clip = _numbered_clip(tmp_path / "numbered.mkv", 10)
    view = SegmentVideo(clip, 0.0, 24, 10, 240, 160)
    detector, pose = _FrameNumberDetector(arrives=4), _CountingPose()
    poses = collect_poses(estimate_segment(view, 24.0, detector, pose, Pose2dOptions(fps=8, changes_only=True)))[0]

    # keyframes 0, 3, 6, 9; the newcomer is on 6 and not on 3, so frames 4 and 5 are looked at
    assert sorted({f for f, _ in pose.posed}) == [0, 3, 4, 5, 6, 9]
    assert [x for f, x in pose.posed if f in (4, 5)] == [150.0, 150.0]  # the newcomer alone
    at = {(int(f), int(b[0])): bool(i) for f, b, i in zip(poses.frame, poses.box, poses.interpolated)}
    assert at[(4, 150)] is False and at[(5, 150)] is False          # posed where first seen
    assert at[(4, 14)] is True and at[(5, 15)] is True               # the first dancer drawn between 3 and 6
    assert np.array_equal(np.bincount(poses.frame), [1, 1, 1, 1, 2, 2, 2, 2, 2, 2])
    newcomer = poses.detected[(poses.frame == 4) & (poses.box[:, 0] == 150)]
    assert newcomer.tolist() == [True]

    everyone = _CountingPose()  # the default: such frames posed in full
    collect_poses(estimate_segment(view, 24.0, detector, everyone, Pose2dOptions(fps=8)))
    assert sorted(x for f, x in everyone.posed if f == 4) == [14.0, 150.0]
