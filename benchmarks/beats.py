"""Beat tracking, every tracker side by side: the first dance3d tracker (librosa on the 24 fps
onset envelope), librosa at full resolution, and madmom's RNN (the default), on synthetic music
whose beats are known (tests/music/synthetic.py), scored with mir_eval (first 5 s ignored).
Real annotated music: ``dance3d eval beats --dir D``.

Usage: python benchmarks/beats.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import librosa
import mir_eval
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.music.audio import HOP  # noqa: E402
from pipeline.music.beats import track_beats, track_beats_motion_rate  # noqa: E402
from tests.music.synthetic import SR, pieces  # noqa: E402

METHODS = ("first", "librosa", "rnn")


def first(y: np.ndarray) -> np.ndarray:
    y24 = librosa.resample(y, orig_sr=SR, target_sr=24 * HOP)
    return track_beats_motion_rate(librosa.onset.onset_strength(y=y24, sr=24 * HOP, hop_length=HOP), 24, HOP)


def main() -> None:
    track = {"first": first, "librosa": lambda y: track_beats(y, SR, "librosa").times,
             "rnn": lambda y: track_beats(y, SR, "rnn").times}
    for method in METHODS:  # each tracker's one-off cost (imports, JIT, model loading) before timing
        track[method](pieces()[0].audio[: 10 * SR])
    rows, seconds, audio = [], dict.fromkeys(METHODS, 0.0), 0.0
    for piece in pieces():
        audio += len(piece.audio) / SR
        result = {}
        for method in METHODS:
            start = time.perf_counter()
            est = track[method](piece.audio)
            seconds[method] += time.perf_counter() - start
            s = mir_eval.beat.evaluate(piece.beats, np.asarray(est, float))
            result[method] = (s["F-measure"], s["Correct Metric Level Total"], s["Any Metric Level Total"])
        rows.append((piece.name, result))
    print(f"{'piece':32s} " + " ".join(f"{'F ' + m:>10s}" for m in METHODS) + " "
          + " ".join(f"{'AMLt ' + m:>13s}" for m in METHODS))
    for name, r in [*rows, ("mean", {m: np.mean([r[m] for _, r in rows], axis=0) for m in METHODS})]:
        print(f"{name:32s} " + " ".join(f"{r[m][0]:10.3f}" for m in METHODS) + " "
              + " ".join(f"{r[m][2]:13.3f}" for m in METHODS))
    print(f"tracking time over {audio:.0f} s of music, one-off costs excluded: "
          + ", ".join(f"{m} {seconds[m]:.2f} s ({seconds[m] / audio:.3f} s per s)" for m in METHODS))


if __name__ == "__main__":
    main()
