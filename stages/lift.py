"""lift stage: data/clean + models/lifter.onnx -> data/pose3d/<segment_id>.parquet (H36M-17, metres)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.errors import ModelMissingError
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import CLEAN, POSE3D
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta, sha256_file
from pipeline.motion.motionfile import SCHEMA_VERSION

CODE = code_fingerprint("pipeline.motion.lifting.infer", "pipeline.motion.world.contact_model",
                        "pipeline.motion.lifting.geometry",  # the lifter's input normalisation
                        "pipeline.motion.mocap.skeleton",  # the mirror tables of the flip averaging
                        "pipeline.motion.world.trajectory", "pipeline.motion.world.bones",  # the root path, rays
                        "pipeline.motion.resample",  # the contact model's time axis
                        "pipeline.motion.smoothing",  # the 2D's denoising
                        "pipeline.motion.hands", "pipeline.pose.pose2dfile")  # the hands: layout, sure presence


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "lift")
    model = root / params.get("model", "models/lifter.onnx")
    if not model.exists():
        raise ModelMissingError(f"lifter {model} not found: run the train_lifter stage (dvc repro train_lifter) or "
                                "convert the official weights with `dance3d models convert-videopose3d`")
    contact = root / params["contact_model"] if params.get("contact_model") else None
    if contact is not None and not contact.exists():
        raise ModelMissingError(f"contact model {contact} not found: run the train_contact stage (dvc repro "
                                "train_contact), or set lift.contact_model to '' for the ankle rule")
    opts = Deferred("pipeline.motion.lifting.infer:LiftOptions.from_params", (params,))
    model_hash = sha256_file(model)
    contact_hash = sha256_file(contact) if contact is not None else ""
    items = []
    for clean_file in item_files(root / CLEAN):
        inputs = {"clean": read_meta(clean_file).get("fingerprint", ""), "lifter": model_hash,
                  "contact_model": contact_hash}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / POSE3D / clean_file.name
        job = Deferred("pipeline.motion.lifting.infer:LiftJob", (clean_file, out, opts, params, inputs, fp))
        items.append(WorkItem(clean_file.stem, fp, (out,), job))
    run_item_stage("lift", items, "pipeline.motion.lifting.infer:lift_segment", out_dirs=[root / POSE3D],
                   params=params, setup="pipeline.motion.lifting.infer:load_models",
                   setup_args=(str(model), str(contact or ""), int(params.get("threads", 1))),
                   gpu=True, light=True)


def main() -> int:
    setup_logging()
    return run_stage("lift", run)


if __name__ == "__main__":
    sys.exit(main())
