"""A small BVH reader and vectorised forward kinematics (scipy rotations).

Rotation channels are Euler angles in degrees applied intrinsically in the order the
CHANNELS line lists them (``Zrotation Xrotation Yrotation`` -> R = Rz·Rx·Ry). A joint's
translation from its parent is its OFFSET, or, for joints with position channels, either
the channel values instead of the offset (``replace``: Bandai Namco, DanceDB, whose
channels repeat the offset) or offset plus channels (``add``: the CMU iClone root).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.core.errors import InputError


@dataclass
class BvhJoint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str] = field(default_factory=list)
    end_site: np.ndarray | None = None
    first_channel: int = 0


@dataclass
class Bvh:
    joints: list[BvhJoint]
    frame_time: float
    motion: np.ndarray  # frames x channels

    def index(self, name: str) -> int:
        for i, joint in enumerate(self.joints):
            if joint.name == name:
                return i
        raise KeyError(name)


def read_bvh(path: Path) -> Bvh:
    tokens = Path(path).read_text(errors="replace").split()
    joints: list[BvhJoint] = []
    stack: list[int] = []
    pos = 0
    n_channels = 0
    pending_end = False
    try:
        while tokens[pos] != "MOTION":
            tok = tokens[pos]
            if tok in ("ROOT", "JOINT"):
                joints.append(BvhJoint(tokens[pos + 1], stack[-1] if stack else -1, np.zeros(3)))
                pos += 2
            elif tok == "End":
                pending_end = True
                pos += 2
            elif tok == "{":
                stack.append(-2 if pending_end else len(joints) - 1)
                pos += 1
            elif tok == "}":
                top = stack.pop()
                pending_end = False if top == -2 else pending_end
                pos += 1
            elif tok == "OFFSET":
                value = np.array([float(t) for t in tokens[pos + 1: pos + 4]])
                if stack and stack[-1] == -2:
                    joints[_last_real(stack)].end_site = value
                else:
                    joints[-1].offset = value
                pos += 4
            elif tok == "CHANNELS":
                count = int(tokens[pos + 1])
                joints[-1].channels = tokens[pos + 2: pos + 2 + count]
                joints[-1].first_channel = n_channels
                n_channels += count
                pos += 2 + count
            else:
                pos += 1
        frames = int(tokens[tokens.index("Frames:", pos) + 1])
        time_at = tokens.index("Time:", pos)
        frame_time = float(tokens[time_at + 1])
        values = np.array(tokens[time_at + 2: time_at + 2 + frames * n_channels], dtype=np.float64)
    except (IndexError, ValueError) as exc:
        raise InputError(path, f"not a readable BVH file ({exc})") from None
    if values.size != frames * n_channels:
        raise InputError(path, f"MOTION has {values.size} values, expected {frames} x {n_channels}")
    return Bvh(joints, frame_time, values.reshape(frames, n_channels))


def _last_real(stack: list[int]) -> int:
    return next(i for i in reversed(stack) if i >= 0)


def forward_kinematics(bvh: Bvh, position_mode: str = "replace") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Global joint positions (T x J x 3), rotations (T x J x 3 x 3) and End Site positions
    (T x J x 3, NaN for joints without one)."""
    frames = bvh.motion.shape[0]
    n = len(bvh.joints)
    positions = np.zeros((frames, n, 3))
    rotations = np.zeros((frames, n, 3, 3))
    ends = np.full((frames, n, 3), np.nan)
    for j, joint in enumerate(bvh.joints):
        chans = bvh.motion[:, joint.first_channel: joint.first_channel + len(joint.channels)]
        rot_axes = "".join(c[0] for c in joint.channels if c.endswith("rotation"))
        rot_values = np.stack([chans[:, k] for k, c in enumerate(joint.channels) if c.endswith("rotation")], -1) \
            if rot_axes else np.zeros((frames, 0))
        local_r = Rotation.from_euler(rot_axes.upper(), rot_values, degrees=True).as_matrix() if rot_axes \
            else np.broadcast_to(np.eye(3), (frames, 3, 3))
        pos_cols = {c[0]: k for k, c in enumerate(joint.channels) if c.endswith("position")}
        translation = np.broadcast_to(joint.offset, (frames, 3)).copy()
        if pos_cols:
            channel_t = np.stack([chans[:, pos_cols[a]] if a in pos_cols else np.zeros(frames) for a in "XYZ"], -1)
            translation = channel_t if position_mode == "replace" else translation + channel_t
        if joint.parent < 0:
            positions[:, j] = translation
            rotations[:, j] = local_r
        else:
            parent_r = rotations[:, joint.parent]
            positions[:, j] = positions[:, joint.parent] + np.einsum("tij,tj->ti", parent_r, translation)
            rotations[:, j] = parent_r @ local_r
        if joint.end_site is not None:
            ends[:, j] = positions[:, j] + np.einsum("tij,j->ti", rotations[:, j], joint.end_site)
    return positions, rotations, ends
