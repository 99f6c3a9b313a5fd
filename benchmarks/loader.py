"""Benchmark for the training loader (issue: corpus): samples/s of WindowDataset against a raw
pyarrow read of the same shards (same columns, decoded to arrays), side by side in one run.

Usage: python benchmarks/loader.py [--windows 2048 --frames 480] (builds a synthetic corpus in a temp dir)
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.corpus.build import write_shards  # noqa: E402
from pipeline.corpus.windows import Window  # noqa: E402
from pipeline.train.dataset import WindowDataset, shard_files  # noqa: E402


def build(root: Path, n: int, frames: int) -> Path:
    rng = np.random.default_rng(0)
    windows = []
    for i in range(n):
        meta = {"window_id": f"w{i:06d}", "split": "train", "video_id": f"v{i // 20}", "url": "", "title": "",
                "channel": "", "style": "", "licence": "", "segment_id": "s", "clip_id": f"c{i // 5}", "track_id": 1,
                "start_frame": 0, "start_time": 0.0, "segment_start": 0.0, "tempo": 120.0}
        windows.append(Window(meta, rng.normal(size=(frames, 17, 3)).astype(np.float32),
                              rng.normal(size=(frames, 39)).astype(np.float32), np.zeros((frames, 12), np.float32),
                              np.zeros(frames, np.float32), np.zeros(frames, np.int8)))
    write_shards(root, windows, frames, per_shard=256, row_group=32, params={})
    return root / "data/corpus/train"


def raw_pyarrow(folder: Path) -> int:
    n = 0
    for path in shard_files(folder):
        table = pq.read_table(path, columns=["window_id", "motion", "mfcc", "beat"])
        motion = np.asarray(table.column("motion").combine_chunks().flatten().flatten().flatten())
        mfcc = np.asarray(table.column("mfcc").combine_chunks().flatten().flatten())
        beat = np.asarray(table.column("beat").combine_chunks().flatten())
        n += table.num_rows
        assert motion.size and mfcc.size and beat.size
    return n


def loader(folder: Path) -> int:
    return sum(1 for _ in WindowDataset(folder, shuffle_buffer=256, seed=0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--windows", type=int, default=2048)
    parser.add_argument("--frames", type=int, default=480)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = build(Path(tmp), args.windows, args.frames)
        ours, raw = [], []
        for _ in range(args.runs):  # interleaved
            t0 = time.perf_counter()
            n1 = loader(folder)
            ours.append(n1 / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            n2 = raw_pyarrow(folder)
            raw.append(n2 / (time.perf_counter() - t0))
        assert n1 == n2 == args.windows
    report = {"windows": args.windows, "frames_per_window": args.frames, "runs": args.runs,
              "loader_samples_per_s": round(statistics.median(ours), 1),
              "raw_pyarrow_samples_per_s": round(statistics.median(raw), 1),
              "ratio": round(statistics.median(ours) / statistics.median(raw), 3)}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
