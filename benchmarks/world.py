"""World-grounded motion on held-out motion capture through pitched cameras.

Usage: python -m benchmarks.world [--mocap DIR] [--model pipeline/motion/lifting/weights/lifter_dance3d.onnx]
                                  [--seconds 20] [--out benchmarks/results/world.json]

Every held-out sequence of the lifter's protocol (pipeline/motion/lifting/evaluate.py) is filmed
by a portrait phone 3 m away at 1.2 m, from three headings, pitched -20, -10, 0, 10 and 20
degrees (positive: looking down), with the protocol's noisy 2D (a pose model of expected OKS
0.80). The 2D is lifted by the lifter (flip averaging on), the pose and the root path are
HP-filtered as the smooth stage does (lambda 1), then:

- up: the angle between the up direction estimated from the lifted body and the true one;
- root: the root's camera-frame path from the lifted pose and the 2D (focal length assumed
  from the frame size, as on real video) against the true path: raw, and after one scale and
  offset per clip;
- bones: the largest limb-length coefficient of variation before and after one skeleton per
  clip, and how far that moved the joints;
- skating: horizontal ankle speed while in contact, before and after pinning the feet, beside
  the motion capture's own (the same contact rule on the true motion);
- contact (a lifter with feet): the F1 score of each frame's foot-contact flags against the
  motion capture's (its heel or toe tip within 3 cm of rest and slower than 0.2 m/s), judged
  from the lifted heels and toes and, beside it, from the lifted ankles alone.
"""

from __future__ import annotations

import argparse
import json
import os
from functools import partial
from pathlib import Path

import numpy as np

from pipeline.motion.lifting.evaluate import Camera, add_pose_noise, camera_pose, split, view
from pipeline.motion.lifting.infer import load_lifter
from pipeline.motion.mocap.sources import first_seconds, keypoints_and_joints, load_folder, resample
from pipeline.motion.smoothing import hp_trend
from pipeline.motion.world.bones import apply_skeleton, bone_length_cv, fit_skeleton
from pipeline.motion.world.contact import carry_feet, foot_contact, pin_feet, skating
from pipeline.motion.world.gravity import to_world, up_error_deg
from pipeline.motion.world.trajectory import align_scale_offset, assumed_focal, root_from_2d

WIDTH, HEIGHT, FPS = 1080, 1920, 25.0
PITCHES = (-20.0, -10.0, 0.0, 10.0, 20.0)
HEADINGS = (0.0, 120.0, 240.0)


def f1(estimate: np.ndarray, truth: np.ndarray) -> float:
    hits = float((estimate & truth).sum())
    return 2 * hits / max(1.0, float(estimate.sum() + truth.sum()))


def measure(lift, seq, heading: float, pitch: float, rng: np.random.Generator, feet: bool) -> dict:
    camera = Camera(f"phone_{heading:g}_{pitch:+g}", heading, 1.2, 3.0, WIDTH, HEIGHT, pitch_deg=pitch)
    keypoints, body = keypoints_and_joints(seq, feet)
    xy, everything = view(body, keypoints, camera)
    joints = everything[:, :17]
    true_up = camera_pose(seq.h36m, camera)[0] @ [0.0, 1.0, 0.0]
    xy = add_pose_noise(xy, rng)
    (rel,) = lift([xy], WIDTH, HEIGHT)
    rel = rel.astype(np.float64)
    root = root_from_2d(rel[:, :17], xy[:, :17], assumed_focal(WIDTH, HEIGHT), WIDTH, HEIGHT)
    rel = hp_trend(rel.reshape(len(rel), -1), 1.0).reshape(rel.shape)  # the smooth stage
    root = hp_trend(root, 1.0)
    true_root = joints[:, 0]
    world_all, camera = to_world(rel, root=root)
    world = world_all[:, :17]
    lengths = fit_skeleton(world)
    fitted = apply_skeleton(world, lengths)
    contact = foot_contact(fitted, FPS)
    pinned = pin_feet(fitted, contact)
    truth_all, _ = to_world(everything - everything[:, :1], root=true_root)
    truth = truth_all[:, :17]
    feet_rows = {}
    if feet:
        true_contact = foot_contact(truth, FPS, feet=truth_all[:, 17:], feet_height=0.03, speed=0.2)
        by_feet = foot_contact(fitted, FPS, feet=carry_feet(world_all[:, 17:], world, fitted))
        feet_rows = {"contact_f1_feet": f1(by_feet, true_contact), "contact_f1_ankles": f1(contact, true_contact),
                     "contact_share_true": float(true_contact.mean())}
    return {**feet_rows, "up_deg": up_error_deg(camera, true_up), "pitch_error_deg": camera.pitch_deg - pitch,
            "root_mm": 1000 * float(np.linalg.norm(root - true_root, axis=-1).mean()),
            "root_aligned_mm": 1000 * float(np.linalg.norm(align_scale_offset(root, true_root) - true_root,
                                                           axis=-1).mean()),
            "cv_before": bone_length_cv(world), "cv_after": bone_length_cv(fitted),
            "fit_moved_mm": 1000 * float(np.linalg.norm(fitted - world, axis=-1).mean()),
            "contact_share": float(contact.mean()),
            "skate_before": skating(fitted, contact, FPS), "skate_after": skating(pinned, contact, FPS),
            "pin_moved_mm": 1000 * float(np.linalg.norm(pinned - fitted, axis=-1).mean()),
            "skate_mocap": skating(truth, foot_contact(truth, FPS), FPS)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--model", type=Path, default=Path("pipeline/motion/lifting/weights/lifter_dance3d.onnx"))
    parser.add_argument("--seconds", type=float, default=20.0, help="at most this much of each sequence")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/world.json"))
    args = parser.parse_args()
    lifter = load_lifter(str(args.model), 2)
    lift = partial(lifter.lift, flip=True)
    _, held = split(load_folder(args.mocap))
    rng = np.random.default_rng(0)
    rows: dict[str, list[dict]] = {}
    for seq in held:
        seq = first_seconds(resample(seq, FPS), args.seconds)
        for heading in HEADINGS:
            for pitch in PITCHES:
                row = measure(lift, seq, heading, pitch, rng, lifter.feet)
                rows.setdefault(seq.source, []).append({"pitch": pitch, **row})
    keys = [k for k in next(iter(rows.values()))[0] if k != "pitch"]
    summary = {source: {k: float(np.nanmedian([r[k] for r in rs])) for k in keys} for source, rs in rows.items()}
    every = [r for rs in rows.values() for r in rs]
    summary["all"] = {k: float(np.nanmedian([r[k] for r in every])) for k in keys}
    summary["all_by_pitch"] = {str(p): {k: float(np.nanmedian([r[k] for r in every if r["pitch"] == p]))
                                        for k in ("up_deg", "root_aligned_mm")} for p in PITCHES}
    print(f"{'source':26s} {'up°':>5s} {'root mm':>8s} {'aligned':>8s} {'CV':>6s} {'->':>6s} {'fit mm':>6s} "
          f"{'skate m/s':>9s} {'pinned':>7s} {'mocap':>6s}")
    for source, s in summary.items():
        if source == "all_by_pitch":
            continue
        print(f"{source:26s} {s['up_deg']:5.1f} {s['root_mm']:8.0f} {s['root_aligned_mm']:8.0f} "
              f"{s['cv_before']:6.1%} {s['cv_after']:6.1%} {s['fit_moved_mm']:6.1f} {s['skate_before']:9.3f} "
              f"{s['skate_after']:7.3f} {s['skate_mocap']:6.3f}")
    if lifter.feet:
        print(f"{'source':26s} contact F1: heels and toes  ankles alone  (true contact share)")
        for source, s in summary.items():
            if source != "all_by_pitch":
                print(f"{source:26s}             {s['contact_f1_feet']:15.3f} {s['contact_f1_ankles']:13.3f}  "
                      f"({s['contact_share_true']:.2f})")
    print("by pitch (median up error deg, aligned root mm):",
          {p: (round(v["up_deg"], 1), round(v["root_aligned_mm"])) for p, v in summary["all_by_pitch"].items()})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "protocol": __doc__}, indent=1))


if __name__ == "__main__":
    main()
