"""FineDance's layout: SMPL-H's 52 joints as 6D rows after the root, names LODGE's preprocessing
keeps as they are, and fingers re-solved onto a template's flat hands."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.core.errors import Dance3dError
from pipeline.export.finedance import motion_vector, read_template, sequence_name, smplh_poses
from pipeline.motion.smpl.hands import hand_forward, template_rest
from pipeline.motion.smpl.kinematics import from_axis_angle, global_rotations
from tests.motion.test_smpl_hands import _posed, _template


def test_the_motion_is_the_root_on_the_unit_body_then_52_joints_as_the_first_two_rows_of_each_rotation() -> None:
    frames = 3
    poses = Rotation.random(frames * 52, random_state=0).as_rotvec().reshape(frames, 156)
    trans = np.random.default_rng(1).normal(size=(frames, 3))
    pelvis = np.array([0.003, -0.35, 0.012])
    motion = motion_vector(poses, trans, 1.25, pelvis)
    assert motion.shape == (frames, 315) and motion.dtype == np.float32
    assert np.allclose(motion[:, :3], trans / 1.25 - pelvis, atol=1e-6)  # LODGE adds it to the posed template
    rows = motion[:, 3:].reshape(frames, 52, 2, 3)
    assert np.allclose(rows, from_axis_angle(poses)[:, :, :2, :], atol=1e-6)


def test_names_are_stable_and_hold_no_capital_m_which_lodge_would_cut() -> None:
    names = {sequence_name(f"clip{k}") for k in range(200)}
    assert len(names) == 200 and not any("M" in n for n in names)
    assert sequence_name("clip7") == sequence_name("clip7") and sequence_name("clip7").startswith("d3d")


def test_with_a_template_the_fingers_point_where_the_world_hands_do_under_its_forward_kinematics() -> None:
    frames, template = 8, _template()
    body = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    local = np.broadcast_to(np.eye(3), (frames, 24, 3, 3)).copy()
    local[:, 18] = body  # the left elbow turned: the hand must follow its parent
    own = template_rest(template, 0)
    wrist_world = global_rotations(local)[:, 18] @ Rotation.from_euler("y", 50, degrees=True).as_matrix()
    left, _ = _posed(own, wrist_world[0], frames, 5)
    hands = np.stack([left, np.full_like(left, np.nan)], axis=1)
    clip = SimpleNamespace(smpl_poses=Rotation.from_matrix(local.reshape(-1, 3, 3)).as_rotvec().reshape(frames, 72),
                           hands=hands, hand_presence=np.ones((frames, 2)), smpl_hand_poses=np.zeros((frames, 90)))
    poses, seen = smplh_poses(clip, template)
    assert seen and poses.shape == (frames, 156)
    rot = from_axis_angle(poses)
    glob = global_rotations(np.concatenate([rot[:, :22], np.broadcast_to(np.eye(3), (frames, 2, 3, 3))], axis=1))
    again = hand_forward(left[:, 0], glob[:, 20], rot[:, 22:37], own)
    assert np.abs(again - left).max() < 1e-6
    assert np.allclose(rot[:, 37:], np.eye(3))  # the right hand was never seen: flat


def test_without_hands_the_fingers_are_flat() -> None:
    poses72 = Rotation.random(4 * 24, random_state=2).as_rotvec().reshape(4, 72)
    poses, seen = smplh_poses(SimpleNamespace(smpl_poses=poses72, hands=None, smpl_hand_poses=None), None)
    assert not seen and np.allclose(poses[:, :66], poses72[:, :66]) and (poses[:, 66:] == 0).all()


def test_a_template_that_is_not_a_joint_array_is_refused_naming_the_file(tmp_path) -> None:
    bad = tmp_path / "J.npy"
    np.save(bad, np.zeros((24, 3)))
    with pytest.raises(Dance3dError, match=r"J\.npy: a joint template is 52 x 3"):
        read_template(bad)
    (tmp_path / "text.npy").write_text("hello")
    with pytest.raises(Dance3dError, match=r"text\.npy: not a joint template"):
        read_template(tmp_path / "text.npy")
