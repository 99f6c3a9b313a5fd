"""World-grounded motion on held-out motion capture: `dance3d eval world` on the shared capture,
its figures written to benchmarks/results/world.json for the closing notes.

Usage: python -m benchmarks.world [--mocap DIR] [--seconds 20] [--out benchmarks/results/world.json]

The protocol (cameras, noise, metrics, the baseline without the contact model) is
pipeline/motion/world/evaluate.py's; this runs it with the shipped lifter and contact model.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

from pipeline.motion.world.evaluate import PoseInput, evaluate_folder, format_report
from stages.train_contact import SHIPPED as CONTACT
from stages.train_lifter import SHIPPED as LIFTER


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--seconds", type=float, default=20.0, help="at most this much of each sequence")
    parser.add_argument("--pose-fps", type=float, default=0.0, help="2D on keyframes at this rate (pose2d.fps)")
    parser.add_argument("--clean-2d", action="store_true", help="no 2D noise")
    parser.add_argument("--frame-noise", type=float, default=1.0,
                        help="share of the 2D noise new on every frame (the rest drifts; default 1)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/world.json"))
    args = parser.parse_args()
    pose_input = PoseInput(not args.clean_2d, args.frame_noise, args.pose_fps)
    run_and_save(lambda: evaluate_folder(LIFTER, CONTACT, args.mocap, seconds=args.seconds, pose_input=pose_input),
                 format_report, args.out)


def run_and_save(evaluate: Callable[[], dict], report: Callable[[dict], str], out: Path) -> dict:
    """Run an evaluation, time it (``protocol.wall_seconds``), print its report, save it as JSON."""
    started = time.monotonic()
    result = evaluate()
    result["protocol"]["wall_seconds"] = round(time.monotonic() - started, 1)
    print(report(result))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
