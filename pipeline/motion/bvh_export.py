"""BVH files that Blender and other tools load, from joint rotations on a clip's one skeleton
(``world.rotations``): metres, y up, channels ``Zrotation Xrotation Yrotation`` (R = Rz·Rx·Ry)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.motion.world.rotations import BVH_JOINTS, BVH_JOINTS_FEET, SkeletonMotion, solve_rotations

# End sites of the leaf joints (a BVH leaf needs one), metres in the joint's rest frame.
_END_SITES = {"RightFoot": (0.0, -0.05, 0.1), "LeftFoot": (0.0, -0.05, 0.1), "Head": (0.0, 0.1, 0.0),
              "LeftWrist": (0.08, 0.0, 0.0), "RightWrist": (-0.08, 0.0, 0.0)}

__all__ = ["BVH_JOINTS", "BVH_JOINTS_FEET", "SkeletonMotion", "solve_rotations", "write_bvh", "read_back"]


def _num(v: float) -> str:
    return f"{round(float(v), 6) + 0.0:.6f}"  # + 0.0: no "-0.000000"


def write_bvh(path: Path, motion: SkeletonMotion, fps: float) -> None:
    """A BVH file of the motion (metres, y up, ZXY Euler angles in degrees), written atomically."""
    from pipeline.core.storage import atomic_path

    lines = ["HIERARCHY"]

    specs = motion.spec
    order: list[int] = []  # joints in the file's (depth-first) order: the order of the MOTION channels

    def emit(i: int, depth: int) -> None:
        order.append(i)
        spec, pad = specs[i], "  " * depth
        lines.append(f"{pad}{'ROOT' if spec.parent < 0 else 'JOINT'} {spec.name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(_num(v) for v in motion.offsets[i])}")
        channels = "6 Xposition Yposition Zposition" if spec.parent < 0 else "3"
        lines.append(f"{pad}  CHANNELS {channels} Zrotation Xrotation Yrotation")
        kids = [k for k, s in enumerate(specs) if s.parent == i]
        for k in kids:
            emit(k, depth + 1)
        if not kids:
            end = (motion.ends or {}).get(spec.name, _END_SITES.get(spec.name, (0.0, 0.05, 0.0)))
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {' '.join(_num(v) for v in end)}",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    emit(0, 0)
    frames = len(motion.root)
    euler = Rotation.from_matrix(motion.local.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True).reshape(
        frames, len(specs), 3)
    values = np.concatenate([motion.root, euler[:, order].reshape(frames, -1)], axis=1)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(_num(v) for v in row) for row in values]
    with atomic_path(Path(path)) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def read_back(path: Path) -> np.ndarray:
    """The H36M joints (T x 17 x 3, or 21 with feet) of a BVH written by ``write_bvh``, by forward kinematics."""
    from pipeline.motion.mocap.bvh import forward_kinematics, read_bvh

    bvh = read_bvh(path)
    positions, _, _ = forward_kinematics(bvh, "replace")
    specs = BVH_JOINTS_FEET if any(j.name == "LeftHeel" for j in bvh.joints) else BVH_JOINTS
    out = np.zeros((len(positions), 21 if specs is BVH_JOINTS_FEET else 17, 3))
    for spec in specs:
        if spec.h36m is not None:
            out[:, spec.h36m] = positions[:, bvh.index(spec.name)]
    return out
