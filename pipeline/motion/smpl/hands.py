"""Finger rotations on the SMPL-H skeleton from the world hands (``pipeline.motion.hands``).

SMPL-H keeps SMPL's first 22 joints and hangs 15 joints on each wrist: index, middle, pinky, ring
and thumb, three joints each, in that order (52 joints: ``SMPLH_JOINTS``). A finger joint's rotation
turns the bone to its next joint; the third turns the last bone, to the fingertip, which SMPL-H has
no joint for. The hand model's 21 points give each of them: a finger's knuckle, its two middle
joints and its tip (``CHAINS``; the thumb's first joint is the hand model's CMC point).

Rotations are relative to a rest hand (``RestHand``): where the knuckles sit about the wrist and
where each finger's bones point, in SMPL's rest frame (y up, facing +z, the left hand along +x, the
right along -x, palms down, thumbs forward). Two rest hands:

- **dance3d's own** (``clip_rest``): the clip's palm (its knuckles at their mean place about the
  wrist once each frame is turned onto it, over the frames the hand model is sure of) with every
  finger straight on from its knuckle, the line from the wrist through the knuckle. No SMPL-H file
  is needed, and a rotation says how far a finger bends away from that line;
- **a template's** (``template_rest``): the joint positions of a body whose hands are flat, such
  as ``smplx_neu_J_1.npy``, the neutral SMPL-X joints that FineDance's and LODGE's forward kinematics
  hang their rotations on. Its licence forbids redistribution, so dance3d never ships it: a user
  who has it gives its path (``dance3d export finedance --template``) and gets rotations relative
  to exactly that rest pose.

The solve, per hand and frame: the wrist turns the rest palm onto the seen one (the five knuckles
as near as one rotation puts them: SMPL-H's palm is rigid, the seen one cups), then each finger
joint swings its bone onto the seen bone by the smallest rotation, from the knuckle to the tip, so
no finger gains a twist of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.mocap.skeleton import unit
from pipeline.motion.smpl.retarget import frame, swing
from pipeline.motion.smpl.skeleton import JOINTS, PARENTS
from pipeline.pose.pose2dfile import MIN_PRESENCE

FINGERS = ("index", "middle", "pinky", "ring", "thumb")  # SMPL-H's order within a hand
# Each finger's hand-model points: its first joint (knuckle; the thumb's CMC), second, third, tip.
CHAINS = ((5, 6, 7, 8), (9, 10, 11, 12), (17, 18, 19, 20), (13, 14, 15, 16), (1, 2, 3, 4))
SIDES = ("left", "right")
HAND_JOINTS = tuple(f"{side}_{finger}{k}" for side in SIDES for finger in FINGERS for k in (1, 2, 3))
SMPLH_JOINTS = JOINTS[:22] + HAND_JOINTS
SMPL_WRISTS = (20, 21)
SMPLH_PARENTS = PARENTS[:22] + tuple(
    wrist if k == 0 else 22 + 15 * s + 3 * f + k - 1
    for s, wrist in enumerate(SMPL_WRISTS) for f in range(5) for k in range(3))
_LONG = (np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]))  # a rest hand's wrist -> middle knuckle
_SIDE = np.array([0.0, 0.0, 1.0])                                   # ... and its pinky -> index knuckle
PALM_ROUNDS = 3  # Procrustes rounds for a clip's mean palm (it settles within a few)
# About the largest active flexion of any finger joint (the PIP: 100-110 degrees): a finger the hand
# model folds further (its noisy frames) is bent this far, and the rest of its chain reaches on.
FINGER_RANGE_DEG = 110.0


@dataclass(frozen=True)
class RestHand:
    """One hand at rest, SMPL's rest frame, about its wrist (metres)."""

    knuckles: np.ndarray  # 5 x 3 each finger's first joint (FINGERS order)
    bones: np.ndarray     # 5 x 3 x 3 unit directions of each finger's bones: to its second, third joint, tip
    lengths: np.ndarray   # 5 x 3 those bones' lengths



def _chain_points(hand: np.ndarray) -> np.ndarray:
    """(..., 5, 4, 3): each finger's knuckle, two joints and tip, in FINGERS order."""
    return hand[..., np.array(CHAINS), :]


def clip_rest(hand: np.ndarray, presence: np.ndarray, side: int, min_presence: float = MIN_PRESENCE) -> RestHand:
    """dance3d's rest hand for one of a clip's hands (T x 21 x 3 world points, ``presence`` T; side 0
    left, 1 right): the clip's palm in the hand's own frame, turned to SMPL's rest, with straight
    fingers at the clip's median bone lengths."""
    points = np.asarray(hand, np.float64)
    sure = np.asarray(presence) >= min_presence
    if not sure.any():
        sure = np.ones(len(points), bool)
    chains = _chain_points(points[sure]) - points[sure, None, None, 0]       # S x 5 x 4 x 3
    seen = frame(chains[:, 1, 0], chains[:, 0, 0] - chains[:, 2, 0])       # S x 3 x 3
    palm = np.median(np.einsum("sji,sfj->sfi", seen, chains[:, :, 0]), axis=0)  # 5 x 3 in the hand's frame
    for _ in range(PALM_ROUNDS):  # the mean palm each frame's best rotation brings back (Procrustes)
        turn = _best_rotation(palm, chains[:, :, 0])
        palm = np.einsum("sji,sfj->sfi", turn, chains[:, :, 0]).mean(axis=0)
    palm = palm @ frame(palm[1], palm[0] - palm[2])  # back in the hand's own frame
    rest_frame = frame(_LONG[side], _SIDE)
    knuckles = palm @ rest_frame.T
    return straight_rest(knuckles, np.median(np.linalg.norm(np.diff(chains, axis=2), axis=-1), axis=0))


def straight_rest(knuckles: np.ndarray, lengths: np.ndarray) -> RestHand:
    """dance3d's rest hand on ``knuckles`` (5 x 3): every finger straight on from its knuckle, the
    line from the wrist through it, its bones ``lengths`` (5 x 3) long."""
    knuckles = np.asarray(knuckles, np.float64)
    return RestHand(knuckles, np.repeat(unit(knuckles)[:, None], 3, axis=1), np.asarray(lengths, np.float64))


def template_rest(joints: np.ndarray, side: int) -> RestHand:
    """The rest hand of a template's joints (52 x 3 in SMPL-H's order, or 55 x 3 in SMPL-X's: the
    jaw and eyes after the wrists); its fingertips carry the last bone on."""
    j = np.asarray(joints, np.float64)
    if j.shape not in ((52, 3), (55, 3)):
        raise ValueError(f"a joint template is 52 x 3 (SMPL-H) or 55 x 3 (SMPL-X), not {' x '.join(map(str, j.shape))}")
    first = 22 if len(j) == 52 else 25
    fingers = j[first + 15 * side: first + 15 * (side + 1)].reshape(5, 3, 3) - j[SMPL_WRISTS[side]]
    bones = np.diff(fingers, axis=1)                                         # 5 x 2 x 3
    bones = np.concatenate([bones, bones[:, -1:]], axis=1)                   # the last bone points on
    return RestHand(fingers[:, 0], unit(bones), np.linalg.norm(bones, axis=-1))


def _best_rotation(rest: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """T x 3 x 3 rotations taking the points ``rest`` (N x 3) nearest to each ``seen`` (T x N x 3) in
    the least-squares sense (Kabsch), both about the origin."""
    u, _, vt = np.linalg.svd(np.einsum("ni,tnj->tij", rest, seen))
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.broadcast_to(np.eye(3), d.shape + (3, 3)).copy()
    fix[:, 2, 2] = d
    return np.swapaxes(vt, -1, -2) @ fix @ np.swapaxes(u, -1, -2)


def solve_hand(hand: np.ndarray, rest: RestHand, parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T x 3 x 3 the wrist's local rotation, T x 15 x 3 x 3 the fingers' local rotations) that put
    ``rest`` on the world ``hand`` (T x 21 x 3), no finger joint bent past ``FINGER_RANGE_DEG``;
    ``parent``: the elbow's world rotations (T x 3 x 3)."""
    points = np.asarray(hand, np.float64)
    chains = _chain_points(points)
    wrist = _best_rotation(rest.knuckles, chains[:, :, 0] - points[:, None, 0])
    local = np.empty((len(points), 15, 3, 3))
    for f in range(5):
        above = wrist
        for k in range(3):
            turned = swing(above @ rest.bones[f, k], chains[:, f, k + 1] - chains[:, f, k], FINGER_RANGE_DEG) @ above
            local[:, 3 * f + k] = np.swapaxes(above, -1, -2) @ turned
            above = turned
    return np.swapaxes(parent, -1, -2) @ wrist, local


def hand_forward(wrist_position: np.ndarray, wrist_rotation: np.ndarray, fingers: np.ndarray, rest: RestHand
                 ) -> np.ndarray:
    """T x 21 x 3 a hand's points (the hand model's order) by forward kinematics: the wrist's world
    position and rotation (T x 3, T x 3 x 3) and the fingers' local rotations (T x 15 x 3 x 3)."""
    out = np.empty((len(fingers), 21, 3))
    out[:, 0] = wrist_position
    for f, chain in enumerate(CHAINS):
        out[:, chain[0]] = wrist_position + wrist_rotation @ rest.knuckles[f]
        above = wrist_rotation
        for k in range(3):
            above = above @ fingers[:, 3 * f + k]
            out[:, chain[k + 1]] = out[:, chain[k]] + rest.lengths[f, k] * (above @ rest.bones[f, k])
    return out


@dataclass(frozen=True)
class SmplHands:
    local: np.ndarray                         # T x 24 x 3 x 3 the body's rotations, the wrists turned with the palms
    fingers: np.ndarray                       # T x 30 x 3 x 3 left, then right hand's 15 joints (unseen: I)
    rests: tuple[RestHand | None, RestHand | None]  # the rest hand each side's rotations are relative to

    @property
    def poses(self) -> np.ndarray:
        """T x 90 axis-angle: the 30 finger joints of SMPL-H (after its 22 body joints), joint-major."""
        from pipeline.motion.smpl.kinematics import to_axis_angle

        return to_axis_angle(self.fingers)


def retarget_hands(local: np.ndarray, hands: np.ndarray, presence: np.ndarray,
                   rests: tuple[RestHand | None, RestHand | None] | None = None) -> SmplHands:
    """The SMPL body's rotations (T x 24 x 3 x 3) with each seen hand's wrist and fingers solved
    onto the world ``hands`` (T x 2 x 21 x 3, NaN for a hand never seen) relative to ``rests``
    (default: each hand's ``clip_rest``). An unseen hand keeps its wrist and straight fingers."""
    from pipeline.motion.smpl.kinematics import global_rotations

    local = np.array(local, np.float64)
    hands = np.asarray(hands, np.float64)
    glob = global_rotations(local)
    fingers = np.broadcast_to(np.eye(3), (len(local), 30, 3, 3)).copy()
    used: list[RestHand | None] = [None, None]
    for side in range(2):
        if not np.isfinite(hands[:, side]).all():
            continue
        rest = clip_rest(hands[:, side], presence[:, side], side) if rests is None or rests[side] is None \
            else rests[side]
        wrist = SMPL_WRISTS[side]
        local[:, wrist], fingers[:, 15 * side: 15 * (side + 1)] = solve_hand(hands[:, side], rest,
                                                                              glob[:, PARENTS[wrist]])
        used[side] = rest
    return SmplHands(local, fingers, (used[0], used[1]))


def rest_facts(rests: tuple[RestHand | None, RestHand | None]) -> dict:
    """The rest hands as a world file's clip facts (``smpl_hands``): per side, knuckles and bone
    lengths (millimetre precision), or None for a hand never seen."""
    return {side: None if rest is None else {"knuckles": np.round(rest.knuckles, 4).tolist(),
                                             "lengths": np.round(rest.lengths, 4).tolist()}
            for side, rest in zip(SIDES, rests)}


def rests_from_facts(facts: dict) -> tuple[RestHand | None, RestHand | None]:
    """The rest hands ``rest_facts`` wrote: dance3d's own, straight fingers on from the knuckles."""
    out: list[RestHand | None] = []
    for side in SIDES:
        fact = (facts or {}).get(side)
        if fact is None:
            out.append(None)
            continue
        out.append(straight_rest(fact["knuckles"], fact["lengths"]))
    return out[0], out[1]


def mirrored(rest: RestHand) -> RestHand:
    """The other hand's rest: ``rest`` mirrored left to right (x)."""
    flip = np.array([-1.0, 1.0, 1.0])
    return RestHand(rest.knuckles * flip, rest.bones * flip, rest.lengths)


def both_rests(rests: tuple[RestHand | None, RestHand | None]) -> tuple[RestHand, RestHand]:
    """Both rest hands, an unseen one the seen one mirrored (at least one must be seen)."""
    left, right = rests
    return (left if left is not None else mirrored(right)), (right if right is not None else mirrored(left))


def smplh_offsets(body: np.ndarray, rests: tuple[RestHand, RestHand]) -> tuple[np.ndarray, np.ndarray]:
    """(52 x 3 SMPL-H rest offsets: the body's first 22 (``body``, already scaled), each finger joint's
    from its parent on the rest hands; 30 x 3 each finger joint's bone beyond it, to the next joint
    or, for a third joint, the fingertip)."""
    offsets, beyond = np.zeros((52, 3)), np.zeros((30, 3))
    offsets[:22] = np.asarray(body, np.float64)[:22]
    for side, rest in enumerate(rests):
        for f in range(5):
            k = 15 * side + 3 * f
            offsets[22 + k] = rest.knuckles[f]
            for step in range(3):
                beyond[k + step] = rest.lengths[f, step] * rest.bones[f, step]
            offsets[23 + k: 25 + k] = beyond[k: k + 2]
    return offsets, beyond


def smplh_hand_points(local: np.ndarray, joints: np.ndarray, rests: tuple[RestHand | None, RestHand | None]
                      ) -> np.ndarray:
    """T x 2 x 21 x 3 both hands' points, fingertips included, by forward kinematics of SMPL-H's
    local rotations and joints (T x 52 x 3 x 3, T x 52 x 3) on ``rests``; NaN for a hand without one."""
    from pipeline.motion.smpl.kinematics import global_rotations

    glob = global_rotations(local, SMPLH_PARENTS)
    out = np.full((len(local), 2, 21, 3), np.nan)
    for side, rest in enumerate(rests):
        if rest is not None:
            wrist = SMPL_WRISTS[side]
            fingers = local[:, 22 + 15 * side: 37 + 15 * side]
            out[:, side] = hand_forward(joints[:, wrist], glob[:, wrist], fingers, rest)
    return out
