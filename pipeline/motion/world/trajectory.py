"""The root's path in camera space, from the lifted pose and the 2D keypoints it came from.

The lifter gives a root-relative pose in the camera's orientation; where the body is follows
from where that pose projects. With a focal length assumed from the frame size (a phone's
26 mm-equivalent main camera), the root translation T of each frame solves a small linear
least-squares problem over the twelve body keypoints that COCO and Human3.6M share: for a
joint at X + T seen at pixel (u, v) from the principal point, f (X + T)_x = u (X + T)_z and
f (X + T)_y = v (X + T)_z (and over the heels and toe tips too, for a lifter with feet). A wrong
focal length or body size scales the whole path (depth and travel together), which is why errors
are also reported after one scale and offset per clip.

Two things the lifter's pose needs before it is placed (``place_root``): it is turned from the
camera it was lifted for, aimed at the dancer, onto the dancer's viewing ray
(``toward_camera_axis``), and it is given one skeleton for the clip, so that a frame whose bones
the lifter made 10 % longer is not put 10 % further away.

The per-frame placement is sure across the viewing ray and unsure along it: its depth comes from
how large the body looks, and drifts with the lifter's errors over seconds. Where a planted heel or
toe tip is seen, the floor fixes that depth (``floor_anchors``): its sight ray meets the floor at
one point, steeply for a camera above the floor, so a pixel there is centimetres.
"""

from __future__ import annotations

import numpy as np

from pipeline.motion.mocap.skeleton import COCO_H36M_SHARED, FEET_ANKLES_H36M, smallest_rotation
from pipeline.motion.world.bones import apply_skeleton, fit_skeleton

# The joints whose pixels place the root: the twelve COCO and H36M share, then the heels and toe
# tips (joints 17-20 of both the 21-joint keypoints and the 21-joint lifted pose).
SHARED_WITH_FEET = COCO_H36M_SHARED + tuple((j, j) for j in range(17, 21))


def sight_rays(xy: np.ndarray, focal: float, width: float, height: float) -> np.ndarray:
    """Unit directions (… x 3, camera frame) in which pixels ``xy`` (… x 2) are seen."""
    uv = (np.asarray(xy, np.float64) - [width / 2, height / 2]) / focal
    rays = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], -1)
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def assumed_focal(width: float, height: float, equiv_mm: float = 26.0) -> float:
    """Focal length in pixels of a lens of ``equiv_mm`` 35 mm-equivalent (diagonal 43.27 mm)."""
    return equiv_mm / 43.27 * float(np.hypot(width, height))


def root_from_2d(joints: np.ndarray, keypoints: np.ndarray, focal: float, width: float, height: float,
                 scores: np.ndarray | None = None) -> np.ndarray:
    """Per-frame root translation (T x 3, metres, camera frame) placing the root-relative pose
    ``joints`` (T x 17 x 3, H36M) where its COCO ``keypoints`` (T x 17 x 2, pixels) are seen; with
    21 of each, the heels and toe tips count too."""
    both = joints.shape[1] == 21 and keypoints.shape[1] == 21
    coco, h36m = (np.array(i) for i in zip(*(SHARED_WITH_FEET if both else COCO_H36M_SHARED)))
    xyz = joints[:, h36m].astype(np.float64)
    uv = keypoints[:, coco, :2].astype(np.float64) - np.array([width / 2, height / 2])
    w = np.ones(uv.shape[:2]) if scores is None else np.clip(scores[:, coco], 1e-3, None)
    # Rows f*Tx - u*Tz = u*Z - f*X and f*Ty - v*Tz = v*Z - f*Y, weighted, solved per frame.
    frames, n = uv.shape[:2]
    a = np.zeros((frames, 2 * n, 3))
    b = np.zeros((frames, 2 * n))
    for axis in (0, 1):
        rows = slice(axis * n, (axis + 1) * n)
        a[:, rows, axis] = focal
        a[:, rows, 2] = -uv[..., axis]
        b[:, rows] = uv[..., axis] * xyz[..., 2] - focal * xyz[..., axis]
    sw = np.sqrt(np.concatenate([w, w], 1))
    a, b = a * sw[..., None], b * sw
    ata = np.einsum("tki,tkj->tij", a, a)
    atb = np.einsum("tki,tk->ti", a, b)
    return np.linalg.solve(ata, atb[..., None])[..., 0]


def toward_camera_axis(joints: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Root-relative joints (T x J x 3) lifted as a camera aimed at the dancer would see them,
    turned into the real camera's frame, where the dancer sits off its axis on the ray through
    ``root`` (T x 3, camera frame). The lifter is trained on cameras aimed at the dancer and sees
    person-centred keypoints only, so it cannot know where in the image the dancer stood: a dancer
    low in the frame of a camera pitched up is lifted as if filmed level. The rotation taking the
    optical axis onto the ray (no roll) puts the pose back: a perspective crop, undone."""
    ray = np.asarray(root, np.float64)
    ray = ray / np.maximum(np.linalg.norm(ray, axis=-1, keepdims=True), 1e-9)
    turn = smallest_rotation(np.array([0.0, 0.0, 1.0]), ray)
    return np.einsum("tij,tkj->tki", turn, joints - joints[:, :1]).astype(joints.dtype)


def one_skeleton(joints: np.ndarray) -> np.ndarray:
    """Joints (T x 17 or 21 x 3) with the clip's one skeleton (``bones``); heels and toe tips ride
    on their ankles."""
    body = joints[:, :17].astype(np.float64)
    fitted = apply_skeleton(body, fit_skeleton(body))
    if joints.shape[1] == 17:
        return fitted
    ankles = list(FEET_ANKLES_H36M)
    return np.concatenate([fitted, joints[:, 17:] + (fitted[:, ankles] - body[:, ankles])], 1)


def place_root(joints: np.ndarray, keypoints: np.ndarray, focal: float, width: float, height: float,
               scores: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The lifted pose turned onto its viewing ray, and the root path that places it (T x 3):
    a first placement finds the ray, the turned pose with one skeleton is placed again."""
    first = root_from_2d(joints, keypoints, focal, width, height, scores)
    turned = toward_camera_axis(joints, first)
    return turned, root_from_2d(one_skeleton(turned), keypoints, focal, width, height, scores)


def align_scale_offset(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """``pred`` (T x 3) after the one scale and offset that bring it nearest ``true`` (least squares)."""
    p, t = pred - pred.mean(0), true - true.mean(0)
    scale = float((p * t).sum() / max((p * p).sum(), 1e-12))
    return scale * p + true.mean(0)


# Noise scales of the refiner's terms (metres), chosen on the protocol's noisy 2D of the lifter's
# training sequences (``dance3d eval world`` figures, docs/pipeline/3d.md): the per-frame root is sure across
# its viewing ray, unsure along it (0.25 m once it is placed by the turned one-skeleton pose;
# 0.5 m before, when each frame's bones wobbled). With the floor fixing the depth at contacts, a
# smoother path between them (5 mm per frame^2, from 10) took a third of the training sequences'
# root error from 61.2 to 60.4 mm and their jitter from 222 to 182 m/s^3 (RTE 2.09 to 2.14 %).
ACROSS_RAY = 0.02    # per-frame root, across its viewing ray
ALONG_RAY = 0.25    # per-frame root, along it (depth)
PLANTED = 0.005       # a planted point's motion from one frame to the next
ACCELERATION = 0.005  # the root's second difference per frame


FLOOR = 0.05         # a root placed where a planted point's sight ray meets the floor
MIN_FLOOR_SINE = float(np.sin(np.radians(5.0)))  # rays nearer the horizon than this meet the floor too far off


def floor_anchors(rays: np.ndarray, points: np.ndarray, planted: np.ndarray, up: np.ndarray, level: float,
                  sigma: float = FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """Root positions (T x 3, camera frame) from where the planted points are seen on the floor, and
    their weights (T, 1 / sigma^2 per point; 0 where none is seen): a planted point lies where its
    sight ray (``rays``: T x P unit vectors) meets the floor ``up . X = level`` (``up``: world up in
    camera coordinates), and the root is that point less its root-relative offset (``points``:
    T x P x 3). Only rays at least 5 degrees below the horizon count: nearer it, a pixel's error
    moves the meeting point by metres."""
    den = np.asarray(rays, np.float64) @ np.asarray(up, np.float64)
    seen = np.asarray(planted, bool) & (den * np.sign(level) > MIN_FLOOR_SINE) & np.isfinite(den)
    reach = np.where(seen, level / np.where(seen, den, 1.0), 0.0)
    roots = np.where(seen[..., None], reach[..., None] * np.nan_to_num(rays) - np.nan_to_num(points), 0.0)
    count = seen.sum(1)
    return roots.sum(1) / np.maximum(count, 1)[:, None], count / sigma ** 2


def refine_root(root: np.ndarray, points: np.ndarray, planted: np.ndarray, *, across: float = ACROSS_RAY,
                along: float = ALONG_RAY, still: float = PLANTED, accel: float = ACCELERATION,
                floor: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The root path (T x 3, camera frame) that planted feet anchor, in the spirit of WHAM's and
    GVHMR's refiners but as one linear least-squares problem over the whole clip: each frame's
    root stays near the per-frame estimate ``root`` (tightly across its viewing ray, loosely in
    depth), a planted point (``points``: T x P x 3 root-relative, camera frame; ``planted``: T x P
    bool) does not move between two frames where it is planted, and the root's acceleration is
    small. Depth jitter and drift while a foot is planted come out; travel and jumps between
    contacts stay with the per-frame estimate. With ``floor`` (``floor_anchors``: targets T x 3 and
    weights T), the root also stays near where the planted points are seen on the floor, which
    takes the per-frame estimate's slow drift in depth out."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    root = np.asarray(root, np.float64)
    n = len(root)
    if n < 3:
        return root.copy()
    ray = root / np.maximum(np.linalg.norm(root, axis=-1, keepdims=True), 1e-9)
    outer = ray[:, :, None] * ray[:, None, :]
    anchor = (np.eye(3) - outer) / across ** 2 + outer / along ** 2          # T x 3 x 3
    rows, cols, vals = [], [], []

    def block(i: np.ndarray, j: np.ndarray, m: np.ndarray) -> None:
        """Add the 3 x 3 blocks ``m`` (K x 3 x 3) at block rows ``i``, columns ``j``."""
        a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
        rows.append((3 * i[:, None, None] + a).ravel())
        cols.append((3 * j[:, None, None] + b).ravel())
        vals.append(m.ravel())

    rhs = np.einsum("tij,tj->ti", anchor, root)
    if floor is not None:
        targets, weights = floor
        anchor = anchor + np.eye(3)[None] * weights[:, None, None]
        rhs = rhs + weights[:, None] * targets
    t = np.arange(n)
    block(t, t, anchor)
    # Planted between frames t and t+1: r[t+1] - r[t] = -(q[t+1] - q[t]), weight by how many points agree.
    both = (planted[:-1] & planted[1:]).astype(np.float64)
    weight = both.sum(1) / still ** 2
    if weight.any():
        step = np.where(both[..., None] > 0, np.diff(points, axis=0), 0.0).sum(1) / np.maximum(both.sum(1), 1)[:, None]
        eye = np.eye(3)[None] * weight[:, None, None]
        k = np.arange(n - 1)
        block(k, k, eye)
        block(k + 1, k + 1, eye)
        block(k, k + 1, -eye)
        block(k + 1, k, -eye)
        np.add.at(rhs, k, weight[:, None] * step)
        np.add.at(rhs, k + 1, -weight[:, None] * step)
    # Second differences: r[t-1] - 2 r[t] + r[t+1] = 0.
    k = np.arange(1, n - 1)
    coeffs = (1.0, -2.0, 1.0)
    for a, ca in zip((-1, 0, 1), coeffs):
        for b, cb in zip((-1, 0, 1), coeffs):
            block(k + a, k + b, np.eye(3)[None] * (ca * cb / accel ** 2) * np.ones((len(k), 1, 1)))
    matrix = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(3 * n, 3 * n)).tocsc()
    return spsolve(matrix, rhs.ravel()).reshape(n, 3)
