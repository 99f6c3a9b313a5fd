"""Learned foot contact and the contact-aware world: labels, the model's inputs, the root refiner,
the floor from planted points, pinning, and the world evaluation on real motion capture."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest

from pipeline.motion.world.contact import capture_contact, pin_planted, planted_points
from pipeline.motion.world.contact_model import ContactModel, features
from pipeline.motion.world.gravity import up_from_contacts
from pipeline.motion.world.trajectory import refine_root

FPS = 25.0


def test_a_still_foot_on_the_floor_is_planted_a_raised_or_sliding_one_is_not() -> None:
    t = np.arange(100)
    feet = np.zeros((100, 4, 3))
    feet[:, :, 0] = [0.0, 0.3, 0.2, 0.5]         # four points apart on the floor
    feet[:, 1, 1] = 0.10                          # the right heel 10 cm up: not planted
    feet[:, 2, 2] = 0.5 * t / FPS                 # the left toe slides at 0.5 m/s: not planted
    planted = capture_contact(feet, FPS)
    assert planted[:, 0].all() and planted[:, 3].all()
    assert not planted[:, 1].any() and not planted[:, 2].any()


def test_single_frame_blips_are_not_steps() -> None:
    prob = np.zeros((20, 4))
    prob[5, 0] = 0.9          # one frame
    prob[10:14, 1] = 0.8      # four frames
    planted = planted_points(prob)
    assert not planted[:, 0].any() and planted[10:14, 1].all() and planted[:, 1].sum() == 4


def test_a_contact_holds_while_its_probability_stays_above_the_hold_level() -> None:
    prob = np.zeros((40, 4))
    prob[5:20, 0] = 0.2
    prob[10:14, 0] = 0.8      # a sure contact inside a longer, weaker one: held from 5 to 20
    prob[25:35, 1] = 0.3      # never sure: never planted, however long
    assert planted_points(prob, 0.4, 3)[:, 0].sum() == 4
    held = planted_points(prob, 0.4, 3, hold=0.1)
    assert held[5:20, 0].all() and held[:, 0].sum() == 15 and not held[:, 1].any()


def test_the_model_sees_motion_about_the_body_not_where_or_how_big_the_body_is_in_the_image() -> None:
    rng = np.random.default_rng(0)
    xy = rng.normal(0, 50, (40, 21, 2)) + 500
    moved = xy * 1.7 + np.array([120.0, -40.0])
    np.testing.assert_allclose(features(xy), features(moved), atol=1e-4)
    assert features(xy).shape == (40, 31, 21, 2)


def test_mirroring_the_clip_swaps_left_and_right_contact() -> None:
    def forward(x: np.ndarray) -> np.ndarray:  # "planted" = a heel stands outside its side of the hips
        return np.stack([x[:, 15, 17, 0], -x[:, 15, 18, 0], np.zeros(len(x)), np.zeros(len(x))], -1) * 10

    model = ContactModel(forward)
    rng = np.random.default_rng(1)
    xy = rng.normal(0, 30, (30, 21, 2)) + 400
    mirrored = xy * np.array([-1.0, 1.0])
    from pipeline.motion.mocap.skeleton import COCO21_FLIP

    a = model.probabilities(xy, FPS, flip=False)
    b = model.probabilities(mirrored[:, list(COCO21_FLIP)], FPS, flip=False)
    np.testing.assert_allclose(a[:, [1, 0, 3, 2]], b, atol=1e-6)


def test_a_clip_at_another_rate_is_scored_at_the_models_rate_and_brought_back() -> None:
    seen = []

    def forward(x: np.ndarray) -> np.ndarray:
        seen.append(len(x))
        return np.zeros((len(x), 4), np.float32)

    out = ContactModel(forward).probabilities(np.random.default_rng(2).normal(0, 1, (60, 21, 2)), 50.0, flip=False)
    assert out.shape == (60, 4) and np.allclose(out, 0.5)
    assert sum(seen) == 30  # 60 frames at 50 fps are 30 at 25 fps


def test_planted_feet_take_the_depth_jitter_out_of_the_root_path() -> None:
    rng = np.random.default_rng(3)
    n = 120
    true = np.column_stack([np.linspace(-0.3, 0.3, n), np.full(n, 0.2), np.full(n, 4.0)])  # walking across
    noisy = true * (1 + rng.normal(0, 0.05, (n, 1)))   # depth error moves the root along its ray
    foot = np.zeros((n, 1, 3))
    foot[:, 0] = np.array([0.0, 0.9, 4.0]) - true      # one point planted at a fixed spot for the whole clip
    refined = refine_root(noisy, foot, np.ones((n, 1), bool))
    raw_jitter = np.abs(np.diff(noisy[:, 2])).mean()
    assert np.abs(np.diff(refined[:, 2])).mean() < raw_jitter / 10
    assert np.abs(refined - true).mean() < np.abs(noisy - true).mean() / 2
    # Without contact the refiner only smooths the per-frame estimate: closer to the truth, not further.
    free = refine_root(noisy, foot, np.zeros((n, 1), bool))
    assert np.abs(free - true).mean() < np.abs(noisy - true).mean()


def test_where_planted_feet_are_seen_on_the_floor_takes_the_depth_drift_out_of_the_root_path() -> None:
    from pipeline.motion.world.trajectory import floor_anchors

    # A level camera 1.2 m above the floor (camera frame: y down, so the floor is y = 1.2) and a
    # dancer stepping toward it from 4 m to 2.5 m, left and right foot planted in turn.
    n = 120
    t = np.arange(n)
    true = np.column_stack([0.3 * np.sin(t / 15), np.full(n, 0.25), 4.0 - 1.5 * t / n])
    planted = np.zeros((n, 2), bool)
    feet = true[:, None] + np.array([[-0.1, 0.85, 0.0], [0.1, 0.85, 0.0]])   # lifted feet
    for k, start in enumerate(range(0, n, 30)):
        side = k % 2
        planted[start:start + 30, side] = True
        feet[start:start + 30, side] = true[start] + [0.2 * side - 0.1, 0.95, 0.0]  # on the floor, still
    points = feet - true[:, None]
    rays = feet / np.linalg.norm(feet, axis=-1, keepdims=True)
    # The per-frame root drifts slowly along its ray (+-12 cm): the planted feet's stillness cannot see it.
    noisy = true * (1 + 0.03 * np.sin(t / 40))[:, None]
    up, level = np.array([0.0, -1.0, 0.0]), -1.2
    still = refine_root(noisy, points, planted)
    floored = refine_root(noisy, points, planted, floor=floor_anchors(rays, points, planted, up, level))
    assert np.linalg.norm(still - true, axis=-1).mean() > 0.04
    assert np.linalg.norm(floored - true, axis=-1).mean() < 0.01
    # A ray that does not reach the floor ahead (a point seen above the horizon) gives no anchor.
    _, weight = floor_anchors(-rays, points, planted, up, level)
    assert not weight.any()


def test_the_floor_normal_comes_from_the_planted_points_where_they_spread() -> None:
    rng = np.random.default_rng(4)
    tilt = np.radians(12.0)
    up = np.array([0.0, -np.cos(tilt), -np.sin(tilt)])        # camera frame: y down, pitched 12 degrees
    across = np.array([1.0, 0.0, 0.0])
    along = np.cross(up, across)
    points = rng.uniform(-4, 4, (200, 1)) * across + rng.uniform(-4, 4, (200, 1)) * along + [0, 1.5, 4]
    body_up = np.array([0.0, -1.0, 0.0])                       # a level body guess, 12 degrees off
    estimate = up_from_contacts(points + rng.normal(0, 0.01, points.shape), body_up)
    assert np.degrees(np.arccos(estimate @ up)) < 1.0
    assert (up_from_contacts(points[:5], body_up) == body_up).all()  # too few points: the body's guess


def test_pinned_points_stand_still_on_the_floor_and_the_legs_keep_their_lengths(mocap_dir: Path) -> None:
    from pipeline.motion.mocap.sources import load_source, resample

    seq = resample(load_source(mocap_dir, "dancedb_ucy")[0], FPS)
    world = seq.h36m[:200] + np.random.default_rng(5).normal(0, 0.01, (200, 17, 3))
    feet = seq.feet[:200] + np.random.default_rng(6).normal(0, 0.01, (200, 4, 3))
    planted = capture_contact(seq.feet[:200], FPS)
    joints, pinned = pin_planted(world, feet, planted)
    for k in range(4):
        runs = np.flatnonzero(np.diff(np.concatenate([[0], planted[:, k].astype(int), [0]])))
        for a, b in zip(runs[::2], runs[1::2]):
            assert np.ptp(pinned[a:b, k], axis=0).max() < 1e-9 and abs(pinned[a, k, 1]) < 1e-9
    for hip, knee, ankle in ((4, 5, 6), (1, 2, 3)):
        thigh = np.linalg.norm(joints[:, knee] - joints[:, hip], axis=-1)
        assert np.ptp(thigh[planted.any(1)]) < 0.05


def test_the_shipped_contact_model_says_what_made_it_and_holds_its_figure(mocap_dir: Path) -> None:
    from pipeline.motion.lifting.evaluate import HOLDOUT, split
    from pipeline.motion.lifting.train import LifterConfig, load_mocap
    from pipeline.motion.world.contact_model import load_contact_model
    from pipeline.motion.world.contact_train import evaluate_contact
    from stages.train_contact import SHIPPED

    meta = ort.InferenceSession(str(SHIPPED)).get_modelmeta().custom_metadata_map
    trained_on, params = json.loads(meta["trained_on"]), json.loads(meta["params"])
    assert all(name.startswith(HOLDOUT) for name in trained_on["heldout"]) and len(meta["git_commit"]) == 40
    assert params["steps"] == int(meta["steps"])
    recorded = json.loads(meta["metrics"])
    # Re-measured on the held-out protocol: the figure in the metadata is the model's.
    _, val = split(load_mocap(mocap_dir, LifterConfig()))
    measured = evaluate_contact(load_contact_model(SHIPPED, 2), val, params["eval_seconds"], params["seed"] + 1)
    assert abs(measured["contact_f1"] - recorded["contact_f1"]) < 0.002
    assert measured["contact_f1"] > measured["heldout"]["all"]["f1_all_planted"] + 0.05


def test_training_twice_gives_the_same_contact_model_bytes(mocap_dir: Path, tmp_path: Path) -> None:
    from pipeline.motion.mocap.sources import load_source, resample
    from pipeline.motion.world.contact_train import ContactConfig, export_onnx, train_contact

    sequences = [resample(s, FPS) for s in load_source(mocap_dir, "perfume")]
    cfg = ContactConfig(steps=5, batch=4, eval_seconds=1)
    for k in range(2):
        export_onnx(train_contact(cfg, sequences[1:], sequences[:1]).model, tmp_path / f"{k}.onnx")
    assert (tmp_path / "0.onnx").read_bytes() == (tmp_path / "1.onnx").read_bytes()


def test_the_train_contact_stage_uses_the_shipped_model_by_default(tmp_path: Path) -> None:
    from stages.train_contact import SHIPPED, run
    from tests.conftest import PROJECT

    (tmp_path / "params.yaml").write_text((PROJECT / "params.yaml").read_text())
    run(tmp_path)
    assert (tmp_path / "models/contact.onnx").read_bytes() == SHIPPED.read_bytes()
    metrics = json.loads((tmp_path / "reports/contact.json").read_text())
    assert metrics["shipped"] is True and 0 < metrics["contact_f1"] <= 1
    assert (tmp_path / "metrics/contact_loss.csv").read_text().startswith("step,train_bce\n0,")


def test_eval_world_scores_the_corpus_path_against_the_path_without_learned_contact(mocap_dir: Path,
                                                                                   tmp_path: Path) -> None:
    from pipeline.cli import main
    from stages.train_contact import SHIPPED as CONTACT
    from stages.train_lifter import SHIPPED as LIFTER

    out = tmp_path / "world.json"
    assert main(["eval", "world", "--mocap", str(mocap_dir / "perfume"), "--model", str(LIFTER), "--contact",
                 str(CONTACT), "--seconds", "12", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    learned, baseline = result["learned"]["all"], result["baseline"]["all"]
    assert result["protocol"]["sequences"] == 1 and result["protocol"]["cameras"] == 10
    assert learned["contact_f1"] > 0.6 > baseline["contact_f1"]
    assert learned["foot_sliding_mm"] < baseline["foot_sliding_mm"] / 3
    assert learned["wa_mpjpe100_mm"] < baseline["wa_mpjpe100_mm"] and learned["jitter"] < baseline["jitter"] / 1.5
    assert learned["planted_height_mm"] < 20 < baseline["planted_height_mm"]
    assert result["protocol"]["denoise_2d"] == 10.0  # the lift stage's default, as the corpus is made
    assert result["protocol"]["contact_rules"] == {"threshold": 0.4, "min_frames": 3, "hold": 0.1}  # the ground stage's
    assert set(result["learned"]["by_pitch"]) == {"-20", "-10", "+0", "+10", "+20"}


def test_eval_world_and_eval_group_run_the_projects_own_lift_and_ground_params() -> None:
    from pipeline.motion.world.evaluate import path_from_params

    params = {"lift": {"min_score": 0.5, "flip_tta": False, "denoise_2d": 3.0},
              "ground": {"contact_threshold": 0.6, "min_contact_frames": 5, "contact_hold": 0.2}}
    lift, rules = path_from_params(params)
    assert (lift.min_score, lift.flip, lift.denoise) == (0.5, False, 3.0)
    assert (rules.threshold, rules.min_frames, rules.hold) == (0.6, 5, 0.2)
    assert path_from_params(params, denoise=0.0)[0].denoise == 0.0  # --denoise-2d
    assert path_from_params({})[0].denoise == 0.0  # a project from before lift.denoise_2d keeps its 2D as it was


def test_the_ground_stage_writes_world_files_that_read_back_and_skips_them_when_up_to_date(mocap_dir: Path,
                                                                                          tmp_path: Path) -> None:
    from pipeline.core.paths import MOTION24, WORLD
    from pipeline.core.storage import read_meta
    from pipeline.motion.lifting.evaluate import PROTOCOL_CAMERAS, view
    from pipeline.motion.mocap.sources import load_source, resample
    from pipeline.motion.motionfile import MotionClip, write_motion
    from pipeline.motion.world.worldfile import read_world
    from stages.ground import run
    from tests.conftest import PROJECT

    seq = resample(load_source(mocap_dir, "perfume")[0], 24.0)
    n = 96
    _, cam = view(np.concatenate([seq.h36m, seq.feet], 1)[:n], np.concatenate([seq.coco, seq.feet], 1)[:n],
                  PROTOCOL_CAMERAS[0])
    rel = (cam - cam[:, :1]).astype(np.float32)
    planted = capture_contact(seq.feet[:n], 24.0).astype(np.float32)
    clips = [MotionClip("vid_000_1_0", 1, np.arange(n, dtype=np.int32), np.arange(n) / 24.0, rel[:, :17],
                        np.zeros(n, bool), np.zeros(n, np.int8), cam[:, 0].astype(np.float32), rel[:, 17:],
                        0.1 + 0.8 * planted, (cam[:, 17:] / np.linalg.norm(cam[:, 17:], axis=-1, keepdims=True))),
             MotionClip("vid_000_2_0", 2, np.arange(n, dtype=np.int32), np.arange(n) / 24.0, rel[:, :17],
                        np.zeros(n, bool), np.zeros(n, np.int8))]  # no root, feet or contact: the older rules
    (tmp_path / MOTION24).mkdir(parents=True)
    write_motion(tmp_path / MOTION24 / "vid_000.parquet", clips, {"segment_id": "vid_000", "fps": 24.0,
                 "width": 1080, "height": 1920}, fingerprint="m24", params={}, inputs={})
    (tmp_path / "params.yaml").write_text((PROJECT / "params.yaml").read_text())
    run(tmp_path)
    learned, older = read_world(tmp_path / WORLD / "vid_000.parquet")
    assert learned.joints.shape == (n, 17, 3) and learned.rotations_6d.shape == (n, 23, 6)
    assert (learned.planted == (planted > 0.5)).mean() > 0.95 and learned.facts["contact_learned"]
    assert np.abs(learned.feet[..., 1][learned.planted]).max() < 1e-6  # planted points on the floor
    assert older.planted is None and older.feet is None and not older.facts["contact_learned"]
    # Both clips are in the segment's one scene: the learned one set its floor at its own scale.
    scene = read_meta(tmp_path / WORLD / "vid_000.parquet")["scene"]
    assert scene["shared_floor"] and scene["clips"] == 2 and learned.facts["scene_scale"] == pytest.approx(1.0)
    stamp = (tmp_path / WORLD / "vid_000.parquet").stat().st_mtime_ns
    run(tmp_path)  # up to date: not rewritten
    assert (tmp_path / WORLD / "vid_000.parquet").stat().st_mtime_ns == stamp


def test_eval_world_in_a_fresh_clone_uses_the_shipped_models_and_says_so(mocap_dir: Path, tmp_path: Path,
                                                                         capsys) -> None:
    """No models/ folder (train_lifter and train_contact never ran): the shipped lifter and contact
    model are scored, and the report names them."""
    import shutil

    from pipeline.cli import main
    from stages.train_contact import SHIPPED as CONTACT
    from stages.train_lifter import SHIPPED as LIFTER

    shutil.copy(Path(__file__).resolve().parents[2] / "params.yaml", tmp_path / "params.yaml")
    out = tmp_path / "world.json"
    assert main(["--root", str(tmp_path), "eval", "world", "--mocap", str(mocap_dir / "perfume"), "--seconds", "4",
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "models/lifter.onnx does not exist: using the shipped lifter" in err
    assert "models/contact.onnx does not exist: using the shipped contact model" in err
    protocol = json.loads(out.read_text())["protocol"]
    assert protocol["lifter"] == str(LIFTER) and protocol["contact_model"] == str(CONTACT)

