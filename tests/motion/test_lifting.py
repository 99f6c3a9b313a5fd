"""The VideoPose3D-style lifter: architecture, official-checkpoint conversion, training, inference."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch

from pipeline.core.errors import InputError
from pipeline.motion.lifting.convert import convert_videopose3d, infer_architecture
from pipeline.motion.lifting.evaluate import split
from pipeline.motion.lifting.geometry import mpjpe, n_mpjpe, p_mpjpe
from pipeline.motion.lifting.infer import Lifter, fill_low_confidence
from pipeline.motion.lifting.model import TemporalModel
from pipeline.motion.lifting.train import LifterConfig, checkpoint_path, export_onnx, load_mocap, train_lifter
from pipeline.motion.mocap.skeleton import bone_lengths
from pipeline.motion.quality import LIMBS


def test_official_coco_architecture_has_the_documented_size() -> None:
    model = TemporalModel(17, 17, (3, 3, 3, 3, 3), 1024)
    assert model.receptive_field == 243
    assert sum(p.numel() for p in model.parameters()) == 16_952_371  # MODELS.md §4
    assert model.pad == [1, 3, 9, 27, 81]
    out = model.eval()(torch.zeros(2, 250, 17, 2))
    assert out.shape == (2, 250 - 242, 17, 3)


def _official_checkpoint(path: Path, filter_widths=(3, 3, 3, 3, 3), channels: int = 1024) -> Path:
    torch.manual_seed(1)
    model = TemporalModel(17, 17, filter_widths, channels)
    with torch.no_grad():  # non-trivial BatchNorm statistics, as a trained checkpoint has
        for name, buffer in model.named_buffers():
            if name.endswith("running_mean"):
                buffer.normal_(0, 0.1)
            elif name.endswith("running_var"):
                buffer.uniform_(0.5, 1.5)
    torch.save({"epoch": 80, "lr": 1e-5, "model_pos": model.state_dict(), "optimizer": {}}, path)
    return path


def test_converter_round_trip_matches_torch(tmp_path: Path) -> None:
    checkpoint = _official_checkpoint(tmp_path / "pretrained_h36m_detectron_coco.bin")
    model = convert_videopose3d(checkpoint, tmp_path / "lifter.onnx")
    session = ort.InferenceSession(str(tmp_path / "lifter.onnx"))
    assert session.get_modelmeta().custom_metadata_map["receptive_field"] == "243"
    x = np.random.default_rng(0).normal(0, 0.5, (1, 260, 17, 2)).astype(np.float32)
    (onnx_out,) = session.run(None, {"keypoints2d": x})
    with torch.no_grad():
        torch_out = model(torch.from_numpy(x)).numpy()
    assert onnx_out.shape == (1, 18, 17, 3)
    assert np.abs(onnx_out - torch_out).max() < 1e-4


def test_converter_rejects_a_wrong_layout_with_the_reason(tmp_path: Path) -> None:
    state = TemporalModel(17, 17, (3, 3, 3), 64).state_dict()
    del state["layers_bn.1.running_var"]
    state["shrink.bias"] = torch.zeros(50)
    torch.save({"model_pos": state}, tmp_path / "bad.bin")
    with pytest.raises(InputError) as err:
        convert_videopose3d(tmp_path / "bad.bin", tmp_path / "out.onnx")
    message = str(err.value)
    assert message.startswith(f"{tmp_path / 'bad.bin'}: wrong checkpoint layout: missing layers_bn.1.running_var")
    assert "wrong shape shrink.bias (50,) (expected (51,))" in message
    assert not (tmp_path / "out.onnx").exists()


def test_converter_rejects_files_that_are_not_checkpoints(tmp_path: Path) -> None:
    torch.save({"state_dict": {}}, tmp_path / "other.bin")
    with pytest.raises(InputError, match=r"other\.bin: not a VideoPose3D checkpoint: no 'model_pos' entry"):
        convert_videopose3d(tmp_path / "other.bin", tmp_path / "out.onnx")
    (tmp_path / "junk.bin").write_bytes(b"junk")
    with pytest.raises(InputError, match=r"junk\.bin: cannot read the checkpoint"):
        convert_videopose3d(tmp_path / "junk.bin", tmp_path / "out.onnx")
    with pytest.raises(ValueError, match="missing 'expand_conv.weight'"):
        infer_architecture({"shrink.weight": torch.zeros(51, 8, 1)})


def test_p_mpjpe_ignores_rotation_scale_and_translation() -> None:
    rng = np.random.default_rng(0)
    target = rng.normal(size=(5, 17, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    pred = 1.7 * target @ q + np.array([0.3, -2.0, 5.0])
    assert p_mpjpe(pred, target) < 1e-9


def test_n_mpjpe_forgives_the_size_alone() -> None:
    """A child lifted at an adult's size: all of MPJPE is scale, none of N-MPJPE; a turn is not forgiven."""
    target = np.random.default_rng(0).normal(size=(5, 17, 3))
    assert n_mpjpe(1.4 * target, target) < 1e-9 < 0.1 < mpjpe(1.4 * target, target)
    turned = target[..., [2, 1, 0]] * [1.0, 1.0, -1.0]
    assert n_mpjpe(turned, target) > 0.5


def test_low_confidence_joints_are_interpolated_over_time() -> None:
    kps = np.zeros((5, 17, 3))
    kps[:, :, 0] = np.arange(5)[:, None] * 10.0
    kps[:, :, 2] = 0.9
    kps[2, 3] = [999.0, 999.0, 0.05]
    filled, mask = fill_low_confidence(kps, 0.3)
    assert filled[2, 3, 0] == pytest.approx(20.0) and filled[2, 3, 1] == pytest.approx(0.0)
    assert mask.sum() == 1 and mask[2, 3]


@pytest.fixture(scope="module")
def tiny_lifter(mocap_dir: Path, tmp_path_factory) -> tuple:
    cfg = LifterConfig(steps=400, channels=128, sources=("bandai_namco_1", "perfume", "dancedb_ucy",
                                                         "cmu_subject05_iclone"))
    train, val = split(load_mocap(mocap_dir, cfg), cfg.holdout)
    result = train_lifter(cfg, train, val)
    path = tmp_path_factory.mktemp("lifter") / "lifter.onnx"
    export_onnx(result.model, path)
    return result, path


def test_trained_lifter_beats_the_mean_pose_on_held_out_mocap(tiny_lifter: tuple) -> None:
    result, _ = tiny_lifter
    metrics = result.metrics
    assert metrics["val_sequences"] >= 4
    assert metrics["val_mpjpe_mm"] < 0.8 * metrics["mean_pose_mpjpe_mm"], metrics
    assert metrics["val_p_mpjpe_mm"] < metrics["val_mpjpe_mm"]
    assert np.mean(result.losses[-50:]) < 0.5 * np.mean(result.losses[:50])


def test_lifting_the_dance_clip_gives_plausible_skeletons(tiny_lifter: tuple, dance_clip: Path,
                                                          models_dir: Path) -> None:
    from pipeline.ingest.media import probe
    from pipeline.ingest.segmentvideo import SegmentVideo
    from pipeline.pose.models.detector import RTMDetDetector
    from pipeline.pose.models.pose import MoveNetPose
    from pipeline.pose.models.session import create_session
    from pipeline.pose.pose2d import Pose2dOptions, estimate_segment

    _, path = tiny_lifter
    det = RTMDetDetector(create_session(models_dir / "rtmdet_nano_person_end2end.onnx"))
    pose = MoveNetPose(create_session(models_dir / "movenet_singlepose_lightning_4_dequant.onnx"))
    view = SegmentVideo.whole(dance_clip, probe(dance_clip))  # 2D as the stage makes it: keyframes at 8 a second
    kps = np.stack([fp.keypoints[0] for fp in estimate_segment(view, 24.0, det, pose, Pose2dOptions(fps=8))
                    if len(fp.scores)])
    filled, _ = fill_low_confidence(kps, 0.3)
    lifter = Lifter.from_session(ort.InferenceSession(str(path)))
    (joints,) = lifter.lift([filled], 1080, 1920, flip=True)
    assert joints.shape == (len(kps), 17, 3) and np.isfinite(joints).all()
    assert np.abs(joints[:, 0]).max() < 1e-3  # root-relative
    # Right thigh, shin, left thigh, shin, then left upper arm, forearm, right upper arm, forearm.
    limbs = np.median(bone_lengths(joints)[:, LIMBS], 0)
    assert np.all((limbs[:4] > 0.25) & (limbs[:4] < 0.6)), limbs  # legs of a human size (m)
    assert np.all((limbs[4:] > 0.1) & (limbs[4:] < 0.45)), limbs  # arms (a tiny model shortens forearms)
    assert 0.6 < limbs[0] / limbs[2] < 1.6 and 0.6 < limbs[4] / limbs[6] < 1.6  # left and right agree
    # Camera frame, y down: the head is above the pelvis and the ankles below it.
    assert (joints[:, 10, 1] < joints[:, 0, 1]).mean() > 0.95
    assert (joints[:, 3, 1] > joints[:, 0, 1]).mean() > 0.95


def test_clips_lifted_together_equal_clips_lifted_alone(tiny_lifter: tuple) -> None:
    _, path = tiny_lifter
    lifter = Lifter.from_session(ort.InferenceSession(str(path)))
    rng = np.random.default_rng(0)
    a, b = rng.uniform(100, 600, (40, 17, 2)), rng.uniform(100, 600, (9, 17, 2))
    together = lifter.lift([a, b], 640, 720)
    alone = lifter.lift([a], 640, 720) + lifter.lift([b], 640, 720)
    for x, y in zip(together, alone):
        assert np.abs(x - y).max() < 1e-5


def test_centred_input_ignores_where_and_how_large_the_dancer_is_in_the_image() -> None:
    from pipeline.motion.lifting.geometry import normalise

    xy = np.random.default_rng(0).uniform(100, 300, (40, 17, 2))
    moved = xy * 2.5 + np.array([700.0, -40.0])
    a = normalise(xy, 1920, 1080, "centred", 27)
    b = normalise(moved, 1080, 1920, "centred", 27)
    assert np.abs(a - b).max() < 1e-9
    assert np.abs((a[:, 11] + a[:, 12]) / 2).max() < 1e-9  # the hips' midpoint is the origin
    with pytest.raises(ValueError, match="unknown input normalisation 'pixels'"):
        normalise(xy, 1920, 1080, "pixels", 27)


def test_the_exported_lifter_lifts_as_the_torch_model_does(tmp_path: Path) -> None:
    torch.manual_seed(0)
    model = TemporalModel(17, 17, (3, 3), 32).eval()
    export_onnx(model, tmp_path / "lifter.onnx", input_norm="centred")
    session = ort.InferenceSession(str(tmp_path / "lifter.onnx"))
    onnx_lifter = Lifter.from_session(session)
    assert onnx_lifter.input_norm == "centred" and onnx_lifter.receptive_field == 9
    clip = np.random.default_rng(1).uniform(200, 900, (30, 17, 2))
    (a,) = onnx_lifter.lift([clip], 1080, 1920, flip=True)
    (b,) = Lifter.from_torch(model, "centred").lift([clip], 1080, 1920, flip=True)
    assert np.abs(a - b).max() < 1e-4


def test_a_lifter_with_feet_takes_and_returns_heels_and_toes_and_mirrors_them(tmp_path: Path) -> None:
    from pipeline.motion.mocap.skeleton import COCO21_FLIP, H36M21_FLIP

    torch.manual_seed(0)
    export_onnx(TemporalModel(21, 21, (3, 3), 32).eval(), tmp_path / "feet.onnx", input_norm="centred")
    session = ort.InferenceSession(str(tmp_path / "feet.onnx"))
    meta = session.get_modelmeta().custom_metadata_map
    assert (meta["joints_in"], meta["joints_out"]) == ("coco17+feet", "h36m17+feet")
    lifter = Lifter.from_session(session)
    assert lifter.feet
    clip = np.random.default_rng(2).uniform(200, 900, (30, 21, 2))
    (out,) = lifter.lift([clip], 1080, 1920, flip=True)
    assert out.shape == (30, 21, 3)
    # Mirroring the image mirrors the body, the heels and the toes: left becomes right.
    mirrored = np.stack([1080 - clip[..., 0], clip[..., 1]], -1)[:, list(COCO21_FLIP)]
    (back,) = lifter.lift([mirrored], 1080, 1920, flip=True)
    np.testing.assert_allclose((back * [-1, 1, 1])[:, list(H36M21_FLIP)], out, atol=1e-5)


def test_feet_a_pose_model_never_saw_stand_at_the_ankles() -> None:
    from pipeline.motion.lifting.infer import with_feet

    keypoints = np.random.default_rng(0).uniform(0, 500, (10, 17, 3))
    feet = np.zeros((10, 4, 3))
    feet[:, 1] = [300.0, 400.0, 0.9]  # only the right heel was seen
    both = with_feet(keypoints, feet)
    assert both.shape == (10, 21, 3)
    np.testing.assert_array_equal(both[:, 18], feet[:, 1])
    np.testing.assert_array_equal(both[:, [17, 19, 20], :2], keypoints[:, [15, 15, 16], :2])
    assert (both[:, [17, 19, 20], 2] == 0).all()


def test_the_train_lifter_stage_uses_the_shipped_lifter_by_default(tmp_path: Path) -> None:
    from stages.train_lifter import SHIPPED, run
    from tests.conftest import PROJECT

    (tmp_path / "params.yaml").write_text((PROJECT / "params.yaml").read_text())
    run(tmp_path)  # no motion capture, no training
    assert (tmp_path / "models/lifter.onnx").read_bytes() == SHIPPED.read_bytes()
    metrics = json.loads((tmp_path / "reports/lifter.json").read_text())
    assert metrics["shipped"] is True and metrics["val_p_mpjpe_mm"] > 0
    assert (tmp_path / "metrics/lifter_loss.csv").read_text().startswith("step,train_mpjpe_mm\n0,")


def test_the_shipped_lifter_says_what_made_it_and_holds_its_figures_on_held_out_performers(mocap_dir: Path) -> None:
    from pipeline.motion.lifting.evaluate import HOLDOUT, evaluate_onnx
    from stages.train_lifter import SHIPPED

    meta = ort.InferenceSession(str(SHIPPED)).get_modelmeta().custom_metadata_map
    trained_on, params = json.loads(meta["trained_on"]), json.loads(meta["params"])
    assert all(name.startswith(HOLDOUT) for name in trained_on["heldout"])
    assert "choreonet_c3d" in trained_on["train_minutes_per_source"] and len(meta["git_commit"]) == 40
    assert params["steps"] == int(meta["steps"]) and meta["input_norm"] == params["input_norm"]
    assert params["feet"] and meta["joints_in"] == "coco17+feet" and meta["joints_out"] == "h36m17+feet"
    result = evaluate_onnx(SHIPPED, mocap_dir)
    assert result["protocol"]["split"].startswith("held-out")
    clean = result["clean"]
    # Issue 14's target: P-MPJPE <= 70 and MPJPE <= 100 mm on clean 2D (measured 54.1 and 91.8).
    assert clean["p_mpjpe_mm"] <= 70 and clean["mpjpe_mm"] <= 100, clean
    assert result["noisy"]["p_mpjpe_mm"] < clean["mean_pose_p_mpjpe_mm"] / 2
    # Scale alone is most of MPJPE's gap (the held-out child is lifted 1.4x her size): N-MPJPE 78.9.
    assert clean["p_mpjpe_mm"] < clean["n_mpjpe_mm"] < clean["mpjpe_mm"] - 10
    assert result["sources"]["animated_drawings_fair"]["clean"]["n_mpjpe_mm"] < 80
    # The heels and toe tips: under half the mean pose's error (measured 141.8 against 298.0 mm).
    assert clean["feet_mpjpe_mm"] < clean["mean_pose_feet_mpjpe_mm"] / 2
    # The figures recorded at training are the ones measured here.
    recorded = json.loads(meta["metrics"])
    for key, measured in (("val_p_mpjpe_mm", clean["p_mpjpe_mm"]), ("val_mpjpe_mm", clean["mpjpe_mm"]),
                          ("val_feet_mpjpe_mm", clean["feet_mpjpe_mm"])):
        assert abs(recorded[key] - measured) < 0.5, key


def test_the_train_lifter_stage_trains_a_profile_and_records_what_made_it(tmp_path: Path, mocap_dir: Path) -> None:
    import yaml

    from stages.train_lifter import run
    from tests.conftest import PROJECT

    params = yaml.safe_load((PROJECT / "params.yaml").read_text())
    params["train_lifter"].update(shipped=False, profile="short", steps=30, channels=32, mocap=str(mocap_dir),
                                  sources=["perfume", "dancedb_ucy"], eval_seconds=5)
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    run(tmp_path)
    metrics = json.loads((tmp_path / "reports/lifter.json").read_text())
    assert metrics["steps"] == 30 and metrics["val_p_mpjpe_mm"] > 0 and "shipped" not in metrics
    assert set(metrics["heldout"]["sources"]) == {"perfume", "dancedb_ucy"}
    meta = ort.InferenceSession(str(tmp_path / "models/lifter.onnx")).get_modelmeta().custom_metadata_map
    assert meta["input_norm"] == "centred" and json.loads(meta["params"])["channels"] == 32
    trained_on = json.loads(meta["trained_on"])
    assert set(trained_on["train_minutes_per_source"]) == {"perfume", "dancedb_ucy"}
    assert trained_on["heldout"] == ["perfume/kashiyuka", "dancedb_ucy/olivia"]


def test_training_twice_gives_the_same_lifter_bytes(mocap_dir: Path, tmp_path: Path) -> None:
    # What lets a profile regenerate the shipped lifter: seeded data, fixed steps, no time limit.
    cfg = LifterConfig(steps=20, channels=32, sources=("perfume", "dancedb_ucy"), eval_seconds=1)
    train, val = split(load_mocap(mocap_dir, cfg), cfg.holdout)
    for k in range(2):
        export_onnx(train_lifter(cfg, train, val[:1]).model, tmp_path / f"{k}.onnx", input_norm=cfg.input_norm)
    assert (tmp_path / "0.onnx").read_bytes() == (tmp_path / "1.onnx").read_bytes()


def test_training_stopped_and_resumed_gives_the_bytes_of_an_uninterrupted_run(mocap_dir: Path, tmp_path: Path) -> None:
    # A session stopped mid-training leaves a checkpoint; starting again resumes from it.
    cfg = LifterConfig(steps=20, channels=32, sources=("perfume", "dancedb_ucy"), eval_seconds=1)
    train, val = split(load_mocap(mocap_dir, cfg), cfg.holdout)
    whole = train_lifter(cfg, train, val[:1], evaluate_after=False, progress=False)
    export_onnx(whole.model, tmp_path / "whole.onnx", input_norm=cfg.input_norm)
    checkpoint = checkpoint_path(tmp_path / "checkpoints", cfg, train)
    stopped = train_lifter(cfg, train, val[:1], checkpoint=checkpoint, stop_after=7, evaluate_after=False,
                           progress=False)
    assert len(stopped.losses) == 7 and checkpoint.is_file()
    resumed = train_lifter(cfg, train, val[:1], checkpoint=checkpoint, evaluate_after=False, progress=False)
    export_onnx(resumed.model, tmp_path / "resumed.onnx", input_norm=cfg.input_norm)
    assert resumed.losses == whole.losses
    assert (tmp_path / "whole.onnx").read_bytes() == (tmp_path / "resumed.onnx").read_bytes()
    # Another config (or other data, or changed code) never resumes this run's checkpoint.
    assert checkpoint_path(tmp_path / "checkpoints", replace(cfg, steps=21), train) != checkpoint
    assert checkpoint_path(tmp_path / "checkpoints", cfg, train[1:]) != checkpoint


def test_source_weights_set_each_sources_share_of_the_windows(mocap_dir: Path) -> None:
    from pipeline.motion.lifting.data import AugmentOptions, PairSampler

    train, _ = split(load_mocap(mocap_dir, LifterConfig(sources=("perfume", "dancedb_ucy"))))
    plain = PairSampler(train, 27, AugmentOptions(), 0).share()
    weighted = PairSampler(train, 27, AugmentOptions(), 0, weights={"perfume": 0.5}).share()
    half = 0.5 * plain["perfume"]
    assert weighted["perfume"] == pytest.approx(half / (half + plain["dancedb_ucy"]))


def test_a_lifter_trains_with_feet_and_scores_them_apart_from_the_body(mocap_dir: Path) -> None:
    cfg = LifterConfig(steps=20, channels=32, sources=("perfume", "dancedb_ucy"), eval_seconds=2, feet=True)
    train, val = split(load_mocap(mocap_dir, cfg), cfg.holdout)
    result = train_lifter(cfg, train, val[:1])
    assert result.model.joints_in == result.model.joints_out == 21
    # The body on its 17 joints (comparable with any lifter); the heels and toes on their own, beside
    # the mean pose's (how well a full training does: the shipped lifter's test).
    assert {"val_mpjpe_mm", "val_feet_mpjpe_mm", "noisy_feet_mpjpe_mm", "mean_pose_feet_mpjpe_mm"} <= set(
        result.metrics)
    assert "feet_mpjpe_mm" in result.metrics["heldout"]["sources"]["perfume"]["clean"]
