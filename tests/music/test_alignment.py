"""Motion beats and beat alignment: matched music must score clearly higher than shuffled music."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.music.alignment import beat_align_score, beat_f1, half_beat_later, kinematic_beats, shuffled_pairs
from pipeline.music.audio import compute_features, feature_rate
from tests.music.test_audio import click_track

FPS = 24


def swinging_arms(seconds: float, period: float, fps: float = FPS) -> np.ndarray:
    """A still body whose arms swing up and down with ``period``: they turn every period / 2."""
    t = np.arange(int(seconds * fps)) / fps
    joints = np.zeros((len(t), 17, 3))
    joints[:, :, 1] = -np.linspace(0, 1.7, 17)  # some fixed pose
    joints[:, 11:, 1] += 0.3 * np.cos(2 * np.pi * t / period)[:, None]
    return joints


def test_kinematic_beats_are_the_turning_points() -> None:
    beats = kinematic_beats(swinging_arms(10, period=1.0), FPS) / FPS
    turns = np.arange(0.5, 10, 0.5)
    assert len(beats) == len(turns) - 1 or len(beats) == len(turns)
    assert np.abs(beats[:, None] - turns[None, :]).min(axis=1).max() <= 1.5 / FPS


def test_matched_music_scores_higher_than_shifted_music() -> None:
    motion = kinematic_beats(swinging_arms(20, period=1.0), FPS) / FPS
    on_beat = np.arange(0.5, 20, 0.5)
    off_beat = on_beat + 0.25  # a quarter period late: the worst case
    assert beat_align_score(on_beat, motion) > 0.9 > 0.1 > beat_align_score(off_beat, motion)
    assert beat_f1(on_beat, motion, FPS) > 0.9 and beat_f1(off_beat, motion, FPS) < 0.1
    assert np.isnan(beat_align_score(np.zeros(0), motion)) and beat_align_score(on_beat, np.zeros(0)) == 0.0


def test_shuffled_partners_come_from_other_videos() -> None:
    groups = ["a", "a", "b", "b", "c"]
    partners = shuffled_pairs(groups, seed=1)
    assert all(groups[j] != groups[i] for i, j in enumerate(partners))
    assert (shuffled_pairs(groups, seed=1) == partners).all()


def _warp_to_grid(joints: np.ndarray, fps: float, beat_period: float) -> np.ndarray:
    """Time-warp motion so its kinematic beats fall on a grid of ``beat_period`` seconds."""
    beats = kinematic_beats(joints, fps)
    beats = beats[np.concatenate([[True], np.diff(beats) >= 0.25 * fps])]  # one turn per step
    src = np.concatenate([[0], beats, [len(joints) - 1]]) / fps
    dst = np.concatenate([[0], beat_period * np.arange(1, len(beats) + 1),
                          [beat_period * (len(beats) + 1)]])
    t_new = np.arange(0, dst[-1], 1 / fps)
    t_src = np.interp(t_new, dst, src)
    flat = joints.reshape(len(joints), -1)
    frames = np.arange(len(joints)) / fps
    return np.stack([np.interp(t_src, frames, flat[:, c]) for c in range(flat.shape[1])], -1).reshape(-1, 17, 3)


@pytest.mark.parametrize("clip", ["perfume/aachan.bvh", "perfume/kashiyuka.bvh"])
def test_motion_capture_timed_to_clicks_aligns_with_its_music_not_with_shuffled(mocap_dir: Path, clip: str) -> None:
    """Real dance whose steps are timed to generated clicks; the clicks go through the audio features."""
    from pipeline.motion.mocap.sources import BVH_SOURCES, load_bvh_sequence, resample

    seq = resample(load_bvh_sequence(mocap_dir / clip, BVH_SOURCES["perfume"]), FPS)
    joints = seq.h36m - seq.h36m[:, :1]  # root-relative, as in the corpus
    period = 0.5  # 120 BPM
    warped = _warp_to_grid(joints[: 30 * FPS], FPS, period)[: 20 * FPS]
    motion = kinematic_beats(warped, FPS) / FPS
    audio, clicks = click_track(120, 20, sr=feature_rate(FPS), first=period)
    music = compute_features(audio, fps=FPS).beat_times
    half_beat_late = half_beat_later(music)
    assert np.allclose(half_beat_late - music, period / 2, atol=0.02)
    matched, control = beat_align_score(music, motion), beat_align_score(half_beat_late, motion)
    assert matched > 0.35 and matched > 4 * control  # measured: 0.50 / 0.06 and 0.42 / 0.05
    assert beat_f1(music, motion, FPS) > beat_f1(half_beat_late, motion, FPS) + 0.3
