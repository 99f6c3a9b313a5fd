"""How much to denoise the 2D before lifting (``lift.denoise_2d``), chosen on training sequences.

The lift stage HP-filters each clip's 2D keypoints before the lifter (``infer.denoise_2d``, lambda
as at 30 fps). This benchmark makes that choice the way the contact threshold was made: on the
train_lifter split's **training** sequences (at most three per source, evenly spaced, five of the
ten cameras of ``dance3d eval world``), through the corpus's path, for each lambda and for clean
and noisy 2D; then it scores the candidates on the held-out sequences with the whole protocol
(``evaluate_world``: ten cameras), noisy, clean and with keyframes at 8 fps as pose2d poses them.
Medians over the runs, as ``dance3d eval world`` reports them.

Usage:
  DANCE3D_MOCAP=../shared/mocap python -m benchmarks.denoise_2d [--lambdas 0,3,5,10,20]
      [--held-out 0,3,10] [--out benchmarks/results/denoise_2d.json]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from pipeline.motion.lifting.evaluate import split
from pipeline.motion.lifting.infer import LiftOptions, load_models
from pipeline.motion.mocap.sources import load_folder
from pipeline.motion.shipped import SHIPPED_CONTACT, SHIPPED_LIFTER
from pipeline.motion.world.evaluate import CAMERAS, PoseInput, evaluate_world

KEYS = ("wa_mpjpe100_mm", "w_mpjpe100_mm", "root_aligned_mm", "rte_percent", "jitter", "jitter_capture",
        "foot_sliding_mm", "contact_f1")
CONDITIONS = {"noisy": PoseInput(), "clean": PoseInput(noise=False), "keyframes_8fps": PoseInput(pose_fps=8.0)}


def training_sample(sequences: list) -> list:
    """At most three training sequences per source, evenly spaced, with heels and toes."""
    by_source: dict[str, list] = {}
    for seq in split(sequences)[0]:
        if seq.feet is not None:
            by_source.setdefault(seq.source, []).append(seq)
    return [s for group in by_source.values() for s in group[:: max(1, len(group) // 3)][:3]]


def on_training(models, sequences: list, lamb: float, pose_input: PoseInput) -> dict:
    """``evaluate_world``'s medians over all runs, on five of its ten cameras (one set-up at every pitch)."""
    result = evaluate_world(models, sequences, pose_input=pose_input, lift=LiftOptions(denoise=lamb),
                            cameras=CAMERAS[::2])
    runs = result["protocol"]["sequences"] * result["protocol"]["cameras"]
    return {"runs": runs, **{k: round(result["learned"]["all"][k], 2) for k in KEYS}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--lambdas", default="0,3,5,10,20", help="lambdas tried on the training sequences")
    parser.add_argument("--held-out", default="0,3,10", help="lambdas scored on the held-out sequences")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/denoise_2d.json"))
    args = parser.parse_args()
    sequences = load_folder(Path(os.environ["DANCE3D_MOCAP"]))
    models = load_models(str(SHIPPED_LIFTER), str(SHIPPED_CONTACT), 2)
    sample = training_sample(sequences)
    result: dict = {"protocol": {"training_sequences": len(sample), "training_cameras": len(CAMERAS[::2]),
                                 "held_out": "dance3d eval world's held-out sequences, ten cameras"},
                    "training": {}, "held_out": {}}
    for name in ("noisy", "clean"):
        for lamb in (float(x) for x in args.lambdas.split(",")):
            row = on_training(models, sample, lamb, CONDITIONS[name])
            result["training"][f"{name} {lamb:g}"] = row
            print("training", name, lamb, row, flush=True)
    held = [s for s in split(sequences)[1] if s.feet is not None]
    for name, pose_input in CONDITIONS.items():
        for lamb in (float(x) for x in args.held_out.split(",")):
            figures = evaluate_world(models, held, pose_input=pose_input,
                                     lift=LiftOptions(denoise=lamb))["learned"]["all"]
            result["held_out"][f"{name} {lamb:g}"] = {k: figures[k] for k in KEYS}
            print("held out", name, lamb, result["held_out"][f"{name} {lamb:g}"], flush=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
