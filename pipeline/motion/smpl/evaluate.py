"""``dance3d eval smpl``: how much of the world motion survives retargeting onto the SMPL tree.

Protocol: every clip of the world files (the corpus's motion), or every sequence of a motion
capture folder (its own joints, y up, at its own rate: real human proportions with no lifting
error), is retargeted (``retarget.retarget``) and forward kinematics of the result (the SMPL rest
offsets times the clip's scale) is compared with the joints it came from:

- per mapped point (``skeleton.MAPPED``, the hips' midpoint, the balls of the feet), the distance
  in mm: median and 95th percentile over frames, pooled over clips;
- foot sliding (mm a frame at 30 fps) of the ankles and balls of the feet on the frames where each
  stands (the world file's planted flags; the capture's own contact), before (the input's points)
  and after (SMPL's joints);
- frames on which a joint leaves its human range (``checks.RANGES``, ``checks.HINGES``);
- per limb (upper arms, forearms, thighs, shins), the angle between the SMPL bone and the world
  bone in degrees, median and 95th percentile: the direction a trainer sees, whatever the two
  skeletons' bone lengths.

- with hands (``pose2d.hands``), SMPL-H's fingers (``hands.retarget_hands``) posed again by forward
  kinematics on the clip's own rest hands against the world hands, about the wrist: per joint the
  distance in mm (median, 95th percentile and the worst joint's median), and the share of finger
  joints held at ``hands.FINGER_RANGE_DEG``, where the hand model folded them further (its noise).

Baseline beside the figures: the SMPL rest skeleton placed at each frame's hips with no rotation
(what a trainer would get from an exporter that wrote no poses): its mapped-point error.

Beside them, the same rules on the SMPL tree given the clip's own proportions
(``proportions.own_offsets``): the error of the inverse kinematics alone. What the SMPL figures add
to it is the neutral body's proportions, which no rotations can remove.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.motion.smpl import checks
from pipeline.motion.smpl.hands import FINGER_RANGE_DEG
from pipeline.motion.smpl.kinematics import forward
from pipeline.motion.smpl.proportions import own_offsets
from pipeline.motion.smpl.retarget import SmplMotion, retarget

LIMBS = ("knees", "ankles", "feet", "shoulders", "elbows", "wrists")


@dataclass(frozen=True)
class Clip:
    source: str
    name: str
    joints: np.ndarray            # T x 17 x 3, y up
    feet: np.ndarray | None       # T x 4 x 3
    standing: np.ndarray | None   # T x 4: ankles and balls standing (checks.foot_planted's order)
    fps: float
    hands: np.ndarray | None = None     # T x 2 x 21 x 3 world hands (NaN: never seen)
    presence: np.ndarray | None = None  # T x 2


def world_clips(root: Path) -> list[Clip]:
    """The clips of ``root``'s data/world files; none is an InputError saying what makes them."""
    from pipeline.core.errors import InputError
    from pipeline.core.paths import WORLD
    from pipeline.core.storage import item_files, read_meta
    from pipeline.motion.world.worldfile import read_world

    files = item_files(root / WORLD)
    if not files:
        raise InputError(root / WORLD, "no world files: the ground stage makes them (dvc repro ground), "
                                       "or measure motion capture with --mocap DIR")
    out = []
    for path in files:
        fps = float(read_meta(path).get("fps", 24.0))
        for c in read_world(path):
            out.append(Clip(path.stem, c.clip_id, c.joints, c.feet, checks.foot_planted(c.contact, c.planted), fps,
                            c.hands, c.hand_presence))
    return out


def capture_clips(mocap: Path, seconds: float = 0.0) -> list[Clip]:
    """The sequences of a motion capture folder (``sources.load_folder``) with heels and toes."""
    from pipeline.motion.mocap.sources import first_seconds, load_folder
    from pipeline.motion.world.contact import capture_contact

    out = []
    for seq in load_folder(mocap):
        if seq.feet is None:
            continue
        if seconds:
            seq = first_seconds(seq, seconds)
        standing = checks.foot_planted(np.zeros((seq.frames, 2), bool), capture_contact(seq.feet, seq.fps))
        out.append(Clip(seq.source, seq.name, seq.h36m, seq.feet, standing, seq.fps))
    return out


def _rest_at_hips(smpl: SmplMotion) -> np.ndarray:
    """The baseline: the rest skeleton, unrotated, at the retargeted pelvis."""
    frames = len(smpl.trans)
    return forward(np.broadcast_to(np.eye(3), (frames, 24, 3, 3)), smpl.trans, smpl.scale)


def finger_errors(smpl: SmplMotion, hands: np.ndarray, presence: np.ndarray) -> dict | None:
    """SMPL-H's fingers solved and posed again against the world hands (T x 2 x 21 x 3): per seen
    hand, the distance of each of its 20 points beyond the wrist (T x 20, metres, about the wrist),
    and every finger joint's angle (degrees); None without a seen hand."""
    from scipy.spatial.transform import Rotation

    from pipeline.motion.smpl.hands import hand_forward, retarget_hands
    from pipeline.motion.smpl.kinematics import global_rotations

    solved = retarget_hands(smpl.local, hands, presence)
    glob = global_rotations(solved.local)
    errors, angles = [], []
    for side, rest in enumerate(solved.rests):
        if rest is None:
            continue
        fingers = solved.fingers[:, 15 * side: 15 * side + 15]
        again = hand_forward(hands[:, side, 0], glob[:, 20 + side], fingers, rest)
        errors.append(np.linalg.norm(again - hands[:, side], axis=-1)[:, 1:])
        angles.append(np.degrees(np.linalg.norm(Rotation.from_matrix(fingers.reshape(-1, 3, 3)).as_rotvec(), axis=-1)))
    return {"errors": errors, "angles": np.concatenate(angles)} if errors else None


def score_clip(clip: Clip) -> dict:
    smpl = retarget(clip.joints, clip.feet)
    errors = checks.joint_errors(smpl, clip.joints, clip.feet)
    baseline = checks.joint_errors(SmplMotion(smpl.local, smpl.trans, smpl.scale, _rest_at_hips(smpl)),
                                   clip.joints, clip.feet)
    before = checks.world_foot_points(clip.joints, clip.feet)
    ranges = checks.joint_ranges(smpl)
    own = checks.joint_errors(retarget(clip.joints, clip.feet, own_offsets(clip.joints, clip.feet)), clip.joints,
                              clip.feet)
    row = {"source": clip.source, "clip": clip.name, "frames": len(clip.joints), "scale": round(smpl.scale, 4),
           "errors": errors, "baseline": baseline, "own_proportions": own,
           "directions": checks.limb_directions(smpl, clip.joints),
           "sliding_before": checks.sliding(before, clip.standing, clip.fps) if before is not None else float("nan"),
           "sliding_after": checks.sliding(checks.foot_points(smpl), clip.standing, clip.fps)
           if before is not None else float("nan"),
           "outside": {k: v for k, v in ranges.outside.items() if v},
           "fingers": None if clip.hands is None else finger_errors(smpl, clip.hands, clip.presence)}
    return row


def _pooled(rows: list[dict], key: str) -> dict:
    joints = dict.fromkeys(k for r in rows for k in r[key])
    out = {}
    for name in joints:
        values = 1000 * np.concatenate([r[key][name] for r in rows if name in r[key]])
        out[name] = _figures(values)
    out["all"] = _figures(1000 * np.concatenate([v for r in rows for v in r[key].values()]))
    return out


def _figures(values: np.ndarray) -> dict:
    return {"median_mm": round(float(np.median(values)), 1), "p95_mm": round(float(np.percentile(values, 95)), 1)}


def _directions(rows: list[dict]) -> dict:
    """Per limb, the SMPL bone's angle from the world bone (degrees): median and 95th percentile."""
    out = {}
    for name in rows[0]["directions"]:
        values = np.concatenate([r["directions"][name] for r in rows])
        out[name] = {"median_deg": round(float(np.median(values)), 1),
                     "p95_deg": round(float(np.percentile(values, 95)), 1)}
    return out


def _fingers(rows: list[dict]) -> dict | None:
    """Pooled SMPL-H finger figures over the rows' seen hands."""
    hands = [e for r in rows if r.get("fingers") for e in r["fingers"]["errors"]]
    if not hands:
        return None
    angles = np.concatenate([r["fingers"]["angles"] for r in rows if r.get("fingers")])
    worst = max(float(np.median(e, axis=0).max()) for e in hands)
    return {"hands": len(hands), **_figures(1000 * np.concatenate([e.ravel() for e in hands])),
            "worst_joint_median_mm": round(1000 * worst, 1),
            # held at the limit, to within the rotation's round trip through axis-angle
            "at_range_share": round(float(np.mean(angles > FINGER_RANGE_DEG - 0.01)), 4)}


def summarise(rows: list[dict]) -> dict:
    """Pooled errors, sliding and range counts over ``rows``."""
    frames = sum(r["frames"] for r in rows)
    outside: dict[str, int] = {}
    for r in rows:
        for k, v in r["outside"].items():
            outside[k] = outside.get(k, 0) + v

    def mean(key: str) -> float:
        values = [r[key] for r in rows if r[key] == r[key]]
        return round(float(np.mean(values)), 3) if values else float("nan")

    return {"clips": len(rows), "frames": frames, "error": _pooled(rows, "errors"),
            "baseline_rest_pose": _pooled(rows, "baseline")["all"],
            "error_own_proportions": _pooled(rows, "own_proportions"),
            "limb_direction_deg": _directions(rows),
            "sliding_before_mm": mean("sliding_before"), "sliding_after_mm": mean("sliding_after"),
            "frames_outside_range": outside, "scale_median": round(float(np.median([r["scale"] for r in rows])), 4),
            "fingers": _fingers(rows)}


def evaluate(clips: list[Clip]) -> dict:
    """The figures over all clips and per source, and one line per clip."""
    rows = [score_clip(c) for c in clips]
    if not rows:
        return {"clips": 0}
    result = {"all": summarise(rows)}
    for source in dict.fromkeys(r["source"] for r in rows):
        result[source] = summarise([r for r in rows if r["source"] == source])
    result["per_clip"] = [{"clip": r["clip"], "frames": r["frames"], "scale": r["scale"],
                           "median_mm": round(float(1000 * np.median(np.concatenate(list(r["errors"].values())))), 1),
                           "sliding_before_mm": round(r["sliding_before"], 3),
                           "sliding_after_mm": round(r["sliding_after"], 3), "outside": r["outside"]} for r in rows]
    return result


def format_report(result: dict) -> str:
    """A table a person reads: one line per source, then the pooled per-joint figures."""
    if not result.get("clips", 1):
        return "no clips to measure"
    lines = [f"{'source':28s} {'clips':>5s} {'median mm':>9s} {'p95 mm':>7s} {'rest mm':>7s} {'own prop. mm':>12s} "
             f"{'slide before':>12s} {'after':>6s} {'frames outside range':>20s}"]
    for source, s in result.items():
        if source == "per_clip":
            continue
        error, own = s["error"]["all"], s["error_own_proportions"]["all"]
        lines.append(f"{source:28s} {s['clips']:5d} {error['median_mm']:9.1f} {error['p95_mm']:7.1f} "
                     f"{s['baseline_rest_pose']['median_mm']:7.1f} {own['median_mm']:5.1f} /{own['p95_mm']:5.1f} "
                     f"{s['sliding_before_mm']:12.3f} "
                     f"{s['sliding_after_mm']:6.3f} {sum(s['frames_outside_range'].values()):>8d} of {s['frames']}")
    lines.append("")
    lines.append("per point (all clips): median / p95 mm on SMPL's proportions, and on the clip's own")
    own = result["all"]["error_own_proportions"]
    for name, e in result["all"]["error"].items():
        if name != "all":
            lines.append(f"  {name:16s} {e['median_mm']:7.1f} {e['p95_mm']:7.1f}    "
                         f"{own[name]['median_mm']:7.1f} {own[name]['p95_mm']:7.1f}")
    lines.append("(own proportions: the SMPL tree with the clip's bone lengths, proportions.own_offsets: the inverse "
                 "kinematics' own error; the rest is SMPL's neutral proportions, which every trainer poses)")
    lines.append("limb directions (all clips): the SMPL bone's angle from the world bone, median / p95 degrees")
    for name, d in result["all"]["limb_direction_deg"].items():
        lines.append(f"  {name:16s} {d['median_deg']:7.1f} {d['p95_deg']:7.1f}")
    fingers = result["all"].get("fingers")
    if fingers:
        lines.append(f"fingers on SMPL-H ({fingers['hands']} hands, about the wrist, against the world hands): "
                     f"{fingers['median_mm']:.1f} / {fingers['p95_mm']:.1f} mm median / p95, the worst joint's median "
                     f"{fingers['worst_joint_median_mm']:.1f} mm; {100 * fingers['at_range_share']:.1f} % of finger "
                     f"joints held at {FINGER_RANGE_DEG:g} degrees (the hand model folded them further)")
    if result["all"]["frames_outside_range"]:
        lines.append("frames outside range: " + ", ".join(f"{k} {v}" for k, v in
                                                          result["all"]["frames_outside_range"].items()))
    return "\n".join(lines)
