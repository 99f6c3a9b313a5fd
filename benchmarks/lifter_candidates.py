"""Lifter candidates side by side under the same CPU time (issue: 3D at the field's level).

Each candidate is a train_lifter profile's recipe (default ``long``: all the capture, the dance
sources weighted up) with another architecture. Its step time is measured first (``--probe`` steps),
then it trains for as many steps as fit in ``--minutes`` on this machine, with the learning rate
decaying over exactly those steps (a run cut short by the clock would stop at a high rate and
favour nobody), and is scored with the held-out protocol: the 40 sequences of today's set and the
later sources' takes, clean and noisy 2D.

Candidates: ``rf81`` (the shipped architecture: dilated convolutions, 81 frames, 256 channels),
``rf243`` (243 frames, 256 channels) and ``stt81`` (a compact spatio-temporal transformer of the
MixSTE kind, ``pipeline.motion.lifting.transformer``: 81 frames, width 64, three spatial and three
temporal blocks), trained by the same loop with the transformer in the convolutions' place. The
loop's own module is left as it is while the long run resumes from checkpoints keyed by its source.

Usage: DANCE3D_MOCAP=../shared/mocap python -m benchmarks.lifter_candidates [--minutes 20]
           [--candidates rf81,rf243,stt81] [--profile long] [--out benchmarks/results/lifter_candidates.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from benchmarks.lifter_training import optimiser_step_times
from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.storage import write_json
from pipeline.motion.lifting.evaluate import format_report, held_out_later, split
from stages.train_lifter import config_from_params

ARCHITECTURES = {"rf81": {"filter_widths": (3, 3, 3, 3), "channels": 256},
                 "rf243": {"filter_widths": (3, 3, 3, 3, 3), "channels": 256},
                 "stt81": {"filter_widths": (3, 3, 3, 3), "channels": 64}}
TRANSFORMERS = {"stt81": {"dim": 64, "depth": 3, "heads": 4}}


@contextmanager
def architecture(name: str, chunk: int):
    """The training loop builds ``name``'s model: the convolutions, or in their place a transformer
    with the same receptive field (the loop's ``TemporalModel`` swapped for the duration)."""
    from pipeline.motion.lifting import train as training

    if name not in TRANSFORMERS:
        yield
        return
    from pipeline.motion.lifting.transformer import SpatioTemporalTransformer

    def build(joints_in, joints_out, filter_widths, channels, dropout):
        rf = 1
        for w in filter_widths:
            rf *= w
        return SpatioTemporalTransformer(joints_in, joints_out, rf, chunk, **TRANSFORMERS[name])

    original = training.TemporalModel
    training.TemporalModel = build
    try:
        yield
    finally:
        training.TemporalModel = original


def seconds_per_step(cfg, train, steps: int) -> float:
    """The median time between optimiser steps over the last half of ``steps`` steps (the first
    half warms up)."""
    from pipeline.motion.lifting import train as training

    with optimiser_step_times() as stamps:
        training.train_lifter(replace(cfg, steps=steps), train, [], stop_after=steps, evaluate_after=False,
                              progress=False)
    half = stamps[len(stamps) // 2:]
    gaps = sorted(b - a for a, b in zip(half, half[1:]))
    return gaps[len(gaps) // 2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=20.0, help="training time per candidate (default 20)")
    parser.add_argument("--candidates", default="rf81,rf243")
    parser.add_argument("--profile", default="long", help="the train_lifter profile whose recipe they share")
    parser.add_argument("--probe", type=int, default=40, help="steps timed before each run (default 40)")
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/lifter_candidates.json"))
    args = parser.parse_args()

    from pipeline.motion.lifting import train as training

    section = stage_params(load_params("params.yaml"), "train_lifter")
    base = config_from_params(with_profile({**section, "profile": args.profile}, "train_lifter"))
    sequences = training.load_mocap(args.mocap, base)
    train, val = split(sequences, base.holdout)
    later = held_out_later(sequences)
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    for name in args.candidates.split(","):
        cfg = replace(base, **ARCHITECTURES[name])
        with architecture(name, cfg.chunk):
            per_step = seconds_per_step(cfg, train, args.probe)
            cfg = replace(cfg, steps=max(1, int(args.minutes * 60 / per_step)))
            print(f"== {name}: {per_step:.3f} s a step, {cfg.steps} steps in {args.minutes:g} minutes", flush=True)
            started = time.monotonic()
            result = training.train_lifter(cfg, train, val, progress=True)
            seconds = time.monotonic() - started
            heldout = result.metrics["heldout"]
            later_result = training.evaluate(result.model, later, cfg)["heldout"] if later else None
        results[name] = {"minutes_budget": args.minutes, "seconds_per_step": round(per_step, 4),
                         "steps": cfg.steps, "seconds_with_evaluation": round(seconds, 1),
                         "train_seconds": result.metrics["train_seconds"],
                         "receptive_field": result.metrics["receptive_field"], "channels": cfg.channels,
                         "parameters": sum(p.numel() for p in result.model.parameters()),
                         "profile": args.profile, "clean": heldout["clean"], "noisy": heldout["noisy"],
                         "sources": {k: {"clean": v["clean"], "noisy": v["noisy"]}
                                     for k, v in heldout["sources"].items()},
                         "later": ({"clean": later_result["clean"], "noisy": later_result["noisy"]}
                                   if later_result else None)}
        print(format_report(heldout), flush=True)
        write_json(args.out, results)
    print("\ncandidate  steps  s/step   MPJPE  P-MPJPE | noisy MPJPE  P-MPJPE | later MPJPE  P-MPJPE")
    for name, r in results.items():
        later_row = r["later"]["clean"] if r.get("later") else {"mpjpe_mm": float("nan"), "p_mpjpe_mm": float("nan")}
        print(f"{name:9s} {r['steps']:6d} {r['seconds_per_step']:7.3f} {r['clean']['mpjpe_mm']:7.1f} "
              f"{r['clean']['p_mpjpe_mm']:8.1f} | {r['noisy']['mpjpe_mm']:11.1f} {r['noisy']['p_mpjpe_mm']:8.1f} | "
              f"{later_row['mpjpe_mm']:11.1f} {later_row['p_mpjpe_mm']:8.1f}")


if __name__ == "__main__":
    main()
