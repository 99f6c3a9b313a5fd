"""Group windows: the dancers of a segment window together, in the segment's scene, as the `groups` config."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pipeline.corpus.groups import link_solo_windows, segment_group_windows
from pipeline.corpus.windows import Window
from pipeline.motion.world.worldfile import WorldClip

W, HOP = 48, 24


def _dancer(track: int, first: int, frames: int, x: float) -> WorldClip:
    """A dancer standing at x (metres, scene frame), swaying, from segment frame ``first``."""
    t = np.arange(first, first + frames)  # the segment clock: dancers sway together
    joints = np.zeros((frames, 17, 3), np.float32)
    joints[..., 1] = np.linspace(0.0, 1.7, 17)
    joints[..., 0] = x + 0.1 * np.sin(t / 5)[:, None]
    feet = np.zeros((frames, 4, 3), np.float32)
    feet[..., 0] = x
    return WorldClip(f"seg_000_{track}_0", track, np.arange(first, first + frames, dtype=np.int32),
                     np.arange(first, first + frames) / 24.0, joints, feet, np.ones((frames, 2), bool),
                     np.ones((frames, 4), bool), np.full((frames, 4), 0.9, np.float32),
                     np.zeros((frames, 23, 6), np.float32), {})


def _features(frames: int) -> SimpleNamespace:
    rng = np.random.default_rng(0)
    return SimpleNamespace(frames=frames, mfcc=rng.normal(size=(frames, 39)), chroma=rng.random((frames, 12)),
                           onset=rng.random(frames), beat=(np.arange(frames) % 12 == 0).astype(np.int8), tempo=120.0)


META = {"segment_id": "seg_000", "split": "train", "video_id": "seg", "url": "file:///seg.mp4", "licence": "CC-BY",
        "segment_start": 0.0, "fps": 24.0, "tempo": 120.0, "camera_pitch": 5.0, "camera_roll": 0.0}


@pytest.fixture
def groups() -> list:
    # Dancer 1 the whole segment (frames 0-143), dancer 2 from frame 20, dancer 3 only frames 60-100.
    clips = [_dancer(1, 0, 144, -1.0), _dancer(2, 20, 124, 1.0), _dancer(3, 60, 41, 0.0)]
    return segment_group_windows(clips, _features(144), W, HOP, META)


def test_a_group_window_holds_every_dancer_who_covers_it_where_they_stand(groups: list) -> None:
    # Segment-grid starts 0, 24, 48, 72, 96: dancer 2 covers from 24; dancer 3 covers no whole window.
    assert [g.meta["start_frame"] for g in groups] == [24, 48, 72, 96]
    assert all(g.meta["dancers"] == 2 and g.meta["track_ids"] == [1, 2] for g in groups)
    first = groups[0]
    assert first.world.shape == (2, W, 17, 3) and first.mfcc.shape == (W, 39)
    # 2 m apart, about the group's centre; the floor stays at y = 0.
    gap = first.world[1, :, 0, 0] - first.world[0, :, 0, 0]
    assert np.allclose(gap, 2.0) and abs(first.world[:, :, 0, 0].mean()) < 1e-6 and first.world[..., 1].min() == 0


def test_each_solo_window_links_to_the_group_window_that_overlaps_it_most(groups: list) -> None:
    solo = [Window({"clip_id": "seg_000_2_0", "start_frame": k}, *([None] * 5)) for k in (20, 44, 68, 92)]
    solo.append(Window({"clip_id": "seg_000_3_0", "start_frame": 60}, *([None] * 5)))
    link_solo_windows(solo, groups, W)
    assert [w.meta["group_window_id"] for w in solo] == ["seg_000_g000024", "seg_000_g000048", "seg_000_g000072",
                                                         "seg_000_g000096", ""]


def test_group_shards_load_as_the_groups_config_of_the_card(groups: list, tmp_path: Path) -> None:
    import datasets

    from pipeline.corpus.build import write_group_shards, write_shards
    from pipeline.corpus.card import hf_front_matter
    from tests.corpus.test_corpus import synthetic_windows

    write_shards(tmp_path, synthetic_windows(), 48, per_shard=8, row_group=4, params={})
    assert write_group_shards(tmp_path, groups, W, per_shard=3, row_group=2, params={}) == {"train": 4, "val": 0}
    folder = tmp_path / "data/corpus"
    (folder / "README.md").write_text(hf_front_matter(["train", "val"], ["train"]) + "# dance3d corpus\n")
    loaded = datasets.load_dataset(str(folder), "groups", cache_dir=str(tmp_path / "hf"))
    rows = loaded["train"]
    assert len(rows) == 4 and rows[0]["dancers"] == 2 and rows[0]["clip_ids"] == ["seg_000_1_0", "seg_000_2_0"]
    world = np.array(rows[0]["world_joints"], np.float32)
    assert world.shape == (2, W, 17, 3) and np.allclose(world, groups[0].world, atol=1e-6)
    assert "world_joints" in datasets.load_dataset(str(folder), cache_dir=str(tmp_path / "hf2"))["train"].column_names
    # The loading tutorial asks for the configs first: here `groups` is one of them ...
    assert "groups" in datasets.get_dataset_config_names(str(folder))
    # ... and on a corpus of solo dancers it is not, so the tutorial's check takes its other branch.
    (folder / "README.md").write_text(hf_front_matter(["train", "val"], []) + "# dance3d corpus\n")
    assert datasets.get_dataset_config_names(str(folder)) == ["default", "smpl"]
