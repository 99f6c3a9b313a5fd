"""2D pose for a whole segment, streamed: decode, detect the top-k largest people, pose each.

Decoding with the detector's preprocessing, the detector, the body's pose model and the
feet's (when it is a separate one) run in four threads joined by small bounded queues, so
the two CPU cores overlap work on consecutive frames while memory stays constant in the
video's length. With ``fps`` the models pose keyframes only, at that rate, and the frames
between are interpolated (:mod:`pipeline.pose.keyframes`). With ``det_every = k > 1`` the
detector runs on every k-th posed frame; in between each person's box is carried over from
their keypoints in the previous posed frame, and the detector runs after all on a frame where
a person is lost, a pose is weak or two people overlap (:func:`needs_detection`), as MediaPipe
and rtmlib's trackers fall back to their detectors.

Who counts as a person (:func:`find_people`): a box at ``det_score`` or above, or a weaker one
(down to ``confirm_score``) whose pose the pose model confirms with ``confirm_joints``
confident joints: small, cropped and seated people score low with the detectors but give a
clear skeleton. Very dark frames are brightened first (:func:`lift_dark`).
"""

from __future__ import annotations

import dataclasses
import functools
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import cv2
import numpy as np

from pipeline.core.threads import threaded
from pipeline.ingest.media import Frame
from pipeline.ingest.segmentvideo import SegmentVideo, frames_of
from pipeline.pose.boxes import iou_matrix
from pipeline.pose.hands import HandModels, hands_array
from pipeline.pose.keyframes import drawn_boxes, held, in_between, keyframe_step, newcomers, people_change
from pipeline.pose.models.detector import Detections, FusedDetector, PicoDetDetector, RTMDetDetector, largest
from pipeline.pose.models.pose import BlazePose, BodyAndFeet, MoveNetPose, PoseBatch, RTMPose, TinyPose
from pipeline.pose.pose2dfile import FEET, HAND_POINTS, Poses, SegmentInfo, write_pose2d


@dataclass(frozen=True)
class Pose2dOptions:
    top_k: int = 5                 # keep the k largest people per frame (the seed recipe uses 5)
    fps: float = 0.0               # the models pose at least this many frames a second, the frames between
                                   # are interpolated (keyframes.keyframe_step; 0: every frame)
    det_every: int = 1             # run the detector every k-th posed frame
    carry_min_score: float = 0.2   # keypoints at least this confident define a carried-over box
    carry_margin: float = 0.15     # carried box = keypoint extent grown by this share per side ...
    carry_framed: bool = True      # ... or framed as the detector last framed that person (box_framing)
    pose_changes: bool = True      # where someone is on only one of two keyframes, the frames between are
                                   # looked at too, not only drawn (keyframes.people_change) ...
    changes_only: bool = False     # ... and only the people who came or went are posed there, the others
                                   # drawn (keyframes.newcomers; faster on crowds, less exact: reports/throughput.md)
    redetect_overlap: float = 0.3  # between detections, two carried people overlapping this much (IoU) ...
    redetect_joints: int = 6       # ... or a carried pose with fewer joints at confirm_joint_score, or one
                                   # lost: the detector runs on that frame after all (0: never on demand)
    queue_size: int = 4
    det_score: float = 0.5         # a box this confident is a person
    confirm_score: float = 0.0     # a weaker box down to this is a person if its pose confirms it (0: off)
    confirm_joints: int = 10       # ... with at least this many joints ...
    confirm_joint_score: float = 0.3  # ... at least this confident
    confirm_min_height: float = 40.0  # ... and is at least this tall (pixels): tiny crops give confident noise
    confirm_min_share: float = 0.0    # ... and at least this share of the tallest sure person's height (0: any)
    min_joints: int = 0            # even a sure box needs this many joints at confirm_joint_score (0: none)
    dark_mean: float = 40.0        # frames darker than this mean pixel value are brightened (0: never)
    hands: bool = False            # 21 points per hand of every posed person (hands.body_hands)
    hand_passes: int = 2           # the hand model's passes: the forearm's region, then the hand's own
    hand_recrop: bool = True       # the forearm's region refined by Holistic's re-crop model first

    @staticmethod
    def from_params(params: dict) -> "Pose2dOptions":
        names = ("top_k", "fps", "det_every", "det_score", "confirm_score", "confirm_joints", "confirm_joint_score",
                 "confirm_min_height", "confirm_min_share", "min_joints", "dark_mean", "redetect_overlap",
                 "redetect_joints", "carry_framed", "pose_changes", "changes_only", "hands", "hand_passes",
                 "hand_recrop")
        fields = {f: type(getattr(Pose2dOptions, f)) for f in names}
        return Pose2dOptions(**{f: kind(params[f]) for f, kind in fields.items() if f in params})

    @property
    def detector_floor(self) -> float:
        """The score threshold the detectors run at: the lowest box that may become a person."""
        return self.confirm_score if 0 < self.confirm_score < self.det_score else self.det_score


def lift_dark(image: np.ndarray, below: float) -> np.ndarray:
    """A frame whose mean pixel value is under ``below``, scaled so its 99.5th percentile is 200.

    Night clubs and stage lighting: both models were trained on well-lit photos and see
    nobody in a near-black frame, though the picture is there.
    """
    if below <= 0 or _mean_value(image) >= below:
        return image
    top = max(float(np.percentile(image, 99.5)), 1.0)
    return np.clip(image.astype(np.float32) * (200.0 / top), 0, 255).astype(np.uint8)


def _mean_value(image: np.ndarray) -> float:
    """The mean pixel value over all channels (OpenCV's, several times numpy's speed on a 1080p frame)."""
    channels = image.shape[2] if image.ndim == 3 else 1
    return float(sum(cv2.mean(image)[:channels]) / channels)


def _share_inside(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(Na x Nb): the share of each box of ``a``'s area that lies inside each box of ``b``."""
    x1, y1 = np.maximum(a[:, None, 0], b[None, :, 0]), np.maximum(a[:, None, 1], b[None, :, 1])
    x2, y2 = np.minimum(a[:, None, 2], b[None, :, 2]), np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    area = np.maximum((a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1]), 1e-9)
    return inter / area[:, None]


def find_people(image: np.ndarray, dets: Detections, pose, opts: Pose2dOptions,
                known: np.ndarray | None = None) -> tuple[Detections, PoseBatch]:
    """The people among ``dets`` and their poses, the ``top_k`` largest first.

    Boxes at ``det_score`` or above are people if their pose has ``min_joints`` joints at
    ``confirm_joint_score`` (a detector's box around a poster or a whole test card has none);
    of the weaker ones (the ``top_k`` most confident), those at least ``confirm_min_height``
    tall and ``confirm_min_share`` of the tallest sure box's height whose pose has
    ``confirm_joints`` such joints and that do not lie inside a sure box. ``known``: boxes (M x 4)
    of people already known on this image and not to be posed again (drawn between keyframes),
    who count as sure people for those rules.
    """
    known = np.zeros((0, 4), np.float32) if known is None else np.asarray(known, np.float32).reshape(-1, 4)
    strong = dets.scores >= opts.det_score
    sure = largest(Detections(dets.boxes[strong], dets.scores[strong]), opts.top_k)
    weak = np.flatnonzero(~strong)
    if opts.confirm_score > 0:  # worth a pose: tall enough, and not a part of a sure person (a lap, a torso)
        box, sure_boxes = dets.boxes[weak], np.concatenate([sure.boxes.reshape(-1, 4), known])
        tallest = float((sure_boxes[:, 3] - sure_boxes[:, 1]).max(initial=0.0))
        worth = (box[:, 3] - box[:, 1] >= max(opts.confirm_min_height, opts.confirm_min_share * tallest)) & (
            _share_inside(box, sure_boxes).max(1, initial=0.0) < 0.5)
        weak = weak[worth]
        weak = weak[np.argsort(-dets.scores[weak], kind="stable")][: opts.top_k]
    else:
        weak = weak[:0]
    body_model = pose.body if isinstance(pose, BodyAndFeet) else pose  # the feet only for the people kept
    batch: PoseBatch = body_model.estimate(image, sure.boxes)
    is_sure = _joints(batch.keypoints, opts) >= opts.min_joints
    weak, weak_batch, confirmed = _confirm_largest_first(image, dets.boxes, weak,
                                                         np.concatenate([sure.boxes[is_sure].reshape(-1, 4), known]),
                                                         body_model, opts)
    batch = _joined(batch, weak_batch)
    boxes = np.concatenate([sure.boxes, dets.boxes[weak]]).reshape(-1, 4)
    scores = np.concatenate([sure.scores, dets.scores[weak]])
    keep = np.flatnonzero(np.concatenate([is_sure, confirmed]))
    keep = keep[np.lexsort((-scores[keep], -_areas(boxes[keep])))][: opts.top_k]
    people = Detections(boxes[keep], scores[keep])
    if isinstance(pose, BodyAndFeet):
        return people, pose.complete(image, people.boxes, PoseBatch.body_only(batch.keypoints[keep]))
    world = batch.world[keep] if batch.world is not None else None
    return people, PoseBatch(batch.keypoints[keep], batch.feet[keep], world)


def _joints(keypoints: np.ndarray, opts: Pose2dOptions) -> np.ndarray:
    """(N) each pose's joints at ``confirm_joint_score`` or more."""
    return (keypoints[:, :, 2] >= opts.confirm_joint_score).sum(1)


def _confirm_largest_first(image: np.ndarray, boxes: np.ndarray, weak: np.ndarray, sure_people: np.ndarray,
                           body_model, opts: Pose2dOptions) -> tuple[np.ndarray, PoseBatch, np.ndarray]:
    """The weak candidates worth a pose (indices into ``boxes``: already tall enough and not lying
    inside a sure person, see find_people), largest first, their poses, and which of them the pose
    confirms (``confirm_joints`` joints).

    Only the top_k largest people are kept, so once top_k people are known (the ``sure_people``,
    the weak ones confirmed), a candidate no larger than the top_k-th of them cannot be kept (ties
    go to the surer box): it and every smaller one are not posed (a crowd's bystanders).
    """
    areas = _areas(boxes[weak])
    order = np.argsort(-areas, kind="stable")
    weak, areas = weak[order], areas[order]
    people = list(_areas(sure_people))  # the areas of the people known so far
    posed: list[PoseBatch] = []
    confirmed: list[bool] = []
    for k, (i, area) in enumerate(zip(weak, areas)):
        if len(people) >= opts.top_k and area <= sorted(people, reverse=True)[opts.top_k - 1]:
            weak = weak[:k]
            break
        posed.append(body_model.estimate(image, boxes[i:i + 1]))
        confirmed.append(bool(_joints(posed[-1].keypoints, opts)[0] >= opts.confirm_joints))
        if confirmed[-1]:
            people.append(float(area))
    batch = functools.reduce(_joined, posed, PoseBatch.body_only(np.zeros((0, 17, 3), np.float32)))
    return weak, batch, np.array(confirmed, bool)


def _areas(boxes: np.ndarray) -> np.ndarray:
    return (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])


def _joined(a: PoseBatch, b: PoseBatch) -> PoseBatch:
    if not len(a) or not len(b):
        return b if not len(a) else a
    world = np.concatenate([a.world, b.world]) if a.world is not None and b.world is not None else None
    return PoseBatch(np.concatenate([a.keypoints, b.keypoints]), np.concatenate([a.feet, b.feet]), world)


@dataclass
class FramePoses:
    frame: int
    time: float
    boxes: np.ndarray      # Nx4
    scores: np.ndarray     # N
    keypoints: np.ndarray  # Nx17x3
    detected: bool | np.ndarray  # (per person, or for all) the box is the detector's, not carried over
    feet: np.ndarray       # Nx4x3
    interpolated: bool | np.ndarray = False  # (per person, or for all) drawn between two keyframes
                                             # (keyframes.in_between), not posed
    hands: np.ndarray | None = None        # Nx2x21x3 left and right hand (hands.hands_array); None: not asked
    hands_world: np.ndarray | None = None  # Nx2x21x3 metres about each hand


@dataclass(frozen=True)
class _Newcomers:
    """The people who came or went, posed on a frame between two keyframes whose people differ."""

    frame: int
    time: float
    image: np.ndarray
    dets: Detections
    batch: PoseBatch


def keypoint_extent(keypoints: np.ndarray, min_score: float) -> np.ndarray:
    """(N x 4) the box spanned by each person's keypoints of at least ``min_score``; NaN when fewer than 3."""
    boxes = np.full((len(keypoints), 4), np.nan, np.float32)
    for i, kp in enumerate(keypoints):
        good = kp[kp[:, 2] >= min_score]
        if len(good) >= 3:
            boxes[i] = [*good[:, :2].min(0), *good[:, :2].max(0)]
    return boxes


def _sides(extent: np.ndarray) -> np.ndarray:
    w, h = np.maximum(extent[:, 2] - extent[:, 0], 1.0), np.maximum(extent[:, 3] - extent[:, 1], 1.0)
    return np.stack([w, h, w, h], 1)


def box_framing(boxes: np.ndarray, keypoints: np.ndarray, min_score: float, margin: float) -> np.ndarray:
    """(N x 4) how each box frames its person's keypoints: its edges' offsets from the keypoints'
    extent, in shares of the extent's width and height (``margin`` on every side where too few)."""
    extent = keypoint_extent(keypoints, min_score)
    framing = (np.asarray(boxes, np.float32).reshape(-1, 4) - extent) / _sides(extent)
    default = np.array([-margin, -margin, margin, margin], np.float32)
    return np.where(np.isnan(framing), default, framing).astype(np.float32)


def carried_boxes(keypoints: np.ndarray, width: int, height: int, min_score: float, margin: float,
                  framing: np.ndarray | None = None) -> np.ndarray:
    """Boxes around each person's confident keypoints, framed as ``framing`` says (their last
    detected box's :func:`box_framing`) or grown by ``margin``; NaN rows when too few."""
    extent = keypoint_extent(keypoints, min_score)
    if framing is None:
        framing = np.tile(np.array([-margin, -margin, margin, margin], np.float32), (len(keypoints), 1))
    boxes = extent + framing * _sides(extent)
    boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, width)
    boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, height)
    return boxes.astype(np.float32)


def estimate_segment(video: Path | SegmentVideo, fps: float, detector, pose, opts: Pose2dOptions,
                     span: tuple[int, int] | None = None, hands: HandModels | None = None) -> Iterator[FramePoses]:
    """Yield the poses of every frame of ``video`` (a segment view or a video file), in order;
    ``span``: only a segment view's frames first to end - 1 (a part, ``parts.plan_parts``); with
    ``hands`` (the hand models), every posed person's hands too.

    The models pose every ``keyframe_step``-th frame (and a segment's or a part's last); the frames
    between are decoded but not converted, and come out interpolated once the next keyframe is
    posed, or posed after all where the two keyframes' people differ (``pose_changes``).
    """
    stop = threading.Event()
    every = max(1, int(opts.det_every))
    step = keyframe_step(fps, opts.fps)
    first, end = span if span is not None else (0, video.frames if isinstance(video, SegmentVideo) else 0)
    last = end - 1 if isinstance(video, SegmentVideo) else -1

    def posed(index: int) -> bool:
        return index % step == 0 or index == last

    def frames() -> Iterator[Frame]:
        if span is None:
            yield from frames_of(video, keep=posed if step > 1 else None)
            return
        assert isinstance(video, SegmentVideo), "a span is a segment view's"
        for frame in video.iter_frames(keep=posed if step > 1 else None, first=first):
            yield frame
            if frame.index >= last:
                return

    def decoded() -> Iterator[tuple | Frame]:
        keyframes = 0
        for frame in frames():
            number = int(round(frame.time * fps))
            if frame.image is None:  # between keyframes: passed on unconverted
                yield dataclasses.replace(frame, index=number)
                continue
            image = lift_dark(frame.image, opts.dark_mean)
            box: Any = detector.preprocess(image) if keyframes % every == 0 else None  # None: carry over
            keyframes += 1
            yield number, frame.time, image, box

    def detected(frames: Iterator[tuple | Frame]) -> Iterator[tuple | Frame]:
        for item in frames:
            if isinstance(item, Frame):
                yield item
                continue
            number, time, image, box = item
            dets = detector.infer(box) if box is not None else None
            yield number, time, image, dets

    # With a separate feet model, the body (and who is a person) and the feet run in different
    # threads, so the two models overlap on consecutive frames.
    feet_model = pose if isinstance(pose, BodyAndFeet) else None
    body_model = pose.body if feet_model else pose

    def people(frames: Iterator[tuple | Frame]) -> Iterator[tuple | Frame | _Newcomers]:
        previous: Detections | None = None
        previous_number = 0
        keypoints = np.zeros((0, 17, 3), np.float32)
        framing = np.zeros((0, 4), np.float32)  # how the detector framed each person (box_framing)
        waiting: list[Frame] = []  # the frames since the last keyframe
        for item in frames:
            if isinstance(item, Frame):
                waiting.append(item)
                continue
            number, time, image, dets = item
            found = dets  # None: carry the boxes over
            if dets is None:
                dets, kept = _carry(previous, keypoints, framing, image, opts)
                framing = framing[kept]
                batch: PoseBatch = body_model.estimate(image, dets.boxes)
                if needs_detection(previous, dets, batch.keypoints, opts):
                    found = detector.detect(image)
            if found is not None:
                dets, batch = find_people(image, found, body_model, opts)
                framing = box_framing(dets.boxes, batch.keypoints, opts.carry_min_score, opts.carry_margin)
            if waiting and previous is not None and opts.pose_changes and people_change(previous, dets):
                if opts.changes_only:  # drawing the newcomers would guess; the others are drawn
                    shares = [(frame.index - previous_number) / (number - previous_number) for frame in waiting]
                    drawn = drawn_boxes(previous.boxes, dets.boxes, np.array(shares))
                    yield from (posed_newcomers(frame, boxes) for frame, boxes in zip(waiting, drawn))
                else:
                    yield from (posed_now(frame) for frame in waiting)
            else:
                yield from waiting
            waiting = []
            previous, previous_number, keypoints = dets, number, batch.keypoints
            yield number, time, image, dets, batch, found is not None
        yield from waiting

    def posed_now(frame: Frame) -> tuple:
        """A frame between two keyframes whose people differ, posed as a keyframe is."""
        image = lift_dark(frame.shown(), opts.dark_mean)
        dets, batch = find_people(image, detector.detect(image), body_model, opts)
        return frame.index, frame.time, image, dets, batch, True

    def posed_newcomers(frame: Frame, drawn: np.ndarray) -> _Newcomers:
        """A frame between two keyframes whose people differ: the people the detector finds there who
        are none of those on both keyframes (their boxes ``drawn`` on this frame), posed as on a keyframe."""
        image = lift_dark(frame.shown(), opts.dark_mean)
        found = detector.detect(image)
        new = newcomers(found.boxes, drawn)
        dets, batch = find_people(image, Detections(found.boxes[new], found.scores[new]), body_model, opts, drawn)
        return _Newcomers(frame.index, frame.time, image, dets, batch)

    def with_hands(posed: FramePoses, image: np.ndarray) -> FramePoses:
        if hands is None:
            return posed
        points, world = hands_array(hands.find(image, posed.keypoints, opts.hand_passes))
        return dataclasses.replace(posed, hands=points, hands_world=world)

    try:
        q = opts.queue_size
        stream = threaded(people(threaded(detected(threaded(decoded(), q, stop)), q, stop)), q, stop)
        keyframe: FramePoses | None = None
        between: list[Frame] = []  # frames since the last keyframe, waiting for the next
        newcomers_on: dict[int, FramePoses] = {}  # ... and the people posed on some of them
        for item in stream:
            if isinstance(item, Frame):
                between.append(item)
                continue
            if isinstance(item, _Newcomers):
                batch = feet_model.complete(item.image, item.dets.boxes, item.batch) if feet_model else item.batch
                newcomers_on[item.frame] = with_hands(_frame_poses(item.frame, item.time, item.dets, batch, True),
                                                      item.image)
                between.append(Frame(item.frame, item.time, None))
                continue
            number, time, image, dets, batch, was_detected = item
            if feet_model is not None:
                batch = feet_model.complete(image, dets.boxes, batch)
            current = with_hands(_frame_poses(number, time, dets, batch, was_detected), image)
            if between and keyframe is not None:
                yield from in_between(keyframe, current, [(f.index, f.time) for f in between], opts.top_k,
                                      newcomers_on)
            between, newcomers_on = [], {}
            yield current
            keyframe = current
        if between and keyframe is not None:  # a video file's frames after its last keyframe
            yield from held(keyframe, [(f.index, f.time) for f in between])
    finally:
        stop.set()


def _frame_poses(number: int, time: float, people: Detections, batch: PoseBatch, detected: bool) -> FramePoses:
    return FramePoses(number, time, people.boxes, people.scores, batch.keypoints, detected, batch.feet)


def needs_detection(previous: Detections | None, carried: Detections, keypoints: np.ndarray,
                    opts: Pose2dOptions) -> bool:
    """Whether a frame between detections needs the detector after all: someone was lost (too few
    confident keypoints to carry a box), a carried pose is weak (fewer than ``redetect_joints``
    joints at ``confirm_joint_score``), or two people overlap (IoU above ``redetect_overlap``), where
    carried boxes may slide from one dancer onto the other."""
    if opts.redetect_joints <= 0:
        return False
    if previous is not None and len(carried) < len(previous):
        return True
    if ((keypoints[:, :, 2] >= opts.confirm_joint_score).sum(1) < opts.redetect_joints).any():
        return True
    if len(carried) > 1:
        overlap = iou_matrix(carried.boxes, carried.boxes)
        np.fill_diagonal(overlap, 0.0)
        return bool((overlap > opts.redetect_overlap).any())
    return False


def _carry(previous: Detections | None, keypoints: np.ndarray, framing: np.ndarray, image: np.ndarray,
           opts: Pose2dOptions) -> tuple[Detections, np.ndarray]:
    """The previous people's boxes carried onto this frame, and which of them could be (a mask)."""
    if previous is None or not len(previous.scores):
        return Detections(np.zeros((0, 4), np.float32), np.zeros(0, np.float32)), np.zeros(0, bool)
    h, w = image.shape[:2]
    boxes = carried_boxes(keypoints, w, h, opts.carry_min_score, opts.carry_margin,
                          framing if opts.carry_framed else None)
    keep = ~np.isnan(boxes[:, 0])
    return Detections(boxes[keep], previous.scores[keep]), keep


def collect_poses(frames: Iterator[FramePoses], progress: Callable[[], None] | None = None) -> tuple[Poses, int]:
    """Collect per-person rows of every frame; returns them and the number of frames seen."""
    rows: dict[str, list] = {k: [] for k in ("frame", "time", "person", "box", "box_score", "keypoints", "detected",
                                             "feet", "interpolated", "hands", "hands_world")}
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
        rows["detected"].append(np.broadcast_to(np.asarray(fp.detected, bool), (n,)))
        rows["feet"].append(np.asarray(fp.feet, np.float32).reshape(n, FEET, 3))
        rows["interpolated"].append(np.broadcast_to(np.asarray(fp.interpolated, bool), (n,)))
        if fp.hands is not None:
            rows["hands"].append(np.asarray(fp.hands, np.float32).reshape(n, 2, HAND_POINTS, 3))
            rows["hands_world"].append(np.asarray(fp.hands_world, np.float32).reshape(n, 2, HAND_POINTS, 3))
        if progress:
            progress()
    empty = {"box": (0, 4), "keypoints": (0, 17, 3), "feet": (0, FEET, 3)}
    hands = rows.pop("hands"), rows.pop("hands_world")
    cat = {k: np.concatenate(v) if v else np.zeros(empty.get(k, (0,))) for k, v in rows.items()}
    if hands[0] and len(hands[0]) != seen:
        raise ValueError("hands on some frames but not on others")
    if hands[0]:
        cat.update(hands=np.concatenate(hands[0]), hands_world=np.concatenate(hands[1]))
    return Poses(**cat), seen


# --- the pose2d stage's worker -----------------------------------------------------------

@dataclass(frozen=True)
class PoseModels:
    detector: RTMDetDetector | PicoDetDetector | FusedDetector
    pose: MoveNetPose | RTMPose | TinyPose | BlazePose | BodyAndFeet
    hands: HandModels | None = None  # the hand models (pose2d.hands)


@dataclass(frozen=True)
class Pose2dJob:
    video: SegmentVideo
    out: Path
    segment: SegmentInfo
    opts: Pose2dOptions
    params: dict
    inputs: dict
    fingerprint: str
    span: tuple[int, int] | None = None  # a part's frames (parts.plan_parts); None: the whole segment


def pose_segment(models: PoseModels, job: Pose2dJob) -> dict:
    if job.opts.hands and models.hands is None:
        raise ValueError("pose2d.hands is on but no hand model was loaded")
    poses, frames = collect_poses(estimate_segment(job.video, job.segment.fps, models.detector, models.pose,
                                                   job.opts, job.span, models.hands if job.opts.hands else None))
    segment = SegmentInfo(job.segment.segment_id, job.segment.fps, frames, job.segment.width, job.segment.height)
    write_pose2d(job.out, poses, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"frames": frames, "detections": len(poses), "frames_with_people": len(np.unique(poses.frame))}
