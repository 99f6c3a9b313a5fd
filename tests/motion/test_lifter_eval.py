"""The lifter's held-out protocol: whole performers held out, fixed cameras, noise of a known
level, figures next to the mean pose; `dance3d eval lifter` on capture a user brings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.motion.lifting.evaluate import (
    HOLDOUT,
    OKS80_NOISE,
    PROTOCOL_CAMERAS,
    add_pose_noise,
    evaluate_lifter,
    held_out_later,
    split,
    view,
)
from pipeline.motion.mocap.skeleton import coco_from_h36m
from pipeline.motion.mocap.sources import MocapSequence, load_folder, load_source
from pipeline.pose.pose2dfile import COCO_SIGMAS


def _walker(name: str = "mine/walk", frames: int = 60) -> MocapSequence:
    """A stick figure walking 1 m along x: enough of a human for the geometry."""
    rng = np.random.default_rng(0)
    rest = np.array([[0, 1, 0], [-.1, 1, 0], [-.1, .55, 0], [-.1, .1, 0], [.1, 1, 0], [.1, .55, 0], [.1, .1, 0],
                     [0, 1.25, 0], [0, 1.5, 0], [0, 1.6, .05], [0, 1.75, 0], [.2, 1.45, 0], [.45, 1.45, 0],
                     [.7, 1.45, 0], [-.2, 1.45, 0], [-.45, 1.45, 0], [-.7, 1.45, 0]], float)
    h36m = rest[None] + np.linspace(0, 1, frames)[:, None, None] * np.array([1.0, 0, 0])
    h36m = h36m + rng.normal(0, 0.01, h36m.shape)
    return MocapSequence(name, name.split("/")[0], 25.0, h36m, coco_from_h36m(h36m))


def test_the_split_holds_out_whole_performers_and_takes(mocap_dir: Path) -> None:
    sequences = load_folder(mocap_dir)
    train, held = split(sequences)
    train_names = {s.name for s in train}
    assert not train_names & {s.name for s in held}
    assert all(not name.startswith(HOLDOUT) for name in train_names)
    # ChoreoNet's second dancer (files ll_*, mm_*) is wholly held out; the first is wholly trained on.
    choreo = [s.name.split("/")[1] for s in held if s.source == "choreonet_c3d"]
    assert len(choreo) == 22 and all(n.startswith(("ll_", "mm_")) for n in choreo)
    # Every earlier source is scored but Bandai's second set (locomotion by the first set's actors and
    # skeleton), on the same 40 sequences as before the later sources came ...
    later = {"bandai_namco_2_more", "cmu_salsa_60_61", "mocap_recovery_c3d"}
    assert {s.source for s in held} == {s.source for s in sequences} - {"bandai_namco_2_subset"} - later
    assert len(held) == 40
    # ... and the later sources' own held-out takes are in neither the training set nor those 40.
    apart = held_out_later(sequences)
    assert {s.source for s in apart} == later and not {s.name for s in apart} & (train_names | {s.name for s in held})
    assert {s.name for s in apart if s.source == "cmu_salsa_60_61"} == {
        f"cmu_salsa_60_61/{who}_{take}_scaled" for who in ("60", "61") for take in ("14", "15")}


def test_cameras_see_the_dancer_in_front_of_them_from_five_headings() -> None:
    seq = _walker()
    assert len(PROTOCOL_CAMERAS) == 10 and len({c.heading_deg for c in PROTOCOL_CAMERAS}) == 5
    for camera in PROTOCOL_CAMERAS:
        xy, joints = view(seq.h36m, seq.coco, camera)
        assert (joints[:, 0, 2] > camera.distance_m - 0.05).all()  # never nearer than the set-up's distance
        assert (joints[:, 10, 1] < joints[:, 3, 1]).all()  # camera y is down: the head above the ankles
        centre = xy.reshape(-1, 2).mean(0)
        assert abs(centre[0] - camera.width / 2) < camera.width / 3


def test_noise_is_that_of_a_pose_model_with_oks_080() -> None:
    seq = _walker(frames=400)
    xy, _ = view(seq.h36m, seq.coco, PROTOCOL_CAMERAS[0])
    noisy = add_pose_noise(xy, np.random.default_rng(1), drop=0.0)
    span = xy.max(1) - xy.min(1)
    area = (span[:, 0] * span[:, 1])[:, None]
    k = 2 * COCO_SIGMAS[None]
    oks = np.exp(-((noisy - xy) ** 2).sum(-1) / (2 * area * k ** 2)).mean()
    assert abs(oks - 1 / (1 + OKS80_NOISE ** 2)) < 0.02
    assert abs(oks - 0.80) < 0.02


def test_noise_that_mostly_drifts_has_the_same_level_but_little_of_it_changes_from_frame_to_frame() -> None:
    seq = _walker(frames=400)
    xy, _ = view(seq.h36m, seq.coco, PROTOCOL_CAMERAS[0])
    white = add_pose_noise(xy, np.random.default_rng(1), drop=0.0) - xy
    drifting = add_pose_noise(xy, np.random.default_rng(1), drop=0.0, frame_share=0.05) - xy
    assert np.array_equal(add_pose_noise(xy, np.random.default_rng(1), drop=0.0, frame_share=1.0) - xy, white)
    assert np.std(drifting) == pytest.approx(np.std(white), rel=0.15)
    step = np.std(np.diff(drifting, axis=0)) / np.std(np.diff(white, axis=0))
    assert 0.15 < step < 0.35  # about sqrt(0.05) of the white noise's frame-to-frame change, plus a little drift


def test_a_lifter_that_answers_zeros_scores_the_distance_of_joints_from_the_root() -> None:
    seq = _walker()

    def zeros(clips, width, height):
        return [np.zeros((len(c), 17, 3)) for c in clips]

    result = evaluate_lifter(zeros, [seq], cameras=PROTOCOL_CAMERAS[:1])
    _, joints = view(seq.h36m, seq.coco, PROTOCOL_CAMERAS[0])
    expected = np.linalg.norm(joints - joints[:, :1], axis=-1).mean() * 1000
    assert result["clean"]["mpjpe_mm"] == pytest.approx(expected, abs=0.1)
    assert result["noisy"]["mpjpe_mm"] == pytest.approx(expected, abs=0.1)
    assert set(result["sources"]) == {"mine"} and result["protocol"]["sequences"] == 1


def test_the_feet_are_scored_apart_from_the_body() -> None:
    walker = _walker()
    ankles = walker.h36m[:, [6, 3, 6, 3]]
    feet = ankles + np.array([[-0.06, -0.08, 0], [-0.06, -0.08, 0], [0.0, -0.08, 0.18], [0.0, -0.08, 0.18]])
    seq = MocapSequence(walker.name, walker.source, walker.fps, walker.h36m, walker.coco, feet)

    def zeros(clips, width, height):
        assert clips[0].shape[1] == 21  # the heels and toes come after the 17 keypoints
        return [np.zeros((len(c), 21, 3)) for c in clips]

    result = evaluate_lifter(zeros, [seq], cameras=PROTOCOL_CAMERAS[:1], feet=True)
    _, joints = view(np.concatenate([seq.h36m, feet], 1), np.concatenate([seq.coco, feet], 1), PROTOCOL_CAMERAS[0])
    rel = joints - joints[:, :1]
    assert result["clean"]["mpjpe_mm"] == pytest.approx(np.linalg.norm(rel[:, :17], axis=-1).mean() * 1000, abs=0.1)
    assert result["clean"]["feet_mpjpe_mm"] == pytest.approx(np.linalg.norm(rel[:, 17:], axis=-1).mean() * 1000,
                                                             abs=0.1)
    assert "feet_mpjpe_mm" not in evaluate_lifter(lambda c, w, h: [np.zeros((len(x), 17, 3)) for x in c], [seq],
                                                  cameras=PROTOCOL_CAMERAS[:1])["clean"]


def _untrained_lifter_and_capture(tmp_path: Path, joints: int) -> tuple[Path, Path, MocapSequence]:
    """An untrained ONNX lifter of ``joints`` joints in and out, and a folder with one walk (no feet)."""
    torch = pytest.importorskip("torch")
    from pipeline.motion.lifting.model import TemporalModel
    from pipeline.motion.lifting.train import export_onnx

    torch.manual_seed(0)
    export_onnx(TemporalModel(joints, joints, (3, 3), 16).eval(), tmp_path / "lifter.onnx")
    capture = tmp_path / "capture"
    capture.mkdir()
    seq = _walker()
    np.savez(capture / "walk.npz", joints=seq.h36m, fps=25.0)
    return tmp_path / "lifter.onnx", capture, seq


def test_eval_lifter_scores_an_onnx_lifter_on_a_folder_of_joint_files(tmp_path: Path, capsys) -> None:
    _, capture, _ = _untrained_lifter_and_capture(tmp_path, 17)
    out = tmp_path / "r.json"
    assert main(["--root", str(tmp_path), "eval", "lifter", "--mocap", str(capture), "--model",
                 str(tmp_path / "lifter.onnx"), "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "capture" in table and "all" in table and "mean pose" in table
    import json

    result = json.loads(out.read_text())
    assert result["protocol"]["split"] == "every sequence" and result["clean"]["mpjpe_mm"] > 0


def test_a_lifter_with_feet_asks_for_capture_with_feet(tmp_path: Path, capsys) -> None:
    model, capture, seq = _untrained_lifter_and_capture(tmp_path, 21)
    args = ["--root", str(tmp_path), "eval", "lifter", "--mocap", str(capture), "--model", str(model)]
    assert main(args) == 2
    assert f"{capture}: 1 sequences (capture/walk) have no heels and toes, which lifter" in capsys.readouterr().err
    np.savez(capture / "walk.npz", joints=seq.h36m, fps=25.0, feet=seq.h36m[:, [6, 3, 6, 3]] - [0.0, 0.08, 0.0])
    assert main(args) == 0
    assert "feet" in capsys.readouterr().out


def test_eval_lifter_names_a_folder_without_motion_capture(tmp_path: Path, capsys) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "params.yaml").write_text("lift: {model: models/lifter.onnx}\n")
    assert main(["--root", str(tmp_path), "eval", "lifter", "--mocap", str(tmp_path / "empty")]) == 2
    assert f"{tmp_path / 'empty'}: no motion capture found" in capsys.readouterr().err
    np.savez(tmp_path / "empty" / "bad.npz", joints=np.zeros((5, 12, 3)), fps=25.0)
    with pytest.raises(Exception, match=r"bad\.npz: 'joints' must be finite, T x 17 x 3"):
        load_folder(tmp_path / "empty")


def test_the_known_sources_load_by_folder(mocap_dir: Path) -> None:
    assert [s.name for s in load_folder(mocap_dir / "dancedb_ucy")] == [
        s.name for s in load_source(mocap_dir, "dancedb_ucy")]
