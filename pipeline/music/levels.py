"""The dancers' beat level: which metrical level of the music a window's dance follows.

A tracker finds one level of the music's pulse, but music often allows two: a slow song whose
dancers step on every beat or on every other one, a fast one danced at half time, loud off-beats
that make double time as plausible as the written beat. The dance decides. For each window the
candidate levels are the tracked beats, half of them (every other beat, the ones bars start on;
only with an even number of beats a bar) and double (the tracked beats and the midpoints between
them), each kept only when its tempo lies in ``TEMPO_RANGE``. Each is scored by how well the
dancer's kinematic beats (``alignment.kinematic_beats``) fall on it: mir_eval's F-measure with a
tolerance of ``TOLERANCE_FRAMES``. Another level replaces the tracked one only when it scores at
least ``MARGIN`` higher and at least ``MIN_FIT``, and the window has ``MIN_MOTION_BEATS`` motion
beats; the window's
``beat_level`` column says which level and ``beat_level_reason`` why.

Bar starts (downbeats) are the same instants at every level; beat and bar phase (0-1) are
computed from the chosen level's beats over the whole segment, so a window's first and last
frames have a phase as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import mir_eval
import numpy as np

from pipeline.music.beats import tempo_of

TEMPO_RANGE = (40.0, 240.0)  # BPM a level may have: a slow half time to fast footwork
MARGIN = 0.1
MIN_FIT = 0.4  # below this F-measure no level describes the dance (speech, free movement): keep the tracked one
MIN_MOTION_BEATS = 4
TOLERANCE_FRAMES = 2
FACTORS = {"tracked": 1.0, "half": 0.5, "double": 2.0}


@dataclass(frozen=True)
class BeatLevel:
    name: str                    # "tracked", "half" or "double"
    scores: dict[str, float]     # each candidate level's F-measure against the motion beats (NaN: not scored)
    reason: str


def candidate_levels(beats: np.ndarray, downbeats: np.ndarray, beats_per_bar: int) -> dict[str, np.ndarray]:
    """The beat times of each level the music allows (seconds, the clock of ``beats``)."""
    beats = np.asarray(beats, float)
    out = {"tracked": beats}
    if len(beats) < 2:
        return out
    if beats_per_bar % 2 == 0:  # every other beat, the half that holds the bar starts
        on_bar = np.isin(np.round(beats, 6), np.round(np.asarray(downbeats, float), 6))
        parity = int(np.argmax([on_bar[0::2].sum(), on_bar[1::2].sum()]))
        out["half"] = beats[parity::2]
    out["double"] = np.sort(np.concatenate([beats, (beats[1:] + beats[:-1]) / 2]))
    low, high = TEMPO_RANGE
    return {name: b for name, b in out.items() if name == "tracked" or low <= tempo_of(b) <= high}


def choose_level(levels: dict[str, np.ndarray], motion_beats: np.ndarray, start: float, end: float,
                 fps: float) -> BeatLevel:
    """The level a window [start, end) s follows; ``motion_beats`` in seconds on the same clock."""
    motion = np.asarray(motion_beats, float)
    inside = {name: b[(b >= start) & (b < end)] for name, b in levels.items()}
    if len(motion) < MIN_MOTION_BEATS or len(inside["tracked"]) < 2:
        return BeatLevel("tracked", {n: float("nan") for n in FACTORS},
                         f"as tracked: {len(motion)} motion beats and {len(inside['tracked'])} music beats are too "
                         "few to tell the dance's level")
    window = TOLERANCE_FRAMES / fps
    scores = {name: float(mir_eval.beat.f_measure(b, motion, f_measure_threshold=window)) if len(b) else 0.0
              for name, b in inside.items()}
    best = max(scores, key=scores.get)
    others = ", ".join(f"{n} {scores[n]:.2f}" for n in FACTORS if n in scores and n != best)
    missing = [n for n in FACTORS if n not in scores]
    note = f"; {' and '.join(missing)} outside {TEMPO_RANGE[0]:g}-{TEMPO_RANGE[1]:g} BPM" if missing else ""
    full = {n: scores.get(n, float("nan")) for n in FACTORS}
    if best != "tracked" and scores[best] >= max(scores["tracked"] + MARGIN, MIN_FIT):
        return BeatLevel(best, full, f"{best}: the dance's beats fall on it (F {scores[best]:.2f}; {others}){note}")
    alternatives = ", ".join(f"{n} {scores[n]:.2f}" for n in FACTORS if n in scores and n != "tracked")
    why = "no other level fits the dance clearly better" if scores[best] >= MIN_FIT else \
        f"no level fits the motion beats well (F below {MIN_FIT:g})"
    return BeatLevel("tracked", full, f"as tracked: {why} (F {scores['tracked']:.2f}; "
                                      f"{alternatives or 'no other level'}){note}")


def phase(events: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Where each of ``times`` falls between consecutive ``events`` (0 at an event, towards 1 before
    the next); before the first and after the last, the nearest interval carried on. NaN with fewer
    than two events."""
    events, times = np.asarray(events, float), np.asarray(times, float)
    if len(events) < 2:
        return np.full(len(times), np.nan)
    i = np.clip(np.searchsorted(events, times, side="right") - 1, 0, len(events) - 2)
    return np.mod((times - events[i]) / (events[i + 1] - events[i]), 1.0)
