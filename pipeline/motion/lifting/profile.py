"""The train_lifter stage's training of a params profile: the capture split by whole takes and
performers, training that checkpoints and resumes (``train``), the later sources' own held-out
table, and the ONNX with what made it."""

from __future__ import annotations

import logging
from pathlib import Path

from pipeline.core.errors import InputError

log = logging.getLogger("dance3d.train_lifter")


def train_profile(out: Path, cfg, mocap: Path, checkpoint_minutes: float = 5.0):
    """The train_lifter stage's training: the capture split by whole takes and performers, training
    that checkpoints and resumes (``lifting.train``), the later sources' own held-out table, and
    the ONNX with its provenance at ``out``. Returns the ``TrainResult``."""
    # Imported here: the stage imports this module also when it only copies the shipped lifter,
    # which needs no torch.
    from pipeline.motion.lifting.evaluate import held_out_later, split
    from pipeline.motion.lifting.train import (
        checkpoint_path,
        default_checkpoints,
        evaluate,
        export_onnx,
        load_mocap,
        provenance,
        train_lifter,
    )

    sequences = load_mocap(mocap, cfg)
    train, val = split(sequences, cfg.holdout)
    if not train or not val:
        raise InputError(mocap, f"need training and held-out sequences; found {len(train)} and {len(val)} "
                                "(check train_lifter.sources and train_lifter.holdout)")
    log.info("training on %d sequences, holding out %d", len(train), len(val))
    checkpoint = checkpoint_path(default_checkpoints(), cfg, train)
    log.info("checkpoints: %s (a stopped run resumes from it)", checkpoint)
    result = train_lifter(cfg, train, val, checkpoint=checkpoint, checkpoint_minutes=checkpoint_minutes)
    later = held_out_later(sequences)
    if later:  # the later sources' own held-out table (evaluate.HOLDOUT_LATER)
        result.metrics["heldout_later"] = evaluate(result.model, later, cfg)["heldout"]
    export_onnx(result.model, out, provenance(cfg, train, val, result, mocap), input_norm=cfg.input_norm)
    return result
