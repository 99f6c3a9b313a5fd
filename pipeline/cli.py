"""The ``dance3d`` command."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from stages import STAGES

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
"""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dance3d", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=Path.cwd(),
                        help="project root holding params.yaml (default: the current folder)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser("run", help="run one pipeline stage outside DVC",
                         description="Run one stage on the project in --root, as `dvc repro` would.")
    run.add_argument("stage", choices=STAGES, help="the stage to run")
    sub.add_parser("status", help="summarise downloads, segments and failures",
                   description="Summarise the download ledger, the segment index and every stage's failures.")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    root = args.root.resolve()
    if args.command == "run":
        from pipeline.stage import run_stage, setup_logging

        setup_logging()
        module = importlib.import_module(f"stages.{args.stage}")
        os.chdir(root)
        return run_stage(args.stage, module.run, root)
    if args.command == "status":
        from pipeline.status import summarise

        print(summarise(root))
        return 0
    return 1


if __name__ == "__main__":
    sys.exit(main())
