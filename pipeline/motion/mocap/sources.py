"""Loaders for each motion-capture source in shared/mocap (see its MOCAP.md), all into
``MocapSequence``: H36M-17 and COCO-17 positions in metres, y up, right-handed.

Each BVH source is described by a small table: its units, up axis, how position
channels combine with offsets, and which joint (or midpoint, or End Site) gives each
Human3.6M joint. A head top missing from the rig is placed along the head's up axis.

Feet (``MocapSequence.feet``, heels and toe tips in ``skeleton.FEET`` order): what a source
measures is kept (Tang's and ChoreoNet's heels, toe-tip End Sites, DeepMimic's foot boxes);
what it lacks (every BVH rig's heel, a toe tip where the rig ends at the ball of the foot)
is placed by ``skeleton.foot_points`` from the ankle, the knee and the point the rig has.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.core.errors import InputError
from pipeline.motion.mocap.bvh import Bvh, forward_kinematics, read_bvh
from pipeline.motion.mocap.markers import feet_from_markers, h36m_from_markers, read_c3d
from pipeline.motion.mocap.skeleton import (
    FOOT_TEMPLATE,
    coco_from_h36m,
    feet_array,
    floor_height,
    foot_points,
    head_frame,
    leg_stature,
    sole_height,
    stature,
    unit,
)


@dataclass
class MocapSequence:
    name: str            # "<source>/<file stem>"
    source: str
    fps: float
    h36m: np.ndarray     # T x 17 x 3, metres
    coco: np.ndarray     # T x 17 x 3, metres
    feet: np.ndarray | None = None  # T x 4 x 3, metres: heels and toe tips (skeleton.FEET); None: unknown

    @property
    def frames(self) -> int:
        return len(self.h36m)


@dataclass(frozen=True)
class BvhSource:
    folder: str
    unit: float               # metres per file unit
    z_up: bool                # True: convert (x, y, z) -> (x, z, -y)
    position_mode: str        # replace | add (see pipeline.motion.mocap.bvh)
    joints: tuple             # 17 specs: "Name", ("mid", a, b), ("end", "Name"), ("top", share_or_metres)
    toes: tuple = ()          # (left, right) front-of-foot specs: "Name" or ("end", "Name")
    toe_kind: str = "ball"    # what the toe specs are: the ball of the foot or the tip of the toes


def _body(pelvis, rhip, rknee, rankle, lhip, lknee, lankle, spine, thorax, head, top, lsh, lel, lwr, rsh, rel, rwr):
    return (pelvis, rhip, rknee, rankle, lhip, lknee, lankle, spine, thorax, head, top, lsh, lel, lwr, rsh, rel, rwr)


BVH_SOURCES = {
    "bandai_namco_1": BvhSource("bandai_namco_1", 0.01, False, "replace", _body(
        "Hips", "UpperLeg_R", "LowerLeg_R", "Foot_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Chest", "Neck", "Head",
        ("top", 0.10), "UpperArm_L", "LowerArm_L", "Hand_L", "UpperArm_R", "LowerArm_R", "Hand_R"),
        ("Toes_L", "Toes_R"), "ball"),  # the Toes End Site has zero length
    "cmu_subject05_iclone": BvhSource("cmu_subject05_iclone", 0.01, False, "add", _body(
        "CC_Base_Hip", "CC_Base_R_Thigh", "CC_Base_R_Calf", "CC_Base_R_Foot", "CC_Base_L_Thigh", "CC_Base_L_Calf",
        "CC_Base_L_Foot", "CC_Base_Spine02", "CC_Base_NeckTwist01", "CC_Base_Head", ("top_m", 0.12),
        "CC_Base_L_Upperarm", "CC_Base_L_Forearm", "CC_Base_L_Hand", "CC_Base_R_Upperarm", "CC_Base_R_Forearm",
        "CC_Base_R_Hand"), ("CC_Base_L_BigToe1", "CC_Base_R_BigToe1"), "ball"),  # the big toe's base joint
    "perfume": BvhSource("perfume", 0.01, False, "replace", _body(
        "Hips", "RightHip", "RightKnee", "RightAnkle", "LeftHip", "LeftKnee", "LeftAnkle", "Chest3", "Neck", "Head",
        ("end", "Head"), "LeftShoulder", "LeftElbow", "LeftWrist", "RightShoulder", "RightElbow", "RightWrist"),
        (("end", "LeftToe"), ("end", "RightToe")), "tip"),
    "dancedb_ucy": BvhSource("dancedb_ucy", 0.01, False, "replace", _body(
        "Hips", "RightUpLeg", "RightLeg", "RightFoot", "LeftUpLeg", "LeftLeg", "LeftFoot", "Spine2", "Neck", "Head",
        ("top", 0.10), "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand"),
        ("LeftToeBase", "RightToeBase"), "ball"),  # the ToeBase End Site has zero length
    "animated_drawings_fair": BvhSource("animated_drawings_fair", 0.0254, True, "replace", _body(
        "Hips", "RightUpLeg", "RightLeg", "RightFoot", "LeftUpLeg", "LeftLeg", "LeftFoot", "Spine2", "Neck", "Head",
        ("end", "Head"), "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand"),
        (("end", "LeftToeBase"), ("end", "RightToeBase")), "tip"),
}
for _more in ("bandai_namco_2_subset", "bandai_namco_2_more"):  # dataset-2: the same rig as dataset-1
    BVH_SOURCES[_more] = BvhSource(_more, *list(vars(BVH_SOURCES["bandai_namco_1"]).values())[1:])
# CMU's salsa files are scaled to about 0.68 of an adult (MOCAP.md §13); both partners share one rig
# whose thigh + shank is 0.642 units. 1.32 m per unit gives 0.85 m, the adult sources' median leg
# (0.74-0.98 m), and 1.38 m from ankle to head joint (DanceDB 1.39-1.42). One factor for the whole
# source keeps the two partners of a take in one room frame.
BVH_SOURCES["cmu_salsa_60_61"] = BvhSource("cmu_salsa_60_61", 1.32, False, "replace", _body(
    "hip", "rThigh", "rShin", "rFoot", "lThigh", "lShin", "lFoot", "chest", "neck", "head", ("top", 0.10),
    "lShldr", "lForeArm", "lHand", "rShldr", "rForeArm", "rHand"), (("end", "lFoot"), ("end", "rFoot")), "ball")
MARKER_SOURCES = ("choreonet_c3d", "mocap_recovery_c3d")  # Plug-in-Gait C3D (markers.py)
SOURCES = (*BVH_SOURCES, "deepmimic", "tang2018_ballroom", *MARKER_SOURCES)


def _to_canonical(points: np.ndarray, unit: float, z_up: bool) -> np.ndarray:
    points = points * unit
    if z_up:
        points = np.stack([points[..., 0], points[..., 2], -points[..., 1]], -1)
    return points


def load_bvh_sequence(path: Path, source: BvhSource) -> MocapSequence:
    bvh = read_bvh(path)
    positions, rotations, ends = forward_kinematics(bvh, source.position_mode)
    positions = _to_canonical(positions, source.unit, source.z_up)
    ends = _to_canonical(ends, source.unit, source.z_up)
    h36m = np.zeros((len(positions), 17, 3))
    tops: list[tuple[int, tuple]] = []
    for k, spec in enumerate(source.joints):
        if isinstance(spec, str):
            h36m[:, k] = positions[:, bvh.index(spec)]
        elif spec[0] == "mid":
            h36m[:, k] = (positions[:, bvh.index(spec[1])] + positions[:, bvh.index(spec[2])]) / 2
        elif spec[0] == "end":
            h36m[:, k] = ends[:, bvh.index(spec[1])]
        else:
            tops.append((k, spec))
    for k, (kind, amount) in tops:  # needs the rest of the body first
        up, _, _ = head_frame(h36m)
        length = amount * stature(h36m) if kind == "top" else amount
        h36m[:, k] = h36m[:, 9] + length * up
    feet = _rig_feet(bvh, source, positions, rotations, ends, leg_stature(h36m)) if source.toes else None
    return MocapSequence(f"{source.folder}/{path.stem}", source.folder, 1.0 / bvh.frame_time, h36m,
                         coco_from_h36m(h36m), feet)


def _rig_feet(bvh: Bvh, source: BvhSource, positions: np.ndarray, rotations: np.ndarray, ends: np.ndarray,
              size: float) -> np.ndarray:
    """Heels and toe tips (T x 4 x 3) of a rig that has ankles and a toe point but no heel.

    Where a foot stands flat (its ankle near its lowest, its toe point on the floor), the heel,
    and the toe tip of a rig ending at the ball of the foot, are placed by ``FOOT_TEMPLATE``
    on the floor; their median offset in the foot joint's frame then rides on that joint's
    rotation in every frame. Rest poses differ between rigs, so they are not trusted to stand flat."""
    axes = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]) if source.z_up else np.eye(3)

    def toe(spec) -> np.ndarray:
        return ends[:, bvh.index(spec[1])] if isinstance(spec, tuple) else positions[:, bvh.index(spec)]

    sides = [(bvh.index(source.joints[6]), toe(source.toes[0])), (bvh.index(source.joints[3]), toe(source.toes[1]))]
    floor = floor_height(np.stack([t for _, t in sides]))
    sole = sole_height(floor, size)
    heels, tips = [], []
    for (a, toe_point), spec in zip(sides, source.toes):
        ankle = positions[:, a]
        flat = (ankle[:, 1] < np.percentile(ankle[:, 1], 10) + 0.02) & (toe_point[:, 1] < floor + 0.03)
        if flat.sum() < 3:
            flat = ankle[:, 1] <= np.percentile(ankle[:, 1], 10)
        forward = unit((toe_point - ankle) * [1.0, 0.0, 1.0])[flat]

        def ride(points: np.ndarray, joint: int) -> np.ndarray:
            """Points placed in the flat frames -> the same points in every frame, carried by ``joint``."""
            turn = np.einsum("ij,tjk,lk->til", axes, rotations[:, joint], axes)  # canonical axes
            local = np.median(np.einsum("tji,tj->ti", turn[flat], points - positions[flat, joint]), axis=0)
            return positions[:, joint] + turn @ local

        heel = ankle[flat] + FOOT_TEMPLATE["heel"][0] * size * forward
        heel[:, 1] = sole
        heels.append(ride(heel, a))
        if source.toe_kind == "tip":
            tips.append(toe_point)
        else:  # the toes bend with the rig's toe joint
            tip = toe_point[flat] + (FOOT_TEMPLATE["tip"][0] - FOOT_TEMPLATE["ball"][0]) * size * forward
            tip[:, 1] = sole
            # A ball End Site (CMU's foot) bends with its own joint, a ball joint with itself.
            tips.append(ride(tip, bvh.index(spec[1] if isinstance(spec, tuple) else spec)))
    return feet_array((heels[0], heels[1]), (tips[0], tips[1]))


# DeepMimic humanoid3d: offsets (m) in the parent frame; +z is the character's right side.
_DM = {"chest": (0, 0.236, 0), "neck": (0, 0.224, 0), "r_hip": (0, 0, 0.085), "l_hip": (0, 0, -0.085),
       "knee": (0, -0.422, 0), "ankle": (0, -0.410, 0), "r_shoulder": (-0.024, 0.244, 0.183),
       "l_shoulder": (-0.024, 0.244, -0.183), "elbow": (0, -0.275, 0), "wrist": (0, -0.259, 0),
       "head": (0, 0.175, 0), "head_top": (0, 0.2775, 0),
       # the foot box (0.177 x 0.055 m, centred 4.5 cm ahead of and 2.25 cm below the ankle): its sole's ends
       "heel": (-0.0435, -0.05, 0), "toe": (0.1335, -0.05, 0)}


def _quat(wxyz: np.ndarray) -> Rotation:
    return Rotation.from_quat(wxyz[:, [1, 2, 3, 0]])


def load_deepmimic(path: Path) -> MocapSequence:
    frames = np.array(json.loads(Path(path).read_text())["Frames"], dtype=np.float64)
    dt = frames[0, 0] if frames[0, 0] > 0 else 1 / 60
    cols = iter(range(1, 44))

    def take(n: int) -> np.ndarray:
        return frames[:, [next(cols) for _ in range(n)]]

    root_pos, root_q = take(3), _quat(take(4))
    chest_q, neck_q = _quat(take(4)), _quat(take(4))
    # Ankle rotations turn the foot boxes, whose sole ends are the heels and toe tips.
    r_hip_q, r_knee, r_ankle_q, r_sh_q, r_elbow = _quat(take(4)), take(1), _quat(take(4)), _quat(take(4)), take(1)
    l_hip_q, l_knee, l_ankle_q, l_sh_q, l_elbow = _quat(take(4)), take(1), _quat(take(4)), _quat(take(4)), take(1)

    def revolute(angle: np.ndarray) -> Rotation:
        return Rotation.from_rotvec(np.column_stack([np.zeros(len(angle)), np.zeros(len(angle)), angle[:, 0]]))

    def at(parent_pos, parent_rot: Rotation, offset) -> np.ndarray:
        return parent_pos + parent_rot.apply(np.asarray(offset, float))

    chest_r = root_q * chest_q
    neck_pos = at(at(root_pos, root_q, _DM["chest"]), chest_r, _DM["neck"])
    neck_r = chest_r * neck_q
    legs, arms, feet = {}, {}, {}
    sides = (("r", r_hip_q, r_knee, r_ankle_q, r_sh_q, r_elbow), ("l", l_hip_q, l_knee, l_ankle_q, l_sh_q, l_elbow))
    for side, hip_q, knee, ankle_q, sh_q, elbow in sides:
        hip = at(root_pos, root_q, _DM[f"{side}_hip"])
        hip_r = root_q * hip_q
        knee_pos = at(hip, hip_r, _DM["knee"])
        shin_r = hip_r * revolute(knee)
        ankle = at(knee_pos, shin_r, _DM["ankle"])
        legs[side] = (hip, knee_pos, ankle)
        feet[side] = (at(ankle, shin_r * ankle_q, _DM["heel"]), at(ankle, shin_r * ankle_q, _DM["toe"]))
        shoulder = at(at(root_pos, root_q, _DM["chest"]), chest_r, _DM[f"{side}_shoulder"])
        sh_r = chest_r * sh_q
        elbow_pos = at(shoulder, sh_r, _DM["elbow"])
        wrist = at(elbow_pos, sh_r * revolute(elbow), _DM["wrist"])
        arms[side] = (shoulder, elbow_pos, wrist)
    h36m = np.stack([root_pos, *legs["r"], *legs["l"], (root_pos + neck_pos) / 2, neck_pos,
                     at(neck_pos, neck_r, _DM["head"]), at(neck_pos, neck_r, _DM["head_top"]),
                     *arms["l"], *arms["r"]], axis=1)
    return MocapSequence(f"deepmimic/{Path(path).stem}", "deepmimic", 1.0 / dt, h36m, coco_from_h36m(h36m),
                         feet_array((feet["l"][0], feet["r"][0]), (feet["l"][1], feet["r"][1])))


def load_tang(path: Path) -> MocapSequence:
    data = np.load(path)
    points = (data["skeletons"] + data["center"][:, None]).astype(np.float64) * 0.01
    points[..., 2] *= -1  # the dataset is left-handed (Unity)
    head = (points[:, 0] + points[:, 1]) / 2
    thorax = (points[:, 3] + points[:, 12]) / 2
    h36m = np.stack([points[:, 2], points[:, 16], points[:, 17], points[:, 18], points[:, 7], points[:, 8],
                     points[:, 9], (points[:, 2] + thorax) / 2, thorax, head, head + 0.5 * (head - thorax),
                     points[:, 3], points[:, 4], points[:, 6], points[:, 12], points[:, 13], points[:, 15]], axis=1)
    # Its heel points are kept. Its toe points lie about 18 cm from the ankle, short of a toe tip
    # (about 21 cm for these dancers): they are read as the ball of the foot and the tip placed beyond.
    size = leg_stature(h36m)
    floor = floor_height(points[:, [10, 11, 19, 20]])
    tips = [foot_points(points[:, knee], points[:, ankle], points[:, toe], "ball", size, floor)["tip"]
            for knee, ankle, toe in ((8, 9, 11), (17, 18, 20))]
    return MocapSequence(f"tang2018_ballroom/{Path(path).stem}", "tang2018_ballroom", float(data["fps_nominal"]),
                         h36m, coco_from_h36m(h36m), feet_array((points[:, 10], points[:, 19]), tips))


def load_markers(path: Path) -> MocapSequence:
    """A C3D file of Plug-in-Gait markers (ChoreoNet), joint centres estimated (markers.py)."""
    markers, rate = read_c3d(path)
    h36m = h36m_from_markers(markers)
    folder = Path(path).parent.name
    return MocapSequence(f"{folder}/{Path(path).stem}", folder, rate, h36m, coco_from_h36m(h36m),
                         feet_from_markers(markers, h36m))


def load_source(root: Path, source: str, include_waltz: bool = False) -> list[MocapSequence]:
    """Every sequence of one source folder under ``root`` (the mocap folder)."""
    folder = Path(root) / source
    if source in BVH_SOURCES:  # the salsa keeps each subject in a folder of its own
        return [load_bvh_sequence(p, BVH_SOURCES[source]) for p in sorted(folder.rglob("*.bvh"), key=lambda p: p.name)]
    if source == "deepmimic":
        return [load_deepmimic(p) for p in sorted(folder.glob("humanoid3d_*.txt")) if "character" not in p.name]
    if source == "tang2018_ballroom":
        # Waltz files are temporally subsampled (about 6 fps effective): left out unless asked for.
        return [load_tang(p) for p in sorted(folder.glob("*.npz")) if include_waltz or "_W_" not in p.name]
    if source in MARKER_SOURCES:
        return [load_markers(p) for p in sorted(folder.glob("*.c3d"))]
    raise ValueError(f"unknown mocap source {source!r}; known: {', '.join(SOURCES)}")


def load_joints_npz(path: Path) -> MocapSequence:
    """A plain joint-position file: ``joints`` (T x 17 x 3, Human3.6M order, metres, y up), ``fps``
    and optionally ``feet`` (T x 4 x 3: left heel, right heel, left toe tip, right toe tip)."""
    try:
        data = np.load(path)
        joints, fps = np.asarray(data["joints"], np.float64), float(data["fps"])
        feet = np.asarray(data["feet"], np.float64) if "feet" in data else None
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(path, f"not a joint-position file (needs 'joints' T x 17 x 3 and 'fps'): {exc}") from None
    if joints.ndim != 3 or joints.shape[1:] != (17, 3) or len(joints) < 2 or not np.isfinite(joints).all():
        raise InputError(path, f"'joints' must be finite, T x 17 x 3 with T >= 2, not {joints.shape}")
    if feet is not None and (feet.shape != (len(joints), 4, 3) or not np.isfinite(feet).all()):
        raise InputError(path, f"'feet' must be finite, {len(joints)} x 4 x 3 like 'joints', not {feet.shape}")
    folder = Path(path).parent.name
    return MocapSequence(f"{folder}/{Path(path).stem}", folder, fps, joints, coco_from_h36m(joints), feet)


def load_folder(folder: Path) -> list[MocapSequence]:
    """Every sequence under a folder that is one of the known sources, holds known sources, or
    holds Plug-in-Gait C3D files and joint-position ``.npz`` files (``load_joints_npz``)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "no such motion-capture folder")
    if folder.name in SOURCES:
        return load_source(folder.parent, folder.name)
    known = [s for s in SOURCES if (folder / s).is_dir()]
    if known:
        return [seq for s in known for seq in load_source(folder, s)]
    sequences = [load_markers(p) for p in sorted(folder.glob("*.c3d"))]
    sequences += [load_joints_npz(p) for p in sorted(folder.glob("*.npz"))]
    if not sequences:
        raise InputError(folder, f"no motion capture found: expected one of the known source folders "
                                 f"({', '.join(SOURCES)}), Plug-in-Gait .c3d files or .npz joint files")
    return sequences


def keypoints_and_joints(seq: MocapSequence, feet: bool) -> tuple[np.ndarray, np.ndarray]:
    """A sequence's 3D keypoints as the 2D model sees them (COCO-17) and its 3D joints (H36M-17),
    each followed by the heels and toe tips with ``feet``."""
    if not feet:
        return seq.coco, seq.h36m
    if seq.feet is None:
        raise ValueError(f"{seq.name} has no heels and toes, which a lifter with feet needs")
    return np.concatenate([seq.coco, seq.feet], 1), np.concatenate([seq.h36m, seq.feet], 1)


def first_seconds(seq: MocapSequence, seconds: float) -> MocapSequence:
    """The sequence's first ``seconds`` (all of it when shorter)."""
    n = int(seconds * seq.fps)
    return MocapSequence(seq.name, seq.source, seq.fps, seq.h36m[:n], seq.coco[:n],
                         None if seq.feet is None else seq.feet[:n])


def resample(seq: MocapSequence, fps: float) -> MocapSequence:
    """Linear resampling to ``fps`` (mocap rates are 16-120 Hz; the lifter sees video rates)."""
    if abs(seq.fps - fps) < 1e-6:
        return seq
    t_src = np.arange(seq.frames) / seq.fps
    t_new = np.arange(0, t_src[-1] + 1e-9, 1 / fps)

    def interp(x: np.ndarray) -> np.ndarray:
        from pipeline.motion.resample import interpolate_linear

        return interpolate_linear(t_new, t_src, x)

    return MocapSequence(seq.name, seq.source, fps, interp(seq.h36m), interp(seq.coco),
                         None if seq.feet is None else interp(seq.feet))
