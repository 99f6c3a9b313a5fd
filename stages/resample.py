"""resample stage: data/smooth -> data/motion24/<segment_id>.parquet (cubic spline, exactly 24 fps:
frame k at k / fps s on the segment clock; fps is common.fps, 24 by default)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import corpus_fps, load_params, stage_params
from pipeline.core.paths import MOTION24, SMOOTH
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta
from pipeline.motion.motionfile import SCHEMA_VERSION

CODE = code_fingerprint("pipeline.motion.resample")


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    params = {**stage_params(all_params, "resample"), "fps": corpus_fps(all_params)}
    items = []
    for src in item_files(root / SMOOTH):
        inputs = {"smooth": read_meta(src).get("fingerprint", "")}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / MOTION24 / src.name
        job = Deferred("pipeline.motion.resample:ResampleJob", (src, out, params["fps"], params, inputs, fp))
        items.append(WorkItem(src.stem, fp, (out,), job))
    run_item_stage("resample", items, "pipeline.motion.resample:resample_segment", out_dirs=[root / MOTION24],
                   params=params, light=True)


def main() -> int:
    setup_logging()
    return run_stage("resample", run)


if __name__ == "__main__":
    sys.exit(main())
