"""World-frame motion: gravity from the body, one skeleton per clip, rotations and BVH export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.motion.bvh_export import read_back, solve_rotations, write_bvh
from pipeline.motion.lifting.geometry import look_at, to_camera
from pipeline.motion.mocap.sources import load_source
from pipeline.motion.world.bones import apply_skeleton, bone_length_cv, fit_skeleton
from pipeline.motion.world.gravity import ANKLE_HEIGHT, to_world, up_error_deg


def _pitched_view(h36m: np.ndarray, pitch_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Root-relative camera-frame joints from a camera 4 m away at 1.4 m, pitched down by
    ``pitch_deg``, and the true up direction in that camera's coordinates."""
    centre = h36m[:, 0].mean(0)
    position = centre + np.array([0.0, 0.0, 4.0])
    position[1] = 1.4
    rotation = look_at(position, position + np.array([0.0, -4.0 * np.tan(np.radians(pitch_deg)), -4.0]))
    cam = to_camera(h36m, rotation, position)
    return cam - cam[:, :1], rotation @ np.array([0.0, 1.0, 0.0])


@pytest.fixture(scope="module")
def dance(mocap_dir: Path) -> np.ndarray:
    return load_source(mocap_dir, "dancedb_ucy")[0].h36m[::2]


@pytest.mark.parametrize("pitch", [-20.0, -10.0, 0.0, 10.0, 20.0])
def test_up_and_pitch_are_recovered_from_the_body(dance: np.ndarray, pitch: float) -> None:
    cam, true_up = _pitched_view(dance, pitch)
    world, camera = to_world(cam)
    assert up_error_deg(camera, true_up) < 3.0
    assert abs(camera.pitch_deg - pitch) < 3.0 and abs(camera.roll_deg) < 3.0
    assert (world[:, 10, 1] > world[:, 0, 1]).mean() > 0.99  # y is up: the head is above the pelvis
    lowest = np.minimum(world[:, 3, 1], world[:, 6, 1])
    assert np.allclose(lowest, ANKLE_HEIGHT)  # the floor is y = 0 under the lower ankle


def test_one_skeleton_makes_bones_constant_and_keeps_directions() -> None:
    rng = np.random.default_rng(0)
    rest = np.array([[0, 1, 0], [-.1, 1, 0], [-.1, .55, 0], [-.1, .1, 0], [.1, 1, 0], [.1, .55, 0], [.1, .1, 0],
                     [0, 1.25, 0], [0, 1.5, 0], [0, 1.6, .05], [0, 1.75, 0], [.2, 1.45, 0], [.45, 1.45, 0],
                     [.7, 1.45, 0], [-.2, 1.45, 0], [-.45, 1.45, 0], [-.7, 1.45, 0]], float)
    noisy = rest[None] + rng.normal(0, 0.02, (50, 17, 3))  # a lifter's wandering bones
    assert bone_length_cv(noisy) > 0.05
    lengths = fit_skeleton(noisy)
    fitted = apply_skeleton(noisy, lengths)
    assert bone_length_cv(fitted) < 1e-9
    assert lengths[1] == lengths[4] and lengths[11] == lengths[14]  # left and right thigh, upper arm agree
    # Each bone keeps its direction; the root does not move.
    a, b = noisy[:, 2] - noisy[:, 1], fitted[:, 2] - fitted[:, 1]
    cosine = (a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    assert cosine.min() > 1 - 1e-9 and np.array_equal(fitted[:, 0], noisy[:, 0])


def test_bvh_round_trip_gives_the_joints_back_within_a_millimetre(dance: np.ndarray, tmp_path: Path) -> None:
    cam, _ = _pitched_view(dance, 15.0)
    world, _ = to_world(cam)
    motion = solve_rotations(world)
    write_bvh(tmp_path / "clip.bvh", motion, 24.0)
    back = read_back(tmp_path / "clip.bvh")
    assert np.abs(back - motion.joints).max() < 1e-3
    text = (tmp_path / "clip.bvh").read_text()
    assert f"Frames: {len(dance)}\nFrame Time: 0.04166667\n" in text and "-0.000000" not in text
    # The skeleton fit moves joints by millimetres on real capture, not centimetres.
    assert np.linalg.norm(motion.joints - world, axis=-1).mean() < 0.01


def test_bvh_with_feet_gives_heels_and_toes_back_on_constant_lengths(mocap_dir: Path, tmp_path: Path) -> None:
    seq = load_source(mocap_dir, "dancedb_ucy")[0]
    everything = np.concatenate([seq.h36m, seq.feet], 1)[::2]
    cam, _ = _pitched_view(everything, 10.0)
    world, _ = to_world(cam)
    motion = solve_rotations(world)
    assert {"LeftHeel", "RightHeel", "LeftToe", "RightToe"} <= {j.name for j in motion.spec}
    write_bvh(tmp_path / "feet.bvh", motion, 24.0)
    back = read_back(tmp_path / "feet.bvh")
    assert back.shape == (len(world), 21, 3) and np.abs(back - motion.joints).max() < 1e-3
    heel = np.linalg.norm(back[:, 17] - back[:, 6], axis=-1)
    assert np.ptp(heel) < 1e-3  # one skeleton: the heel keeps its length
    # The body is fitted as without feet, and the feet move by millimetres on real capture.
    np.testing.assert_allclose(motion.joints[:, :17], solve_rotations(world[:, :17]).joints)
    assert np.linalg.norm(motion.joints[:, 17:] - world[:, 17:], axis=-1).mean() < 0.02
    # `dance3d export bvh` writes them for a motion file whose lifter gave feet.
    from pipeline.motion.motionfile import MotionClip, write_motion

    n = len(cam)
    clip = MotionClip("vid_000_1_0", 1, np.arange(n, dtype=np.int32), np.arange(n) / 24.0,
                      cam[:, :17].astype(np.float32), np.zeros(n, bool), np.zeros(n, np.int8),
                      feet=(cam[:, 17:] - cam[:, :1]).astype(np.float32))
    write_motion(tmp_path / "vid_000.parquet", [clip], {"segment_id": "vid_000", "fps": 24.0, "width": 1920,
                                                        "height": 1080}, fingerprint="x", params={}, inputs={})
    assert main(["export", "bvh", str(tmp_path / "vid_000.parquet"), "vid_000_1_0", str(tmp_path / "cli.bvh")]) == 0
    assert read_back(tmp_path / "cli.bvh").shape == (n, 21, 3)


def test_export_bvh_writes_one_clip_of_a_motion_file(dance: np.ndarray, tmp_path: Path, capsys) -> None:
    from pipeline.motion.motionfile import MotionClip, write_motion

    cam, _ = _pitched_view(dance, 10.0)
    n = len(cam)
    clip = MotionClip("vid_000_1_0", 1, np.arange(n, dtype=np.int32), np.arange(n) / 24.0, cam.astype(np.float32),
                      np.zeros(n, bool), np.zeros(n, np.int8))
    motion = tmp_path / "vid_000.parquet"
    write_motion(motion, [clip], {"segment_id": "vid_000", "fps": 24.0, "width": 1920, "height": 1080},
                 fingerprint="x", params={}, inputs={})
    assert main(["export", "bvh", str(motion), "vid_000_1_0", str(tmp_path / "out.bvh")]) == 0
    out = capsys.readouterr().out
    assert "camera pitch +1" in out and "bone-length CV" in out
    assert read_back(tmp_path / "out.bvh").shape == (n, 17, 3)
    assert main(["export", "bvh", str(motion), "nope", str(tmp_path / "x.bvh")]) == 2
    assert "no clip 'nope'; clips: vid_000_1_0" in capsys.readouterr().err


def test_the_root_path_is_where_the_pose_projects(dance: np.ndarray) -> None:
    from pipeline.motion.lifting.evaluate import PROTOCOL_CAMERAS, view
    from pipeline.motion.mocap.skeleton import coco_from_h36m
    from pipeline.motion.world.trajectory import align_scale_offset, root_from_2d

    camera = PROTOCOL_CAMERAS[1]
    xy, joints = view(dance, coco_from_h36m(dance), camera)
    root = root_from_2d(joints - joints[:, :1], xy, camera.focal_px, camera.width, camera.height)
    # Exact but for COCO's wider hips: millimetres.
    assert np.linalg.norm(root - joints[:, 0], axis=-1).mean() < 0.01
    # A pose 10 % too large puts the body 10 % too far: one scale per clip takes that out.
    big = root_from_2d(1.1 * (joints - joints[:, :1]), xy, camera.focal_px, camera.width, camera.height)
    assert np.linalg.norm(big - joints[:, 0], axis=-1).mean() > 0.3
    assert np.linalg.norm(align_scale_offset(big, joints[:, 0]) - joints[:, 0], axis=-1).mean() < 0.01


def test_a_pose_lifted_as_if_filmed_head_on_is_turned_onto_its_viewing_ray(dance: np.ndarray) -> None:
    from pipeline.motion.lifting.evaluate import Camera, view
    from pipeline.motion.mocap.skeleton import coco_from_h36m, smallest_rotation
    from pipeline.motion.world.trajectory import place_root, root_from_2d

    # A phone at 1.2 m pitched 20 degrees up: the dancer stands low in the frame, well off its axis.
    camera = Camera("phone_up", 0.0, 1.2, 3.0, 1080, 1920, pitch_deg=-20.0)
    xy, joints = view(dance, coco_from_h36m(dance), camera)
    true = joints - joints[:, :1]
    # What the lifter gives: the pose as a camera aimed at the dancer (same centre) would see it.
    ray = joints[:, 0] / np.linalg.norm(joints[:, 0], axis=-1, keepdims=True)
    head_on = np.einsum("tji,tkj->tki", smallest_rotation(np.array([0.0, 0.0, 1.0]), ray), true)
    assert np.degrees(np.arccos(ray[:, 2])).mean() > 15  # the turn matters here
    turned, root = place_root(head_on, xy, camera.focal_px, camera.width, camera.height)
    # The ray comes from a first placement of the untouched pose: close, not exact.
    assert np.linalg.norm(turned - true, axis=-1).mean() < 0.005
    # Placed untouched, the pose lands half a metre off (51 cm); turned, within 2 cm (the one skeleton
    # and COCO's wider hips).
    untouched = root_from_2d(head_on, xy, camera.focal_px, camera.width, camera.height)
    assert np.linalg.norm(untouched - joints[:, 0], axis=-1).mean() > 0.3
    assert np.linalg.norm(root - joints[:, 0], axis=-1).mean() < 0.03


def test_bones_that_wobble_from_frame_to_frame_do_not_move_the_body_in_depth(dance: np.ndarray) -> None:
    from pipeline.motion.lifting.evaluate import PROTOCOL_CAMERAS, view
    from pipeline.motion.mocap.skeleton import coco_from_h36m
    from pipeline.motion.world.trajectory import place_root, root_from_2d

    camera = PROTOCOL_CAMERAS[1]
    xy, joints = view(dance, coco_from_h36m(dance), camera)
    wobble = 1 + 0.1 * np.sin(np.arange(len(joints)) / 3.0)   # the lifter's per-frame scale, +-10 %
    lifted = (joints - joints[:, :1]) * wobble[:, None, None]
    per_frame = root_from_2d(lifted, xy, camera.focal_px, camera.width, camera.height)
    _, placed = place_root(lifted, xy, camera.focal_px, camera.width, camera.height)
    depth_error = [np.abs(np.diff(r[:, 2] - joints[:, 0, 2])).mean() for r in (per_frame, placed)]
    assert depth_error[0] > 0.05 and depth_error[1] < depth_error[0] / 5


def test_pinned_feet_stop_sliding_and_keep_the_legs(dance: np.ndarray) -> None:
    from pipeline.motion.world.contact import foot_contact, pin_feet, skating

    fps = 15.0  # the fixture keeps every second frame of 30 fps capture
    world, _ = to_world(dance - dance[:, :1], root=dance[:, 0] - dance[0, 0])
    contact = foot_contact(world, fps)
    assert 0.2 < contact.mean() < 0.95  # a dancer stands on a foot much of the time
    assert skating(world, contact, fps) < 0.15  # motion capture barely slides (m/s)
    # A lifter-like wobble: the whole body drifts back and forth by 5 cm.
    sliding = world + 0.05 * np.sin(np.arange(len(world)) / 2.0)[:, None, None] * np.array([1.0, 0.0, 0.0])
    before = skating(sliding, contact, fps)
    pinned = pin_feet(sliding, contact)
    assert skating(pinned, contact, fps) < 0.4 * before
    for hip, knee, ankle in ((4, 5, 6), (1, 2, 3)):
        thigh = np.linalg.norm(pinned[:, knee] - pinned[:, hip], axis=-1)
        assert np.ptp(thigh[contact.any(1)]) < 0.02  # the leg keeps its length (bent, not stretched)


def test_render_world_draws_the_grounded_clip(dance: np.ndarray, tmp_path: Path) -> None:
    import cv2

    from pipeline.motion.motionfile import MotionClip, write_motion

    cam, _ = _pitched_view(dance[:30], 5.0)
    clip = MotionClip("vid_000_1_0", 1, np.arange(30, dtype=np.int32), np.arange(30) / 24.0,
                      cam.astype(np.float32), np.zeros(30, bool), np.zeros(30, np.int8))
    motion = tmp_path / "vid_000.parquet"
    write_motion(motion, [clip], {"segment_id": "vid_000", "fps": 24.0, "width": 1920, "height": 1080},
                 fingerprint="x", params={}, inputs={})
    assert main(["--root", str(tmp_path), "render", str(motion), "vid_000_1_0", str(tmp_path / "w.mp4"),
                 "--world"]) == 0
    video = cv2.VideoCapture(str(tmp_path / "w.mp4"))
    ok, frame = video.read()
    assert ok and frame.shape == (480, 960, 3) and int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == 30
    assert (np.abs(frame.astype(int) - 24).sum(-1) > 60).mean() > 0.01  # a grid and a skeleton drawn


def test_with_heels_and_toes_the_floor_is_under_the_feet_and_a_foot_on_its_ball_stands(mocap_dir: Path) -> None:
    from pipeline.motion.world.contact import foot_contact
    from pipeline.motion.world.gravity import FOOT_POINT_HEIGHT
    from pipeline.motion.world.grounding import ground_clip

    seq = load_source(mocap_dir, "dancedb_ucy")[0]
    fps = seq.fps / 2
    joints, feet = seq.h36m[::2], seq.feet[::2]
    cam, _ = _pitched_view(np.concatenate([joints, feet], 1), 0.0)
    world, _ = to_world(cam, root=joints[:, 0] - joints[0, 0])
    lowest = world[:, 17:, 1].min(1)
    assert abs(np.percentile(lowest, 5) - FOOT_POINT_HEIGHT) < 1e-9  # the feet, not the ankles, meet the floor
    # Standing still on the left foot's ball: the ankle 12 cm up (no contact by the ankle rule), the toe down.
    raised = np.repeat(world[:1], 20, axis=0)
    raised[:, [4, 5, 6, 17], 1] += 0.12
    raised[:, 6, 1] = ANKLE_HEIGHT + 0.12
    raised[:, 19, 1] = FOOT_POINT_HEIGHT
    by_ankle = foot_contact(raised[:, :17], fps)
    by_feet = foot_contact(raised[:, :17], fps, feet=raised[:, 17:])
    assert not by_ankle[:, 0].any() and by_feet[:, 0].all()
    # Grounding carries the feet with their ankles through the one skeleton and the pinning.
    grounded = ground_clip(cam[:, :17], joints[:, 0] - joints[0, 0] + [0.0, 0.0, 4.0], fps, cam[:, 17:])
    assert grounded.feet.shape == (len(joints), 4, 3)
    for side, (ankle, heel, toe) in enumerate(((6, 17, 19), (3, 18, 20))):
        heel_len = np.linalg.norm(grounded.feet[:, side] - grounded.joints[:, ankle], axis=-1)
        truth = np.linalg.norm(feet[:, side] - joints[:, ankle], axis=-1)
        assert np.abs(np.median(heel_len) - np.median(truth)) < 0.01


def test_render_and_export_given_a_world_file_without_smpl_say_which_file_to_give(tmp_path: Path, capsys) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    world = tmp_path / "vid_000.parquet"
    pq.write_table(pa.table({"clip_id": ["vid_000_1_0"], "smpl_poses": [[0.0] * 72]}), world)
    other = tmp_path / "other.parquet"
    pq.write_table(pa.table({"clip_id": ["vid_000_1_0"], "x": [1.0]}), other)
    assert main(["render", str(world), "vid_000_1_0", str(tmp_path / "w.mp4"), "--world"]) == 2
    err = capsys.readouterr().err
    assert str(world) in err and "world file" in err and "--smpl" in err and "data/motion24" in err
    assert "Traceback" not in err and "KeyError" not in err
    assert main(["export", "bvh", str(world), "--all", str(tmp_path / "bvh")]) == 2
    err = capsys.readouterr().err
    assert str(world) in err and "world file" in err and "Traceback" not in err and "KeyError" not in err
    assert main(["render", str(other), "vid_000_1_0", str(tmp_path / "w.mp4")]) == 2
    err = capsys.readouterr().err
    assert str(other) in err and "not a motion file" in err and "joints" in err
