"""The dancers' beat level: where the music allows half or double time, the dance decides which
level the window's beats use, and says why."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.music.alignment import kinematic_beats
from pipeline.music.levels import candidate_levels, choose_level, phase
from tests.music.test_alignment import FPS, _warp_to_grid, swinging_arms

BEATS = np.arange(0.6, 20.0, 0.6)  # 100 BPM: half 50, double 200, both dance tempos
DOWNBEATS = BEATS[1::4]            # bars start on the second beat


def _level(joints: np.ndarray, beats: np.ndarray = BEATS, downbeats: np.ndarray = DOWNBEATS):
    levels = candidate_levels(beats, downbeats, 4)
    return levels, choose_level(levels, kinematic_beats(joints, FPS) / FPS, 0.0, len(joints) / FPS, FPS)


def test_half_time_keeps_the_beats_the_bars_start_on_and_double_adds_the_midpoints() -> None:
    levels = candidate_levels(BEATS, DOWNBEATS, 4)
    assert set(DOWNBEATS) <= set(levels["half"]) and np.allclose(np.diff(levels["half"]), 1.2)
    assert np.allclose(np.diff(levels["double"]), 0.3)
    assert "half" not in candidate_levels(BEATS, BEATS[::3], 3)  # three beats a bar do not halve
    assert "double" not in candidate_levels(np.arange(0, 20, 0.33), [], 4)  # 364 BPM is no dance tempo


@pytest.mark.parametrize(("turn_every", "level"), [(0.6, "tracked"), (1.2, "half"), (0.3, "double")])
def test_arms_turning_at_a_level_choose_it(turn_every: float, level: str) -> None:
    _, chosen = _level(swinging_arms(20, 2 * turn_every))
    assert chosen.name == level and chosen.reason.startswith(level if level != "tracked" else "as tracked")


def test_a_window_with_too_few_motion_beats_keeps_the_tracked_level_and_says_so() -> None:
    still = np.zeros((FPS * 20, 17, 3))
    _, chosen = _level(still)
    assert chosen.name == "tracked" and "too few" in chosen.reason


@pytest.mark.parametrize("clip", ["perfume/aachan.bvh", "perfume/kashiyuka.bvh"])
def test_captured_dance_tracked_at_double_time_is_labelled_at_its_own_level(mocap_dir: Path, clip: str) -> None:
    """Real dance timed to 120 BPM; the tracker reports 240 BPM (every off-beat too): half is chosen."""
    from pipeline.motion.mocap.sources import BVH_SOURCES, load_bvh_sequence, resample

    seq = resample(load_bvh_sequence(mocap_dir / clip, BVH_SOURCES["perfume"]), FPS)
    joints = _warp_to_grid((seq.h36m - seq.h36m[:, :1])[: 30 * FPS], FPS, 0.5)[: 20 * FPS]
    own = np.arange(0.5, 20.0, 0.5)
    doubled = np.arange(0.5, 20.0, 0.25)
    levels, chosen = _level(joints, doubled, doubled[::8])
    assert chosen.name == "half", chosen.reason
    assert np.allclose(levels["half"], own)
    _, at_own = _level(joints, own, own[::4])  # tracked at its own tempo, it stays there
    assert at_own.name == "tracked", at_own.reason


def test_phase_rises_from_each_beat_to_the_next_and_carries_on_past_the_ends() -> None:
    p = phase(np.array([1.0, 2.0, 4.0]), np.array([0.5, 1.0, 1.5, 3.0, 4.5]))
    assert np.allclose(p, [0.5, 0.0, 0.5, 0.5, 0.25])
    assert np.isnan(phase(np.array([1.0]), np.array([0.0]))).all()


def test_movement_that_fits_no_level_keeps_the_tracked_one() -> None:
    from scipy.ndimage import gaussian_filter1d

    rng = np.random.default_rng(0)  # smooth limbs turning at random instants, as in free movement
    wander = gaussian_filter1d(rng.normal(0, 1.0, (FPS * 20, 17, 3)), sigma=0.3 * FPS, axis=0)
    _, chosen = _level(wander)
    assert chosen.name == "tracked" and ("no level fits" in chosen.reason or "no other level" in chosen.reason)
