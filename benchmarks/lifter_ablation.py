"""Lifter ablation: each variant trained for the same number of steps on the same split,
scored with the held-out protocol (pipeline/motion/lifting/evaluate.py), side by side.

Usage: python benchmarks/lifter_ablation.py [--mocap DIR] [--steps 3000] [--variants a,b,...] [--out FILE]

Variants add one change at a time to the previous default (``previous``):
  previous     the train_lifter default before the ChoreoNet markers: 27 frames, 128 channels
  +choreonet   + the ChoreoNet C3D markers (performer ll/mm held out)
  +noise       + pose-model noise in training (COCO sigmas, level 0-0.5)
  +losses      + velocity (0.5) and bone-length consistency (0.5) terms
  +centred     +noise with 2D input about the hips, divided by the body's image size (not VideoPose3D's screen frame)
  +framing     + people filling 20-95 % of the image height in training (was 35-95 %)
  +feet        + heels and toe tips in and out (21 joints; the body still scored on its 17)
  rf81         the above with an 81-frame receptive field, 256 channels
  rf243        the above with a 243-frame receptive field, 256 channels
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

from pipeline.motion.lifting.data import AugmentOptions
from pipeline.motion.lifting.evaluate import HOLDOUT, format_report, split
from pipeline.motion.lifting.train import LifterConfig, load_mocap, train_lifter
from pipeline.motion.mocap.sources import SOURCES

OLD_SOURCES = tuple(s for s in SOURCES if s != "choreonet_c3d")


def variants(steps: int) -> dict[str, LifterConfig]:
    old_augment = AugmentOptions(pose_noise=(0.0, 0.0), fill=(0.35, 0.95))
    previous = LifterConfig(steps=steps, channels=128, filter_widths=(3, 3, 3), sources=OLD_SOURCES,
                            input_norm="screen", augment=old_augment)
    choreo = replace(previous, sources=SOURCES)
    noise = replace(choreo, augment=replace(old_augment, pose_noise=(0.0, 0.5)))
    losses = replace(noise, velocity_weight=0.5, bone_weight=0.5)
    centred = replace(noise, input_norm="centred")  # the loss terms did not help (docs/pipeline/3d.md): left out
    framing = replace(centred, augment=replace(centred.augment, fill=(0.2, 0.95)))
    return {"previous": previous, "+choreonet": choreo, "+noise": noise, "+losses": losses, "+centred": centred,
            "+framing": framing, "+feet": replace(framing, feet=True),
            "rf81": replace(framing, filter_widths=(3, 3, 3, 3), channels=256),
            "rf243": replace(framing, filter_widths=(3, 3, 3, 3, 3), channels=256)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--variants", default="previous,+choreonet,+noise,+losses,+centred,+framing,+feet")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/lifter_ablation.json"))
    args = parser.parse_args()
    configs = variants(args.steps)
    everything = load_mocap(args.mocap, LifterConfig())
    # One held-out set for every variant (the ChoreoNet performer included), so the figures compare.
    _, val = split(everything, HOLDOUT)
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    for name in args.variants.split(","):
        cfg = configs[name]
        train, _ = split([s for s in everything if s.source in cfg.sources], cfg.holdout)
        started = time.monotonic()
        result = train_lifter(cfg, train, val)
        heldout = result.metrics["heldout"]
        results[name] = {"steps": cfg.steps, "seconds": round(time.monotonic() - started, 1),
                         "receptive_field": result.metrics["receptive_field"], "channels": cfg.channels,
                         "clean": heldout["clean"], "noisy": heldout["noisy"],
                         "sources": {k: {"clean": v["clean"], "noisy": v["noisy"]}
                                     for k, v in heldout["sources"].items()}}
        print(f"\n== {name}: {results[name]['seconds']} s\n{format_report(heldout)}", flush=True)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1))
    print("\nvariant       steps   MPJPE  P-MPJPE | noisy MPJPE  P-MPJPE |  seconds")
    for name, r in results.items():
        print(f"{name:12s} {r['steps']:6d} {r['clean']['mpjpe_mm']:7.1f} {r['clean']['p_mpjpe_mm']:8.1f} | "
              f"{r['noisy']['mpjpe_mm']:11.1f} {r['noisy']['p_mpjpe_mm']:8.1f} | {r['seconds']:8.0f}")


if __name__ == "__main__":
    main()
