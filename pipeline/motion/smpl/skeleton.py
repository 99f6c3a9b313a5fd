"""The SMPL kinematic tree as plain numbers: joint names, parents and the neutral body's rest
offsets, with where they come from. No SMPL model file (mesh, blend shapes, joint regressor) is
shipped or needed: its licence forbids redistribution, and forward kinematics needs only this.

Rest frame (SMPL's own): y up, the body facing +z, its left towards +x, metres; arms out to the
sides (a T-pose), palms down. A joint's local rotation turns the offsets of its children.
"""

from __future__ import annotations

import numpy as np

JOINTS = ("pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
          "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
          "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
          "left_hand", "right_hand")
PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)
J = {name: k for k, name in enumerate(JOINTS)}

# Each joint's offset from its parent in the rest pose (metres), the SMPL neutral body's joints as
# EDGE's forward kinematics uses them: Stanford-TML/EDGE, vis.py (`smpl_offsets`), commit
# 17c3428669ed6733edd9d8c66f7dc62060b8e46d (MIT licence). The pelvis offset is zero: a pose's
# root translation places the pelvis joint itself.
OFFSETS_SOURCE = "Stanford-TML/EDGE vis.py smpl_offsets @ 17c3428669ed6733edd9d8c66f7dc62060b8e46d"
REST_OFFSETS = np.array([
    [0.0, 0.0, 0.0],
    [0.05858135, -0.08228004, -0.01766408],
    [-0.06030973, -0.09051332, -0.01354254],
    [0.00443945, 0.12440352, -0.03838522],
    [0.04345142, -0.38646945, 0.008037],
    [-0.04325663, -0.38368791, -0.00484304],
    [0.00448844, 0.1379564, 0.02682033],
    [-0.01479032, -0.42687458, -0.037428],
    [0.01905555, -0.4200455, -0.03456167],
    [-0.00226458, 0.05603239, 0.00285505],
    [0.04105436, -0.06028581, 0.12204243],
    [-0.03483987, -0.06210566, 0.13032329],
    [-0.0133902, 0.21163553, -0.03346758],
    [0.07170245, 0.11399969, -0.01889817],
    [-0.08295366, 0.11247234, -0.02370739],
    [0.01011321, 0.08893734, 0.05040987],
    [0.12292141, 0.04520509, -0.019046],
    [-0.11322832, 0.04685326, -0.00847207],
    [0.2553319, -0.01564902, -0.02294649],
    [-0.26012748, -0.01436928, -0.03126873],
    [0.26570925, 0.01269811, -0.00737473],
    [-0.26910836, 0.00679372, -0.00602676],
    [0.08669055, -0.01063603, -0.01559429],
    [-0.0887537, -0.00865157, -0.01010708],
])

# SMPL joints that stand for the same anatomical point as a dance3d joint (H36M-17 index, or
# "ball": the ball of the foot, 72 % of the way from heel to toe tip, ``FOOT_TEMPLATE``). The hip
# joints are placed differently by the two skeletons (SMPL's regressor puts them ~12 cm apart on
# the neutral body, mocap skeletons 15-19 cm), so their midpoint is the mapped point.
MAPPED = {"left_knee": 5, "right_knee": 2, "left_ankle": 6, "right_ankle": 3, "left_shoulder": 11,
          "right_shoulder": 14, "left_elbow": 12, "right_elbow": 15, "left_wrist": 13, "right_wrist": 16}
BALL_SHARE = 0.72  # the ball of the foot along heel -> toe tip (Drillis & Contini; skeleton.FOOT_TEMPLATE)


def rest_positions(scale: float = 1.0) -> np.ndarray:
    """24 x 3: the rest pose's joints (pelvis at the origin)."""
    out = np.zeros((len(JOINTS), 3))
    for j in range(1, len(JOINTS)):
        out[j] = out[PARENTS[j]] + scale * REST_OFFSETS[j]
    return out


def leg_length(scale: float = 1.0, offsets: np.ndarray = REST_OFFSETS) -> float:
    """Thigh plus shin of the rest skeleton (left and right averaged), metres."""
    return scale * float(np.mean([np.linalg.norm(offsets[J[f"{s}_knee"]]) +
                                  np.linalg.norm(offsets[J[f"{s}_ankle"]]) for s in ("left", "right")]))
