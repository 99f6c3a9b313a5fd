"""The 2D models a stage runs: which files (resolved once, in the stage's process, so a missing one
is one clear error up front), which runtime and precision each runs in (``session.choose_runtime``),
and one worker's sessions built from them (``load_pose_models``), reused for every segment.

Model loading lives beside the models rather than in ``pose2d.py``: how a model is loaded is not
what pose2d computes, and a change here does not change pose2d's code fingerprint. The model
wrappers (OpenCV) and pose2d (SciPy) are imported only to load models: a stage with nothing to do
needs the files' hashes (``model_hashes``), not the models.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline.core.errors import InputError
from pipeline.pose.models.session import CUDA, choose_runtime, create_session, providers, runtime_label

if TYPE_CHECKING:
    from pipeline.pose.pose2d import PoseModels

DEFAULT_DETECTOR = "rtmdet-nano-person"
DEFAULT_POSE_MODEL = "movenet-lightning"
HAND_MODEL = "hand-landmark-full"  # with pose2d.hands
HAND_RECROP = "hand-recrop"        # ... and pose2d.hand_recrop


@dataclass(frozen=True)
class ModelFiles:
    """What a worker needs to build its sessions (resolved once, in the stage's process)."""

    detectors: tuple[tuple[str, str, tuple[int, int]], ...]  # (file, kind, input size): several are fused
    poses: tuple[tuple[str, str, tuple[int, int]], ...]      # the body's model, then optionally the feet's
    threads: int = 1
    det_score: float = 0.5      # the detectors' own threshold (Pose2dOptions.detector_floor)
    crop_padding: float = 1.25
    device: str = "auto"        # session.DEVICES
    runtimes: tuple[tuple[str, str, str], ...] = ()  # (file, runtime, precision) where not ONNX Runtime f32
    hands: str | None = None    # the hand model's file (pose2d.hands)
    hand_recrop: str | None = None  # the re-crop model's file (pose2d.hand_recrop)

    def runtime(self, path: str) -> tuple[str, str]:
        return next(((r, p) for f, r, p in self.runtimes if f == path), ("onnxruntime", "f32"))


def model_names(value: str | list[str]) -> list[str]:
    """``pose2d.detector`` / ``pose2d.pose_model``: one registry name, or several (a list, or joined by '+')."""
    names = value if isinstance(value, list) else str(value).split("+")
    return [n.strip() for n in names if n.strip()]


def hands_on(params: dict, key: str = "hands", default: bool = False) -> bool:
    """Whether ``pose2d.hands`` (or another switch) is on (a YAML boolean, or a string from the command line)."""
    value = params.get(key, default)
    return value if isinstance(value, bool) else str(value).strip().lower() in ("true", "yes", "on", "1")


def hand_models(params: dict) -> list[str]:
    """The hand models the pose2d section ``params`` runs: none with hands off, the landmark model,
    and the re-crop model unless ``hand_recrop`` is off."""
    if not hands_on(params):
        return []
    return [HAND_MODEL] + ([HAND_RECROP] if hands_on(params, "hand_recrop", True) else [])


def models_run(params: dict) -> list[str]:
    """The registry names of the models the pose2d section ``params`` runs: the detectors, the pose
    models and the hand models (what ``dance3d models fetch`` fetches by default)."""
    return model_names(params.get("detector", DEFAULT_DETECTOR)) + model_names(
        params.get("pose_model", DEFAULT_POSE_MODEL)) + hand_models(params)


def _chosen(root: Path, params: dict) -> tuple[list, list, dict[str, Path], str, dict[str, tuple[str, str]]]:
    """(detector specs, pose specs, each model's file, the device, each model's runtime and precision),
    checked in the main process, so a missing model or a bad runtime is one clear error up front. The
    hand model (``pose2d.hands``) is among the files and runtimes, not the specs."""
    from pipeline.pose.models.fetch import resolve_model
    from pipeline.pose.models.registry import get_spec

    dets = [get_spec(name) for name in model_names(params.get("detector", DEFAULT_DETECTOR))]
    poses = [get_spec(name) for name in model_names(params.get("pose_model", DEFAULT_POSE_MODEL))]
    if len(poses) > 2:
        raise ValueError(f"pose2d.pose_model names {len(poses)} models; give one, or a body model + a feet model")
    extra = [get_spec(name) for name in hand_models(params)]
    paths = {spec.name: resolve_model(spec.name, root) for spec in dets + poses + extra}
    device = str(params.get("device", "auto"))
    try:  # an unknown device or runtime, cuda without CUDA, openvino not installed: one clear line up front
        providers(device)
        chosen = {spec.name: choose_runtime(spec.kind, str(params.get("runtime", "auto")),
                                            str(params.get("precision", "auto")), device)
                  for spec in dets + poses + extra}
    except (ValueError, RuntimeError) as exc:
        raise InputError(root / "params.yaml", f"pose2d.{exc}") from None
    return dets, poses, paths, device, chosen


def model_hashes(root: Path, params: dict) -> dict[str, str]:
    """What the models are, as an input of every file they make: each file's SHA-256, and the runtime
    where it is not ONNX Runtime's f32 (it computes other numbers). No model is loaded."""
    from pipeline.core.storage import sha256_file

    _, _, paths, _, chosen = _chosen(root, params)
    hashes = {name: sha256_file(path) for name, path in paths.items()}
    hashes.update({f"{name}@runtime": label for name in paths if (label := runtime_label(*chosen[name]))})
    return hashes


def worker_files(root: Path, params: dict) -> ModelFiles:
    """What a worker needs to build its sessions (``load_pose_models``)."""
    from pipeline.pose.pose2d import Pose2dOptions

    dets, poses, paths, device, chosen = _chosen(root, params)
    return ModelFiles(tuple((str(paths[d.name]), d.kind, d.input_size) for d in dets),
                      tuple((str(paths[p.name]), p.kind, p.input_size) for p in poses),
                      int(params.get("threads", 1)), Pose2dOptions.from_params(params).detector_floor,
                      float(params.get("crop_padding", 1.25)), device,
                      tuple((str(paths[name]), *chosen[name]) for name in paths if runtime_label(*chosen[name])),
                      str(paths[HAND_MODEL]) if HAND_MODEL in paths else None,
                      str(paths[HAND_RECROP]) if HAND_RECROP in paths else None)


def model_files(root: Path, params: dict) -> tuple[ModelFiles, dict[str, str]]:
    """``worker_files`` and ``model_hashes`` together."""
    return worker_files(root, params), model_hashes(root, params)


BATCHED_KINDS = ("tinypose", "blazepose")  # published with a batch of 1: on a GPU, edited to take a frame's crops


def unused_outputs(kind: str):
    """Which outputs of a model of ``kind`` are removed from its graph at load (pruning.without_outputs):
    BlazePose's segmentation mask, half of its cost."""
    if kind != "blazepose":
        return None
    from pipeline.pose.models.pose import BlazePose

    return BlazePose.unused_output


def batch_crops(device: str) -> bool:
    """Whether a frame's crops go to the crop models in one call: on a GPU. On the CPU one crop
    per call is faster (2 cores: five TinyPose crops 56 ms one by one against 71 ms at once, their
    activations overflowing the core's cache; BlazePose the same either way)."""
    return providers(device)[0] == CUDA


def load_pose_models(files: ModelFiles) -> PoseModels:
    """One worker's sessions, built once and reused for every segment it gets."""
    from pipeline.pose.models.detector import FusedDetector, PicoDetDetector, RTMDetDetector
    from pipeline.pose.models.pose import BlazePose, BodyAndFeet, MoveNetPose, RTMPose, TinyPose
    from pipeline.pose.pose2d import PoseModels

    wrappers = {"movenet": MoveNetPose, "rtmpose": RTMPose, "tinypose": TinyPose, "blazepose": BlazePose}
    detectors = []
    for path, kind, size in files.detectors:
        runtime, precision = files.runtime(path)
        session = create_session(Path(path), files.threads, device=files.device, runtime=runtime, precision=precision)
        if kind == "rtmdet":
            detectors.append(RTMDetDetector(session, size, files.det_score))
        elif kind == "picodet":
            detectors.append(PicoDetDetector(session, size, files.det_score))
        else:
            raise ValueError(f"model kind {kind!r} is not a person detector")
    detector = detectors[0] if len(detectors) == 1 else FusedDetector(detectors)
    poses = []
    for path, kind, size in files.poses:
        if kind not in wrappers:
            raise ValueError(f"model kind {kind!r} is not a 2D pose model")
        batched = kind in BATCHED_KINDS and batch_crops(files.device)
        runtime, precision = files.runtime(path)
        session = create_session(Path(path), files.threads, any_batch=batched, unused_outputs=unused_outputs(kind),
                                 device=files.device, runtime=runtime, precision=precision)
        poses.append(wrappers[kind](session, size, files.crop_padding))
    hands = None
    if files.hands is not None:
        from pipeline.pose.hands import HandLandmarks, HandModels, HandRecrop

        def session(path: str):
            runtime, precision = files.runtime(path)
            return create_session(Path(path), files.threads, device=files.device, runtime=runtime, precision=precision)

        hands = HandModels(HandLandmarks(session(files.hands)),
                           HandRecrop(session(files.hand_recrop)) if files.hand_recrop else None)
    return PoseModels(detector, poses[0] if len(poses) == 1 else BodyAndFeet(*poses), hands)
