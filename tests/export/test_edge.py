"""EDGE's prepared layout: its slicing rule, its 151-d motion vector with dance3d's contacts, and its
35-d music features with dance3d's beats."""

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.export.edge import EDGE_FPS, FEATURE_SR, Z_UP, edge_features, music_features, slice_starts
from pipeline.motion.smpl.kinematics import from_axis_angle


def test_slices_are_five_seconds_every_half_second_while_a_whole_one_fits():
    assert slice_starts(600, 60.0, 5.0, 0.5) == [0, 30, 60, 90, 120, 150, 180, 210, 240, 270, 300]
    assert slice_starts(299, 60.0, 5.0, 0.5) == []


def test_the_motion_vector_is_contacts_root_and_6d_rows_turned_z_up():
    frames = 4
    rng = np.random.default_rng(0)
    poses = Rotation.random(frames * 24, random_state=1).as_rotvec().reshape(frames, 72)
    trans = rng.normal(size=(frames, 3))
    planted = rng.random((frames, 4)) > 0.5
    vec = edge_features(poses, trans, 2.0, planted)
    assert vec.shape == (frames, 151) and vec.dtype == np.float32
    assert (vec[:, :4] == planted).all()
    assert np.allclose(vec[:, 4:7], np.stack([trans[:, 0], -trans[:, 2], trans[:, 1]], 1) / 2.0, atol=1e-6)
    six = vec[:, 7:].reshape(frames, 24, 2, 3)
    local = from_axis_angle(poses)
    assert np.allclose(six[:, 1:], local[:, 1:, :2, :], atol=1e-6)        # joints below the root: as they are
    assert np.allclose(six[:, 0], (Z_UP @ local[:, 0])[:, :2, :], atol=1e-6)  # the root turned with the world
    up = (Z_UP @ local[:, 0]) @ np.array([0.0, 1.0, 0.0])  # the body's y axis in z-up coordinates
    assert np.allclose(up, (local[:, 0] @ np.array([0.0, 1.0, 0.0])) @ Z_UP.T)


def test_music_features_are_edges_35_columns_with_the_beats_given():
    seconds, start = 5.0, 10.0
    t = np.arange(int(seconds * FEATURE_SR)) / FEATURE_SR
    clicks = (np.sin(2 * np.pi * 440 * t) * (np.mod(t, 0.5) < 0.03)).astype(np.float32)
    beats = start + np.array([0.5, 1.0, 2.0, 4.9, 7.0])  # the last falls after the slice
    feats = music_features(clicks, beats, start)[: int(seconds * EDGE_FPS)]
    assert feats.shape == (150, 35)
    assert list(np.flatnonzero(feats[:, 34])) == [15, 30, 60, 147]
    peaks = np.flatnonzero(feats[:, 33]) / EDGE_FPS  # onset peaks: one at each click (every 0.5 s)
    assert all(np.abs(peaks - click).min() < 0.05 for click in np.arange(0.5, 5.0, 0.5))
