"""Motion beats and how well they fall on the music's beats: a quality signal per window.

Motion beats are AIST++'s kinematic beats: local minima of the mean joint speed after a
Gaussian smoothing of 5 frames at 60 fps (0.083 s), i.e. the instants where the dancer's
movement turns. Two scores compare them with the music beats:

- the **beat-align score** as Bailando computes it (lisiyao21/Bailando,
  ``utils/beat_align_score.py``, and the papers that reuse its code): for every music beat,
  exp(-d^2 / 2 sigma^2) with d its distance to the nearest motion beat and sigma = 3 frames at
  60 fps (0.05 s), averaged over the music beats;
- the **beat-align score** as AIST++ defines and computes it (google-research/mint,
  ``tools/calculate_beat_scores.py``): the same kernel the other way round, for every motion
  beat towards its nearest music beat, averaged over the motion beats. It rewards a dance with
  few, well-placed turns; Bailando's rewards a dance that marks every beat;
- the **beat-consistency F-score** (the seed system): mir_eval's F-measure of the motion
  beats against the music beats with a tolerance of 2 frames at the corpus rate.

A real dance corpus scores clearly higher with its own music than with a control: that gap
checks the whole pipeline (sync, lifting, smoothing) at once. Two controls: another video's
music (shuffled), which fails on covers (two videos dancing to one song share their beats), and
the window's own music beats shifted by half a beat (``half_beat_later``), which holds for any
corpus: the same tempo and the same beat count, only the phase is wrong.
"""

from __future__ import annotations

import mir_eval
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import argrelextrema

SMOOTH_SECONDS = 5 / 60
SIGMA_SECONDS = 3 / 60
F1_TOLERANCE_FRAMES = 2


def kinematic_beats(joints: np.ndarray, fps: float) -> np.ndarray:
    """Frame indices (into ``joints``, T x J x 3) of the local minima of the smoothed mean joint speed."""
    joints = np.asarray(joints, np.float64)
    if len(joints) < 3:
        return np.zeros(0, np.int64)
    speed = np.linalg.norm(np.diff(joints, axis=0), axis=-1).mean(axis=-1)
    speed = gaussian_filter1d(speed, SMOOTH_SECONDS * fps, mode="nearest")
    return argrelextrema(speed, np.less)[0].astype(np.int64)


def beat_align_score(music_beats: np.ndarray, motion_beats: np.ndarray) -> float:
    """Bailando's beat-align score of beat times in seconds (NaN without music beats; 0 without motion beats)."""
    music_beats, motion_beats = np.asarray(music_beats, float), np.asarray(motion_beats, float)
    if not len(music_beats):
        return float("nan")
    if not len(motion_beats):
        return 0.0
    d = np.abs(music_beats[:, None] - motion_beats[None, :]).min(axis=1)
    return float(np.exp(-(d ** 2) / (2 * SIGMA_SECONDS ** 2)).mean())


def beat_align_score_aistpp(music_beats: np.ndarray, motion_beats: np.ndarray) -> float:
    """AIST++'s beat-align score: each motion beat towards its nearest music beat (NaN without motion
    beats; 0 without music beats)."""
    music_beats, motion_beats = np.asarray(music_beats, float), np.asarray(motion_beats, float)
    if not len(motion_beats):
        return float("nan")
    if not len(music_beats):
        return 0.0
    d = np.abs(motion_beats[:, None] - music_beats[None, :]).min(axis=1)
    return float(np.exp(-(d ** 2) / (2 * SIGMA_SECONDS ** 2)).mean())


def beat_f1(music_beats: np.ndarray, motion_beats: np.ndarray, fps: float) -> float:
    """Beat-consistency F-score: motion beats against music beats, within 2 frames (NaN without music beats)."""
    music_beats, motion_beats = np.asarray(music_beats, float), np.asarray(motion_beats, float)
    if not len(music_beats):
        return float("nan")
    return float(mir_eval.beat.f_measure(music_beats, motion_beats, f_measure_threshold=F1_TOLERANCE_FRAMES / fps))


def half_beat_later(beat_frames: np.ndarray) -> np.ndarray:
    """Beat frames moved later by half their median interval: the same music, off the beat.
    (Fewer than two beats: unchanged, there is no interval to halve.)"""
    beat_frames = np.asarray(beat_frames, float)
    if len(beat_frames) < 2:
        return beat_frames
    return beat_frames + np.median(np.diff(beat_frames)) / 2


def shuffled_pairs(groups: list[str], seed: int = 0) -> np.ndarray:
    """For each item i a partner j != i, from another group (video) wherever one exists; seeded."""
    rng = np.random.default_rng(seed)
    n = len(groups)
    partners = np.arange(n)
    for i in range(n):
        others = [j for j in range(n) if groups[j] != groups[i]] or [j for j in range(n) if j != i]
        partners[i] = others[rng.integers(len(others))] if others else i
    return partners
