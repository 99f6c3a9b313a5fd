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
from pipeline.pose.hands import HandLandmarks, region_from_box, region_from_forearm, region_from_landmarks
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
        hand_model: Path, palm_model: Path, hand_eval_dir: Path, models_dir: Path, tmp_path: Path) -> None:
    (tmp_path / "models").mkdir()
    for model in (hand_model, palm_model):
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
