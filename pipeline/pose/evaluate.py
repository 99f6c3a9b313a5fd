"""``dance3d eval pose2d``: the configured detector and pose model on COCO-style annotated images.

Protocol: every image of the annotation file is run through the same detector and top-down
pose wrappers as the pose2d stage (or, in ground-truth-box mode, the pose model alone on
the annotated boxes). Scores, all at the image level and per ``source`` / ``eval_tier``
field of the file where present:

- COCO keypoint AP / AP50 / AP75 / AR (pycocotools' ``COCOeval``, OKS with the COCO sigmas;
  joints an annotation does not label have visibility 0 and do not count);
- detection recall at IoU 0.5 against every annotated person, and false positives per image
  (detections matching no annotated person; only meaningful where all people are annotated);
- PCK@0.2 of the torso (left shoulder to right hip) on people matched at IoU 0.5, and the
  mean per-joint error in torso units.
"""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from pipeline.core.errors import InputError
from pipeline.pose.boxes import iou_matrix
from pipeline.pose.pose2d import Pose2dOptions, find_people, lift_dark
from pipeline.pose.pose2dfile import COCO17

TORSO = (5, 12)  # left shoulder, right hip


@dataclass(frozen=True)
class Prediction:
    image_id: int
    box: np.ndarray        # x1, y1, x2, y2
    box_score: float
    keypoints: np.ndarray  # 17 x 3


def _xyxy(bbox: list[float]) -> np.ndarray:
    x, y, w, h = bbox
    return np.array([x, y, x + w, y + h], np.float32)


def predict(coco, images: Path, detector, pose, gt_boxes: bool, opts: Pose2dOptions) -> list[Prediction]:
    """Detector (or annotated) boxes and keypoints for every image of ``coco``, chosen as the stage does."""
    out = []
    for image_id in sorted(coco.getImgIds()):
        info = coco.loadImgs(image_id)[0]
        path = Path(images) / info["file_name"]
        image = cv2.imread(str(path))
        if image is None:
            raise InputError(path, "cannot read this image (named by the annotation file)")
        image = lift_dark(image, opts.dark_mean)
        if gt_boxes:
            anns = coco.loadAnns(coco.getAnnIds(imgIds=image_id, iscrowd=False))
            boxes = np.array([_xyxy(a["bbox"]) for a in anns], np.float32).reshape(-1, 4)
            scores = np.ones(len(boxes), np.float32)
            keypoints = pose.estimate(image, boxes).keypoints
        else:
            people, batch = find_people(image, detector.detect(image), pose, replace(opts, top_k=100))
            boxes, scores, keypoints = people.boxes, people.scores, batch.keypoints
        out += [Prediction(image_id, boxes[i], float(scores[i]), keypoints[i]) for i in range(len(boxes))]
    return out


def _coco_results(predictions: list[Prediction]) -> list[dict]:
    results = []
    for p in predictions:
        kp = p.keypoints.astype(float)
        visible = kp[:, 2] > 0.2
        confidence = float(kp[visible, 2].mean()) if visible.any() else 0.0
        x1, y1, x2, y2 = (float(v) for v in p.box)
        results.append({"image_id": int(p.image_id), "category_id": 1, "keypoints": kp.ravel().round(2).tolist(),
                        "score": p.box_score * confidence, "bbox": [x1, y1, x2 - x1, y2 - y1]})
    return results


def keypoint_ap(coco, predictions: list[Prediction], image_ids: list[int]) -> dict[str, float]:
    """pycocotools keypoint AP/AR over ``image_ids``."""
    from pycocotools.cocoeval import COCOeval

    results = [r for r in _coco_results(predictions) if r["image_id"] in set(image_ids)]
    if not results:
        return {"AP": 0.0, "AP50": 0.0, "AP75": 0.0, "AR": 0.0}
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its tables
        evaluator = COCOeval(coco, coco.loadRes(results), "keypoints")
        evaluator.params.imgIds = list(image_ids)
        evaluator.evaluate()
        evaluator.accumulate()
        evaluator.summarize()
    stats = evaluator.stats
    return {"AP": round(float(max(stats[0], 0)), 4), "AP50": round(float(max(stats[1], 0)), 4),
            "AP75": round(float(max(stats[2], 0)), 4), "AR": round(float(max(stats[5], 0)), 4)}


def matching(coco, predictions: list[Prediction], image_ids: list[int]) -> dict:
    """Detection recall and false positives at IoU 0.5; PCK@0.2 torso and per-joint errors of matches."""
    found = total = false_pos = 0
    correct = np.zeros(17)
    labelled = np.zeros(17)
    error = np.zeros(17)
    for image_id in image_ids:
        anns = [a for a in coco.loadAnns(coco.getAnnIds(imgIds=image_id)) if not a.get("iscrowd")]
        preds = sorted([p for p in predictions if p.image_id == image_id], key=lambda p: -p.box_score)
        gt = np.array([_xyxy(a["bbox"]) for a in anns], np.float32).reshape(-1, 4)
        iou = iou_matrix(np.array([p.box for p in preds], np.float32).reshape(-1, 4), gt)
        taken = set()
        for i, p in enumerate(preds):  # greedy by score, as detection benchmarks match
            candidates = [j for j in np.argsort(-iou[i]) if iou[i, j] >= 0.5 and j not in taken] if len(gt) else []
            if not candidates:
                false_pos += 1
                continue
            j = candidates[0]
            taken.add(j)
            truth = np.asarray(anns[j]["keypoints"], float).reshape(17, 3)
            if truth[TORSO[0], 2] > 0 and truth[TORSO[1], 2] > 0:
                torso = np.linalg.norm(truth[TORSO[0], :2] - truth[TORSO[1], :2])
                seen = truth[:, 2] > 0
                dist = np.linalg.norm(p.keypoints[:, :2] - truth[:, :2], axis=1) / max(torso, 1e-6)
                labelled += seen
                correct += seen & (dist <= 0.2)
                error += np.where(seen, dist, 0)
        found += len(taken)
        total += len(anns)
    per_joint = {name: round(float(error[k] / labelled[k]), 3) for k, name in enumerate(COCO17) if labelled[k]}
    return {"people": total, "detection_recall": round(found / total, 4) if total else 0.0,
            "false_positives_per_image": round(false_pos / len(image_ids), 3) if image_ids else 0.0,
            "pck_0.2_torso": round(float(correct.sum() / labelled.sum()), 4) if labelled.sum() else 0.0,
            "joint_error_torso": per_joint}


def read_coco(annotations: Path):
    """A COCO keypoint annotation file (pycocotools' ``COCO``), or an ``InputError`` naming it."""
    from pycocotools.coco import COCO

    try:
        with contextlib.redirect_stdout(io.StringIO()):
            return COCO(str(annotations))
    except FileNotFoundError:
        raise InputError(annotations, "no such file") from None
    except (OSError, ValueError, KeyError, TypeError, json.JSONDecodeError) as exc:
        raise InputError(annotations, f"not a COCO keypoint annotation file: {exc}") from None


def evaluate_pose2d(annotations: Path, images: Path, detector, pose, *, gt_boxes: bool = False,
                    opts: Pose2dOptions = Pose2dOptions(), describe: dict | None = None, coco=None) -> dict:
    """Scores overall, per source and per tier; ``describe`` names the models and options used;
    ``coco``: the annotation file as ``read_coco`` already read it."""
    coco = read_coco(annotations) if coco is None else coco
    predictions = predict(coco, images, detector, pose, gt_boxes, opts)
    groups: dict[str, list[int]] = {"all": sorted(coco.getImgIds())}
    for image in coco.loadImgs(coco.getImgIds()):
        for field in ("source", "eval_tier"):
            if image.get(field):
                groups.setdefault(f"{field}={image[field]}", []).append(image["id"])
    scores = {name: {**keypoint_ap(coco, predictions, ids), **matching(coco, predictions, ids), "images": len(ids)}
              for name, ids in groups.items()}
    return {"annotations": str(annotations), "mode": "ground-truth boxes" if gt_boxes else "detector boxes",
            **(describe or {}), "scores": scores}


def format_table(result: dict) -> str:
    lines = [f"{result['annotations']}: {result['mode']}, " + ", ".join(
        f"{k} {v}" for k, v in result.items() if k not in ("annotations", "mode", "scores"))]
    lines.append(f"{'group':28s} {'images':>6s} {'people':>6s} {'AP':>6s} {'AP50':>6s} {'AR':>6s} {'recall':>6s} "
                 f"{'FP/img':>6s} {'PCK@.2':>6s}")
    for name, s in result["scores"].items():
        lines.append(f"{name:28s} {s['images']:6d} {s['people']:6d} {s['AP']:6.3f} {s['AP50']:6.3f} {s['AR']:6.3f} "
                     f"{s['detection_recall']:6.3f} {s['false_positives_per_image']:6.2f} {s['pck_0.2_torso']:6.3f}")
    return "\n".join(lines)
