"""World joints onto the SMPL tree: joint rotations by inverse kinematics, a root path and one
scale per clip (AIST++'s ``smpl_poses``, ``smpl_trans``, ``smpl_scaling``).

The input is a clip's world motion (``worldfile``: H36M-17, y up, the floor at 0, one skeleton;
heels and toe tips when the pose model gave them). The rules, joint by joint:

- **scale**: the clip's thigh plus shin over the SMPL rest skeleton's, so a straight leg reaches
  the floor it stood on;
- **pelvis**: its orientation from the hips (left-right) and the spine (up); the translation puts
  the SMPL hips' midpoint on the clip's (SMPL's pelvis joint sits above its hips, H36M's between
  them);
- **spine1-3**: each turns a third of the way from the pelvis to the chest (shoulders left-right,
  spine to thorax up); then spine1 swings the chain so the shoulders' midpoint points where the
  clip's does;
- **collars**: each swings its shoulder towards the clip's shoulder (no twist), at most 30 degrees;
- **neck**: up from the thorax to the head top, facing where the chest faces; **head**: none of its
  own (the nose of a lifted pose is too close to the head's axis to give a steady facing);
- **hips and knees**: two-bone inverse kinematics puts the ankle exactly where the clip has it (when
  the SMPL leg reaches), so a planted foot stays planted; the knee lies in the clip's bending plane,
  whose normal is the leg's hinge axis, so the knee turns about it alone and the thigh's twist comes
  from it. A straight limb shows no plane: its hinge carries over from the last frame that bent (a
  twist never jumps);
- **shoulders and elbows**: the upper arm and the forearm point where the clip's do, twisted by the
  arm's hinge as the leg is. Arms touch nothing, and SMPL's arm bones are not the dancer's: placing
  the wrist exactly (as the legs do) turned the upper arms and forearms 10-15 degrees away from the
  world arms (median), which a trainer learns as the dance;
- **ankles**: the foot points at the ball of the foot (72 % of the way from heel to toe tip) and rolls
  with the knee's hinge (the sole's own plane flips where heel, ankle and toe tip line up); without
  feet the ankle keeps the shin's frame;
- **feet (toes), wrists and hands**: none of their own (nothing in the clip sees them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.mocap.skeleton import unit
from pipeline.motion.smpl.kinematics import forward, to_axis_angle
from pipeline.motion.smpl.skeleton import BALL_SHARE, PARENTS, REST_OFFSETS, leg_length

_X, _Y, _Z = np.eye(3)
STRAIGHT_DEG = 5.0    # a limb bent less than this shows no plane ...
PLANE_DEG = 20.0      # ... and one bent this much more shows it fully
COLLAR_DEG = 30.0     # a collar turns at most this far (a shoulder shrug, not a dislocation)
# A limb's hinge turns at most this far about the limb from its neutral (the parent's rest hinge):
# a lifted knee or elbow pointing further round than a hip or shoulder turns is noise in the 3D,
# and the limb is bent in the nearest plane a body allows instead (the ankle or wrist stays put).
TWIST_DEG = {"leg": 60.0, "arm": 100.0}
ANKLE_DEG = 80.0      # a foot turns at most this far from its rest direction on the shin


@dataclass(frozen=True)
class SmplMotion:
    local: np.ndarray     # T x 24 x 3 x 3 local joint rotations
    trans: np.ndarray     # T x 3 the pelvis joint (metres, the world frame)
    scale: float          # the rest offsets' scale (``smpl_scaling``)
    joints: np.ndarray    # T x 24 x 3 forward kinematics of the above

    @property
    def poses(self) -> np.ndarray:
        """T x 72 axis-angle (AIST++'s ``smpl_poses``)."""
        return to_axis_angle(self.local)


def _square(v: np.ndarray, to: np.ndarray) -> np.ndarray:
    """Vectors ``v`` made square to the unit vectors ``to``, of length 1."""
    return unit(v - (v * to).sum(-1, keepdims=True) * to)


def frame(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) orthonormal frames with columns a, b made square to a, and a x b."""
    a = unit(np.asarray(a, np.float64))
    b = _square(np.asarray(b, np.float64), a)
    return np.stack([a, b, np.cross(a, b)], axis=-1)


def _aligning(rest_a: np.ndarray, rest_b: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """T x 3 x 3 rotations taking the rest pair (a along, b beside) to each target pair."""
    return frame(a, b) @ np.swapaxes(frame(rest_a, rest_b), -1, -2)


def _power(rotations: np.ndarray, share: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(Rotation.from_matrix(rotations).as_rotvec() * share).as_matrix()


def hinge_axes(upper: np.ndarray, lower: np.ndarray, first: np.ndarray, reference: np.ndarray | None = None
               ) -> np.ndarray:
    """T x 3 unit hinge axes of a limb (upper and lower bone vectors, T x 3): the normal of its
    bending plane, upper x lower, where it bends; carried over from the frame before where it is
    straight (``first``: the axis before any bend). With ``reference`` (T x 3), a bend whose
    normal points away from it (a knee bent backwards) shows no plane either."""
    u, low = unit(upper), unit(lower)
    bend = np.degrees(np.arccos(np.clip((u * low).sum(-1), -1.0, 1.0)))
    weight = np.clip((bend - STRAIGHT_DEG) / PLANE_DEG, 0.0, 1.0)
    normal = unit(np.cross(u, low))
    out = np.empty_like(u)
    previous = first
    for t in range(len(u)):
        carried = previous - (previous @ u[t]) * u[t]
        carried = carried / max(np.linalg.norm(carried), 1e-9)
        w = weight[t]
        if reference is not None and normal[t] @ reference[t] < 0:
            w = 0.0
        if normal[t] @ carried < 0:  # opposite axes do not blend: the stronger one wins
            axis = normal[t] if w >= 0.5 else carried
        else:
            axis = w * normal[t] + (1 - w) * carried
        out[t] = previous = axis / max(np.linalg.norm(axis), 1e-9)
    return out


def limit_twist(hinge: np.ndarray, neutral: np.ndarray, along: np.ndarray, most: float) -> np.ndarray:
    """Hinges (T x 3, square to ``along``) turned back about ``along`` to at most ``most`` degrees
    from ``neutral`` (squared to ``along`` too)."""
    base = _square(neutral, along)
    angle = np.arctan2((np.cross(base, hinge) * along).sum(-1), (base * hinge).sum(-1))
    limit = np.radians(most)
    over = np.abs(angle) > limit
    if not over.any():
        return hinge
    turned = np.clip(angle, -limit, limit)[:, None]
    out = hinge.copy()
    out[over] = (np.cos(turned) * base + np.sin(turned) * np.cross(along, base))[over]
    return out


def two_bone(root: np.ndarray, end: np.ndarray, hinge: np.ndarray, upper: float, lower: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """The middle joint and the end (T x 3 each) of a two-bone limb from ``root`` reaching for
    ``end`` (exactly, when in reach), bending in the plane square to ``hinge``."""
    d = end - root
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    along = d / np.maximum(dist, 1e-9)
    reach = np.clip(dist, abs(upper - lower) + 1e-6, upper + lower - 1e-6)
    side = unit(np.cross(along, hinge))
    cos = np.clip((upper ** 2 + reach ** 2 - lower ** 2) / (2 * upper * reach), -1.0, 1.0)
    middle = root + upper * (cos * along + np.sqrt(1 - cos ** 2) * side)
    return middle, root + reach * along


def retarget(joints: np.ndarray, feet: np.ndarray | None = None, offsets: np.ndarray = REST_OFFSETS
             ) -> SmplMotion:
    """SMPL rotations, root path and scale for world joints (T x 17 x 3, H36M-17, y up) and, when
    known, the heels and toe tips (T x 4 x 3: left heel, right heel, left toe, right toe).
    ``offsets``: the tree's rest offsets (SMPL's; others only to measure, ``proportions``)."""
    h = np.asarray(joints, np.float64)
    frames = len(h)
    o = offsets
    thigh = np.median(np.linalg.norm(h[:, [5, 2]] - h[:, [4, 1]], axis=-1))
    shin = np.median(np.linalg.norm(h[:, [6, 3]] - h[:, [5, 2]], axis=-1))
    scale = float((thigh + shin) / leg_length(offsets=o))
    glob = np.broadcast_to(np.eye(3), (frames, 24, 3, 3)).copy()
    pos = np.zeros((frames, 24, 3))

    def place(*js: int) -> None:  # joints' positions from their parents'
        for j in js:
            pos[:, j] = pos[:, PARENTS[j]] + glob[:, PARENTS[j]] @ (scale * o[j])

    # Pelvis: left-right from the hips, up from the spine; the hips' midpoint on the clip's.
    glob[:, 0] = _aligning(o[1] - o[2], _Y, h[:, 4] - h[:, 1], h[:, 7] - h[:, 0])
    trans = (h[:, 1] + h[:, 4]) / 2 - glob[:, 0] @ (scale * (o[1] + o[2]) / 2)
    pos[:, 0] = trans
    place(1, 2, 3)

    # Spine: a third each of the turn from the pelvis to the chest, then one swing at spine1 so the
    # shoulders' midpoint points where the clip's does.
    chest = _aligning(_X, _Y, h[:, 11] - h[:, 14], h[:, 8] - h[:, 7])
    step = _power(np.swapaxes(glob[:, 0], -1, -2) @ chest, 1 / 3)
    for j in (3, 6, 9, 13, 14):
        glob[:, j] = glob[:, PARENTS[j]] @ step if j in (3, 6, 9) else glob[:, 9]
    place(6, 9, 13, 14, 16, 17)
    turn = swing((pos[:, 16] + pos[:, 17]) / 2 - pos[:, 3], (h[:, 11] + h[:, 14]) / 2 - pos[:, 3])
    for j in (3, 6, 9):
        glob[:, j] = turn @ glob[:, j]
    place(6, 9, 12, 13, 14)

    # Collars swing their shoulders towards the clip's; the neck looks where the head does.
    for collar, shoulder, target in ((13, 16, 11), (14, 17, 14)):
        glob[:, collar] = swing(glob[:, 9] @ o[shoulder], h[:, target] - pos[:, collar], COLLAR_DEG) @ glob[:, 9]
        place(shoulder)
    glob[:, 12] = glob[:, 15] = _aligning(_Y, _Z, h[:, 10] - h[:, 8], glob[:, 9] @ _Z)
    place(15)

    # Limbs: two-bone IK about each limb's hinge.
    limbs = (  # root, middle, end (SMPL); middle and end targets (H36M); the rest hinge; a leg?
        (16, 18, 20, 12, 13, -_Y, False), (17, 19, 21, 15, 16, _Y, False),
        (1, 4, 7, 5, 6, _X, True), (2, 5, 8, 2, 3, _X, True))
    for root, middle, end, mid_t, end_t, rest_hinge, leg in limbs:
        above = glob[:, PARENTS[root]] @ rest_hinge  # the rest hinge as the limb's parent holds it
        hinge = hinge_axes(h[:, mid_t] - h[:, mid_t - 1], h[:, end_t] - h[:, mid_t], above[0],
                           above if leg else None)
        # The limb's line: from SMPL's hip to the clip's ankle (the leg reaches for it); the clip's own
        # shoulder to wrist (the arm copies the clip's bones, square to their bending plane's normal).
        along = unit(h[:, end_t] - (pos[:, root] if leg else h[:, mid_t - 1]))
        hinge = _square(hinge, along)
        # The neutral hinge where the limb points now: the rest hinge carried by the smallest turn
        # from the limb's rest direction (as its parent holds it) to its direction now.
        rest_along = glob[:, PARENTS[root]] @ unit(o[middle] + o[end])
        neutral = (swing(rest_along, along) @ above[..., None])[..., 0]
        hinge = limit_twist(hinge, neutral, along, TWIST_DEG["leg" if leg else "arm"])
        if leg:  # the ankle exactly where it was: feet stand and slide on it
            mid, tip = two_bone(pos[:, root], h[:, end_t], hinge, scale * np.linalg.norm(o[middle]),
                                scale * np.linalg.norm(o[end]))
        else:  # arms touch nothing: the world arm's directions, the wrist wherever SMPL's lengths put it
            mid = pos[:, root] + scale * np.linalg.norm(o[middle]) * unit(h[:, mid_t] - h[:, mid_t - 1])
            tip = mid + scale * np.linalg.norm(o[end]) * unit(h[:, end_t] - h[:, mid_t])
        glob[:, root] = _aligning(o[middle], rest_hinge, mid - pos[:, root], hinge)
        place(middle)
        glob[:, middle] = _aligning(o[end], rest_hinge, tip - pos[:, middle], hinge)
        place(end)
        glob[:, end] = glob[:, middle]  # wrists and (until the feet below) ankles: none of their own

    # Ankles: towards the ball of the foot, rolled by the sole's plane.
    if feet is not None and np.isfinite(feet).all():
        f = np.asarray(feet, np.float64)
        for ankle, target, heel, toe in ((7, 6, 0, 2), (8, 3, 1, 3)):
            ball = f[:, heel] + BALL_SHARE * (f[:, toe] - f[:, heel])
            rest_foot = glob[:, ankle - 3] @ unit(o[ankle + 3])  # where the foot points at rest, from the shin
            aim = (swing(rest_foot, ball - pos[:, ankle], ANKLE_DEG) @ rest_foot[..., None])[..., 0]
            glob[:, ankle] = _aligning(o[ankle + 3], _X, aim, glob[:, ankle - 3] @ _X)
    for j, p in ((10, 7), (11, 8), (22, 20), (23, 21)):
        glob[:, j] = glob[:, p]
    local = glob.copy()
    for j, p in enumerate(PARENTS):
        if p >= 0:
            local[:, j] = np.swapaxes(glob[:, p], -1, -2) @ glob[:, j]
    return SmplMotion(local, trans, scale, forward(local, trans, scale, o))


def swing(have: np.ndarray, want: np.ndarray, most: float = 180.0) -> np.ndarray:
    """T x 3 x 3 smallest rotations taking each vector ``have`` to the direction of ``want``, or
    ``most`` degrees of the way there (``mocap.skeleton.smallest_rotation`` takes one rest vector)."""
    from scipy.spatial.transform import Rotation

    have, want = unit(have), unit(want)
    axis = np.cross(have, want)
    angle = np.minimum(np.arctan2(np.linalg.norm(axis, axis=-1), (have * want).sum(-1)), np.radians(most))
    return Rotation.from_rotvec(unit(axis) * angle[:, None]).as_matrix()
