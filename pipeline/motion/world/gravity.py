"""From the lifter's camera frame (x right, y down, z away from the camera) to a gravity-aligned
world frame: y up, the floor at y = 0, the dancer facing +z when facing the camera.

Up is estimated from the body: over a clip a dancer stands upright on average, so the robust
mean of the body's long axis (pelvis to thorax, ankles to pelvis) is the direction opposite
gravity. Its tilt in the camera frame is the camera's pitch and roll, recorded with the motion.
With a root trajectory (``trajectory.root_from_2d``) the body travels and jumps, and the floor
is where the lower ankle rests most of the time (its 5th percentile height, an ankle sitting
``ANKLE_HEIGHT`` above the floor). Without one, the lower ankle is set on the floor in every
frame: crouches are kept, jumps are not seen. With heels and toe tips (a lifter with feet),
the lowest foot point takes the ankle's place, ``FOOT_POINT_HEIGHT`` above the floor, so a
dancer on the balls of the feet is not pushed into it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.motion.mocap.skeleton import smallest_rotation, unit

ANKLE_HEIGHT = 0.08   # m, ankle joint centre above the floor when the foot is flat
FOOT_POINT_HEIGHT = 0.02  # m, a heel or toe-tip keypoint above the floor it stands on
# Camera frame to a level world: y down -> up, z away from the camera -> toward it (180 deg about x).
_FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class CameraEstimate:
    rotation: np.ndarray   # 3 x 3, camera frame -> world frame
    pitch_deg: float       # > 0: the camera looks down
    roll_deg: float        # > 0: the image is turned clockwise (up leans toward image right)

    @property
    def up(self) -> np.ndarray:
        """World up in camera coordinates."""
        return self.rotation[1]


@dataclass(frozen=True)
class WorldFrame:
    """A world frame that several clips share (a scene): the camera's tilt, the floor (where
    ``camera.up . X = floor`` in camera coordinates, metres) and the world point that becomes the
    horizontal origin."""
    camera: CameraEstimate
    floor: float
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))


def estimate_up(joints_cam: np.ndarray) -> np.ndarray:
    """World up in camera coordinates (unit 3-vector) from a clip (T x 17 x 3, H36M)."""
    ankles = (joints_cam[:, 3] + joints_cam[:, 6]) / 2
    axis = unit(joints_cam[:, 8] - joints_cam[:, 0]) + unit(joints_cam[:, 0] - ankles)
    return unit(np.median(unit(axis), axis=0))


# How much the body's long axis counts against the planted points' plane (m^2): the plane wins
# where the contacts spread well beyond sqrt(BODY_PRIOR) (0.45 m) across the floor; measured on
# lifted motion (`dance3d eval world`), where planted points are noisy in depth.
BODY_PRIOR = 0.2


def up_from_contacts(points_cam: np.ndarray, body_up: np.ndarray, prior: float = BODY_PRIOR) -> np.ndarray:
    """Up (camera coordinates) as the normal of the plane the planted heels and toe tips lie on
    (``points_cam``: N x 3, camera frame, with the root path), pulled toward the body's long axis
    ``body_up`` where they spread little: the smallest eigenvector of their scatter plus
    ``prior`` (I - u u^T). Planted feet touch one floor; a lifted body leans with the camera's view."""
    if len(points_cam) < 10:
        return body_up
    centred = points_cam - points_cam.mean(0)
    scatter = centred.T @ centred / len(centred) + prior * (np.eye(3) - np.outer(body_up, body_up))
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal if normal @ body_up > 0 else -normal


def estimate_camera(joints_cam: np.ndarray, contacts_cam: np.ndarray | None = None) -> CameraEstimate:
    """The camera's tilt from the body's long axis, and from the planted points (N x 3, camera
    frame) when they are given."""
    up = estimate_up(joints_cam)
    if contacts_cam is not None:
        up = up_from_contacts(contacts_cam, up)
    return camera_from_up(up)


def camera_from_up(up: np.ndarray) -> CameraEstimate:
    """The camera's tilt (no heading) that world up ``up`` (camera coordinates) gives."""
    up = unit(np.asarray(up, np.float64))
    rotation = smallest_rotation(_FLIP @ up, np.array([[0.0, 1.0, 0.0]]))[0] @ _FLIP
    pitch = float(np.degrees(np.arctan2(-up[2], -up[1])))
    roll = float(np.degrees(np.arctan2(up[0], -up[1])))
    return CameraEstimate(rotation, pitch, roll)


def lowest_point(world: np.ndarray) -> tuple[np.ndarray, float]:
    """Per frame, the height of the lowest foot point (ankles; heels and toes when the joints
    (T x 17 or 21 x 3) have them) and how high above the floor that point sits when standing."""
    if world.shape[1] == 21:
        return world[:, 17:, 1].min(1), FOOT_POINT_HEIGHT
    return np.minimum(world[:, 3, 1], world[:, 6, 1]), ANKLE_HEIGHT


def to_world(joints_cam: np.ndarray, camera: CameraEstimate | None = None,
             root: np.ndarray | None = None, planted: np.ndarray | None = None,
             frame: WorldFrame | None = None) -> tuple[np.ndarray, CameraEstimate]:
    """Root-relative camera-frame joints (T x 17 x 3, or 21 with the feet), and optionally the root's
    camera-frame path (T x 3), -> world joints with the floor at y = 0 and the root starting above
    the origin. With ``planted`` (T x 4 flags of the heels and toe tips, joints 17-20), the floor
    is where the planted points are (their median height is y = 0), so planted feet touch it.
    With a shared ``frame`` (and a root path), its camera, floor and origin are used instead."""
    rel = joints_cam - joints_cam[:, :1]
    if frame is not None and root is not None:
        world = (rel + root[:, None]) @ frame.camera.rotation.T
        world[..., 1] -= frame.floor
        world[..., [0, 2]] -= frame.origin[[0, 2]]
        return world, frame.camera
    if camera is None:
        contacts = None
        if planted is not None and root is not None and joints_cam.shape[1] == 21 and planted.any():
            contacts = (rel[:, 17:] + root[:, None])[planted]
        camera = estimate_camera(joints_cam, contacts)
    if root is None:
        world = rel @ camera.rotation.T
        lowest, height = lowest_point(world)
        world[..., 1] += (height - lowest)[:, None]
        return world, camera
    world = (rel + root[:, None]) @ camera.rotation.T
    if planted is not None and world.shape[1] == 21 and planted.any():
        world[..., 1] -= np.median(world[:, 17:, 1][planted])
    else:
        lowest, height = lowest_point(world)
        world[..., 1] += height - np.percentile(lowest, 5)
    world[..., [0, 2]] -= world[0, 0, [0, 2]]
    return world, camera


def up_error_deg(camera: CameraEstimate, true_up_cam: np.ndarray) -> float:
    """Angle (degrees) between the estimated and the true up direction, both in camera coordinates."""
    estimated = camera.rotation.T @ np.array([0.0, 1.0, 0.0])
    return float(np.degrees(np.arccos(np.clip(np.dot(estimated, unit(true_up_cam)), -1.0, 1.0))))
