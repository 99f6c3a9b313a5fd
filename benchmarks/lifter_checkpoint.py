"""Where a lifter training stands: the held-out protocol on a profile's checkpoint, mid-run, beside
the shipped lifter, so "train for as long as it pays" is decided on held-out figures, not the loss.

Usage: python -m benchmarks.lifter_checkpoint [--profile long] [--mocap DIR] [--checkpoint FILE]
                                              [--out benchmarks/results/lifter_checkpoint_<step>.json]

It finds the checkpoint the train_lifter stage writes for the profile (the same name: config,
training sequences, training code), loads its weights, and scores them and the shipped lifter with
the held-out protocol (``pipeline/motion/lifting/evaluate.py``: 40 sequences, ten fixed cameras,
clean and noisy 2D, flip averaging) and on the later sources' held-out takes. The checkpoint is only
read: a training that is running goes on.
"""

from __future__ import annotations

import argparse
import os
from functools import partial
from pathlib import Path

from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.storage import write_json
from stages.train_lifter import config_from_params


def profile_run(profile: str, mocap: Path, checkpoint: Path | None = None):
    """A train_lifter profile of params.yaml as its training sees it: (config, training sequences,
    the 40 held-out ones, the later sources' held-out takes, the checkpoint file, which must exist)."""
    from pipeline.motion.lifting.evaluate import held_out_later, split
    from pipeline.motion.lifting.train import checkpoint_path, default_checkpoints, load_mocap

    params = with_profile({**stage_params(load_params(Path("params.yaml")), "train_lifter"), "profile": profile},
                          "train_lifter")
    cfg = config_from_params(params)
    sequences = load_mocap(mocap, cfg)
    train, val = split(sequences, cfg.holdout)
    checkpoint = checkpoint or checkpoint_path(default_checkpoints(), cfg, train)
    if not checkpoint.is_file():
        raise SystemExit(f"{checkpoint}: no checkpoint for profile {profile} (run train_lifter with it first)")
    return cfg, train, val, held_out_later(sequences), checkpoint


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="long", help="a train_lifter profile of params.yaml (default long)")
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the profile's own")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    import torch

    from pipeline.motion.lifting.evaluate import evaluate_lifter
    from pipeline.motion.lifting.infer import Lifter, load_lifter
    from pipeline.motion.lifting.model import TemporalModel
    from pipeline.motion.shipped import SHIPPED_LIFTER

    cfg, train, val, later, checkpoint = profile_run(args.profile, args.mocap, args.checkpoint)
    state = torch.load(checkpoint, weights_only=False)
    joints = 21 if cfg.feet else 17
    model = TemporalModel(joints, joints, cfg.filter_widths, cfg.channels, cfg.dropout)
    model.load_state_dict(state["model"])
    losses = state["losses"]
    print(f"{checkpoint.name}: step {state['step']} of {cfg.steps}, {state['elapsed'] / 3600:.2f} h of training; "
          f"training MPJPE over the last 1000 steps {1000 * sum(losses[-1000:]) / len(losses[-1000:]):.1f} mm")

    # Both lifters through the one protocol call: every entry is evaluate_lifter's result, per source.
    lifters = {"checkpoint": Lifter.from_torch(model, cfg.input_norm), "shipped": load_lifter(str(SHIPPED_LIFTER), 2)}
    figures = {}
    for name, lifter in lifters.items():
        for suffix, seqs in (("", val), ("_later", later)):
            figures[name + suffix] = evaluate_lifter(partial(lifter.lift, flip=True), seqs, fps=cfg.fps,
                                                     max_seconds=cfg.eval_seconds, seed=cfg.seed + 1, feet=cfg.feet)
    record = {"profile": args.profile, "checkpoint": checkpoint.name, "step": state["step"], "steps": cfg.steps,
              "hours": round(state["elapsed"] / 3600, 2), "figures": figures}
    out = args.out or Path(f"benchmarks/results/lifter_checkpoint_{state['step']}.json")
    write_json(out, record)
    for suffix, title in (("", "the held-out sequences"), ("_later", "the later sources' held-out takes")):
        print(f"\n{title}: MPJPE / P-MPJPE, clean and noisy 2D (mm)")
        rows = {"all": {n: figures[n + suffix] for n in lifters}}
        rows.update({source: {n: figures[n + suffix]["sources"][source] for n in lifters}
                     for source in figures["checkpoint" + suffix]["sources"]})
        for row, by_lifter in rows.items():
            print(f"  {row:<24}" + "   ".join(
                f"{n} {r['clean']['mpjpe_mm']:.1f} / {r['clean']['p_mpjpe_mm']:.1f}, "
                f"{r['noisy']['mpjpe_mm']:.1f} / {r['noisy']['p_mpjpe_mm']:.1f}" for n, r in by_lifter.items()))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
