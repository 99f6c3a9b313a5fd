"""The model registry: each model's file, checksum, official source and input spec.

Lookup order for a model file: ``$DANCE3D_MODELS``, the project's ``models/`` folder, the
copy shipped in the package (``weights/``: PP-TinyPose, which has no download), then a
download from its route (``fetch.resolve_model``: sha256 checked, outputs verified). This
module is the table and the places to look; fetching sits above it. Models whose route needs
a conversion are fetched by ``dance3d models fetch``, never silently during a stage. A model
that cannot be found gives one line saying which file to put where.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

from pipeline.core.errors import ModelMissingError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModelSpec:
    name: str
    file: str
    kind: str                   # rtmdet | picodet | movenet | rtmpose | tinypose | blazepose | hand | hand_recrop
                                # | palm | lifter
    input_size: tuple[int, int]  # (width, height) the model expects
    sha256: str | None          # None: not pinned, so never downloaded automatically
    url: str | None = None      # where users get it by hand (fetchable models have routes in fetch.py)
    member: str | None = None   # the file inside that archive
    note: str = ""
    shipped: bool = False       # a copy ships in the package (SHIPPED; licence and provenance beside it)


SHIPPED = Path(__file__).resolve().parent / "weights"


REGISTRY: dict[str, ModelSpec] = {
    spec.name: spec
    for spec in (
        ModelSpec(
            "rtmdet-nano-person", "rtmdet_nano_person_end2end.onnx", "rtmdet", (320, 320),
            "4720eda18a18402e7b76d85827d4bc60fba18111fc0b74b559e4d24da9ddc3d2",
            note="RTMDet-nano person detector (OpenMMLab, Apache-2.0), mmdeploy end2end export with NMS",
        ),
        ModelSpec(
            "picodet-s-pedestrian", "picodet_s_320_pedestrian.onnx", "picodet", (320, 320),
            "620ca936c542462aa647380e7ccf98709cb603e582e2e6ef522f3ca165159cc4",
            note="PicoDet-S-LCNet pedestrian 320 (PaddleDetection, Apache-2.0), no NMS in the graph, converted from "
                 "an OpenVINO IR export (MODELS.md 4c); no official ONNX download",
        ),
        ModelSpec(
            "movenet-lightning", "movenet_singlepose_lightning_4_dequant.onnx", "movenet", (192, 192),
            "c7ce583bf620af48a3d0d14226691d3ebd2783165bf525b58d4dc33132aed735",
            note="MoveNet SinglePose Lightning v4 (Google, Apache-2.0) converted from the TF-Hub int8 "
                 "TFLite with tf2onnx --dequantize; there is no official ONNX download",
        ),
        ModelSpec(
            "tinypose", "tinypose_256x192.onnx", "tinypose", (192, 256),
            "d6b08c1ada0a807d27b260d3a19cfade722e7253cc1bfe59d6bfb98932061a1f",
            note="PP-TinyPose 256x192 (PaddleDetection, Apache-2.0), COCO-17 heatmaps, converted from an OpenVINO "
                 "IR export; no official ONNX download, so it ships in the package (weights/PROVENANCE.md)",
            shipped=True,
        ),
        ModelSpec(
            "blazepose-full", "blazepose_full.onnx", "blazepose", (256, 256), None,
            note="BlazePose GHUM Full (Google, Apache-2.0): 33 landmarks with heels and toes, and world "
                 "landmarks; converted from the mediapipe 0.10.21 wheel by `dance3d models fetch blazepose-full`",
        ),
        ModelSpec(
            "hand-landmark-full", "hand_landmark_full.onnx", "hand", (224, 224), None,
            note="MediaPipe's hand landmark model, full (Google, Apache-2.0): 21 hand points in the image and in "
                 "metres; converted from the mediapipe 0.10.21 wheel by `dance3d models fetch hand-landmark-full`",
        ),
        ModelSpec(
            "hand-recrop", "hand_recrop.onnx", "hand_recrop", (256, 256), None,
            note="MediaPipe Holistic's hand re-crop model (Google, Apache-2.0): in a region around a hand, the "
                 "hand's centre and size; converted from the mediapipe 0.10.21 wheel by `dance3d models fetch "
                 "hand-recrop`",
        ),
        ModelSpec(
            "palm-detection-full", "palm_detection_full.onnx", "palm", (192, 192), None,
            note="MediaPipe's palm detector, full (Google, Apache-2.0), the peer of `eval hands`; converted from the "
                 "mediapipe 0.10.21 wheel by `dance3d models fetch palm-detection-full`",
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


def search_dirs(spec: ModelSpec, project_root: Path | None = None) -> list[Path]:
    """Where ``spec``'s file is looked for, in order: ``model_dirs``, then the package's copy if it ships."""
    return model_dirs(project_root) + ([SHIPPED] if spec.shipped else [])


def get_spec(name: str) -> ModelSpec:
    if name not in REGISTRY:
        raise ModelMissingError(f"unknown model {name!r}; registered: {', '.join(sorted(REGISTRY))}")
    return REGISTRY[name]
