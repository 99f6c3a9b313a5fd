"""Windows, the video-level split, shards that any Parquet reader reads, the streaming loader, training."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import torch
from torch.utils.data import DataLoader

from pipeline.corpus.build import write_shards
from pipeline.corpus.card import style_stats
from pipeline.corpus.windows import SCHEMA_VERSION, Window, split_of, window_starts
from pipeline.train.dataset import WindowDataset
from pipeline.train.loop import TrainConfig, train_tsmt
from pipeline.train.model import TSMTConfig, TwoStreamMotionTransformer, generate


def test_a_45_s_clip_gives_three_windows_and_short_clips_none() -> None:
    starts = window_starts(0, 45 * 24, 480, 240)
    assert [(s / 24, (s + 480) / 24) for s in starts] == [(0, 20), (10, 30), (20, 40)]
    assert window_starts(100, 479, 480, 240) == []
    assert window_starts(7, 480, 480, 240) == [7]


def test_split_is_by_video_stable_and_about_the_requested_share() -> None:
    videos = [f"video{i}" for i in range(2000)]
    splits = [split_of(v, 0.2) for v in videos]
    assert splits == [split_of(v, 0.2) for v in videos]  # deterministic
    assert 0.17 < splits.count("val") / len(videos) < 0.23


def synthetic_windows(n_videos: int = 6, clips: int = 2, per_clip: int = 5, frames: int = 48,
                      seed: int = 0) -> list[Window]:
    """Dancing sinusoids whose phase follows a beat in the 'music' (so there is something to learn)."""
    rng = np.random.default_rng(seed)
    windows = []
    for v in range(n_videos):
        video = f"vid{v}"
        for c in range(clips):
            for w in range(per_clip):
                t = (np.arange(frames) + w * 24) / 24
                freq = rng.uniform(0.5, 2.0)
                motion = np.zeros((frames, 17, 3), np.float32)
                motion[:, :, 0] = 0.3 * np.sin(2 * np.pi * freq * t)[:, None] * np.linspace(0.2, 1, 17)
                motion[:, :, 1] = np.linspace(-0.8, 0.8, 17)
                beat = (np.sin(2 * np.pi * freq * t) > 0.99).astype(np.int8)
                mfcc = np.tile(np.sin(2 * np.pi * freq * t)[:, None], (1, 39)).astype(np.float32)
                meta = {"window_id": f"{video}_{c}_w{w:03d}", "split": split_of(video, 0.3), "video_id": video,
                        "url": f"https://example.org/{video}", "title": "t", "channel": "ch", "style": "pop",
                        "tags": ["kpop", f"crew{v}"], "licence": "CC-BY", "segment_id": f"{video}_000",
                        "clip_id": f"{video}_000_{c}_0",
                        "track_id": c + 1, "start_frame": w * 24, "start_time": w, "segment_start": 0.0,
                        "tempo": 60 * freq}
                windows.append(Window(meta, motion, mfcc, np.zeros((frames, 12), np.float32),
                                      np.abs(mfcc[:, 0]), beat))
    return windows


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> tuple[Path, list[Window]]:
    root = tmp_path_factory.mktemp("corpus")
    windows = synthetic_windows()
    write_shards(root, windows, 48, per_shard=8, row_group=4, params={"window_seconds": 2})
    return root / "data/corpus", windows


def test_no_video_is_in_both_splits(corpus) -> None:
    folder, windows = corpus
    seen = {split: set(pd.read_parquet(folder / split)["video_id"]) for split in ("train", "val")}
    assert seen["train"] and seen["val"] and not seen["train"] & seen["val"]


def test_shards_round_trip_through_pyarrow_pandas_and_datasets(corpus) -> None:
    import datasets

    folder, windows = corpus
    by_id = {w.meta["window_id"]: w for w in windows}
    files = sorted(str(p) for p in (folder / "train").glob("*.parquet"))
    table = pq.read_table(files)
    motion = np.asarray(table.column("motion").combine_chunks().flatten().flatten().flatten()).reshape(-1, 48, 17, 3)
    frame = pd.read_parquet(folder / "train")
    hf = datasets.load_dataset("parquet", data_files=files, split="train")
    assert table.num_rows == len(frame) == len(hf) > 0
    for i, window_id in enumerate(table.column("window_id").to_pylist()):
        expected = by_id[window_id]
        assert np.array_equal(motion[i], expected.motion)
        row = frame[frame.window_id == window_id].iloc[0]
        assert np.array_equal(np.stack([np.stack(f) for f in row.motion]), expected.motion)
        assert row.url == expected.meta["url"] and row.licence == "CC-BY"
        assert list(row.tags) == expected.meta["tags"]
    for record in hf.select(range(3)):
        assert np.array_equal(np.array(record["motion"], np.float32), by_id[record["window_id"]].motion)
        assert np.array_equal(np.array(record["beat"], np.int8), by_id[record["window_id"]].beat)
    meta = pq.read_schema(files[0]).metadata[b"dance3d"]
    assert f'"schema_version": {SCHEMA_VERSION}'.encode() in meta and b'"fps": 24' in meta
    assert b"LeftShoulderRoot" in meta and b"left_hip-left_knee" in meta  # rotation joint and bone names


def test_the_card_lets_datasets_find_both_splits_with_no_arguments(corpus, tmp_path: Path) -> None:
    import datasets

    from pipeline.corpus.card import hf_front_matter

    folder, windows = corpus
    (folder / "README.md").write_text(hf_front_matter(["train", "val"]) + "# dance3d corpus\n")
    loaded = datasets.load_dataset(str(folder), cache_dir=str(tmp_path / "hf"))
    assert set(loaded) == {"train", "validation"}
    assert len(loaded["train"]) + len(loaded["validation"]) == len(windows)
    assert {"world_joints", "root", "contact", "rotations_6d", "bone_lengths"} <= set(loaded["train"].column_names)


def test_loader_yields_every_window_once_per_epoch_across_two_workers(corpus) -> None:
    folder, windows = corpus
    dataset = WindowDataset(folder / "train", shuffle_buffer=5, seed=3)
    expected = sorted(w.meta["window_id"] for w in windows if w.meta["split"] == "train")
    loader = DataLoader(dataset, batch_size=4, num_workers=2)
    for epoch in range(2):
        dataset.set_epoch(epoch)
        seen = [i for batch in loader for i in batch["window_id"]]
        assert sorted(seen) == expected  # each exactly once
    batch = next(iter(DataLoader(dataset, batch_size=2)))
    assert batch["motion"].shape == (2, 48, 51) and batch["audio"].shape == (2, 48, 27)
    world = next(iter(DataLoader(WindowDataset(folder / "train", motion="world"), batch_size=2)))
    assert world["motion"].shape == (2, 48, 51)  # the world_joints column (NaN here: synthetic windows)
    with pytest.raises(ValueError, match="motion must be 'camera' or 'world'"):
        WindowDataset(folder / "train", motion="pixels")


def test_training_lowers_the_loss_clearly(corpus) -> None:
    folder, _ = corpus
    cfg = TrainConfig(steps=250, batch=8, lr=1e-3, crop_frames=32, shuffle_buffer=16,
                      model=TSMTConfig(d_model=32, heads=2, ff=64, max_frames=64))
    model, losses = train_tsmt(folder.parent.parent / "data/corpus", cfg)
    assert np.mean(losses[-20:]) < 0.5 * np.mean(losses[:20])
    seed = torch.zeros(4, 51)
    audio = torch.zeros(20, 27)
    out = generate(model, seed, audio, 16)
    assert out.shape == (20, 51) and torch.isfinite(out).all()


def test_generation_is_causal() -> None:
    model = TwoStreamMotionTransformer(TSMTConfig(d_model=16, heads=2, ff=32, max_frames=32)).eval()
    bins = torch.randint(0, 300, (1, 10, 51))
    audio = torch.randn(1, 10, 27)
    full = model(bins, audio)
    changed = bins.clone()
    changed[:, 7:] = torch.randint(0, 300, (1, 3, 51))
    audio2 = audio.clone()
    audio2[:, 7:] = torch.randn(1, 3, 27)
    assert torch.allclose(full[:, :7], model(changed, audio2)[:, :7], atol=1e-5)  # the future does not leak


def test_the_card_counts_windows_per_style() -> None:
    metas = [{"style": "hip-hop", "split": "train", "video_id": "a"},
             {"style": "hip-hop", "split": "val", "video_id": "b"},
             {"style": "hip-hop", "split": "train", "video_id": "a"},
             {"style": "", "split": "train", "video_id": "c"}]
    assert style_stats(metas) == [{"style": "hip-hop", "videos": 2, "windows_train": 2, "windows_val": 1},
                                  {"style": "(none)", "videos": 1, "windows_train": 1, "windows_val": 0}]


def test_the_seed_profile_builds_the_seed_model_and_it_learns_causally() -> None:
    import yaml

    from pipeline.core.params import with_profile
    from pipeline.train.model import next_frame_loss
    from tests.conftest import PROJECT

    section = yaml.safe_load((PROJECT / "params.yaml").read_text())["train"]
    params = with_profile({**section, "profile": "seed"}, "train")
    cfg = TSMTConfig(**params["model"])
    model = TwoStreamMotionTransformer(cfg)
    # 51 coordinates x D^E 5 into a 256-wide pose stream, a 64-wide audio stream, late fusion.
    assert model.pose_in.in_features == 255 and model.coord_embedding.weight.shape == (300, 5)
    assert model.audio_conv.out_channels == 64 and model.beat_embedding.weight.shape == (2, 30)
    assert not hasattr(model, "fusion") and 8_000_000 < sum(p.numel() for p in model.parameters()) < 9_000_000
    model.eval()
    bins = torch.randint(0, 300, (1, 12, 51))
    audio = torch.randn(1, 12, 27)
    changed = bins.clone()
    changed[:, 8:] = torch.randint(0, 300, (1, 4, 51))
    assert torch.allclose(model(bins, audio)[:, :8], model(changed, audio)[:, :8], atol=1e-5)  # causal
    model.train()
    motion = torch.randn(2, 20, 51) * 0.3
    loss = next_frame_loss(model, motion, torch.randn(2, 20, 27))
    loss.backward()
    assert torch.isfinite(loss) and model.coord_embedding.weight.grad.abs().sum() > 0


def test_the_card_and_metrics_use_the_corpus_rate_not_a_clean_files_source_rate(tmp_path: Path) -> None:
    """A 60 fps source video must not change what the card says of 24 fps, 8 s windows."""
    import pyarrow as pa

    from pipeline.core.paths import CLEAN, CORPUS
    from pipeline.core.storage import write_parquet
    from pipeline.corpus.build import write_card_and_metrics

    (tmp_path / CLEAN).mkdir(parents=True)
    write_parquet(pa.table({"clip_id": ["v_000_1_0"] * 600}), tmp_path / CLEAN / "v_000.parquet",
                  schema_version=2, extra={"fps": 60.0})
    windows = synthetic_windows(n_videos=1, clips=1, per_clip=1, frames=192)
    for w in windows:
        w.meta.update(beat_frames=[], motion_beat_frames=[], beat_align_score=float("nan"))
    counts = {"clips": 1, "clips_without_audio": 0, "clips_too_short": 0}
    write_card_and_metrics(tmp_path, windows, counts, {}, window=192, hop=96, fps=24.0)
    card = (tmp_path / CORPUS / "README.md").read_text()
    assert "exactly 24 fps" in card and "60 fps" not in card
    assert "(0.1 minutes of distinct motion)" in card  # 192 frames at 24 fps, not at 60


def test_the_half_beat_control_holds_on_covers_where_shuffled_music_does_not() -> None:
    """Three covers of one song: another video's music is the same music, so a shuffled control
    scores like the matched pairs; the window's own music shifted by half a beat does not."""
    from pipeline.corpus.build import alignment_summary

    beats = list(range(6, 192, 12))  # 120 BPM at 24 fps
    windows = synthetic_windows(n_videos=3, clips=1, per_clip=1, frames=192)
    for w in windows:
        w.meta.update(beat_frames=beats, motion_beat_frames=[b + 1 for b in beats])
    summary = alignment_summary(windows, 24.0)
    assert summary["shuffled_beat_align_score"] == summary["matched_beat_align_score"] > 0.7
    assert summary["half_beat_beat_align_score"] < 0.1
    assert summary["half_beat_beat_f1"] < 0.1 < summary["matched_beat_f1"]


def test_the_loader_refuses_shards_of_another_schema_naming_the_file_and_the_fix(tmp_path: Path) -> None:
    from pipeline.core.errors import InputError

    write_shards(tmp_path, synthetic_windows(n_videos=2, per_clip=2), 48, per_shard=8, row_group=4, params={})
    shard = sorted((tmp_path / "data/corpus").rglob("*.parquet"))[0]
    table = pq.read_table(shard)
    meta = table.schema.metadata[b"dance3d"].replace(f'"schema_version": {SCHEMA_VERSION}'.encode(),
                                                     b'"schema_version": 5')
    pq.write_table(table.replace_schema_metadata({b"dance3d": meta}), shard)
    with pytest.raises(InputError, match=rf"shard-00000.parquet: corpus schema 5, this dance3d reads schema "
                                         rf"{SCHEMA_VERSION}: rebuild the corpus with `dvc repro shard`"):
        WindowDataset(shard.parent)


def test_sample_without_a_trained_model_says_which_stage_makes_one(tmp_path: Path, capsys) -> None:
    from pipeline.cli import main

    assert main(["--root", str(tmp_path), "sample", str(tmp_path / "song.ogg"), str(tmp_path / "out.parquet")]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "models/tsmt.pt") in err and "train stage" in err and "--model" in err
