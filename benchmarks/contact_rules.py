"""The contact rules (``ground.contact_threshold``, ``min_contact_frames``, ``contact_hold``) again,
now that the contact model sees denoised 2D, on training sequences.

Usage: DANCE3D_MOCAP=../shared/mocap python -m benchmarks.contact_rules
    [--out benchmarks/results/contact_rules.json]

As the rules were first chosen (pipeline/motion/world/contact.py) and as ``benchmarks.denoise_2d``
chose the 2D's denoising: the train_lifter split's training sequences (at most three per source),
five of ``dance3d eval world``'s ten cameras, noisy 2D, the lift stage's denoising; for each rule,
``evaluate_world``'s medians of contact F1, foot sliding, WA-MPJPE100 and jitter. A planted point
that slides is what a trainer sees, so F1 is read beside sliding, not alone.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from benchmarks.denoise_2d import training_sample
from pipeline.motion.lifting.infer import load_models
from pipeline.motion.mocap.sources import load_folder
from pipeline.motion.shipped import SHIPPED_CONTACT, SHIPPED_LIFTER
from pipeline.motion.world.contact import ContactRules
from pipeline.motion.world.evaluate import CAMERAS, evaluate_world

RULES = [ContactRules(), ContactRules(threshold=0.3), ContactRules(threshold=0.35), ContactRules(threshold=0.45),
         ContactRules(threshold=0.5), ContactRules(hold=0.05), ContactRules(hold=0.2), ContactRules(min_frames=2),
         ContactRules(min_frames=5)]
KEYS = ("contact_f1", "foot_sliding_mm", "wa_mpjpe100_mm", "jitter")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/contact_rules.json"))
    args = parser.parse_args()
    sample = training_sample(load_folder(Path(os.environ["DANCE3D_MOCAP"])))
    models = load_models(str(SHIPPED_LIFTER), str(SHIPPED_CONTACT), 2)
    result: dict = {"protocol": {"training_sequences": len(sample), "cameras": len(CAMERAS[::2]),
                                 "2d": "noisy, denoised as the lift stage does"}}
    for rules in RULES:
        figures = evaluate_world(models, sample, rules=rules, cameras=CAMERAS[::2])["learned"]["all"]
        name = f"threshold {rules.threshold:g}, min frames {rules.min_frames}, hold {rules.hold:g}"
        result[name] = {k: round(figures[k], 4) for k in KEYS}
        print(name, result[name], flush=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
