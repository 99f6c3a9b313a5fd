"""`dance3d manifests seed | check`: the annotators' track manifests."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_manifests(sub: argparse._SubParsersAction) -> None:
    manifests = sub.add_parser("manifests", help="track manifests for annotators (seed, check)",
                               description="Track manifests: manifests/tracks/<segment_id>.csv. "
                                           "See docs/tutorials/annotating.md.")
    msub = manifests.add_subparsers(dest="action", required=True, metavar="ACTION")
    seed = msub.add_parser("seed", help="write a proposal for every tracked segment that has no manifest",
                           description="Write manifests/tracks/<segment_id>.csv proposals for tracked segments "
                                       "without one. Existing files are never overwritten.")
    seed.set_defaults(handler=seed_all)
    check = msub.add_parser("check", help="validate manifests against their tracks",
                            description="Report every problem as file:line: reason. Exit code 1 on errors "
                                        "(warnings alone exit 0).")
    check.add_argument("files", nargs="*", type=Path, help="manifests to check (default: all)")
    check.set_defaults(handler=check_all)


def seed_all(root: Path, args: argparse.Namespace) -> int:
    from pipeline.annotate.commands import proposal_options, seed_manifests
    from pipeline.core.params import load_params

    written, kept = seed_manifests(root, proposal_options(load_params(root / "params.yaml")))
    for path in written:
        print(f"wrote {path.relative_to(root)}")
    print(f"{len(written)} manifests proposed, {len(kept)} existing left untouched")
    return 0


def check_all(root: Path, args: argparse.Namespace) -> int:
    from pipeline.annotate.commands import check_manifests
    from pipeline.core.params import load_params, stage_params

    min_clip = float(stage_params(load_params(root / "params.yaml"), "clean").get("min_clip_seconds", 2.0))
    files = [f if f.is_absolute() else Path.cwd() / f for f in args.files]
    problems = check_manifests(root, files, min_clip)
    for problem in problems:
        print(problem)
    errors = sum(1 for p in problems if not p.warning)
    print(f"{errors} errors, {len(problems) - errors} warnings")
    return 1 if errors else 0
