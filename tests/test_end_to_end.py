"""`dvc repro` on the demo sources, in a temporary copy of the project."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from pipeline.annotate.clipfile import read_clean
from pipeline.ingest.catalog import read_index, read_ledger
from pipeline.motion.motionfile import read_motion
from pipeline.pose.trackfile import read_tracks
from tests.conftest import demo_copy, dvc


@pytest.mark.slow
def test_dvc_repro_runs_the_demo(built_demo: Path, tmp_path: Path) -> None:
    # built_demo ran `dvc repro` once (tests/conftest.py); this test changes its own copy.
    root = demo_copy(built_demo, tmp_path / "dance3d")

    ledger = list(read_ledger(root / "data/raw").values())
    assert [(r["video_id"], r["status"]) for r in ledger] == [
        ("musepose_dance", "ok"), ("taiji", "ok"), ("raga_trio", "ok"), ("solo_dance", "ok")]
    index = list(read_index(root / "data/segments").values())
    assert [r["segment_id"] for r in index] == ["musepose_dance_000", "solo_dance_000", "solo_dance_001", "taiji_000"]
    assert all((root / "data/raw" / r["source"]).exists() for r in index)  # segments are views, not copies
    proposals = sorted(p.stem for p in (root / "data/segment_proposals").glob("[!_]*.parquet"))
    assert proposals == sorted(r["video_id"] for r in ledger)  # every download, annotated or not
    assert not list((root / "data/segments").glob("*.mp4")) and not (root / "data/qc").exists()

    for seg in index:
        ids = read_tracks(root / "data/tracks" / f"{seg['segment_id']}.parquet").track_id
        assert (ids == 1).sum() >= 0.9 * seg["frames"], seg["segment_id"]  # one dancer, one long track

    for seg in index:
        clips = read_motion(root / "data/motion24" / f"{seg['segment_id']}.parquet").clips
        assert sum(len(c.frame) for c in clips) >= 0.9 * seg["frames"] / seg["fps"] * 24
        assert all(np.allclose(c.time, c.frame / 24) for c in clips)
    lifter = json.loads((root / "reports/lifter.json").read_text())
    assert lifter["shipped"] and lifter["val_p_mpjpe_mm"] < 60

    shards = sorted((root / "data/corpus/train").glob("shard-*.parquet")) + sorted(
        (root / "data/corpus/val").glob("shard-*.parquet"))
    windows = sum(pq.read_metadata(p).num_rows for p in shards)
    corpus = json.loads((root / "reports/corpus.json").read_text())
    assert windows == corpus["windows_train"] + corpus["windows_val"] > 0
    assert corpus["clips_without_audio"] == 2  # the silent solo clip's two segments
    assert "## Statistics" in (root / "data/corpus/README.md").read_text()
    alignment = corpus["beat_alignment"]  # matched and shuffled music, on the demo's windows
    assert alignment["windows"] == windows and 0 <= alignment["matched_beat_align_score"] <= 1
    assert 0 <= alignment["shuffled_beat_align_score"] <= 1
    assert 0 <= alignment["half_beat_beat_align_score"] <= 1
    assert "## Motion–music alignment" in (root / "data/corpus/README.md").read_text()
    # World-grounded columns: y up, the floor under the feet, one skeleton, rotations; any reader finds the splits.
    world = pq.read_table(shards[0], columns=["world_joints", "root", "contact", "rotations_6d", "bone_lengths",
                                              "camera_pitch"]).to_pylist()[0]
    joints = np.array(world["world_joints"])
    assert np.isfinite(joints).all() and (joints[:, 10, 1] > joints[:, 0, 1]).mean() > 0.9
    assert joints[:, [3, 6], 1].min() > -0.15 and np.allclose(np.array(world["root"]), joints[:, 0], atol=1e-6)
    assert len(world["bone_lengths"]) == 16 and -45 < world["camera_pitch"] < 45
    # Contact from the shipped contact model: planted heels and toes stand on the floor (y = 0).
    feet = pq.read_table(shards[0], columns=["world_feet", "planted", "contact_probability", "contact"]).to_pylist()[0]
    planted, probability = np.array(feet["planted"], bool), np.array(feet["contact_probability"])
    # Planted: above 0.4 (ground.contact_threshold), held while above 0.1 (ground.contact_hold).
    assert np.isfinite(probability).all() and ((probability > 0.1) >= planted).all() and planted.any()
    assert (probability[planted] > 0.4).any()
    assert np.abs(np.array(feet["world_feet"])[..., 1][planted]).max() < 1e-5
    by_foot = np.stack([planted[:, [0, 2]].any(1), planted[:, [1, 3]].any(1)], 1)  # heel or toe, left and right
    assert (np.array(feet["contact"], bool) == by_foot).all()
    assert "## World motion" in (root / "data/corpus/README.md").read_text()
    import datasets

    loaded = datasets.load_dataset(str(root / "data/corpus"), cache_dir=str(tmp_path / "hf"))
    assert sum(len(split) for split in loaded.values()) == windows and "train" in loaded
    smpl = datasets.load_dataset(str(root / "data/corpus"), "smpl", cache_dir=str(tmp_path / "hf"))["train"]
    assert np.array(smpl[0]["smpl_poses"]).shape == (8 * 24, 72) and 0.7 < smpl[0]["smpl_scaling"] < 1.3
    _exports_aistpp(root, tmp_path / "aistpp")
    _exports_edge(root, tmp_path / "edge")
    _exports_finedance(root, tmp_path / "finedance")
    _draws_and_exports_the_smpl_skeleton(root, tmp_path)
    beats = pq.read_table(shards[0], columns=["beat", "beat_frames", "motion_beat_frames"]).to_pylist()[0]
    assert beats["beat_frames"] == [i for i, flag in enumerate(beats["beat"]) if flag]  # flags and frames agree
    assert beats["motion_beat_frames"]
    assert (root / "models/tsmt.pt").exists() and json.loads((root / "reports/train.json").read_text())["steps"] == 10
    # dvc metrics show at a glance: the headline figures only, a table a terminal shows; the breakdowns
    # in reports/ beside them.
    metrics = dvc(root, "metrics", "show")
    assert metrics.returncode == 0 and "lifter_p_mpjpe_mm" in metrics.stdout and "corpus_windows" in metrics.stdout
    assert "failed_share" in metrics.stdout and max(len(line) for line in metrics.stdout.splitlines()) < 250
    shown = json.loads(dvc(root, "metrics", "show", "--json").stdout)
    keys = [key for run in shown.values() for files in run["data"].values() for key in files["data"]]
    assert 10 <= len(keys) <= 25, keys
    assert json.loads((root / "reports/failures_pose2d.json").read_text())["failed"] == 0
    assert corpus["failures"]["failed"] == 0 and set(json.loads((root / "metrics/corpus.json").read_text())) >= {
        "corpus_minutes", "corpus_windows", "beat_f1", "beat_f1_shuffled", "failed_share"}
    status = subprocess.run([str(Path(sys.executable).parent / "dance3d"), "status"], cwd=root, capture_output=True,
                            text=True)
    assert "lifter_p_mpjpe_mm" in status.stdout and "corpus_windows" in status.stdout  # the same figures, no DVC
    plots = dvc(root, "plots", "show", "-o", str(tmp_path / "plots"))
    assert plots.returncode == 0, plots.stderr[-2000:]
    assert (tmp_path / "plots/index.html").exists()

    second = dvc(root, "repro")
    assert second.returncode == 0, second.stderr[-3000:]
    assert "didn't change, skipping" in second.stdout or "up to date" in second.stdout

    # An annotator edits one manifest: clean re-runs, nothing upstream does.
    subprocess.run([sys.executable, "-m", "pipeline.cli", "manifests", "seed"], cwd=root, check=True,
                   capture_output=True)
    manifest = root / "manifests/tracks/solo_dance_001.csv"
    manifest.write_text(manifest.read_text().replace(",yes,", ",no,"))
    third = dvc(root, "repro")
    assert third.returncode == 0, third.stderr[-3000:]
    ran = [line.split("'")[1] for line in third.stdout.splitlines() if line.startswith("Running stage")]
    assert ran == ["discover", "clean", "lift", "smooth", "resample", "ground", "shard", "train"]  # discover: always
    assert not read_clean(root / "data/clean/solo_dance_001.parquet").clips
    assert sum(len(c.frame) for c in read_clean(root / "data/clean/solo_dance_000.parquet").clips) == 9 * 30  # 9 s

    status = subprocess.run([sys.executable, "-m", "pipeline.cli", "status"], cwd=root,
                            capture_output=True, text=True, check=True).stdout
    assert "download: 4 sources, 4 ok" in status
    assert "trim: 4 segments from 3 videos" in status


def _draws_and_exports_the_smpl_skeleton(root: Path, tmp_path: Path) -> None:
    """`render --smpl` and `export bvh --smpl` of one world clip: an mp4, and a BVH of SMPL's 24 joints."""
    from pipeline.motion.mocap.bvh import read_bvh
    from pipeline.motion.world.worldfile import read_world

    world = sorted((root / "data/world").glob("[!_]*.parquet"))[0]
    clip = read_world(world)[0]
    for command, out in (("render", tmp_path / "smpl.mp4"), ("export bvh", tmp_path / "smpl.bvh")):
        done = subprocess.run([sys.executable, "-m", "pipeline.cli", *command.split(), "--smpl", str(world),
                               clip.clip_id, str(out)], cwd=root, capture_output=True, text=True)
        assert done.returncode == 0 and out.stat().st_size > 0, done.stderr[-2000:]
    bvh = read_bvh(tmp_path / "smpl.bvh")
    assert len(bvh.joints) == 24 and bvh.motion.shape[0] == len(clip.frame)
    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "export", "bvh", "--smpl", str(world), "--all",
                           str(tmp_path / "smpl_all")], cwd=root, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert sorted(p.stem for p in (tmp_path / "smpl_all").glob("*.bvh")) == sorted(c.clip_id for c in read_world(world))


def _exports_edge(root: Path, out: Path) -> None:
    """`dance3d export edge`: per split the four folders EDGE's loader pairs by sorted name, their shapes."""
    import pickle

    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "export", "edge", str(out), "--length", "2",
                           "--stride", "1"], cwd=root, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    kinds = {"motions_sliced": ".pkl", "wavs_sliced": ".wav", "baseline_feats": ".npy", "edge_features": ".npy"}
    stems = {kind: sorted(p.name[: -len(ext)] for p in out.glob(f"*/{kind}/*{ext}")) for kind, ext in kinds.items()}
    assert stems["motions_sliced"] and all(names == stems["motions_sliced"] for names in stems.values())
    first = next(out.glob("*/motions_sliced/*.pkl"))
    motion = pickle.loads(first.read_bytes())
    assert motion["pos"].shape == (120, 3) and motion["q"].shape == (120, 72)
    features = first.parent.parent / "edge_features" / first.name.replace(".pkl", ".npy")
    assert np.load(features).shape == (60, 151) and set(np.unique(np.load(features)[:, :4])) <= {0.0, 1.0}
    assert np.load(first.parent.parent / "baseline_feats" / features.name).shape == (60, 35)


def _exports_finedance(root: Path, out: Path) -> None:
    """`dance3d export finedance`: one motion, wav and music feature file per dancer, of one name and
    one length (the demo runs without hands: flat fingers)."""
    import soundfile

    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "export", "finedance", str(out)], cwd=root,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    names = sorted(p.stem for p in (out / "motion").glob("*.npy"))
    assert len(names) == 2 and names == sorted(p.stem for p in (out / "music_npy").glob("*.npy"))
    splits = (out / "splits/train.txt").read_text().split() + (out / "splits/test.txt").read_text().split()
    assert sorted(splits) == names
    for name in names:
        motion, music = np.load(out / "motion" / f"{name}.npy"), np.load(out / "music_npy" / f"{name}.npy")
        assert motion.shape[1] == 315 and music.shape == (len(motion), 35)
        assert np.allclose(motion[:, 3 + 22 * 6:].reshape(-1, 30, 2, 3), np.eye(3)[:2])  # flat hands
        assert abs(soundfile.info(str(out / "music_wav" / f"{name}.wav")).duration - len(motion) / 30) < 0.01


def _exports_aistpp(root: Path, out: Path) -> None:
    """`dance3d export aistpp`: AIST++'s files, read as AIST++'s loader and EDGE's split step read them."""
    import pickle
    import wave

    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "export", "aistpp", str(out)], cwd=root,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    names = (out / "splits/crossmodal_train.txt").read_text().split() + (
        out / "splits/crossmodal_test.txt").read_text().split()
    assert len(names) == 2  # the two dancers with music (the silent clip has none)
    for name in names:
        genre, situation, camera, dancer, music, choreo = name.split("_")  # AIST++'s name, as Bailando splits it
        assert camera == "cAll" and music.startswith("m") and (out / "all_musics" / f"{music}.wav").exists()
        data = pickle.loads((out / "motions" / f"{name}.pkl").read_bytes())
        poses, trans, scaling = data["smpl_poses"], data["smpl_trans"], data["smpl_scaling"]
        assert poses.shape[1] == 72 and trans.shape == (len(poses), 3) and scaling.shape == (1,)
        with wave.open(str(out / "wavs" / f"{name}.wav")) as w:  # EDGE slices music and motion together
            assert w.getframerate() == 44100 and abs(w.getnframes() / 44100 - len(poses) / 60) < 0.01
