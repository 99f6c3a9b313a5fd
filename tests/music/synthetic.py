"""Synthetic music whose beats and downbeats are known exactly, built to provoke beat-tracking errors.

Every piece is drums plus a bass line at 22050 Hz: a kick (decaying 55 Hz sine), a snare
(noise burst), a hi-hat (short high-passed noise) and a bass note on chosen beats. The
patterns are the classic traps: strong off-beats at a slow tempo (the double-tempo trap),
swung eighths, and a tempo change half-way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SR = 22050


@dataclass(frozen=True)
class Piece:
    name: str
    audio: np.ndarray       # mono float32 at SR
    beats: np.ndarray       # seconds
    downbeats: np.ndarray   # seconds
    tempo: float            # annotated BPM (the first section's, for a tempo change)


def _kick(sr: int) -> np.ndarray:
    t = np.arange(int(0.25 * sr)) / sr
    return np.sin(2 * np.pi * (55 + 60 * np.exp(-t * 40)) * t) * np.exp(-t * 12)


def _snare(sr: int, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(int(0.15 * sr)) / sr
    return (rng.normal(size=t.size) * 0.7 + np.sin(2 * np.pi * 190 * t)) * np.exp(-t * 30)


def _hat(sr: int, rng: np.random.Generator) -> np.ndarray:
    n = int(0.05 * sr)
    noise = np.diff(rng.normal(size=n + 1))  # a first difference: high-passed noise
    return noise * np.exp(-np.arange(n) / sr * 90) * 0.5


def _bass(sr: int, freq: float, seconds: float) -> np.ndarray:
    t = np.arange(int(seconds * sr)) / sr
    return np.sin(2 * np.pi * freq * t) * np.exp(-t * 3) * 0.6


def _add(y: np.ndarray, sound: np.ndarray, at: float, gain: float, sr: int) -> None:
    i = int(round(at * sr))
    if i < len(y):
        n = min(len(sound), len(y) - i)
        y[i: i + n] += gain * sound[:n]


def render(name: str, beat_times: np.ndarray, *, beats_per_bar: int = 4, kick_gain: float = 1.0,
           snare_gain: float = 0.6, hat_gain: float = 0.4, offbeat_gain: float = 0.0, swing: float = 0.5,
           seconds: float | None = None, seed: int = 0) -> Piece:
    """Drums and bass on ``beat_times``: kick and bass on beats 1 and 3, snare on 2 and 4, hats on
    every beat and (``offbeat_gain``) a loud snare+hat on each off-beat, placed at ``swing`` of the
    beat (0.5 straight, 0.667 triplet swing)."""
    rng = np.random.default_rng(seed)
    seconds = seconds or float(beat_times[-1] + 1.0)
    y = np.zeros(int(seconds * SR))
    kick, snare, hat = _kick(SR), _snare(SR, rng), _hat(SR, rng)
    notes = (55.0, 65.4, 49.0, 73.4)
    for i, t in enumerate(beat_times):
        pos = i % beats_per_bar
        ibi = beat_times[i + 1] - t if i + 1 < len(beat_times) else beat_times[i] - beat_times[i - 1]
        if pos % 2 == 0:
            _add(y, kick, t, kick_gain * (1.3 if pos == 0 else 1.0), SR)
            _add(y, _bass(SR, notes[(i // beats_per_bar) % 4], 0.9 * ibi), t, 1.0 if pos == 0 else 0.5, SR)
        else:
            _add(y, snare, t, snare_gain, SR)
        _add(y, hat, t, hat_gain, SR)
        if offbeat_gain:
            _add(y, snare, t + swing * ibi, offbeat_gain, SR)
            _add(y, hat, t + swing * ibi, offbeat_gain, SR)
        elif swing != 0.5:
            _add(y, hat, t + swing * ibi, hat_gain, SR)
    y = (0.5 * y / np.abs(y).max()).astype(np.float32)
    beats = np.asarray(beat_times, float)
    return Piece(name, y, beats, beats[::beats_per_bar], float(60 / np.median(np.diff(beats[: beats_per_bar * 4]))))


def steady(bpm: float, seconds: float, first: float = 0.5) -> np.ndarray:
    return np.arange(first, seconds - 0.5, 60.0 / bpm)


def pieces() -> list[Piece]:
    """The test set: each is 30-40 s."""
    change = np.concatenate([steady(100, 20.5), 20.3 + steady(132, 20.0, first=0.2)])
    return [
        render("four_on_the_floor_124", steady(124, 30)),
        render("slow_with_strong_offbeats_70", steady(70, 34), offbeat_gain=1.2, kick_gain=0.8),
        render("swing_110", steady(110, 30), swing=2 / 3),
        render("tempo_change_100_to_132", change),
        render("waltz_90", steady(90, 30), beats_per_bar=3),
        render("boom_chick_85.5", steady(85.5, 34), offbeat_gain=0.7, snare_gain=0.9),
        render("between_grid_lags_163", steady(163, 30), offbeat_gain=0.3),
    ]
