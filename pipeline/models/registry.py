"""The model registry: each model's file, checksum, official source and input spec.

Lookup order for a model file: ``$DANCE3D_MODELS``, the project's ``models/`` folder,
then a download from the registered URL with its sha256 checked. A model that cannot be
found gives one line saying which file to put where.
"""

from __future__ import annotations

import io
import logging
import os
import urllib.request
import zipfile
from dataclasses import dataclass
from pathlib import Path

from pipeline.errors import ModelMissingError
from pipeline.storage import atomic_path, sha256_file

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModelSpec:
    name: str
    file: str
    kind: str                   # rtmdet | movenet | rtmpose | lifter
    input_size: tuple[int, int]  # (width, height) the model expects
    sha256: str | None          # None: not pinned, so never downloaded automatically
    url: str | None = None      # official download (a .onnx, or a .zip holding ``member``)
    member: str | None = None
    note: str = ""


REGISTRY: dict[str, ModelSpec] = {
    spec.name: spec
    for spec in (
        ModelSpec(
            "rtmdet-nano-person", "rtmdet_nano_person_end2end.onnx", "rtmdet", (320, 320),
            "4720eda18a18402e7b76d85827d4bc60fba18111fc0b74b559e4d24da9ddc3d2",
            url="https://download.openmmlab.com/mmpose/v1/projects/rtmposev1/onnx_sdk/"
                "rtmdet_nano_8xb32-100e_coco-obj365-person-05d8511e.zip",
            member="end2end.onnx",
            note="RTMDet-nano person detector (OpenMMLab, Apache-2.0), mmdeploy end2end export with NMS",
        ),
        ModelSpec(
            "movenet-lightning", "movenet_singlepose_lightning_4_dequant.onnx", "movenet", (192, 192),
            "c7ce583bf620af48a3d0d14226691d3ebd2783165bf525b58d4dc33132aed735",
            note="MoveNet SinglePose Lightning v4 (Google, Apache-2.0) converted from the TF-Hub int8 "
                 "TFLite with tf2onnx --dequantize; there is no official ONNX download",
        ),
        ModelSpec(
            "rtmpose-m", "rtmpose-m_simcc-body7_256x192.onnx", "rtmpose", (192, 256), None,
            url="https://download.openmmlab.com/mmpose/v1/projects/rtmposev1/onnx_sdk/"
                "rtmpose-m_simcc-body7_pt-body7_420e-256x192-e48f03d0_20230504.zip",
            member="end2end.onnx",
            note="RTMPose-m body7 (OpenMMLab, Apache-2.0), more accurate; place end2end.onnx under this name",
        ),
        ModelSpec(
            "lifter", "lifter.onnx", "lifter", (0, 0), None,
            note="the VideoPose3D-style lifter that the train_lifter stage writes to models/lifter.onnx",
        ),
    )
}


def model_dirs(project_root: Path | None = None) -> list[Path]:
    dirs = []
    if os.environ.get("DANCE3D_MODELS"):
        dirs.append(Path(os.environ["DANCE3D_MODELS"]))
    dirs.append(Path(project_root or Path.cwd()) / "models")
    return dirs


def get_spec(name: str) -> ModelSpec:
    if name not in REGISTRY:
        raise ModelMissingError(f"unknown model {name!r}; registered: {', '.join(sorted(REGISTRY))}")
    return REGISTRY[name]


def resolve_model(name: str, project_root: Path | None = None, *, allow_download: bool = True) -> Path:
    """The path of model ``name``'s file, downloading it (checksum verified) when absent."""
    spec = get_spec(name)
    dirs = model_dirs(project_root)
    for folder in dirs:
        candidate = folder / spec.file
        if candidate.is_file():
            return candidate
    target = dirs[-1] / spec.file
    where = " or ".join(str(d) for d in dirs)
    if not (allow_download and spec.url and spec.sha256):
        raise ModelMissingError(f"model {name}: {spec.file} not found; put it in {where} ({spec.note})")
    try:
        _download(spec, target)
    except Exception as exc:
        raise ModelMissingError(f"model {name}: {spec.file} not found in {where} and the download from "
                                f"{spec.url} failed ({exc}); put the file there by hand") from None
    return target


def _download(spec: ModelSpec, target: Path) -> None:
    log.info("downloading %s from %s", spec.file, spec.url)
    with urllib.request.urlopen(spec.url, timeout=60) as response:
        payload = response.read()
    if spec.member:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            names = [n for n in archive.namelist() if n.endswith(spec.member)]
            if not names:
                raise ValueError(f"archive has no {spec.member}")
            payload = archive.read(names[0])
    with atomic_path(target) as tmp:
        tmp.write_bytes(payload)
        digest = sha256_file(tmp)
        if digest != spec.sha256:
            raise ValueError(f"checksum mismatch: got sha256 {digest}, expected {spec.sha256}")
