"""Joint rotations on a clip's one skeleton (what the corpus's rotations_6d and the BVH export hold).

The skeleton is H36M-17 with constant bone lengths (``bones.fit_skeleton``), in a T-pose at
rest: y up, facing +z, arms along +-x (the subject's left is +x), metres (Blender's BVH
importer takes 1 unit as 1 m at its default scale). The pelvis and the thorax take the full
orientation of the hips and the shoulders; each other joint turns its one bone by the
smallest rotation from its parent's frame (a twist about a bone is not seen in joint
positions, so none is invented). Joints with several children reach each through a
zero-length ``...Root`` joint of its own, so forward kinematics gives back every joint
exactly. Channels: the root's position, then ``Zrotation Xrotation Yrotation`` (R = Rz·Rx·Ry).
With heels and toe tips (21 joints), each foot gets a heel and a toe joint below its ankle,
their lengths constant over the clip like the other bones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.mocap.skeleton import FEET_ANKLES_H36M, H36M_BONES, smallest_rotation, unit
from pipeline.motion.world.bones import apply_skeleton, fit_skeleton

_X, _Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class BvhJointSpec:
    name: str
    parent: int            # index into BVH_JOINTS, -1 for the root
    h36m: int | None       # the H36M joint at this place (None: a zero-length root joint)
    rest: np.ndarray       # unit direction of the bone from the parent, at rest (zero for roots)


def _spec(feet: bool = False) -> tuple[BvhJointSpec, ...]:
    joints: list[BvhJointSpec] = [BvhJointSpec("Hips", -1, 0, np.zeros(3))]

    def chain(parent: int, root_name: str, links: list[tuple[str, int, np.ndarray]]) -> int:
        joints.append(BvhJointSpec(root_name, parent, None, np.zeros(3)))
        for name, h36m, rest in links:
            joints.append(BvhJointSpec(name, len(joints) - 1, h36m, rest))
        return len(joints) - 1

    right_foot = chain(0, "RightHipRoot", [("RightUpLeg", 1, -_X), ("RightLeg", 2, -_Y), ("RightFoot", 3, -_Y)])
    left_foot = chain(0, "LeftHipRoot", [("LeftUpLeg", 4, _X), ("LeftLeg", 5, -_Y), ("LeftFoot", 6, -_Y)])
    if feet:  # rest: the heel down and back, the toes forward and a little down (facing +z)
        heel, toe = unit(np.array([0.0, -0.6, -0.8])), unit(np.array([0.0, -0.35, 0.94]))
        for side, foot, heel_i, toe_i in (("Right", right_foot, 18, 20), ("Left", left_foot, 17, 19)):
            chain(foot, f"{side}HeelRoot", [(f"{side}Heel", heel_i, heel)])
            chain(foot, f"{side}ToeRoot", [(f"{side}Toe", toe_i, toe)])
    thorax = chain(0, "SpineRoot", [("Spine", 7, _Y), ("Thorax", 8, _Y)])
    chain(thorax, "NeckRoot", [("Neck", 9, _Y), ("Head", 10, _Y)])
    chain(thorax, "LeftShoulderRoot", [("LeftShoulder", 11, _X), ("LeftElbow", 12, _X), ("LeftWrist", 13, _X)])
    chain(thorax, "RightShoulderRoot", [("RightShoulder", 14, -_X), ("RightElbow", 15, -_X), ("RightWrist", 16, -_X)])
    return tuple(joints)


BVH_JOINTS = _spec()
BVH_JOINTS_FEET = _spec(feet=True)
# Joints whose rotation is the whole frame of their body part: (x from right to left, y up).
_FRAMES = {"Hips": ((1, 4), (0, 7)), "Thorax": ((14, 11), (8, 9))}


def _frame(joints: np.ndarray, across: tuple[int, int], along: tuple[int, int]) -> np.ndarray:
    """T x 3 x 3 rotations whose columns are the body part's left, up and forward axes."""
    x = unit(joints[:, across[1]] - joints[:, across[0]])
    up = unit(joints[:, along[1]] - joints[:, along[0]])
    z = unit(np.cross(x, up))
    return np.stack([x, np.cross(z, x), z], axis=-1)


@dataclass(frozen=True)
class SkeletonMotion:
    offsets: np.ndarray    # J x 3 rest offsets (metres) of the BVH joints
    root: np.ndarray       # T x 3 root (pelvis) positions
    local: np.ndarray      # T x J x 3 x 3 local rotations
    joints: np.ndarray     # T x 17 x 3 the H36M joints on the skeleton (what forward kinematics gives); 21 with feet
    spec: tuple = BVH_JOINTS  # the hierarchy (BVH_JOINTS, or BVH_JOINTS_FEET)
    ends: dict | None = None  # joint name -> its End Site's offset, where the hierarchy's default will not do


def _fit_feet(world_joints: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, dict[int, float]]:
    """Heels and toe tips on the fitted ankles at constant lengths (median, left and right averaged),
    directions kept: the 21 joints and each foot point's length."""
    out = np.concatenate([joints, world_joints[:, 17:]], 1)
    length_of = {}
    for pair in ((0, 1), (2, 3)):  # heels, then toe tips (skeleton.FEET): left and right share a length
        bones = [(FEET_ANKLES_H36M[k], 17 + k) for k in pair]
        length = float(np.mean([np.median(np.linalg.norm(world_joints[:, p] - world_joints[:, a], axis=-1))
                                for a, p in bones]))
        for ankle, point in bones:
            out[:, point] = out[:, ankle] + length * unit(world_joints[:, point] - world_joints[:, ankle])
            length_of[point] = length
    return out, length_of


def solve_rotations(world_joints: np.ndarray) -> SkeletonMotion:
    """Constant bone lengths, then per-joint rotations, for world-frame H36M joints (T x 17 x 3, or
    21 with the heels and toe tips after them)."""
    lengths = fit_skeleton(world_joints[:, :17])
    joints = apply_skeleton(world_joints[:, :17], lengths)
    length_of = {child: lengths[k] for k, (_, child) in enumerate(H36M_BONES)}
    specs = BVH_JOINTS
    if world_joints.shape[1] == 21:
        joints, foot_lengths = _fit_feet(world_joints, joints)
        length_of.update(foot_lengths)
        specs = BVH_JOINTS_FEET
    frames = len(joints)
    offsets = np.array([spec.rest * length_of.get(spec.h36m, 0.0) if spec.h36m is not None else np.zeros(3)
                        for spec in specs])
    position = np.zeros((frames, len(specs), 3))
    glob = np.zeros((frames, len(specs), 3, 3))
    children = {i: [k for k, s in enumerate(specs) if s.parent == i] for i in range(len(specs))}
    for i, spec in enumerate(specs):
        position[:, i] = joints[:, spec.h36m] if spec.h36m is not None else position[:, spec.parent]
        parent_rot = glob[:, spec.parent] if spec.parent >= 0 else np.broadcast_to(np.eye(3), (frames, 3, 3))
        if spec.name in _FRAMES:
            glob[:, i] = _frame(joints, *_FRAMES[spec.name])
        elif len(children[i]) == 1:
            child = specs[children[i][0]]
            direction = unit(joints[:, child.h36m] - position[:, i])
            in_parent = np.einsum("tji,tj->ti", parent_rot, direction)
            glob[:, i] = parent_rot @ smallest_rotation(child.rest, in_parent)
        else:
            glob[:, i] = parent_rot
    local = glob.copy()
    for i, spec in enumerate(specs):
        if spec.parent >= 0:
            local[:, i] = np.swapaxes(glob[:, spec.parent], -1, -2) @ glob[:, i]
    return SkeletonMotion(offsets, joints[:, 0].copy(), local, joints, specs)
