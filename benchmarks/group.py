"""Groups of dancers in one scene on synthetic groups of held-out motion capture: `dance3d eval
group` on the shared capture, its figures written to benchmarks/results/group.json for the notes.

Usage: python -m benchmarks.group [--mocap DIR] [--groups 10] [--seconds 15] [--out benchmarks/results/group.json]

The protocol (formations, cameras, occlusion, noise, metrics, the baseline of dancers grounded
alone) is pipeline/motion/world/group_eval.py's; this runs it with the shipped lifter and contact model.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from benchmarks.world import run_and_save
from pipeline.motion.world.group_eval import evaluate_group_folder, format_report
from stages.train_contact import SHIPPED as CONTACT
from stages.train_lifter import SHIPPED as LIFTER


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--groups", type=int, default=10, help="groups of each size (2 to 6 dancers)")
    parser.add_argument("--seconds", type=float, default=15.0, help="at most this much of each take")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/group.json"))
    args = parser.parse_args()
    run_and_save(lambda: evaluate_group_folder(LIFTER, CONTACT, args.mocap, groups=args.groups, seconds=args.seconds),
                 format_report, args.out)


if __name__ == "__main__":
    main()
