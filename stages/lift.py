"""lift stage: data/clean + models/lifter.onnx -> data/pose3d/<segment_id>.parquet (H36M-17, metres)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

import pipeline.motion.lifting.infer
from pipeline.core.errors import ModelMissingError
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CLEAN, POSE3D
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta, sha256_file, write_parquet
from pipeline.motion.lifting.infer import Lifter, fill_low_confidence
from pipeline.motion.motionfile import MotionClip, clips_to_table
from pipeline.pose.models.session import create_session

SCHEMA_VERSION = 1
_STATE: dict = {}
CODE = code_fingerprint(pipeline.motion.lifting.infer)


def load_lifter(path: str, threads: int) -> None:
    _STATE["lifter"] = Lifter(create_session(Path(path), threads))


def lift_segment(job: tuple) -> dict:
    clean_file, out, min_score, flip, params, inputs, fp = job
    meta = read_meta(clean_file)
    table = pq.read_table(clean_file)
    ids = np.array(table.column("clip_id").to_pylist())
    kps = np.asarray(table.column("keypoints").combine_chunks().flatten(), np.float32).reshape(-1, 17, 3)
    frame = table.column("frame").to_numpy()
    time = table.column("time").to_numpy()
    track = table.column("track_id").to_numpy()
    interp = table.column("interpolated").to_numpy(zero_copy_only=False)
    order = list(dict.fromkeys(ids))
    rows = [np.flatnonzero(ids == c) for c in order]
    filled = [fill_low_confidence(kps[r], min_score) for r in rows]
    lifted = _STATE["lifter"].lift([f[0] for f in filled], meta["width"], meta["height"], flip=flip)
    clips = [MotionClip(c, int(track[r[0]]), frame[r], time[r], j, interp[r], f[1].sum(1).astype(np.int8))
             for c, r, j, f in zip(order, rows, lifted, filled)]
    extra = {"fingerprint": fp, **{k: meta.get(k) for k in ("segment_id", "fps", "width", "height")}}
    write_parquet(clips_to_table(clips), out, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra=extra)
    return {"clips": len(clips), "frames": int(sum(len(r) for r in rows))}


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "lift")
    model = root / params.get("model", "models/lifter.onnx")
    if not model.exists():
        raise ModelMissingError(f"lifter {model} not found: run the train_lifter stage (dvc repro train_lifter) or "
                                "convert the official weights with `dance3d models convert-videopose3d`")
    model_hash = sha256_file(model)
    items = []
    for clean_file in item_files(root / CLEAN):
        inputs = {"clean": read_meta(clean_file).get("fingerprint", ""), "lifter": model_hash}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / POSE3D / clean_file.name
        job = (clean_file, out, float(params.get("min_score", 0.3)), bool(params.get("flip_tta", True)), params,
               inputs, fp)
        items.append(WorkItem(clean_file.stem, fp, (out,), job))
    run_item_stage("lift", items, lift_segment, out_dirs=[root / POSE3D], params=params,
                   initializer=load_lifter, initargs=(str(model), int(params.get("threads", 1))), gpu=True)


def main() -> int:
    setup_logging()
    return run_stage("lift", run)


if __name__ == "__main__":
    sys.exit(main())
