"""Models that ship with dance3d (the lifter, the contact model) and the training stages that
either copy them or train a profile on motion capture: where the capture is, and what a
training stage writes (the model, its held-out figures, its loss curve)."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.storage import atomic_path, write_json


def mocap_root(root: Path, params: Mapping, section: str) -> Path:
    """The motion-capture folder of a training stage: ``<section>.mocap`` or $DANCE3D_MOCAP."""
    configured = params.get("mocap") or os.environ.get("DANCE3D_MOCAP", "")
    path = Path(configured) if configured else None
    if path is not None and not path.is_absolute():
        path = root / path
    if path is None or not path.is_dir():
        raise InputError(root / "params.yaml", f"no motion capture folder: set {section}.mocap or $DANCE3D_MOCAP "
                                               "to a folder of BVH / DeepMimic / npz / C3D motion (see MOCAP.md)")
    return path


def write_training_outputs(metrics_path: Path, metrics: dict, curve_path: Path, column: str,
                           curve: list[float]) -> None:
    """The figures (JSON, for ``dvc metrics``) and at most ~200 points of the loss curve (CSV, for ``dvc plots``)."""
    write_json(metrics_path, metrics)
    every = max(1, len(curve) // 200)
    with atomic_path(curve_path) as tmp:
        tmp.write_text(f"step,{column}\n" + "".join(f"{i},{value:.4f}\n" for i, value in enumerate(curve)
                                                    if i % every == 0))


def copy_shipped(shipped: Path, dest: Path) -> dict[str, str]:
    """Copy a shipped ONNX model to ``dest``; returns its metadata (what made it, its figures)."""
    import onnx

    meta = {p.key: p.value for p in onnx.load(str(shipped), load_external_data=False).metadata_props}
    with atomic_path(dest) as tmp:
        shutil.copyfile(shipped, tmp)
    return meta


def recorded_metrics(meta: Mapping[str, str]) -> dict:
    return {**json.loads(meta["metrics"]), "shipped": True}
