"""ground stage: data/motion24 -> data/world/<segment_id>.parquet (world motion: every clip of a segment
in one scene, gravity-aligned, the floor at y = 0, the contact-anchored root path placed where the
planted feet are seen, one skeleton per clip, planted feet pinned, rotations, the SMPL skeleton's rotations)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import MOTION24, WORLD
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta
from pipeline.motion.world.contact import ContactRules
from pipeline.motion.world.worldfile import SCHEMA_VERSION

CODE = code_fingerprint(*(f"pipeline.motion.world.{name}" for name in (
    "grounding", "contact", "gravity", "trajectory", "rotations", "worldfile", "scene", "bones", "segment")),
    "pipeline.motion.hands", "pipeline.motion.smpl.retarget", "pipeline.motion.smpl.kinematics",
    "pipeline.motion.smpl.skeleton", "pipeline.motion.smpl.hands", "pipeline.motion.mocap.skeleton",
    "pipeline.pose.pose2dfile")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "ground")
    rules = ContactRules.from_params(params)
    items = []
    for src in item_files(root / MOTION24):
        inputs = {"motion24": read_meta(src).get("fingerprint", "")}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / WORLD / src.name
        job = Deferred("pipeline.motion.world.segment:GroundJob", (src, out, rules, params, inputs, fp))
        items.append(WorkItem(src.stem, fp, (out,), job))
    run_item_stage("ground", items, "pipeline.motion.world.segment:ground_segment", out_dirs=[root / WORLD],
                   params=params, light=True)


def main() -> int:
    setup_logging()
    return run_stage("ground", run)


if __name__ == "__main__":
    sys.exit(main())
