"""Hands: 21 keypoints per hand from MediaPipe's hand landmark model, on a region of the image.

The region is a rotated square, MediaPipe's convention (``models.pose.roi_transform``): from a
box around the hand (an annotation), or from the body's forearm (elbow -> wrist: the hand lies
beyond the wrist along it, about half a forearm long). A second pass takes MediaPipe's own
region from the first pass's landmarks: wrist -> middle finger's knuckle pointing up, twice the
hand's extent. Joints are in MediaPipe's order (``pose2dfile.HAND_JOINTS``), which is also FreiHAND's,
InterHand's and COCO-WholeBody's.

``body_hands`` is how pose2d (``pose2d.hands``) and ``eval hands`` find a posed person's hands: a
region beyond each confident wrist, none where the wrist is unsure, the region mostly out of the
picture or too small for the model; ``hands_array`` packs them into the pose2d file's layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.pose.models.pose import roi_transform, to_image, warp
from pipeline.pose.pose2dfile import MIN_PRESENCE

WRIST, MIDDLE_KNUCKLE = 0, 9
SIDES = ("left", "right")
# The hand's centre beyond the wrist, and the region's side, in forearm lengths (elbow -> wrist):
# an adult hand is about 0.7 of a forearm from wrist to fingertip.
CENTRE_BEYOND_WRIST = 0.35
SIDE_PER_FOREARM = 1.3
COCO_ELBOW_WRIST = ((7, 9), (8, 10))  # (elbow, wrist) of the left, then the right arm
MIN_WRIST_SCORE = 0.3
# A region under this side (pixels) holds a hand under about 10 px: the model sees a blur there
# (hand_eval's 13-31 px hands of whole people: presence under 0.5 on 11 of 13, docs/reports/hands.md).
MIN_REGION_PX = 20.0
MAX_WRIST_OFFSET = 0.5  # a hand whose wrist lies farther than this (forearms) from the body's is another's
SEARCH_PER_FOREARM = 1.8  # the re-crop model's search region: about 2.6 hand lengths, as Holistic's from the pose


@dataclass(frozen=True)
class Hand:
    """One hand found in a region."""

    keypoints: np.ndarray  # 21 x 3: x, y (image pixels), score (the hand's presence; the model has no per-joint one)
    world: np.ndarray      # 21 x 3: metres about the hand's centre, x right and y down as the image
    presence: float        # the model's confidence that a hand is there
    right: float           # its probability that this is a right hand (on the image as it is, not mirrored)
    region: np.ndarray     # the 2 x 3 affine that made the crop


class HandLandmarks:
    """MediaPipe's hand landmark model (full), NHWC RGB [0, 1] 224 x 224 in; per crop 21 points in
    crop pixels (and a relative depth), the hand's presence, its handedness and 21 world points."""

    def __init__(self, session, size: int = 224) -> None:
        self.session, self.size = session, size
        self.input_name = session.get_inputs()[0].name
        names = [o.name for o in session.get_outputs()]  # as converted: screen, presence, handedness, world
        self.screen, self.presence, self.handedness, self.world = names[:4]

    def run(self, image: np.ndarray, region: np.ndarray) -> Hand:
        """The hand in ``region`` (a 2 x 3 affine onto the model's square) of a BGR ``image``."""
        crop = warp(image, region, self.size, self.size)[..., ::-1].astype(np.float32) / 255.0
        screen, presence, handedness, world = self.session.run(
            [self.screen, self.presence, self.handedness, self.world], {self.input_name: crop[None]})
        xy = to_image(screen.reshape(21, 3)[:, :2].astype(np.float64), region)
        p = float(np.ravel(presence)[0])
        rot = region[:, :2] / np.hypot(*region[0, :2])  # the crop's rotation, undone for the world points
        w = world.reshape(21, 3).astype(np.float64)
        # The handedness output is the probability of a right hand on the image as given (on the annotated
        # hands of hand_eval, every clear one agrees; MediaPipe's label map reads it for mirrored images).
        return Hand(np.column_stack([xy, np.full(21, p)]).astype(np.float32),
                    np.column_stack([w[:, :2] @ rot, w[:, 2]]).astype(np.float32), p,
                    float(np.ravel(handedness)[0]), region)

    def estimate(self, image: np.ndarray, region: np.ndarray, passes: int = 2) -> Hand:
        """The hand in ``region``, then ``passes - 1`` times in the region its landmarks give."""
        hand = self.run(image, region)
        for _ in range(passes - 1):
            hand = self.run(image, region_from_landmarks(hand.keypoints[:, :2], self.size))
        return hand


class HandRecrop:
    """MediaPipe Holistic's hand re-crop model: in a search region around a hand (NHWC RGB [0, 1]
    256 x 256) it gives two points, the hand's centre and a point that sets its size and turn, from
    which Holistic takes the region it gives the landmark model (``refine``)."""

    def __init__(self, session, size: int = 256) -> None:
        self.session, self.size = session, size
        self.input_name = session.get_inputs()[0].name

    def points(self, image: np.ndarray, region: np.ndarray) -> np.ndarray:
        """(2 x 2) the centre and the scale point, image pixels, in ``region`` (2 x 3 onto the model's square)."""
        crop = warp(image, region, self.size, self.size)[..., ::-1].astype(np.float32) / 255.0
        out = self.session.run(None, {self.input_name: crop[None]})[0]
        return to_image(np.asarray(out, np.float64).reshape(2, 2), region)

    def refine(self, image: np.ndarray, region: np.ndarray, size: int = 224) -> np.ndarray | None:
        """The landmark model's region: a square centred on the first point, as wide as twice its
        distance to the second, turned so the second lies below the first (towards the wrist), moved a
        tenth of its side towards the fingers (Holistic's graph); None when the points coincide."""
        centre, scale = self.points(image, region)
        down = scale - centre
        half = float(np.hypot(*down))
        if half < 0.5:
            return None
        up = -down / half
        centre = centre + 0.1 * 2 * half * up
        return roi_transform(centre, centre + up * half, size, 1.0)


def region_from_box(box: np.ndarray, size: int = 224, scale: float = 2.0) -> np.ndarray:
    """An upright square on a hand's box (x, y, w, h), ``scale`` times its longer side."""
    x, y, w, h = (float(v) for v in box)
    centre = np.array([x + w / 2, y + h / 2])
    return roi_transform(centre, centre - [0.0, max(w, h) / 2], size, scale)


def region_from_forearm(elbow: np.ndarray, wrist: np.ndarray, size: int = 224,
                        side_per_forearm: float = SIDE_PER_FOREARM) -> np.ndarray | None:
    """The square where the hand beyond ``wrist`` lies, ``side_per_forearm`` forearms wide, turned so
    the forearm points up (None for a forearm shorter than a pixel)."""
    elbow, wrist = np.asarray(elbow, np.float64)[:2], np.asarray(wrist, np.float64)[:2]
    forearm = wrist - elbow
    length = float(np.hypot(*forearm))
    if length < 1.0:
        return None
    centre = wrist + CENTRE_BEYOND_WRIST * forearm
    return roi_transform(centre, centre + forearm / length * (side_per_forearm * length / 2), size, 1.0)


def region_from_landmarks(points: np.ndarray, size: int = 224, scale: float = 2.0) -> np.ndarray:
    """MediaPipe's region from a hand's 21 points: wrist -> middle knuckle up, centred on the points'
    extent in that frame, ``scale`` times its longer side."""
    pts = np.asarray(points, np.float64)[:, :2]
    up = pts[MIDDLE_KNUCKLE] - pts[WRIST]
    if np.hypot(*up) < 1e-6:
        up = np.array([0.0, -1.0])
    up /= np.hypot(*up)
    across = np.array([-up[1], up[0]])
    along, side = pts @ up, pts @ across
    centre = ((along.min() + along.max()) / 2) * up + ((side.min() + side.max()) / 2) * across
    half = max(np.ptp(along), np.ptp(side)) / 2
    return roi_transform(centre, centre + up * max(half, 0.5), size, scale)


@dataclass(frozen=True)
class HandModels:
    """The models pose2d finds a posed person's hands with: the landmark model, and Holistic's
    re-crop model for its region (``pose2d.hand_recrop``; None: the forearm's square as it is)."""

    landmarks: HandLandmarks
    recrop: HandRecrop | None = None

    def find(self, image: np.ndarray, keypoints: np.ndarray, passes: int = 2) -> list[tuple[Hand | None, Hand | None]]:
        return body_hands(self.landmarks, image, keypoints, passes, recrop=self.recrop)


def body_hands(landmarks: HandLandmarks, image: np.ndarray, keypoints: np.ndarray, passes: int = 2,
               min_wrist_score: float = MIN_WRIST_SCORE, recrop: "HandRecrop | None" = None,
               search_per_forearm: float = SEARCH_PER_FOREARM) -> list[tuple[Hand | None, Hand | None]]:
    """Each posed person's (left, right) hand, from COCO-17 ``keypoints`` (N x 17 x 3): the hand model
    in the region beyond each wrist along its forearm, or, with ``recrop``, in the region the re-crop
    model finds in a wider square there (``search_per_forearm`` forearms: about the search region
    Holistic takes from the pose); None (not looked at) where the elbow or wrist is under
    ``min_wrist_score``, the hand's square is under ``MIN_REGION_PX`` or its centre is off the picture."""
    height, width = image.shape[:2]
    found = []
    for person in np.asarray(keypoints, np.float64).reshape(-1, 17, 3):
        pair = []
        for elbow, wrist in COCO_ELBOW_WRIST:
            region = None
            if min(person[elbow, 2], person[wrist, 2]) >= min_wrist_score:
                forearm = person[wrist, :2] - person[elbow, :2]
                centre = person[wrist, :2] + CENTRE_BEYOND_WRIST * forearm
                on_picture = 0 <= centre[0] < width and 0 <= centre[1] < height
                if on_picture and SIDE_PER_FOREARM * np.hypot(*forearm) >= MIN_REGION_PX:
                    region = region_from_forearm(person[elbow], person[wrist], landmarks.size)
            hand = None
            if region is not None and recrop is not None:  # Holistic's way: a wider search region, the
                search = region_from_forearm(person[elbow], person[wrist], recrop.size, search_per_forearm)
                refined = recrop.refine(image, search, landmarks.size) if search is not None else None
                hand = landmarks.estimate(image, refined, passes) if refined is not None else None
                # ... but a wider region may hold the other hand: the hand found must hang on this wrist
                if hand is not None and not on_wrist(hand, person[elbow, :2], person[wrist, :2]):
                    hand = None
            if region is not None and (hand is None or hand.presence < MIN_PRESENCE):  # the forearm's square too
                plain = landmarks.estimate(image, region, passes)
                hand = plain if hand is None or plain.presence > hand.presence else hand
            pair.append(hand)
        found.append((pair[0], pair[1]))
    return found


def on_wrist(hand: Hand, elbow: np.ndarray, wrist: np.ndarray, within: float = MAX_WRIST_OFFSET) -> bool:
    """Whether ``hand``'s wrist lies within ``within`` forearms (elbow -> wrist) of the body's wrist."""
    return bool(np.hypot(*(hand.keypoints[WRIST, :2] - wrist)) <= within * np.hypot(*(wrist - elbow)))


def hands_array(hands: list[tuple[Hand | None, Hand | None]]) -> tuple[np.ndarray, np.ndarray]:
    """(N x 2 x 21 x 3 points: x, y in pixels and the hand's presence as every joint's score;
    N x 2 x 21 x 3 metres about the hand), left then right; zeros where no hand was looked at."""
    points = np.zeros((len(hands), 2, 21, 3), np.float32)
    world = np.zeros((len(hands), 2, 21, 3), np.float32)
    for i, pair in enumerate(hands):
        for side, hand in enumerate(pair):
            if hand is not None:
                points[i, side], world[i, side] = hand.keypoints, hand.world
    return points, world
