"""Benchmark for the smooth stage (issue: 3D): the banded, all-series-at-once HP filter
against statsmodels' hpfilter called once per series, on a corpus-sized input, in one run.
Also: lift-stage throughput (frames/s) of an exported lifter on clips of the demo's size.

Usage: python benchmarks/smooth.py [--clips 200 --series 51 --frames 2000] [--lifter models/lifter.onnx]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.motion.smoothing import hp_trend  # noqa: E402


def per_series_statsmodels(clips: list[np.ndarray], lamb: float) -> list[np.ndarray]:
    from statsmodels.tsa.filters.hp_filter import hpfilter

    return [np.column_stack([hpfilter(c[:, k], lamb)[1] for k in range(c.shape[1])]) for c in clips]


def vectorised(clips: list[np.ndarray], lamb: float) -> list[np.ndarray]:
    return [hp_trend(c, lamb) for c in clips]


def lift_fps(lifter: Path, frames: int = 2000, clips: int = 8, runs: int = 3) -> float:
    import onnxruntime as ort

    from pipeline.motion.lifting.infer import Lifter

    lift = Lifter.from_session(ort.InferenceSession(str(lifter)))
    rng = np.random.default_rng(0)
    data = [rng.uniform(100, 600, (frames, 17, 2)) for _ in range(clips)]
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        lift.lift(data, 720, 1280, flip=True)
        times.append(time.perf_counter() - t0)
    return frames * clips / statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=200)
    parser.add_argument("--series", type=int, default=51)
    parser.add_argument("--frames", type=int, default=2000)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--lifter", type=Path, default=Path("models/lifter.onnx"))
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    clips = [rng.normal(size=(args.frames, args.series)).cumsum(0) for _ in range(args.clips)]
    fast, slow = [], []
    for _ in range(args.runs):  # interleaved, so machine noise hits both alike
        t0 = time.perf_counter()
        ours = vectorised(clips, 1.0)
        fast.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        ref = per_series_statsmodels(clips, 1.0)
        slow.append(time.perf_counter() - t0)
    diff = max(float(np.abs(a - b).max()) for a, b in zip(ours, ref))
    report = {
        "input": f"{args.clips} clips x {args.series} series x {args.frames} frames",
        "runs": args.runs,
        "vectorised_s": round(statistics.median(fast), 3),
        "statsmodels_per_series_s": round(statistics.median(slow), 3),
        "speedup": round(statistics.median(slow) / statistics.median(fast), 1),
        "max_abs_difference": diff,
    }
    if args.lifter.exists():
        report["lift_frames_per_s"] = round(lift_fps(args.lifter), 1)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
