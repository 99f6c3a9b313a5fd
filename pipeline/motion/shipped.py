"""Models that ship with dance3d (the lifter, the contact model) and the training stages that
either copy them or train a profile on motion capture: where the capture is, and what a
training stage writes (the model, its held-out figures, its loss curve)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.storage import atomic_path

SHIPPED_LIFTER = Path(__file__).resolve().parent / "lifting/weights/lifter_dance3d.onnx"
SHIPPED_CONTACT = Path(__file__).resolve().parent / "world/weights/contact_dance3d.onnx"


def model_or_shipped(path: Path, shipped: Path, what: str) -> tuple[Path, str | None]:
    """``path`` when it exists, else the shipped model and a line saying so (a fresh clone has no
    models/ until train_lifter and train_contact run)."""
    if Path(path).is_file():
        return Path(path), None
    return shipped, f"{path} does not exist: using the shipped {what} ({shipped.name})"


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


def write_training_outputs(root: Path, name: str, metrics: dict, curve_path: Path, column: str,
                           curve: list[float]) -> None:
    """The figures (``reports/<name>.json``, the headline in ``metrics/``) and at most ~200 points of
    the loss curve (CSV, for ``dvc plots``)."""
    from pipeline.core.metrics import write_metrics

    write_metrics(root, name, metrics)
    every = max(1, len(curve) // 200)
    with atomic_path(curve_path) as tmp:
        tmp.write_text(f"step,{column}\n" + "".join(f"{i},{value:.4f}\n" for i, value in enumerate(curve)
                                                    if i % every == 0))


def copy_shipped(shipped: Path, dest: Path) -> dict[str, str]:
    """Copy a shipped ONNX model to ``dest``; returns its metadata (what made it, its figures)."""
    import onnxruntime as ort  # its metadata reader: the onnx package costs 0.5 s to import

    meta = dict(ort.InferenceSession(str(shipped), providers=["CPUExecutionProvider"]).get_modelmeta()
                .custom_metadata_map)
    with atomic_path(dest) as tmp:
        shutil.copyfile(shipped, tmp)
    return meta


def recorded_metrics(meta: Mapping[str, str]) -> dict:
    return {**json.loads(meta["metrics"]), "shipped": True}


def config_from_params(config_class, params: Mapping, augment_class=None):
    """A training config dataclass from a params section (lists become tuples; ``augment`` nested)."""
    known = {f.name for f in dataclasses.fields(config_class)} - {"augment"}
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in params.items() if k in known}
    if augment_class is not None:
        augment = {k: tuple(v) if isinstance(v, list) else v for k, v in (params.get("augment") or {}).items()}
        values["augment"] = augment_class(**augment)
    return config_class(**values)


def git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def training_provenance(cfg, train: list, val: list, mocap: Path, metrics: dict, steps: int,
                        code_fingerprint: str) -> dict[str, str]:
    """What made a shipped model, for its ONNX metadata: the capture (minutes per source, the
    held-out sequences), every parameter, the commit and code, the held-out figures."""
    minutes: dict[str, float] = {}
    for seq in train:
        minutes[seq.source] = round(minutes.get(seq.source, 0.0) + seq.frames / seq.fps / 60, 2)
    return {"trained_on": json.dumps({"mocap": mocap.name, "train_minutes_per_source": minutes,
                                      "train_sequences": len(train), "heldout": [s.name for s in val]}),
            "params": json.dumps(dataclasses.asdict(cfg)), "git_commit": git_commit(),
            "code_fingerprint": code_fingerprint, "steps": str(steps), "metrics": json.dumps(metrics)}
