"""How much of the retargeting error is the SMPL body's proportions, not the pose.

Every trainer of the field (EDGE, Bailando, AIOZ-GDANCE) poses SMPL's one neutral skeleton times
a scalar (``smpl_scaling``), so a dancer whose thighs, forearms or shoulders are longer or wider
than that skeleton's, scaled to their legs, cannot be matched joint for joint by any rotations:
with the ankle on the clip's ankle, the knee is at least the shins' difference in length away
from the clip's knee (the triangle inequality), and so for elbows, shoulders and the feet.

``own_offsets`` gives the SMPL tree the clip's own proportions (each mapped bone the clip's median
length, in SMPL's rest directions). Retargeting onto that tree with the same rules measures the
inverse kinematics alone; the difference to the error on SMPL's own offsets is the proportions'.
It is a measurement only: nothing is exported on these offsets.
"""

from __future__ import annotations

import numpy as np

from pipeline.motion.smpl.skeleton import BALL_SHARE, REST_OFFSETS, J

# (SMPL child joint whose offset is the bone, H36M from, H36M to): bones both skeletons have
BONES = (("left_knee", 4, 5), ("right_knee", 1, 2), ("left_ankle", 5, 6), ("right_ankle", 2, 3),
         ("left_elbow", 11, 12), ("right_elbow", 14, 15), ("left_wrist", 12, 13), ("right_wrist", 15, 16))


def _median_length(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.median(np.linalg.norm(a - b, axis=-1)))


def _stretch(fixed: np.ndarray, scaled: np.ndarray, length: float) -> float:
    """The factor m >= 0 for which |fixed + m * scaled| is ``length`` (the larger root; 0 if none)."""
    a, b, c = scaled @ scaled, 2 * fixed @ scaled, fixed @ fixed - length ** 2
    disc = b * b - 4 * a * c
    return max(float((-b + np.sqrt(disc)) / (2 * a)), 0.0) if disc >= 0 else 0.0


def own_offsets(joints: np.ndarray, feet: np.ndarray | None = None) -> np.ndarray:
    """24 x 3 rest offsets with SMPL's directions and the clip's proportions (H36M-17 joints T x 17
    x 3; heels and toe tips T x 4 x 3 when known): hip width, thighs, shins, the hips-to-shoulders
    height, shoulder width, upper arms, forearms and ankle-to-ball lengths as the clip's medians."""
    h = np.asarray(joints, np.float64)
    o = REST_OFFSETS.copy()
    width = _median_length(h[:, 4], h[:, 1])
    o[[1, 2]] *= width / np.linalg.norm(o[1] - o[2])
    for child, a, b in BONES:
        o[J[child]] *= _median_length(h[:, a], h[:, b]) / np.linalg.norm(o[J[child]])
    if feet is not None and np.isfinite(feet).all():
        for side, ankle, heel, toe in (("left", 6, 0, 2), ("right", 3, 1, 3)):
            ball = feet[:, heel] + BALL_SHARE * (feet[:, toe] - feet[:, heel])
            j = J[f"{side}_foot"]
            o[j] *= _median_length(ball, h[:, ankle]) / np.linalg.norm(o[j])
    # shoulder width: the collars' children stretched; then the spine so the shoulders' midpoint
    # stands as high over the hips' midpoint as the clip's
    shoulders = _median_length(h[:, 11], h[:, 14])
    m = _stretch(o[13] - o[14], o[16] - o[17], shoulders)
    o[[16, 17]] *= m
    spine = o[3] + o[6] + o[9]
    rest = spine + (o[13] + o[16] + o[14] + o[17]) / 2 - (o[1] + o[2]) / 2
    torso = _median_length((h[:, 11] + h[:, 14]) / 2, (h[:, 1] + h[:, 4]) / 2)
    k = _stretch(rest - spine, spine, torso)
    o[[3, 6, 9]] *= k
    return o
