"""Adapting the lifter to dance video: VideoPose3D's semi-supervised recipe (lifting/adapt.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch

from pipeline.core.errors import InputError
from pipeline.motion.lifting.adapt import (
    AdaptConfig,
    VideoClip,
    VideoSampler,
    adapt_lifter,
    bone_prior,
    reprojection_error,
    video_reprojection,
)
from pipeline.motion.lifting.convert import model_from_onnx
from pipeline.motion.lifting.data import AugmentOptions, PairSampler, film
from pipeline.motion.lifting.geometry import normalise_centred
from pipeline.motion.lifting.model import TemporalModel
from pipeline.motion.lifting.train import export_onnx
from pipeline.motion.mocap.skeleton import coco_from_h36m
from pipeline.motion.mocap.sources import MocapSequence
from pipeline.motion.shipped import SHIPPED_LIFTER


def _dancer(frames: int = 150, seed: int = 0) -> MocapSequence:
    """A standing body whose arms swing and whose hips sway, with heels and toes."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 25.0
    rest = np.array([[0, 1.0, 0], [-.12, 1.0, 0], [-.12, .55, 0], [-.12, .1, 0], [.12, 1.0, 0], [.12, .55, 0],
                     [.12, .1, 0], [0, 1.25, 0], [0, 1.5, 0], [0, 1.6, .05], [0, 1.72, 0], [.18, 1.48, 0],
                     [.45, 1.48, 0], [.7, 1.48, 0], [-.18, 1.48, 0], [-.45, 1.48, 0], [-.7, 1.48, 0]])
    h36m = np.repeat(rest[None], frames, 0)
    swing = 0.4 * np.sin(2 * np.pi * (0.7 + 0.2 * rng.random()) * t)
    for elbow, wrist, side in ((12, 13, 1), (15, 16, -1)):
        h36m[:, elbow, 1] -= 0.2 * (1 + swing)
        h36m[:, wrist, 1] -= 0.4 * (1 + side * swing)
        h36m[:, wrist, 2] += 0.3 * swing
    h36m[..., 0] += 0.05 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    feet = np.stack([h36m[:, 6] + [0, -.08, -.05], h36m[:, 3] + [0, -.08, -.05],
                     h36m[:, 6] + [0, -.08, .15], h36m[:, 3] + [0, -.08, .15]], 1)
    return MocapSequence("mine/dance", "mine", 25.0, h36m, coco_from_h36m(h36m), feet)


def _filmed_clip(seq: MocapSequence, seed: int) -> tuple[np.ndarray, np.ndarray]:
    shot = film(seq, seq.frames, np.random.default_rng(seed), AugmentOptions(), augment=False, feet=True)
    return shot.xy, shot.h36m_cam - shot.h36m_cam[:, :1]


def test_a_shipped_lifter_read_back_from_its_onnx_lifts_as_onnx_runtime_does() -> None:
    model = model_from_onnx(SHIPPED_LIFTER)
    session = ort.InferenceSession(str(SHIPPED_LIFTER))
    x = np.random.default_rng(0).normal(0, 0.5, (1, 100, 21, 2)).astype(np.float32)
    (expected,) = session.run(None, {session.get_inputs()[0].name: x})
    with torch.no_grad():
        assert np.abs(model(torch.from_numpy(x)).numpy() - expected).max() < 1e-4


def test_reading_an_onnx_that_is_no_lifter_names_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "lifter.onnx"
    bad.write_bytes(b"not onnx")
    with pytest.raises(InputError, match="lifter.onnx"):
        model_from_onnx(bad)


def test_true_3d_reprojects_onto_its_own_2d_and_the_pose_of_half_a_swing_later_does_not() -> None:
    xy, pose = _filmed_clip(_dancer(), seed=3)
    target = torch.tensor(normalise_centred(xy, 27), dtype=torch.float32)
    weight = torch.ones(target.shape[:2])
    true = reprojection_error(torch.tensor(pose, dtype=torch.float32), target, weight)
    later = reprojection_error(torch.tensor(np.roll(pose, 15, axis=0), dtype=torch.float32), target, weight)
    assert float(true.median()) < 0.04           # what remains is perspective: body sizes
    assert float(later.median()) > 3 * float(true.median())
    # weak perspective: neither the pose's size nor its depth's sign can be told from the 2D
    for seen_alike in (2.0 * pose, pose * np.array([1.0, 1.0, -1.0])):
        alike = reprojection_error(torch.tensor(seen_alike, dtype=torch.float32), target, weight)
        assert torch.allclose(alike, true, atol=1e-5)


def test_a_joint_of_no_confidence_does_not_count() -> None:
    xy, pose = _filmed_clip(_dancer(), seed=3)
    target = normalise_centred(xy, 27)
    weight = np.ones(target.shape[:2], np.float32)
    moved = target.copy()
    moved[:, 9] += 5.0  # a wrist far off
    weight[:, 9] = 0.0
    as_is = reprojection_error(torch.tensor(pose).float(), torch.tensor(target).float(), torch.tensor(weight))
    off = reprojection_error(torch.tensor(pose).float(), torch.tensor(moved).float(), torch.tensor(weight))
    assert torch.allclose(as_is, off, atol=1e-6)


def test_the_bone_prior_asks_the_video_bodies_for_the_captures_bone_lengths() -> None:
    pose = torch.tensor(_filmed_clip(_dancer(), seed=1)[1]).float()
    assert float(bone_prior(pose, pose)) < 1e-7
    assert float(bone_prior(0.8 * pose, pose)) > 0.01


def test_video_windows_are_fixed_by_the_step_and_their_targets_are_the_frames_the_lifter_returns() -> None:
    xy, _ = _filmed_clip(_dancer(), seed=2)
    clip = VideoClip("seg/0", xy, np.ones(xy.shape[:2]), 25.0)
    sampler = VideoSampler([clip], length=27 + 15, receptive_field=27, seed=4)
    inputs, targets, weights = sampler.batch(8, step=11)
    again = sampler.batch(8, step=11)
    assert all(np.array_equal(a, b) for a, b in zip((inputs, targets, weights), again))
    assert inputs.shape == (8, 42, 21, 2) and targets.shape == (8, 16, 21, 2) and weights.shape == (8, 16, 21)
    assert np.array_equal(targets, inputs[:, 13: 29])
    assert not np.array_equal(sampler.batch(8, step=12)[0], inputs)


def _tiny_lifter() -> TemporalModel:
    torch.manual_seed(0)
    return TemporalModel(21, 21, (3, 3, 3), 64, 0.1).eval()


def test_adapting_makes_the_lift_explain_the_video_2d_better_than_the_capture_alone_does() -> None:
    capture = PairSampler([_dancer(seed=0)], 27 + 15, AugmentOptions(), 0, "centred", 27, feet=True)
    xy, _ = _filmed_clip(_dancer(seed=5), seed=7)
    video = [VideoClip("seg/0", xy, np.ones(xy.shape[:2]), 25.0)]
    cfg = AdaptConfig(steps=40, batch=8, video_batch=8, lr=1e-3, lr_final=1e-3, threads=1)
    control = adapt_lifter(_tiny_lifter(), AdaptConfig(**{**cfg.__dict__, "reprojection_weight": 0.0,
                                                             "bone_weight": 0.0}), capture, None, progress=False)
    adapted = adapt_lifter(_tiny_lifter(), cfg, capture, VideoSampler(video, 42, 27, 0), progress=False)
    assert not control.losses["reprojection"] and len(adapted.losses["reprojection"]) == 40
    assert video_reprojection(adapted.model, video)["seg/0"] < video_reprojection(control.model, video)["seg/0"]


def test_an_exported_adapted_lifter_reads_back_as_it_was(tmp_path: Path) -> None:
    capture = PairSampler([_dancer()], 27 + 15, AugmentOptions(), 0, "centred", 27, feet=True)
    model = adapt_lifter(_tiny_lifter(), AdaptConfig(steps=3, batch=4, threads=1), capture, None,
                         progress=False).model
    export_onnx(model, tmp_path / "lifter.onnx", input_norm="centred")
    x = torch.from_numpy(np.random.default_rng(1).normal(0, 0.5, (1, 60, 21, 2)).astype(np.float32))
    with torch.no_grad():
        assert torch.allclose(model_from_onnx(tmp_path / "lifter.onnx")(x), model(x), atol=1e-4)
