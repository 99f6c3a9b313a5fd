"""Finger rotations on the SMPL-H skeleton: solved from world hands, relative to a rest hand
(dance3d's own or a template's), and back to the points by forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.motion.smpl.hands import (
    CHAINS,
    FINGER_RANGE_DEG,
    SMPLH_JOINTS,
    SMPLH_PARENTS,
    clip_rest,
    hand_forward,
    retarget_hands,
    solve_hand,
    template_rest,
)
from pipeline.motion.smpl.kinematics import global_rotations
from pipeline.motion.smpl.retarget import frame
from pipeline.motion.smpl.skeleton import rest_positions


def _template() -> np.ndarray:
    """52 x 3: SMPL's rest body with flat hands, fingers spread a little, the thumb forward."""
    body = rest_positions()[:22]
    out = [body]
    for side, sign in ((0, 1.0), (1, -1.0)):
        wrist = body[20 + side]
        for spread, length in ((0.02, 0.095), (0.0, 0.1), (-0.04, 0.085), (-0.02, 0.095), (0.03, 0.03)):
            thumb = length < 0.05
            knuckle = wrist + [sign * length, -0.01, spread]
            step = np.array([sign * 0.6, -0.05, 0.8]) if thumb else np.array([sign, 0.0, spread * 3])
            step = 0.028 * step / np.linalg.norm(step)
            out.append(np.array([knuckle, knuckle + step, knuckle + 2 * step]))
    return np.concatenate([out[0]] + [np.concatenate(out[1:6]), np.concatenate(out[6:])])


def _posed(rest, wrist_rotation: np.ndarray, frames: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A hand's points (T x 21 x 3) and its finger rotations: each joint bent about the hand's side
    axis by up to 80 degrees, plus a little sideways."""
    rng = np.random.default_rng(seed)
    side_axis = frame(rest.knuckles[1], rest.knuckles[0] - rest.knuckles[2])[:, 1]  # the hand's sideways axis
    bend = Rotation.from_rotvec(np.radians(rng.uniform(0, 80, (frames * 15, 1))) * side_axis
                                + np.radians(rng.normal(0, 5, (frames * 15, 3)))).as_matrix()
    fingers = bend.reshape(frames, 15, 3, 3)
    wrist = np.broadcast_to(wrist_rotation, (frames, 3, 3))
    return hand_forward(np.zeros((frames, 3)), wrist, fingers, rest), fingers


def test_smplh_is_smpls_22_body_joints_then_15_joints_on_each_wrist() -> None:
    assert len(SMPLH_JOINTS) == 52 and SMPLH_JOINTS[22] == "left_index1" and SMPLH_JOINTS[-1] == "right_thumb3"
    assert SMPLH_PARENTS[:25] == (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19,
                                  20, 22, 23)
    assert SMPLH_PARENTS[37:40] == (21, 37, 38) and SMPLH_PARENTS[34:37] == (20, 34, 35)


@pytest.mark.parametrize("side", [0, 1])
def test_a_hand_posed_by_forward_kinematics_is_solved_back_onto_its_own_points(side: int) -> None:
    rest = template_rest(_template(), side)
    turn = Rotation.from_euler("xyz", [30, -50, 70], degrees=True).as_matrix()
    points, _ = _posed(rest, turn, 20, side)
    elbow = np.broadcast_to(Rotation.from_euler("y", 40, degrees=True).as_matrix(), (20, 3, 3))
    wrist, fingers = solve_hand(points, rest, elbow)
    again = hand_forward(np.zeros((20, 3)), elbow @ wrist, fingers, rest)
    assert np.abs(again - points).max() < 1e-9


def test_a_flat_hand_on_dance3ds_own_rest_has_straight_fingers() -> None:
    rest = template_rest(_template(), 0)
    flat = np.empty((5, 21, 3))
    flat[:, 0] = 0.0
    from pipeline.motion.smpl.hands import CHAINS
    for f, chain in enumerate(CHAINS):  # each finger straight on from the wrist through its knuckle
        direction = rest.knuckles[f] / np.linalg.norm(rest.knuckles[f])
        for k, point in enumerate(chain):
            flat[:, point] = rest.knuckles[f] + 0.025 * k * direction
    own = clip_rest(flat, np.ones(5), 0)
    _, fingers = solve_hand(flat, own, np.broadcast_to(np.eye(3), (5, 3, 3)))
    assert np.allclose(fingers, np.eye(3), atol=1e-9)
    assert np.allclose(own.lengths, 0.025)


def test_an_unseen_hand_keeps_its_wrist_and_straight_fingers_and_a_seen_one_turns_its_wrist() -> None:
    frames = 6
    local = np.broadcast_to(np.eye(3), (frames, 24, 3, 3)).copy()
    rest = template_rest(_template(), 0)
    turn = Rotation.from_euler("z", 60, degrees=True).as_matrix()
    points, fingers = _posed(rest, turn, frames, 3)
    hands = np.stack([points + 1.0, np.full_like(points, np.nan)], axis=1)
    solved = retarget_hands(local, hands, np.ones((frames, 2)), (rest, None))
    assert np.allclose(solved.local[:, 20], turn) and np.allclose(solved.local[:, 21], np.eye(3))
    assert np.allclose(solved.fingers[:, 15:], np.eye(3)) and solved.rests[1] is None
    glob = global_rotations(solved.local)
    again = hand_forward(np.zeros((frames, 3)), glob[:, 20], solved.fingers[:, :15], rest)
    assert np.abs(again - points).max() < 1e-9
    assert solved.poses.shape == (frames, 90)


def test_no_finger_joint_is_bent_past_what_a_finger_can_bend() -> None:
    """The hand model's noisy frames can fold a finger back on itself; SMPL-H gets it bent as far as a
    finger joint goes (the rest of the chain still reaches for its points), other joints as seen."""
    rest = template_rest(_template(), 0)
    points, fingers = _posed(rest, np.eye(3), 4, 5)
    side_axis = frame(rest.knuckles[1], rest.knuckles[0] - rest.knuckles[2])[:, 1]
    folded = fingers.copy()
    folded[:, 3 + 1] = Rotation.from_rotvec(np.radians(150) * side_axis).as_matrix()  # the middle finger's 2nd joint
    bent = hand_forward(np.zeros((4, 3)), np.broadcast_to(np.eye(3), (4, 3, 3)), folded, rest)
    _, solved = solve_hand(bent, rest, np.broadcast_to(np.eye(3), (4, 3, 3)))
    angles = np.degrees(np.linalg.norm(Rotation.from_matrix(solved.reshape(-1, 3, 3)).as_rotvec(), axis=-1))
    assert angles.max() <= FINGER_RANGE_DEG + 1e-6
    assert np.allclose(angles.reshape(4, 15)[:, 4], FINGER_RANGE_DEG)
    again = hand_forward(np.zeros((4, 3)), np.broadcast_to(np.eye(3), (4, 3, 3)), solved, rest)
    index = list(CHAINS[0])
    assert np.abs(again[:, index] - bent[:, index]).max() < 1e-9  # a finger bent less lands on its points


def test_a_template_of_the_wrong_shape_is_refused_with_its_shape() -> None:
    with pytest.raises(ValueError, match="52 x 3 .* not 24 x 3"):
        template_rest(np.zeros((24, 3)), 0)


def test_an_smplh_bvh_reads_back_as_the_same_52_joints_and_draws_the_fingertips(tmp_path) -> None:
    """A BVH reader's forward kinematics of ``export bvh --smpl`` with hands gives SMPL-H's joints,
    and the hand points drawn by ``render --smpl`` are the rest hand posed by the finger rotations."""
    from pipeline.motion.bvh_export import write_bvh
    from pipeline.motion.mocap.bvh import forward_kinematics, read_bvh
    from pipeline.motion.smpl.bvh import smplh_skeleton_motion
    from pipeline.motion.smpl.hands import smplh_hand_points

    frames = 5
    poses = (Rotation.random(frames * 24, random_state=4).as_rotvec() * 0.4).reshape(frames, 72)
    hand_poses = (Rotation.random(frames * 30, random_state=5).as_rotvec() * 0.3).reshape(frames, 90)
    trans = np.stack([np.linspace(0, 0.5, frames), np.full(frames, 0.9), np.zeros(frames)], 1)
    rest = template_rest(_template(), 0)
    motion = smplh_skeleton_motion(poses, hand_poses, trans, 0.93, (rest, None))  # the right hand: mirrored
    assert motion.joints.shape == (frames, 52, 3)
    write_bvh(tmp_path / "smplh.bvh", motion, 24.0)
    bvh = read_bvh(tmp_path / "smplh.bvh")
    positions, _, _ = forward_kinematics(bvh, "replace")
    back = positions[:, [bvh.index(name) for name in SMPLH_JOINTS]]
    assert np.abs(back - motion.joints).max() < 1e-5  # the file's six decimals
    points = smplh_hand_points(motion.local, motion.joints, (rest, None))
    assert np.isnan(points[:, 1]).all()
    from pipeline.motion.smpl.hands import CHAINS
    knuckles_then_joints = [chain[k] for chain in CHAINS for k in range(3)]
    assert np.allclose(points[:, 0, knuckles_then_joints], motion.joints[:, 22:37], atol=1e-9)
