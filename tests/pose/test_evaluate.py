"""`dance3d eval pose2d`: COCO keypoint AP (pycocotools), detection recall, PCK, per source and tier."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.core.errors import InputError
from pipeline.pose.evaluate import Prediction, evaluate_pose2d, keypoint_ap, matching


def _coco(path: Path):
    from pycocotools.coco import COCO

    with contextlib.redirect_stdout(io.StringIO()):
        return COCO(str(path))


def test_predictions_equal_to_the_annotations_score_perfectly(pose2d_eval_dir: Path) -> None:
    coco = _coco(pose2d_eval_dir / "annotations.json")
    perfect = []
    for ann in coco.loadAnns(coco.getAnnIds()):
        x, y, w, h = ann["bbox"]
        kp = np.asarray(ann["keypoints"], float).reshape(17, 3)
        kp[:, 2] = 1.0
        perfect.append(Prediction(ann["image_id"], np.array([x, y, x + w, y + h]), 1.0, kp))
    ids = sorted(coco.getImgIds())
    assert keypoint_ap(coco, perfect, ids)["AP"] == pytest.approx(1.0)
    scores = matching(coco, perfect, ids)
    assert scores["detection_recall"] == 1.0 and scores["false_positives_per_image"] == 0.0
    assert scores["pck_0.2_torso"] == 1.0 and max(scores["joint_error_torso"].values()) == 0.0


def test_shifted_keypoints_lose_ap_and_pck(pose2d_eval_dir: Path) -> None:
    coco = _coco(pose2d_eval_dir / "annotations.json")
    shifted = []
    for ann in coco.loadAnns(coco.getAnnIds()):
        x, y, w, h = ann["bbox"]
        kp = np.asarray(ann["keypoints"], float).reshape(17, 3)
        kp[:, 0] += 0.3 * w  # every joint a third of the body width off
        kp[:, 2] = 1.0
        shifted.append(Prediction(ann["image_id"], np.array([x, y, x + w, y + h]), 1.0, kp))
    ids = sorted(coco.getImgIds())
    assert keypoint_ap(coco, shifted, ids)["AP"] < 0.3
    assert matching(coco, shifted, ids)["pck_0.2_torso"] < 0.5


def test_the_cli_scores_the_configured_models_per_source_and_tier(tmp_path: Path, models_dir: Path,
                                                                  pose2d_eval_dir: Path, monkeypatch, capsys) -> None:
    from tests.conftest import PROJECT

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    data = pose2d_eval_dir
    out = tmp_path / "r.json"
    assert main(["--root", str(PROJECT), "eval", "pose2d", "--annotations", str(data / "annotations.json"),
                 "--images", str(data / "images"), "--det-score", "0.3", "--out", str(out)]) == 0
    assert "eval_tier=core" in capsys.readouterr().out
    result = json.loads(out.read_text())
    overall = result["scores"]["all"]
    assert overall["people"] == 44 and overall["images"] == 21
    assert overall["AP"] >= 0.3 and overall["detection_recall"] >= 0.7  # measured: 0.371 and 0.727 (MoveNet)
    assert {"source=coco8pose", "source=mpii", "eval_tier=extra"} <= set(result["scores"])
    assert main(["--root", str(PROJECT), "eval", "pose2d", "--annotations", str(data / "annotations.json"),
                 "--images", str(data / "images"), "--gt-boxes", "--out", str(out)]) == 0
    gt = json.loads(out.read_text())["scores"]["all"]
    assert gt["detection_recall"] == 1.0 and gt["false_positives_per_image"] == 0.0


def test_a_file_that_is_not_coco_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"images": [}')
    with pytest.raises(InputError, match="bad.json: not a COCO keypoint annotation file"):
        evaluate_pose2d(bad, tmp_path, None, None)
