"""Hands: where the hand model looks (regions from a box, a forearm, a hand's own points), what it
finds on real annotated hand images, and `dance3d eval hands`."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.core.errors import InputError
from pipeline.pose.hands import (
    HandLandmarks,
    HandModels,
    HandRecrop,
    region_from_box,
    region_from_forearm,
    region_from_landmarks,
)
from pipeline.pose.models.pose import to_image

SIZE = 224


def _in_crop(region: np.ndarray, point) -> np.ndarray:
    return region[:, :2] @ np.asarray(point, np.float64) + region[:, 2]


def test_a_box_region_is_an_upright_square_twice_the_boxs_longer_side() -> None:
    region = region_from_box(np.array([100, 50, 40, 20]), SIZE)
    corners = to_image(np.array([[0.0, 0.0], [SIZE, SIZE]]), region)
    assert np.allclose(corners, [[80, 20], [160, 100]])


def test_a_forearm_region_lies_beyond_the_wrist_with_the_forearm_pointing_up() -> None:
    elbow, wrist = np.array([100.0, 200.0]), np.array([200.0, 200.0])  # a forearm pointing right, 100 px
    region = region_from_forearm(elbow, wrist, SIZE)
    centre = to_image(np.array([[SIZE / 2, SIZE / 2]]), region)[0]
    assert np.allclose(centre, [235, 200])  # 0.35 forearm beyond the wrist
    assert np.allclose(np.hypot(*region[0, :2]), SIZE / 130)  # a side of 1.3 forearms
    up = _in_crop(region, wrist + [10, 0]) - _in_crop(region, wrist)
    assert up[1] < 0 and abs(up[0]) < 1e-9  # along the forearm is up in the crop
    assert region_from_forearm(wrist, wrist, SIZE) is None


def test_a_hands_own_region_turns_its_wrist_down_and_its_fingers_up() -> None:
    rng = np.random.default_rng(0)
    hand = np.zeros((21, 2))
    hand[1:] = rng.uniform(-20, 20, (20, 2))
    hand[9] = [60.0, 0.0]  # middle knuckle to the right of the wrist: the hand points right
    region = region_from_landmarks(hand + [300, 300], SIZE)
    wrist, knuckle = _in_crop(region, [300, 300]), _in_crop(region, [360, 300])
    assert knuckle[1] < wrist[1] and abs(knuckle[0] - wrist[0]) < 1e-6
    inside = np.array([_in_crop(region, p) for p in hand + [300, 300]])
    assert (inside > 0).all() and (inside < SIZE).all()  # every point in the crop, with room around


def test_bad_annotations_name_the_file_and_the_hand(tmp_path: Path) -> None:
    from pipeline.pose.evaluate_hands import read_hand_annotations

    path = tmp_path / "hands.json"
    path.write_text(json.dumps({"images": [{"file": "a.jpg", "hands": [{"bbox": [0, 0, 1, 1], "side": "left",
                                                                       "keypoints": [[0, 0, 1]] * 20}]}]}))
    with pytest.raises(InputError, match=r"hands.json.*images\[0\]\.hands\[0\]\.keypoints"):
        read_hand_annotations(path)
    path.write_text("{")
    with pytest.raises(InputError, match="not JSON"):
        read_hand_annotations(path)


def test_the_hand_model_on_annotated_regions_finds_the_real_hands(hand_model: Path, hand_eval_dir: Path) -> None:
    from pipeline.pose.evaluate_hands import evaluate_hands
    from pipeline.pose.models.session import create_session

    landmarks = HandLandmarks(create_session(hand_model))
    result = evaluate_hands(hand_eval_dir / "annotations.json", hand_eval_dir, landmarks, regions="annotated")
    clear = result["datasets"]["hand_graph_cnn_realworld"]  # twelve large, clear left hands
    assert clear["found"] == clear["hands"] == 12 and clear["pck"] >= 0.95 and clear["error_px"] < 12
    assert clear["error_3d_mm"] < 30  # root-aligned, in millimetres
    assert result["all"]["hands"] == 38


def test_handedness_is_read_on_the_image_as_it_is_not_mirrored(hand_model: Path, hand_eval_dir: Path) -> None:
    import cv2

    from pipeline.pose.evaluate_hands import read_hand_annotations
    from pipeline.pose.models.session import create_session

    landmarks = HandLandmarks(create_session(hand_model))
    as_is, flipped = [], []
    for entry in read_hand_annotations(hand_eval_dir / "annotations.json"):
        if entry["dataset"] == "hand_graph_cnn_realworld":  # twelve left hands
            image = cv2.imread(str(hand_eval_dir / entry["file"]))
            x, y, w, h = entry["hands"][0]["bbox"]
            as_is.append(landmarks.estimate(image, region_from_box([x, y, w, h])).right)
            mirror = np.ascontiguousarray(image[:, ::-1])
            flipped.append(landmarks.estimate(mirror, region_from_box([image.shape[1] - x - w, y, w, h])).right)
    assert np.median(as_is) < 0.2 and np.median(flipped) > 0.8


def test_eval_hands_from_the_body_and_the_palms_prints_a_table_per_dataset(
        hand_model: Path, hand_recrop_model: Path, palm_model: Path, hand_eval_dir: Path, models_dir: Path,
        tmp_path: Path) -> None:
    (tmp_path / "models").mkdir()
    for model in (hand_model, hand_recrop_model, palm_model):
        (tmp_path / "models" / model.name).symlink_to(model)
    out = tmp_path / "hands.json"
    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "eval", "hands", "--annotations",
                           str(hand_eval_dir / "annotations.json"), "--images", str(hand_eval_dir), "--out", str(out)],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "| coco_wholebody |" in done.stdout and "| **all** |" in done.stdout
    result = json.loads(out.read_text())
    assert result["regions"] == "body+palm"
    assert result["datasets"]["coco_wholebody"]["found"] >= 1  # small hands of whole people, found from their arms
    assert result["datasets"]["hand_graph_cnn_realworld"]["found"] == 12  # hands without a body, by their palms
    assert result["all"]["pck"] > 0.6


def test_mediapipes_own_pipeline_runs_as_the_peer(hand_model: Path, palm_model: Path, hand_eval_dir: Path) -> None:
    from pipeline.pose.evaluate_hands import evaluate_hands
    from pipeline.pose.models.session import create_session
    from pipeline.pose.palms import PalmDetector

    result = evaluate_hands(hand_eval_dir / "annotations.json", hand_eval_dir,
                            HandLandmarks(create_session(hand_model)), regions="palm",
                            palms=PalmDetector(create_session(palm_model)))
    assert result["datasets"]["freihand"]["found"] == 4 and result["datasets"]["freihand"]["pck"] >= 0.8
    whole_people = [result["datasets"][name]["found"] for name in ("coco_wholebody", "halpe")]
    assert whole_people == [0, 0]  # its palm detector sees none of the small hands of whole people


# --- hands in pose2d (pose2d.hands) ---------------------------------------------------------

class _FakeLandmarks:
    """Records where it was asked to look; finds a hand of presence 0.9 with its wrist at the region's centre."""

    size = 224

    def __init__(self) -> None:
        self.regions: list[np.ndarray] = []

    def estimate(self, image: np.ndarray, region: np.ndarray, passes: int = 2):
        from pipeline.pose.hands import Hand

        self.regions.append(region)
        centre = to_image(np.array([[SIZE / 2, SIZE / 2]]), region)[0]
        points = np.column_stack([np.tile(centre, (21, 1)), np.full(21, 0.9)]).astype(np.float32)
        return Hand(points, np.ones((21, 3), np.float32), 0.9, 0.5, region)


def _body(left_wrist_score: float = 0.9, right_forearm: float = 100.0, right_wrist_x: float = 300.0) -> np.ndarray:
    kp = np.zeros((1, 17, 3), np.float32)
    kp[0, 7] = [200, 200, 0.9]                       # left elbow, the wrist 100 px below it
    kp[0, 9] = [200, 300, left_wrist_score]
    kp[0, 8] = [right_wrist_x, 300 - right_forearm, 0.9]  # right elbow, the wrist ``right_forearm`` below
    kp[0, 10] = [right_wrist_x, 300, 0.9]
    return kp


def test_a_hand_is_looked_for_beyond_each_sure_wrist_and_marked_where_it_is_not() -> None:
    from pipeline.pose.hands import body_hands, hands_array

    image = np.zeros((480, 640, 3), np.uint8)
    fake = _FakeLandmarks()
    (left, right), = body_hands(fake, image, _body())
    assert left is not None and right is not None
    assert np.allclose(left.keypoints[0, :2], [200, 335], atol=1.0)  # 0.35 forearm beyond the wrist
    (left, right), = body_hands(fake, image, _body(left_wrist_score=0.1))
    assert left is None and right is not None                    # an unsure wrist: not looked at
    (left, right), = body_hands(fake, image, _body(right_forearm=10.0))
    assert right is None                                         # a hand of a few pixels: too small
    (left, right), = body_hands(fake, image, _body(right_wrist_x=-50.0))
    assert right is None                                         # off the picture
    points, world = hands_array([(left, right)])
    assert points.shape == world.shape == (1, 2, 21, 3)
    assert (points[0, 0, :, 2] == np.float32(0.9)).all() and (points[0, 1] == 0).all()  # marked, not guessed


def test_hands_are_drawn_between_keyframes_as_the_body_and_their_metric_depth_is_not_taken_as_a_score() -> None:
    from pipeline.pose.keyframes import in_between
    from pipeline.pose.pose2d import FramePoses

    def keyframe(frame: int, x: float) -> FramePoses:
        hands = np.zeros((1, 2, 21, 3), np.float32)
        hands[..., 0], hands[..., 2] = x, 0.8 if frame == 0 else 0.6
        world = np.full((1, 2, 21, 3), 0.01 * frame, np.float32)
        return FramePoses(frame, frame / 30, np.array([[x, 0, x + 50, 100]], np.float32), np.ones(1, np.float32),
                          np.zeros((1, 17, 3), np.float32), True, np.zeros((1, 4, 3), np.float32), False, hands, world)

    middle, = in_between(keyframe(0, 100.0), keyframe(2, 120.0), [(1, 1 / 30)])
    assert np.allclose(middle.hands[..., 0], 110.0) and np.allclose(middle.hands[..., 2], 0.6)
    assert np.allclose(middle.hands_world, 0.01)  # drawn halfway, every coordinate


def test_a_pose2d_file_carries_hands_only_where_they_were_asked_for(tmp_path: Path) -> None:
    from pipeline.pose.pose2dfile import Poses, SegmentInfo, read_pose2d, write_pose2d

    rng = np.random.default_rng(0)
    n = 3
    base = dict(frame=np.arange(n), time=np.arange(n) / 30, person=np.zeros(n), box=rng.random((n, 4)),
                box_score=rng.random(n), keypoints=rng.random((n, 17, 3)), detected=np.ones(n, bool),
                feet=rng.random((n, 4, 3)))
    segment = SegmentInfo("s", 30.0, n, 64, 48)
    hands, world = rng.random((n, 2, 21, 3)).astype(np.float32), rng.random((n, 2, 21, 3)).astype(np.float32)
    write_pose2d(tmp_path / "with.parquet", Poses(**base, hands=hands, hands_world=world), segment, fingerprint="f",
                 params={}, inputs={})
    write_pose2d(tmp_path / "without.parquet", Poses(**base), segment, fingerprint="f", params={}, inputs={})
    read = read_pose2d(tmp_path / "with.parquet").poses
    assert np.array_equal(read.hands, hands) and np.array_equal(read.hands_world, world)
    assert read_pose2d(tmp_path / "without.parquet").poses.hands is None


def test_pose2d_with_hands_puts_the_dancers_sure_hands_on_her_wrists_on_every_frame(
        dance_clip: Path, hand_model: Path, hand_recrop_model: Path, default_models, tmp_path: Path) -> None:
    from dataclasses import replace

    from pipeline.pose.models.session import create_session
    from pipeline.pose.pose2d import collect_poses, estimate_segment
    from tests.conftest import ffmpeg

    clip = tmp_path / "clip.mp4"  # 2 s: her right hand comes up to her chin, her left to her hip
    ffmpeg("-ss", "2", "-t", "2", "-i", str(dance_clip), "-an", "-c:v", "libx264", "-crf", "18", str(clip))
    models, opts = default_models
    hands = HandModels(HandLandmarks(create_session(hand_model)), HandRecrop(create_session(hand_recrop_model)))
    poses, frames = collect_poses(estimate_segment(clip, 24.0, models.detector, models.pose, replace(opts, hands=True),
                                                   hands=hands))
    assert frames == 48 and poses.hands.shape == (len(poses), 2, 21, 3)
    sure = poses.hands[:, :, 0, 2] >= 0.5
    assert sure[:, 0].any() and sure[:, 1].any()
    assert sure[poses.interpolated_mask()].any()  # drawn between keyframes too
    forearm = np.linalg.norm(poses.keypoints[:, [9, 10], :2] - poses.keypoints[:, [7, 8], :2], axis=-1)
    off = np.linalg.norm(poses.hands[:, :, 0, :2] - poses.keypoints[:, [9, 10], :2], axis=-1)
    assert (off[sure] < 0.5 * forearm[sure]).all()  # the hand's wrist on the body's
    fingers = np.linalg.norm(poses.hands[:, :, 12, :2] - poses.hands[:, :, 0, :2], axis=-1)
    assert (fingers[sure] > 0.3 * forearm[sure]).all()  # a hand, not a point


def test_the_stages_with_hands_on_record_the_hand_model_and_the_qc_video_draws_the_hands(
        project: Path, dance_clip: Path, hand_model: Path, hand_recrop_model: Path, models_dir: Path, monkeypatch,
        tmp_path: Path) -> None:
    import cv2

    from pipeline.core.storage import read_meta
    from pipeline.pose.pose2dfile import read_pose2d
    from pipeline.pose.qc import qc_video
    from pipeline.pose.trackfile import read_tracks
    from tests.conftest import posed_with_hands

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    clip = posed_with_hands(project, dance_clip, (hand_model, hand_recrop_model), 3.5, 1, tmp_path)
    pose2d = project / "data/pose2d/solo_000.parquet"
    assert {"hand-landmark-full", "hand-recrop"} <= set(read_meta(pose2d)["inputs"])
    tracks = read_tracks(project / "data/tracks/solo_000.parquet")
    assert tracks.hands is not None and np.array_equal(tracks.hands, read_pose2d(pose2d).poses.hands)
    sure = np.flatnonzero(tracks.hands[:, 1, 0, 2] >= 0.5)  # her right hand, at her chin
    assert len(sure)
    video = qc_video(project, "solo_000")
    capture = cv2.VideoCapture(str(video))
    capture.set(cv2.CAP_PROP_POS_FRAMES, int(tracks.frame[sure[0]]))
    ok, drawn = capture.read()
    assert ok
    original = cv2.VideoCapture(str(clip))
    original.set(cv2.CAP_PROP_POS_FRAMES, int(tracks.frame[sure[0]]))
    ok, plain = original.read()
    assert ok
    x, y = tracks.hands[sure[0], 1, 8, :2].astype(int)  # the index fingertip: a white joint drawn there
    white = [(image[y - 2: y + 3, x - 2: x + 3].min(-1) > 200).any() for image in (drawn, plain)]
    assert white == [True, False]


class _FakeRecrop(HandRecrop):
    """Points at a fixed spot of the image, whatever the region: as the re-crop model does when the
    other hand lies in its search square."""

    size = 256

    def __init__(self, centre, scale) -> None:
        self.centre, self.scale = np.asarray(centre, np.float64), np.asarray(scale, np.float64)

    def points(self, image: np.ndarray, region: np.ndarray) -> np.ndarray:
        return np.stack([self.centre, self.scale])


def test_the_recrop_square_is_centred_above_its_first_point_turned_so_the_second_lies_towards_the_wrist() -> None:
    region = _FakeRecrop([100, 100], [100, 140]).refine(np.zeros((10, 10, 3), np.uint8), np.eye(2, 3), SIZE)
    corners = to_image(np.array([[0, 0], [SIZE, 0], [0, SIZE], [SIZE, SIZE]], np.float64), region)
    assert np.allclose(corners.mean(0), [100, 92])                   # moved a tenth of its side towards the fingers
    assert np.allclose(np.linalg.norm(corners[1] - corners[0]), 80)  # twice the points' distance
    assert corners[0, 1] < corners[2, 1]                             # the crop's top is the image's top: fingers up


def test_a_recropped_hand_that_is_not_on_its_wrist_gives_way_to_the_forearms_hand() -> None:
    from pipeline.pose.hands import body_hands

    image = np.zeros((480, 640, 3), np.uint8)
    elsewhere = _FakeRecrop([500, 100], [500, 140])  # the other dancer's hand
    (left, right), = body_hands(_FakeLandmarks(), image, _body(), recrop=elsewhere)
    assert np.allclose(left.keypoints[0, :2], [200, 335], atol=1.0)  # the forearm's square, on her wrist


def test_models_fetch_by_default_fetches_the_hand_models_only_when_hands_are_on() -> None:
    from pipeline.pose.models.loading import models_run

    body = {"detector": "rtmdet-nano-person", "pose_model": "tinypose+blazepose-full"}
    assert models_run(body) == ["rtmdet-nano-person", "tinypose", "blazepose-full"]
    assert models_run({**body, "hands": True})[-2:] == ["hand-landmark-full", "hand-recrop"]
    assert models_run({**body, "hands": True, "hand_recrop": False})[-1] == "hand-landmark-full"
