"""Beat tracking before and after: the previous default (librosa on the 24 fps onset envelope)
against the pipeline's tracker (22050 Hz, hop 512, time-varying tempo), on synthetic music
whose beats are known (tests/music/synthetic.py), scored with mir_eval (first 5 s ignored).

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


def previous(y: np.ndarray) -> np.ndarray:
    y24 = librosa.resample(y, orig_sr=SR, target_sr=24 * HOP)
    return track_beats_motion_rate(librosa.onset.onset_strength(y=y24, sr=24 * HOP, hop_length=HOP), 24, HOP)


def main() -> None:
    rows, seconds = [], {"previous": 0.0, "dance3d": 0.0}
    for piece in pieces():
        result = {}
        for name, track in (("previous", previous), ("dance3d", lambda y: track_beats(y, SR).times)):
            start = time.perf_counter()
            est = track(piece.audio)
            seconds[name] += time.perf_counter() - start
            scores = mir_eval.beat.evaluate(piece.beats, np.asarray(est, float))
            result[name] = (scores["F-measure"], scores["Correct Metric Level Total"], scores["Any Metric Level Total"])
        rows.append((piece.name, result))
    print(f"{'piece':32s} {'F prev':>7s} {'F new':>7s} {'CMLt prev':>9s} {'CMLt new':>9s} {'AMLt prev':>9s} "
          f"{'AMLt new':>9s}")
    for name, r in rows:
        print(f"{name:32s} {r['previous'][0]:7.3f} {r['dance3d'][0]:7.3f} {r['previous'][1]:9.3f} "
              f"{r['dance3d'][1]:9.3f} {r['previous'][2]:9.3f} {r['dance3d'][2]:9.3f}")
    mean = {m: np.mean([r[m] for _, r in rows], axis=0) for m in ("previous", "dance3d")}
    print(f"{'mean':32s} {mean['previous'][0]:7.3f} {mean['dance3d'][0]:7.3f} {mean['previous'][1]:9.3f} "
          f"{mean['dance3d'][1]:9.3f} {mean['previous'][2]:9.3f} {mean['dance3d'][2]:9.3f}")
    print(f"tracking time over {len(rows)} pieces: previous {seconds['previous']:.2f} s, "
          f"dance3d {seconds['dance3d']:.2f} s")


if __name__ == "__main__":
    main()
