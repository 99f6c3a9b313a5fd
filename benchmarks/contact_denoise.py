"""Contact models scored on the 2D as the lift stage feeds it (denoised) and as it was trained (raw).

Usage: DANCE3D_MOCAP=../shared/mocap python -m benchmarks.contact_denoise [NAME=MODEL.onnx ...]
    [--out benchmarks/results/contact_denoise.json]

The lift stage HP-filters the 2D before the contact model sees it (``lift.denoise_2d``). This scores
the shipped contact model, and any other given, on the contact model's own held-out protocol
(``contact_train.evaluate_contact``: the 40 sequences, ten cameras, noisy 2D, F1 at probability 0.5)
with the 2D raw and denoised (lambda 10 as at 30 fps), per source.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from pipeline.motion.lifting.evaluate import split
from pipeline.motion.lifting.infer import DENOISE_2D
from pipeline.motion.lifting.train import LifterConfig, load_mocap
from pipeline.motion.shipped import SHIPPED_CONTACT
from pipeline.motion.world.contact_model import load_contact_model
from pipeline.motion.world.contact_train import evaluate_contact


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", help="NAME=MODEL.onnx, scored beside the shipped contact model")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/contact_denoise.json"))
    args = parser.parse_args()
    _, val = split(load_mocap(Path(os.environ["DANCE3D_MOCAP"]), LifterConfig()))
    models = {"shipped": str(SHIPPED_CONTACT), **dict(m.split("=", 1) for m in args.models)}
    result: dict = {"protocol": "contact_train.evaluate_contact: held-out sequences, ten cameras, noisy 2D, seed 1"}
    for name, path in models.items():
        for denoise in (0.0, DENOISE_2D):
            scores = evaluate_contact(load_contact_model(Path(path), 2), val, 60.0, 1, denoise)
            result[f"{name} denoise {denoise:g}"] = {source: row["f1"] for source, row in scores["heldout"].items()}
            print(name, denoise, scores["contact_f1"], flush=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
