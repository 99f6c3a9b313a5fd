"""AIOZ-GDANCE's group sequences: runs where the same dancers are all in view, and the root path
that stands the unit SMPL body on the floor."""

import numpy as np

from pipeline.export.gdance import GroupSequence, group_spans


def test_a_group_sequence_ends_where_a_dancer_leaves_or_joins():
    a, b, c = np.arange(0, 100), np.arange(10, 80), np.arange(50, 120)
    assert group_spans([a, b, c], min_frames=5) == [(10, 50, (0, 1)), (50, 80, (0, 1, 2)), (80, 100, (0, 2))]


def test_runs_with_one_dancer_or_shorter_than_the_minimum_are_left_out():
    a, b = np.arange(0, 100), np.arange(90, 200)
    assert group_spans([a, b], min_frames=11) == []
    assert group_spans([a, b], min_frames=10) == [(90, 100, (0, 1))]
    assert group_spans([a], min_frames=1) == []


def test_a_gap_in_a_clip_splits_the_group():
    a, b = np.arange(0, 60), np.r_[np.arange(0, 20), np.arange(30, 60)]
    assert group_spans([a, b], min_frames=5) == [(0, 20, (0, 1)), (30, 60, (0, 1))]


def test_root_trans_puts_each_pelvis_height_on_the_unit_body_and_keeps_where_they_stand():
    trans = np.array([[[1.0, 0.9, 2.0]], [[-1.0, 1.1, 0.5]]])
    seq = GroupSequence("s_0_1", "s", "v", "train", ("a", "b"), (1, 2), 0.0, np.zeros((2, 1, 72)), trans,
                        np.array([0.9, 1.1]), np.zeros((2, 1, 4), bool), 30.0)
    assert np.allclose(seq.root_trans, [[[1.0, 1.0, 2.0]], [[-1.0, 1.0, 0.5]]])
    assert np.allclose(seq.trans, trans)  # the exact path stays as smpl_trans


def test_a_segment_with_two_dancers_exports_one_sequence_a_group_loader_reads(mocap_dir, tmp_path):
    """Two captured dancers, one joining a second late: one sequence from the frame both are in view,
    every dancer's motion on the SMPL tree at 30 fps, the music and its features beside it."""
    import pickle
    import subprocess

    from pipeline.export.gdance import export
    from pipeline.ingest.catalog import INDEX_SCHEMA, write_index
    from pipeline.ingest.media import ffmpeg_exe
    from pipeline.motion.mocap.sources import load_source, resample
    from pipeline.motion.world.grounding import ground_clip
    from pipeline.motion.world.segment import world_clip
    from pipeline.motion.world.worldfile import write_world
    from pipeline.music.featurefile import features_table, write_features

    fps, n = 24.0, 145
    dance = resample(load_source(mocap_dir, "choreonet_c3d")[0], fps).h36m[:n]
    frames = [np.arange(n), np.arange(24, n)]  # the second dancer is seen from 1 s on
    clips = [world_clip(f"vid_000_{k}_0", k, f.astype(np.int32), f / fps, ground_clip(dance[f] + [k, 0, 0], None, fps))
             for k, f in ((1, frames[0]), (2, frames[1]))]
    write_world(tmp_path / "data/world/vid_000.parquet", clips, {"segment_id": "vid_000", "fps": fps},
                fingerprint="x", params={}, inputs={})
    row = {f.name: None for f in INDEX_SCHEMA}
    row.update(segment_id="vid_000", video_id="vid", start=0.0, end=n / fps, fps=fps, frames=n)
    write_index(tmp_path / "data/segments", [row], params={})
    (tmp_path / "data/audio").mkdir(parents=True)
    subprocess.run([ffmpeg_exe(), "-v", "error", "-f", "lavfi", "-i", f"sine=440:duration={n / fps}", "-ar", "44100",
                    str(tmp_path / "data/audio/vid_000.flac")], check=True)
    z = np.zeros(n, np.float32)
    table = features_table(n, fps, np.zeros((n, 39), np.float32), np.zeros((n, 12), np.float32), z, z.astype(np.int8),
                           {})
    write_features(tmp_path / "data/audio_features/vid_000.parquet", table, {"beat_times": [1.5, 2.0, 2.5]},
                   fingerprint="x", params={}, inputs={})

    (seq,) = export(tmp_path, tmp_path / "out", val_fraction=0.0)
    assert seq.name == "vid_000_30_181" and seq.clip_ids == ("vid_000_1_0", "vid_000_2_0")
    names = (tmp_path / "out/split_sequence_names.txt").read_text().split()
    assert names == [seq.name] and int(names[0].split("_")[-1]) - int(names[0].split("_")[-2]) == 151
    data = pickle.loads((tmp_path / f"out/motions_smpl/{seq.name}.pkl").read_bytes())
    assert data["smpl_poses"].shape == (2, 151, 72) and data["root_trans"].shape == (2, 151, 3)
    assert data["meta"]["orig_start"] == 30 and data["meta"]["orig_end"] == 181
    # Each dancer where the world file has them (the segment's scene) at the sequence's first frame.
    assert np.allclose(data["smpl_trans"][:, 0], [clips[0].smpl_trans[24], clips[1].smpl_trans[0]], atol=1e-5)
    beats = np.load(tmp_path / f"out/baseline_feats/{seq.name}.npy")
    assert beats.shape == (151, 35) and list(np.flatnonzero(beats[:, 34])) == [15, 30, 45]
    assert (tmp_path / f"out/musics/{seq.name}.wav").stat().st_size > 44100 * 2 * 4
