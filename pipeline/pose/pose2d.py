"""2D pose for a whole segment, streamed: decode, detect the top-k largest people, pose each.

Decoding with the detector's preprocessing, the detector, and the pose model run in three
threads joined by small bounded queues, so the two CPU cores overlap work on consecutive
frames while memory stays constant in the video's length. With ``det_every = k > 1`` the
detector runs on every k-th frame; in between each person's box is carried over from
their keypoints in the previous frame.
"""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from pipeline.ingest.media import iter_frames
from pipeline.pose.models.detector import Detections, FusedDetector, PicoDetDetector, RTMDetDetector, largest
from pipeline.pose.models.pose import MoveNetPose, RTMPose, TinyPose
from pipeline.pose.models.session import create_session
from pipeline.pose.pose2dfile import Poses, SegmentInfo, write_pose2d


@dataclass(frozen=True)
class Pose2dOptions:
    top_k: int = 5                 # keep the k largest people per frame (the seed recipe uses 5)
    det_every: int = 1             # run the detector every k-th frame
    carry_min_score: float = 0.2   # keypoints at least this confident define a carried-over box
    carry_margin: float = 0.15     # carried box = keypoint extent grown by this share per side
    queue_size: int = 4


@dataclass
class FramePoses:
    frame: int
    time: float
    boxes: np.ndarray      # Nx4
    scores: np.ndarray     # N
    keypoints: np.ndarray  # Nx17x3
    detected: bool


_DONE = object()


class _Failed:
    def __init__(self, exc: BaseException) -> None:
        self.exc = exc


def _pump(source: Iterator[Any], out: queue.Queue, stop: threading.Event) -> None:
    try:
        for item in source:
            while not stop.is_set():
                try:
                    out.put(item, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if stop.is_set():
                return
        out.put(_DONE)
    except BaseException as exc:  # re-raised in the consumer thread
        out.put(_Failed(exc))


def _drain(q: queue.Queue) -> Iterator[Any]:
    while True:
        item = q.get()
        if item is _DONE:
            return
        if isinstance(item, _Failed):
            raise item.exc
        yield item


def _threaded(source: Iterator[Any], size: int, stop: threading.Event) -> Iterator[Any]:
    q: queue.Queue = queue.Queue(maxsize=size)
    thread = threading.Thread(target=_pump, args=(source, q, stop), daemon=True)
    thread.start()
    return _drain(q)


def carried_boxes(keypoints: np.ndarray, width: int, height: int, min_score: float, margin: float) -> np.ndarray:
    """Boxes around each person's confident keypoints, grown by ``margin``; NaN rows when too few."""
    boxes = np.full((len(keypoints), 4), np.nan, np.float32)
    for i, kp in enumerate(keypoints):
        good = kp[kp[:, 2] >= min_score]
        if len(good) < 3:
            continue
        x1, y1 = good[:, :2].min(0)
        x2, y2 = good[:, :2].max(0)
        mx, my = (x2 - x1) * margin, (y2 - y1) * margin
        boxes[i] = [max(0, x1 - mx), max(0, y1 - my), min(width, x2 + mx), min(height, y2 + my)]
    return boxes


def estimate_segment(path: Path, fps: float, detector, pose, opts: Pose2dOptions) -> Iterator[FramePoses]:
    """Yield the poses of every decoded frame of the segment at ``path``, in order."""
    stop = threading.Event()
    every = max(1, int(opts.det_every))

    def decoded() -> Iterator[tuple]:
        for frame in iter_frames(path):
            number = int(round(frame.time * fps))
            box: Any = detector.preprocess(frame.image) if number % every == 0 else None  # None: carry over
            yield number, frame.time, frame.image, box

    def detected(frames: Iterator[tuple]) -> Iterator[tuple]:
        for number, time, image, box in frames:
            dets = largest(detector.infer(box), opts.top_k) if box is not None else None
            yield number, time, image, dets

    try:
        stream = _threaded(detected(_threaded(decoded(), opts.queue_size, stop)), opts.queue_size, stop)
        previous: FramePoses | None = None
        for number, time, image, dets in stream:
            was_detected = dets is not None
            if dets is None:
                dets = _carry(previous, image, opts)
            keypoints = pose.estimate(image, dets.boxes)
            result = FramePoses(number, time, dets.boxes, dets.scores, keypoints, was_detected)
            previous = result
            yield result
    finally:
        stop.set()


def _carry(previous: FramePoses | None, image: np.ndarray, opts: Pose2dOptions) -> Detections:
    if previous is None or not len(previous.scores):
        return Detections(np.zeros((0, 4), np.float32), np.zeros(0, np.float32))
    h, w = image.shape[:2]
    boxes = carried_boxes(previous.keypoints, w, h, opts.carry_min_score, opts.carry_margin)
    keep = ~np.isnan(boxes[:, 0])
    return Detections(boxes[keep], previous.scores[keep])


def collect_poses(frames: Iterator[FramePoses], progress: Callable[[], None] | None = None) -> tuple[Poses, int]:
    """Collect per-person rows of every frame; returns them and the number of frames seen."""
    rows: dict[str, list] = {k: [] for k in ("frame", "time", "person", "box", "box_score", "keypoints", "detected")}
    seen = 0
    for fp in frames:
        seen += 1
        n = len(fp.scores)
        rows["frame"].append(np.full(n, fp.frame))
        rows["time"].append(np.full(n, fp.time))
        rows["person"].append(np.arange(n))
        rows["box"].append(np.asarray(fp.boxes, np.float32).reshape(n, 4))
        rows["box_score"].append(np.asarray(fp.scores, np.float32))
        rows["keypoints"].append(np.asarray(fp.keypoints, np.float32).reshape(n, 17, 3))
        rows["detected"].append(np.full(n, fp.detected))
        if progress:
            progress()
    empty = {"box": (0, 4), "keypoints": (0, 17, 3)}
    cat = {k: np.concatenate(v) if v else np.zeros(empty.get(k, (0,))) for k, v in rows.items()}
    return Poses(**cat), seen


# --- the pose2d stage's worker -----------------------------------------------------------

@dataclass(frozen=True)
class ModelFiles:
    """What a worker needs to build its sessions (resolved once, in the stage's process)."""

    detectors: tuple[tuple[str, str, tuple[int, int]], ...]  # (file, kind, input size): several are fused
    pose: str
    pose_kind: str  # movenet | rtmpose | tinypose
    pose_input: tuple[int, int]
    threads: int = 1
    det_score: float = 0.5
    crop_padding: float = 1.25


def model_files(root: Path, params: dict) -> tuple[ModelFiles, dict[str, str]]:
    """Resolve both models in the main process, so a missing one is one clear error up front."""
    from pipeline.core.storage import sha256_file
    from pipeline.pose.models.registry import get_spec, resolve_model

    dets = [get_spec(name) for name in detector_names(params.get("detector", "rtmdet-nano-person"))]
    pose = get_spec(params.get("pose_model", "movenet-lightning"))
    det_paths, pose_path = [resolve_model(d.name, root) for d in dets], resolve_model(pose.name, root)
    files = ModelFiles(tuple((str(path), d.kind, d.input_size) for d, path in zip(dets, det_paths)), str(pose_path),
                       pose.kind, pose.input_size, int(params.get("threads", 1)), float(params.get("det_score", 0.5)),
                       float(params.get("crop_padding", 1.25)))
    hashes = {d.name: sha256_file(path) for d, path in zip(dets, det_paths)}
    return files, {**hashes, pose.name: sha256_file(pose_path)}


def detector_names(value: str | list[str]) -> list[str]:
    """``pose2d.detector``: one registry name, or several (a list, or joined by '+') to fuse."""
    names = value if isinstance(value, list) else str(value).split("+")
    return [n.strip() for n in names if n.strip()]


@dataclass(frozen=True)
class PoseModels:
    detector: RTMDetDetector | PicoDetDetector | FusedDetector
    pose: MoveNetPose | RTMPose | TinyPose


def load_pose_models(files: ModelFiles) -> PoseModels:
    """One worker's sessions, built once and reused for every segment it gets."""
    detectors = []
    for path, kind, size in files.detectors:
        session = create_session(Path(path), files.threads)
        if kind == "rtmdet":
            detectors.append(RTMDetDetector(session, size, files.det_score))
        elif kind == "picodet":
            detectors.append(PicoDetDetector(session, size, files.det_score))
        else:
            raise ValueError(f"model kind {kind!r} is not a person detector")
    detector = detectors[0] if len(detectors) == 1 else FusedDetector(detectors)
    session = create_session(Path(files.pose), files.threads)
    if files.pose_kind == "movenet":
        return PoseModels(detector, MoveNetPose(session, files.pose_input, files.crop_padding))
    if files.pose_kind == "rtmpose":
        return PoseModels(detector, RTMPose(session, files.pose_input, files.crop_padding))
    if files.pose_kind == "tinypose":
        return PoseModels(detector, TinyPose(session, files.pose_input, files.crop_padding))
    raise ValueError(f"pose model kind {files.pose_kind!r} is not a 2D pose model")


@dataclass(frozen=True)
class Pose2dJob:
    video: Path
    out: Path
    segment: SegmentInfo
    opts: Pose2dOptions
    params: dict
    inputs: dict
    fingerprint: str


def pose_segment(models: PoseModels, job: Pose2dJob) -> dict:
    poses, frames = collect_poses(estimate_segment(job.video, job.segment.fps, models.detector, models.pose,
                                                   job.opts))
    segment = SegmentInfo(job.segment.segment_id, job.segment.fps, frames, job.segment.width, job.segment.height)
    write_pose2d(job.out, poses, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"frames": frames, "detections": len(poses), "frames_with_people": len(np.unique(poses.frame))}
