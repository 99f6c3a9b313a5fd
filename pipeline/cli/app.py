"""The ``dance3d`` command: its parser, built from one module per command group, and the one place
where a command's errors become a line of text."""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

from pipeline.cli import evaluate, export, manifests, models, render, review, running, sample
from pipeline.cli.messages import one_line
from pipeline.core.errors import Dance3dError

DESCRIPTION = """\
dance3d turns dance videos into a 3D dance-motion corpus synced to music.

The pipeline is driven by DVC: edit manifests/sources.csv, annotations/segments.csv and
params.yaml, then run `dvc repro` in the project root. The commands below run single
stages outside DVC and summarise results.
"""

EPILOG = """\
examples:
  dance3d run download        fetch the sources listed in manifests/sources.csv
  dance3d run trim            cut the annotated dance segments
  dance3d status              what has been downloaded and cut, and what failed
  dance3d retry pose2d        re-run only the items pose2d recorded as failed
  dance3d review              open the annotators' review page at http://127.0.0.1:8765/ (trim mode: /trim)
  dance3d manifests seed      propose a track manifest for every tracked segment without one
  dance3d manifests check     validate manifests: every problem as file:line: reason
  dance3d render data/motion24/musepose_dance_000.parquet musepose_dance_000_1_0 clip.mp4
                              draw a 3D clip (front and side views) with its music
  dance3d export bvh data/motion24/musepose_dance_000.parquet musepose_dance_000_1_0 clip.bvh
                              one clip as BVH: y-up world frame, one skeleton, joint rotations
  dance3d eval pose2d --annotations person_keypoints.json --images images/
                              COCO keypoint AP, detection recall, PCK of the configured 2D models
  dance3d eval beats --audio song.ogg --beats song.beats
                              score the beat tracker against your annotations (mir_eval)
  dance3d eval segments       score the proposed dance segments against annotations/segments.csv
  dance3d eval world --mocap ../mocap
                              world motion through the corpus's path: W-MPJPE, RTE, foot sliding, contact F1
  dance3d eval lifter --mocap ../mocap
                              MPJPE / P-MPJPE of the lifter on motion capture through fixed virtual cameras
  dance3d models fetch        download, convert and verify the default detector and pose model
  dance3d models convert-videopose3d pretrained_h36m_detectron_coco.bin models/lifter.onnx
                              use the official VideoPose3D weights as the lifter
"""


def build_parser() -> argparse.ArgumentParser:
    """Every command's parser; each command group adds its own (the order is the help's)."""
    parser = argparse.ArgumentParser(prog="dance3d", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=Path.cwd(),
                        help="project root holding params.yaml (default: the current folder)")
    parser.add_argument("--debug", action="store_true",
                        help="show a failing command's traceback (also DANCE3D_DEBUG=1)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (running.add_run, review.add_review, running.add_retry, render.add_qc, running.add_status,
                manifests.add_manifests, render.add_render, export.add_export, sample.add_sample,
                evaluate.add_eval, models.add_models):
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The `dance3d` command. Every error a command meets ends here as one line naming what is wrong
    (the file and line where there is one) and a non-zero exit; ``--debug`` or DANCE3D_DEBUG=1 shows
    the traceback instead. Library warnings are kept from the terminal unless debugging."""
    args = build_parser().parse_args(argv)
    debug = args.debug or os.environ.get("DANCE3D_DEBUG") == "1"
    if debug:
        os.environ["DANCE3D_DEBUG"] = "1"  # the handlers that go on after an error stop instead
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.simplefilter("ignore")
            return args.handler(args.root.resolve(), args)
    except KeyboardInterrupt:
        print(f"dance3d {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 -- the one place a command's errors become a sentence
        if debug:
            raise
        print(f"dance3d {args.command}: {one_line(exc)}", file=sys.stderr)
        return 2 if isinstance(exc, Dance3dError) else 1
