"""Retargeting world motion onto the SMPL tree: the tree as data, forward kinematics, the inverse
kinematics' rules, and what the checks report."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.motion.smpl import checks
from pipeline.motion.smpl.kinematics import forward, from_axis_angle, to_6d_rows, to_axis_angle
from pipeline.motion.smpl.proportions import own_offsets
from pipeline.motion.smpl.retarget import hinge_axes, retarget, two_bone
from pipeline.motion.smpl.skeleton import JOINTS, PARENTS, REST_OFFSETS, J, leg_length, rest_positions


def smpl_dance(frames: int = 96, seed: int = 0) -> tuple[np.ndarray, np.ndarray, float]:
    """A motion made on the SMPL skeleton itself: local rotations, the pelvis path and the scale.
    The torso turns as one piece with the pelvis; hips, knees, shoulders and elbows move."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 24.0
    rotvec = np.zeros((frames, 24, 3))
    rotvec[:, 0, 1] = 0.6 * np.sin(0.7 * t)                              # the body turns
    for hip, knee, phase in ((1, 4, 0.0), (2, 5, np.pi)):
        rotvec[:, hip, 0] = -0.5 - 0.4 * np.sin(2 * t + phase)          # thighs swing forward
        rotvec[:, hip, 1] = 0.3 * np.sin(t + phase)                     # and turn in and out
        rotvec[:, knee, 0] = 0.3 + 0.6 * (1 + np.sin(2 * t + phase))    # knees bend (about +x)
    for shoulder, elbow, side in ((16, 18, 1.0), (17, 19, -1.0)):
        rotvec[:, shoulder, 2] = side * (-0.8 + 0.4 * np.sin(1.5 * t))  # arms down and up
        rotvec[:, shoulder, 0] = 0.4 * np.sin(t)
        rotvec[:, elbow, 1] = -side * (0.4 + 0.5 * (1 + np.sin(3 * t)))  # elbows bend forward
    rotvec += rng.normal(0, 0.01, rotvec.shape)
    rotvec[:, [3, 6, 9, 12, 13, 14, 15]] = 0.0
    trans = np.stack([0.3 * np.sin(t), 0.9 + 0.02 * np.sin(4 * t), 0.2 * t], axis=1)
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(frames, 24, 3, 3), trans, 0.95


def as_h36m(smpl: np.ndarray) -> np.ndarray:
    """The H36M-17 joints of a motion on the SMPL skeleton (mapped joints where SMPL has them; the
    spine, thorax, nose and head top placed on the torso and head)."""
    out = np.zeros((len(smpl), 17, 3))
    pairs = {1: 2, 2: 5, 3: 8, 4: 1, 5: 4, 6: 7, 11: 16, 12: 18, 13: 20, 14: 17, 15: 19, 16: 21}
    for h, s in pairs.items():
        out[:, h] = smpl[:, s]
    out[:, 0] = (smpl[:, 1] + smpl[:, 2]) / 2
    out[:, 7], out[:, 8] = smpl[:, 6], smpl[:, 12]
    out[:, 10] = smpl[:, 15] + 0.6 * (smpl[:, 15] - smpl[:, 12])
    out[:, 9] = smpl[:, 15]
    return out


def test_the_tree_is_smpls_24_joints_with_edges_published_rest_offsets():
    assert len(JOINTS) == len(PARENTS) == len(REST_OFFSETS) == 24
    assert all(PARENTS[j] < j for j in range(1, 24))  # parents before children
    rest = rest_positions()
    assert rest[J["left_hip"], 0] > 0 > rest[J["right_hip"], 0]  # the body's left is +x
    assert rest[J["head"], 1] > rest[J["neck"], 1] > 0 > rest[J["left_ankle"], 1]  # y up
    assert leg_length() == pytest.approx(0.8134, abs=1e-3)


def test_forward_kinematics_of_no_rotation_is_the_rest_pose_scaled_and_moved():
    local = np.broadcast_to(np.eye(3), (2, 24, 3, 3))
    trans = np.array([[0.0, 1.0, 0.0], [1.0, 1.0, 2.0]])
    joints = forward(local, trans, 1.1)
    assert np.allclose(joints[1] - trans[1], rest_positions(1.1))


def test_axis_angle_and_6d_round_trip():
    local, _, _ = smpl_dance(8)
    assert np.allclose(from_axis_angle(to_axis_angle(local)), local, atol=1e-9)
    six = to_6d_rows(local)
    assert six.shape == (8, 24, 6) and np.allclose(six[..., :3], local[..., 0, :])


def test_two_bone_reaches_the_end_and_keeps_both_lengths():
    root = np.zeros((3, 3))
    end = np.array([[0.0, -0.5, 0.2], [0.0, -0.9, 0.0], [0.0, -0.05, 0.0]])  # in reach, too far, too near
    hinge = np.tile([1.0, 0, 0], (3, 1))
    mid, tip = two_bone(root, end, hinge, 0.4, 0.42)
    assert np.allclose(tip[0], end[0])
    assert np.allclose(np.linalg.norm(mid - root, axis=-1), 0.4)
    assert np.allclose(np.linalg.norm(tip - mid, axis=-1), 0.42)
    assert mid[0, 2] > np.interp(mid[0, 1], [-0.5, 0], [0.2, 0])  # the knee bends forward of the line


def test_a_straight_limb_keeps_the_hinge_it_had_when_it_last_bent():
    upper = np.tile([0.0, -1.0, 0.0], (4, 1))
    lower = np.array([[0, -0.8, -0.6], [0, -1.0, 0.0], [0, -1.0, 0.001], [0, -0.8, -0.6]])
    axes = hinge_axes(upper, lower, np.array([0.0, 0.0, 1.0]))
    assert np.allclose(axes, [1.0, 0.0, 0.0], atol=1e-6)


def test_a_knee_bent_backwards_does_not_flip_the_thigh():
    upper = np.tile([0.0, -1.0, 0.0], (2, 1))
    lower = np.array([[0, -0.8, -0.6], [0, -0.8, 0.6]])  # bends, then hyper-extends
    axes = hinge_axes(upper, lower, np.array([1.0, 0, 0]), reference=np.tile([1.0, 0, 0], (2, 1)))
    assert np.allclose(axes[1], [1.0, 0, 0], atol=1e-6)


def test_motion_made_on_the_smpl_skeleton_comes_back_at_its_joints():
    local, trans, scale = smpl_dance()
    truth = forward(local, trans, scale)
    motion = retarget(as_h36m(truth))
    assert motion.scale == pytest.approx(scale, rel=1e-3)
    def worst(*names: str) -> float:
        idx = [J[n] for n in names]
        return float(np.linalg.norm(motion.joints[:, idx] - truth[:, idx], axis=-1).max())

    assert worst("left_ankle", "right_ankle") < 1e-6  # two-bone ends: exact
    assert worst("left_hip", "right_hip", "left_knee", "right_knee") < 1e-3  # the pelvis up from its spine
    # the shoulders hang on the spine rules (a third of the turn each), the arms along the world arms
    # from them: the elbows and wrists carry the shoulders' error, no more
    assert worst("left_shoulder", "right_shoulder") < 0.02 and worst("left_elbow", "right_elbow") < 0.02
    assert worst("left_wrist", "right_wrist") < 0.02
    # ... and its knees turn about their hinge alone, within human ranges
    report = checks.joint_ranges(motion)
    assert report.outside["left_knee"] == report.outside["right_knee"] == 0
    assert sum(report.outside.values()) == 0


def test_a_knee_turned_further_than_a_hip_turns_is_bent_in_the_nearest_plane_the_body_allows():
    """3D noise can swing a bent knee round further than a hip turns (here 80 degrees out): the leg
    then bends in a plane a hip allows (60 degrees about the leg from neutral), the ankle where it
    was, the hip in its range."""
    local, trans, scale = smpl_dance(frames=24)
    turn = Rotation.from_rotvec([0.0, np.radians(80.0), 0.0]).as_matrix()  # about the thigh (y)
    local[:, J["left_hip"]] = local[:, J["left_hip"]] @ turn
    truth = forward(local, trans, scale)
    motion = retarget(as_h36m(truth))
    ankle = np.linalg.norm(motion.joints[:, J["left_ankle"]] - truth[:, J["left_ankle"]], axis=-1)
    assert ankle.max() < 1e-6
    assert checks.joint_ranges(motion).outside["left_hip"] == 0
    assert np.linalg.norm(motion.joints[:, J["left_knee"]] - truth[:, J["left_knee"]], axis=-1).min() > 0.03


def test_proportions_other_than_smpls_are_told_apart_from_the_inverse_kinematics():
    """A dancer with forearms and shins 15 % longer than SMPL's, and shoulders 4 cm wider: on
    SMPL's offsets the elbows and knees miss by about the difference (no rotation can help); on the
    clip's own proportions (own_offsets) the same rules find them again."""
    local, trans, scale = smpl_dance()
    offsets = REST_OFFSETS.copy()
    offsets[[7, 8, 20, 21]] *= 1.15
    offsets[[16, 17]] *= 1.2
    truth = forward(local, trans, scale, offsets)
    joints = as_h36m(truth)
    own = own_offsets(joints)
    assert np.linalg.norm(own[[7, 8, 20, 21]], axis=-1) == pytest.approx(
        scale * np.linalg.norm(offsets[[7, 8, 20, 21]], axis=-1), rel=1e-6)
    on_smpl = checks.joint_errors(retarget(joints), joints)
    on_own = checks.joint_errors(retarget(joints, offsets=own), joints)
    for name in ("left_knee", "right_knee", "left_elbow", "right_elbow"):
        assert np.median(on_smpl[name]) > 0.015
        assert np.median(on_own[name]) < 0.01


def test_smpl_arms_point_where_the_world_arms_point_whatever_their_lengths():
    """Arms carry no contact: a dancer with upper arms 10 % shorter and forearms 20 % longer than
    SMPL's gets SMPL arms along the world arms' directions (the wrist then misses by the length
    difference), while the legs still put the ankles exactly where they were."""
    local, trans, scale = smpl_dance()
    offsets = REST_OFFSETS.copy()
    offsets[[18, 19]] *= 0.9
    offsets[[20, 21]] *= 1.2
    joints = as_h36m(forward(local, trans, scale, offsets))
    motion = retarget(joints)
    directions = checks.limb_directions(motion, joints)
    for limb in ("left_upper_arm", "right_upper_arm", "left_forearm", "right_forearm"):
        assert np.max(directions[limb]) < 0.5, (limb, np.max(directions[limb]))
    for ankle, h36m in (("left_ankle", 6), ("right_ankle", 3)):
        assert np.linalg.norm(motion.joints[:, J[ankle]] - joints[:, h36m], axis=-1).max() < 1e-6


def test_feet_point_at_the_ball_of_the_foot():
    local, trans, scale = smpl_dance(24)
    truth = forward(local, trans, scale)
    joints = as_h36m(truth)
    # heels and toe tips that put the ball of each foot 14 cm in front of the ankle, on the floor
    forward_dir = np.array([np.sin(0.3), 0.0, np.cos(0.3)])
    feet = np.zeros((24, 4, 3))
    for k, ankle in enumerate((6, 3)):
        floor = joints[:, ankle] * [1, 0, 1]
        feet[:, k] = floor - 0.05 * forward_dir
        feet[:, 2 + k] = floor + (0.05 + (0.14 * 1.2 - 0.05) / 0.72 * 1.0) * forward_dir
    motion = retarget(joints, feet)
    errors = checks.joint_errors(motion, joints, feet)
    for side in ("left", "right"):
        ball_dir = motion.joints[:, J[f"{side}_foot"]] - motion.joints[:, J[f"{side}_ankle"]]
        wanted = feet[:, 0 if side == "left" else 1] + 0.72 * (feet[:, 2 if side == "left" else 3]
                                                              - feet[:, 0 if side == "left" else 1])
        wanted = wanted - motion.joints[:, J[f"{side}_ankle"]]
        cos = (ball_dir * wanted).sum(-1) / np.linalg.norm(ball_dir, axis=-1) / np.linalg.norm(wanted, axis=-1)
        assert cos.min() > 0.999
        assert np.median(errors[f"{side}_foot"]) < 0.2


def test_sliding_counts_only_planted_frames():
    points = np.zeros((4, 1, 3))
    points[:, 0, 0] = [0.0, 0.001, 0.002, 0.5]  # 1 mm a frame while planted, then a step
    planted = np.array([[True], [True], [True], [False]])
    assert checks.sliding(points, planted, 30.0) == pytest.approx(1.0)


def test_the_smpl_bvh_reads_back_as_the_same_joints(tmp_path):
    """A BVH reader's forward kinematics of ``export bvh --smpl`` gives SMPL's forward kinematics."""
    from scipy.spatial.transform import Rotation

    from pipeline.motion.bvh_export import write_bvh
    from pipeline.motion.mocap.bvh import forward_kinematics, read_bvh
    from pipeline.motion.smpl.bvh import smpl_skeleton_motion
    from pipeline.motion.smpl.skeleton import JOINTS

    frames = 6
    poses = (Rotation.random(frames * 24, random_state=3).as_rotvec() * 0.4).reshape(frames, 72)
    trans = np.stack([np.linspace(0, 0.5, frames), np.full(frames, 0.9), np.zeros(frames)], 1)
    motion = smpl_skeleton_motion(poses, trans, 0.93)
    write_bvh(tmp_path / "smpl.bvh", motion, 24.0)
    bvh = read_bvh(tmp_path / "smpl.bvh")
    positions, _, _ = forward_kinematics(bvh, "replace")
    back = positions[:, [bvh.index(name) for name in JOINTS]]
    assert np.abs(back - motion.joints).max() < 1e-5  # the file's six decimals


def test_eval_smpl_reports_the_error_on_smpls_proportions_beside_the_clips_own():
    from pipeline.motion.smpl.evaluate import Clip, evaluate, format_report

    local, trans, scale = smpl_dance()
    offsets = REST_OFFSETS.copy()
    offsets[[20, 21]] *= 1.2  # long forearms
    joints = as_h36m(forward(local, trans, scale, offsets))
    result = evaluate([Clip("made", "long_forearms", joints, None, None, 24.0)])
    on_smpl, on_own = result["all"]["error"], result["all"]["error_own_proportions"]
    assert on_smpl["left_wrist"]["median_mm"] > 20 > on_own["left_wrist"]["median_mm"]
    assert on_own["all"]["p95_mm"] < on_smpl["all"]["p95_mm"]
    report = format_report(result)
    assert "own prop." in report and "long_forearms" not in report  # per source, not per clip
