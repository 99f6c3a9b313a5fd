"""Lifter training cost: wall time and memory per 1,000 steps of a train_lifter profile, and what a
checkpoint costs, on the machine it runs on.

Usage: python -m benchmarks.lifter_training [--profile long] [--steps 200] [--threads 2] [--mocap DIR]
                                            [--out benchmarks/results/lifter_training.json]

It loads the profile's motion capture (timed apart), trains ``--steps`` steps with a checkpoint at
the end (as ``train_lifter`` does every ``checkpoint_minutes``), and reports seconds per 1,000 steps
(the median over blocks of 50 steps, scaled), the process's peak resident memory (the capture
loaded, as in training) and the checkpoint's size. No evaluation: the held-out protocol's cost is the
same for every profile.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np

from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.storage import write_json
from pipeline.motion.lifting.evaluate import split
from stages.train_lifter import config_from_params


@contextmanager
def optimiser_step_times() -> Iterator[list[float]]:
    """The monotonic time of every optimiser (Adam) step taken inside the block."""
    import torch

    stamps: list[float] = []
    original = torch.optim.Adam.step

    def timed_step(self, *a, **k):
        out = original(self, *a, **k)
        stamps.append(time.monotonic())
        return out

    torch.optim.Adam.step = timed_step
    try:
        yield stamps
    finally:
        torch.optim.Adam.step = original


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="long", help="a train_lifter profile of params.yaml (default long)")
    parser.add_argument("--steps", type=int, default=200, help="steps to time (default 200)")
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/lifter_training.json"))
    args = parser.parse_args()

    from pipeline.motion.lifting import train as training

    section = stage_params(load_params("params.yaml"), "train_lifter")
    params = with_profile({**section, "profile": args.profile}, "train_lifter")
    cfg = config_from_params({**params, "threads": args.threads})
    started = time.monotonic()
    train, _ = split(training.load_mocap(args.mocap, cfg), cfg.holdout)
    load_seconds = time.monotonic() - started

    with tempfile.TemporaryDirectory() as folder, optimiser_step_times() as stamps:
        checkpoint = Path(folder) / "lifter.pt"
        begun = time.monotonic()
        training.train_lifter(cfg, train, [], checkpoint=checkpoint, stop_after=args.steps, evaluate_after=False,
                              progress=False)
        total = time.monotonic() - begun
        size = checkpoint.stat().st_size
    blocks = [stamps[k + 50] - stamps[k] for k in range(0, len(stamps) - 50, 50)]
    per_1000 = 20 * float(np.median(blocks)) if blocks else 1000 * total / args.steps
    result = {"profile": args.profile, "steps_timed": args.steps, "threads": args.threads,
              "filter_widths": list(cfg.filter_widths), "channels": cfg.channels, "batch": cfg.batch,
              "train_minutes_of_capture": round(sum(s.frames / s.fps for s in train) / 60, 1),
              "load_seconds": round(load_seconds, 1), "seconds_per_1000_steps": round(per_1000, 1),
              "hours_for_profile": round(per_1000 * cfg.steps / 1000 / 3600, 2),
              "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
              "checkpoint_mib": round(size / 2 ** 20, 1), "machine": f"{platform.machine()}, {os.cpu_count()} cores"}
    print(json.dumps(result, indent=1))
    write_json(args.out, result)


if __name__ == "__main__":
    main()
