"""`dance3d run`, `retry` and `status`: one stage outside DVC, its failed items again, a summary."""

from __future__ import annotations

import argparse
import importlib
import os
from pathlib import Path

from pipeline.core.paths import FAILURE_DIRS
from stages import STAGES


def add_run(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser("run", help="run one pipeline stage outside DVC",
                         description="Run one stage on the project in --root, as `dvc repro` would.")
    run.add_argument("stage", choices=STAGES, help="the stage to run")
    run.set_defaults(handler=run_one)


def add_retry(sub: argparse._SubParsersAction) -> None:
    retry = sub.add_parser("retry", help="re-run only the items a stage recorded as failed",
                           description="Re-run the items listed in the stage's _failures.parquet, leaving the "
                                       "others as they are (for download and trim, whose finished items are "
                                       "always kept, this is a plain re-run).")
    retry.add_argument("stage", choices=sorted(FAILURE_DIRS), help="the stage whose failed items to run again")
    retry.set_defaults(handler=retry_failed)


def add_status(sub: argparse._SubParsersAction) -> None:
    status = sub.add_parser("status", help="summarise downloads, segments and failures",
                            description="Summarise the download ledger, the segment index and every stage's "
                                        "failures.")
    status.set_defaults(handler=show_status)


def run_one(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.stage import run_stage, setup_logging

    setup_logging()
    module = importlib.import_module(f"stages.{args.stage}")
    os.chdir(root)
    return run_stage(args.stage, module.run, root)


def retry_failed(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.failures import read_failures
    from pipeline.core.itemstage import only_items
    from pipeline.core.stage import run_stage, setup_logging

    setup_logging()
    stage = args.stage
    failed = {f.item for f in read_failures(root / FAILURE_DIRS[stage])}
    if not failed:
        print(f"{stage}: no recorded failures")
        return 0
    print(f"{stage}: retrying {len(failed)} items: {', '.join(sorted(failed))}")
    module = importlib.import_module(f"stages.{stage}")
    os.chdir(root)
    with only_items(failed):
        return run_stage(stage, module.run, root)


def show_status(root: Path, args: argparse.Namespace) -> int:
    from pipeline.status import summarise

    print(summarise(root))
    return 0
