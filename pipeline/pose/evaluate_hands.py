"""`dance3d eval hands`: the hand landmark model on annotated hand images.

Annotations (``hand_eval``'s layout): ``{"keypoint_order": [21 names], "images": [{"file", "dataset",
"hands": [{"side": "left" | "right" | null, "bbox": [x, y, w, h], "keypoints": [[x, y, v] x 21],
"keypoints_3d": [[x, y, z] x 21] | null, "units_3d": "mm" | null}]}]}``; a joint with v = 0 is not labelled.

Regions (``regions``): ``body``, as pose2d finds hands (``hands.body_hands``): the pose2d stage's
detector and body model on the whole image, a region beyond each confident wrist along its forearm
(refined by Holistic's re-crop model with ``pose2d.hand_recrop``), the hand model there; each
annotated hand is matched to the nearest hand found on its side. An image where no person is found
is taken as a crop around one hand (the hand-only datasets: a body cannot be seen
there), its side the model's handedness. ``palm``: MediaPipe's own hand pipeline as the peer
(``palms.py``: its palm detector on the whole image, the landmark model once in each palm's
region). ``body+palm`` (the command's default): both, the surer of two hands on one spot kept
(``fused_hands``): the two fail in opposite places (the palm detector misses small hands of whole
people, the forearm misses where no body is seen). ``annotated``: a region on the annotated box
(the model alone, as if the region were perfect).

Per dataset and over all: PCK at 0.2 of the hand box's longer side over every labelled joint
(a hand not found counts all its joints as misses), the mean error in pixels over the hands
found, hands found against hands annotated, and where an annotation has 3D points the
root-aligned 3D error (wrist on wrist) of the model's metric hand.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pipeline.core.errors import InputError
from pipeline.pose.hands import SIDES, Hand, HandLandmarks, HandRecrop, body_hands, region_from_box
from pipeline.pose.pose2dfile import HAND_JOINTS

PCK_SHARE = 0.2


def read_hand_annotations(path: Path) -> list[dict]:
    """The annotated images, checked: one InputError naming the file and what is wrong."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("images"), list):
        raise InputError(path, "expected an object with an 'images' list")
    order = data.get("keypoint_order")
    if order is not None and list(order) != list(HAND_JOINTS):
        raise InputError(path, f"keypoint_order must be {', '.join(HAND_JOINTS)}")
    for i, image in enumerate(data["images"]):
        for j, hand in enumerate(image.get("hands") or []):
            where = f"images[{i}].hands[{j}]"
            if np.asarray(hand.get("keypoints"), dtype=float).shape != (21, 3):
                raise InputError(path, f"{where}.keypoints: expected 21 [x, y, visible] rows")
            if len(hand.get("bbox") or ()) != 4:
                raise InputError(path, f"{where}.bbox: expected [x, y, w, h]")
            if hand.get("side") not in (None, *SIDES):
                raise InputError(path, f"{where}.side: left, right or null, not {hand.get('side')!r}")
    return data["images"]


def people_hands(image: np.ndarray, detector, pose, opts, landmarks: HandLandmarks,
                 recrop: HandRecrop | None = None) -> list[tuple[str, Hand]]:
    """(side, hand) of every person the pose2d rules find, as pose2d finds them (``hands.body_hands``);
    with no person, the hand the whole image holds (a crop around one hand)."""
    from dataclasses import replace

    from pipeline.pose.pose2d import find_people

    _, batch = find_people(image, detector.detect(image), pose, replace(opts, top_k=100))
    if not len(batch):
        height, width = image.shape[:2]
        hand = landmarks.estimate(image, region_from_box(np.array([0, 0, width, height]), landmarks.size, 1.0))
        return [("right" if hand.right >= 0.5 else "left", hand)]
    return [(side, hand) for pair in body_hands(landmarks, image, batch.keypoints, opts.hand_passes, recrop=recrop)
            for side, hand in zip(SIDES, pair) if hand is not None]


def palm_hands(image: np.ndarray, palms, landmarks: HandLandmarks) -> list[tuple[str, Hand]]:
    """(side, hand) in every palm's region, MediaPipe's way: one landmark pass, the side its handedness."""
    from pipeline.pose.palms import region_from_palm

    hands = [landmarks.estimate(image, region_from_palm(p, landmarks.size), passes=1) for p in palms.detect(image)]
    return [("right" if hand.right >= 0.5 else "left", hand) for hand in hands]


def fused_hands(body: list[tuple[str, Hand]], palm: list[tuple[str, Hand]]) -> list[tuple[str, Hand]]:
    """Hands from both paths, one per place: of two whose wrists lie within half the larger hand's
    extent of each other, the surer is kept (no annotation is looked at)."""
    kept: list[tuple[str, Hand]] = []
    for side, hand in sorted(body + palm, key=lambda pair: -pair[1].presence):
        extent = np.ptp(hand.keypoints[:, :2], axis=0).max()
        if all(np.linalg.norm(hand.keypoints[0, :2] - other.keypoints[0, :2])
               > 0.5 * max(extent, np.ptp(other.keypoints[:, :2], axis=0).max()) for _, other in kept):
            kept.append((side, hand))
    return kept


def _match(truth: list[dict], found: list[tuple[str, Hand]]) -> list[Hand | None]:
    """Each annotated hand's hand found: the nearest on its side (mean error over its labelled joints,
    at most its box's longer side), each hand found matched once, nearest pairs first."""
    pairs = []
    for t, hand in enumerate(truth):
        kp = np.asarray(hand["keypoints"], np.float64)
        seen = kp[:, 2] > 0
        for f, (side, candidate) in enumerate(found):
            if hand.get("side") not in (None, side) or not seen.any():
                continue
            error = float(np.linalg.norm(candidate.keypoints[seen, :2] - kp[seen, :2], axis=1).mean())
            if error <= max(hand["bbox"][2:]):
                pairs.append((error, t, f))
    matched: list[Hand | None] = [None] * len(truth)
    used = set()
    for _, t, f in sorted(pairs):
        if matched[t] is None and f not in used:
            matched[t], used = found[f][1], used | {f}
    return matched


def _score(hand: dict, found: Hand | None, min_presence: float) -> dict:
    kp = np.asarray(hand["keypoints"], np.float64)
    seen = kp[:, 2] > 0
    row = {"joints": int(seen.sum()), "found": found is not None and found.presence >= min_presence}
    if not row["found"]:
        return {**row, "correct": 0, "error_px": None, "error_3d_mm": None}
    errors = np.linalg.norm(found.keypoints[seen, :2] - kp[seen, :2], axis=1)
    row.update(correct=int((errors <= PCK_SHARE * max(hand["bbox"][2:])).sum()), error_px=float(errors.mean()),
               error_3d_mm=None)
    if hand.get("keypoints_3d") is not None:
        truth = np.asarray(hand["keypoints_3d"], np.float64) * (1.0 if hand.get("units_3d") == "mm" else 1000.0)
        mine = found.world.astype(np.float64) * 1000.0
        row["error_3d_mm"] = float(np.linalg.norm((mine - mine[0]) - (truth - truth[0]), axis=1).mean())
    return row


def _summary(rows: list[dict]) -> dict:
    joints = sum(r["joints"] for r in rows)
    found = [r for r in rows if r["found"]]
    three_d = [r["error_3d_mm"] for r in found if r["error_3d_mm"] is not None]
    return {"hands": len(rows), "found": len(found), "joints": joints,
            "pck": round(sum(r["correct"] for r in rows) / joints, 4) if joints else None,
            "error_px": round(float(np.mean([r["error_px"] for r in found])), 2) if found else None,
            "error_3d_mm": round(float(np.mean(three_d)), 1) if three_d else None, "hands_3d": len(three_d)}


REGIONS = ("body", "palm", "body+palm", "annotated")


def load_models(root: Path, params: dict, regions: str) -> dict:
    """What ``evaluate_hands`` needs for ``regions``, from the project (or the models' search path) and
    the pose2d section ``params``: the hand model, and the body models or the palm detector."""
    from pipeline.pose.models.fetch import resolve_model
    from pipeline.pose.models.loading import load_pose_models, worker_files
    from pipeline.pose.models.session import create_session
    from pipeline.pose.palms import PalmDetector
    from pipeline.pose.pose2d import Pose2dOptions

    models = {"landmarks": HandLandmarks(create_session(resolve_model("hand-landmark-full", root))),
              "opts": Pose2dOptions.from_params(params)}
    if "palm" in regions:
        models["palms"] = PalmDetector(create_session(resolve_model("palm-detection-full", root)))
    if "body" in regions:
        pose_models = load_pose_models(worker_files(root, {**params, "hands": False}))
        models["body"] = (pose_models.detector, pose_models.pose)
        if models["opts"].hand_recrop:
            models["recrop"] = HandRecrop(create_session(resolve_model("hand-recrop", root)))
    return models


def evaluate_hands(annotations: Path, images: Path, landmarks: HandLandmarks, *, regions: str = "body",
                   body=None, opts=None, palms=None, recrop: HandRecrop | None = None, min_presence: float = 0.5,
                   describe: dict | None = None) -> dict:
    """Per dataset and over all (see the module's docstring); ``body`` is (detector, pose) for ``body``,
    ``palms`` a ``palms.PalmDetector`` for ``palm``."""
    import cv2

    if regions not in REGIONS:
        raise ValueError(f"regions must be one of {', '.join(REGIONS)}, not {regions!r}")
    rows: dict[str, list[dict]] = {}
    for entry in read_hand_annotations(annotations):
        path = Path(images) / entry["file"]
        image = cv2.imread(str(path))
        if image is None:
            raise InputError(path, "not an image OpenCV can read (or missing)")
        truth = entry.get("hands") or []
        if regions == "annotated":
            matched = [landmarks.estimate(image, region_from_box(h["bbox"], landmarks.size)) for h in truth]
        elif regions == "palm":
            matched = _match(truth, palm_hands(image, palms, landmarks))
        elif regions == "body+palm":
            matched = _match(truth, fused_hands(people_hands(image, *body, opts, landmarks, recrop),
                                                palm_hands(image, palms, landmarks)))
        else:
            matched = _match(truth, people_hands(image, *body, opts, landmarks, recrop))
        rows.setdefault(entry.get("dataset", ""), []).extend(
            _score(h, m, min_presence) for h, m in zip(truth, matched))
    result = {"regions": regions, "pck_share": PCK_SHARE, "min_presence": min_presence,
              "datasets": {name: _summary(r) for name, r in sorted(rows.items())},
              "all": _summary([r for rs in rows.values() for r in rs])}
    return {**result, **({"describe": describe} if describe else {})}


def format_table(result: dict) -> str:
    lines = [f"hands, regions from {result['regions']}: PCK at {result['pck_share']} of the hand box "
             f"(a hand not found misses all its joints), error over the hands found",
             "| dataset | hands found / annotated | PCK | error px | root-aligned 3D error mm (hands) |",
             "|---|---|---|---|---|"]
    for name, s in [*result["datasets"].items(), ("**all**", result["all"])]:
        three_d = f"{s['error_3d_mm']} ({s['hands_3d']})" if s["error_3d_mm"] is not None else ""
        lines.append(f"| {name} | {s['found']} / {s['hands']} | {s['pck']} | {s['error_px']} | {three_d} |")
    return "\n".join(lines)
