"""Joint centres from Vicon Plug-in-Gait optical markers (C3D), as H36M-17 in metres, y up.

Markers sit on the skin, most of them laterally: a joint centre lies inside the limb.
The estimates are the usual ones of clinical gait analysis, kept simple:

- hip joint centres from the four pelvis markers by Harrington et al. (2007)'s regression
  on pelvic width and depth (J Biomech 40:595), the pelvis at their midpoint;
- knee and ankle centres half a joint width (plus the marker's radius) medial of the
  lateral markers, medial taken across the leg from the foot's long axis (the knee and
  ankle hinges stay square to the foot, also with a dancer's turn-out);
- elbow centres likewise from the elbow's flexion axis where the arm is bent, else from the
  wrist bar (a straight arm has no flexion plane);
- shoulder centres below the acromion marker along the trunk; wrists at the wrist bar's
  middle; the head from the four head-band markers.

The file is read with the ``c3d`` package (a well-kept pure-Python reader).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from pipeline.core.errors import InputError
from pipeline.motion.mocap.skeleton import feet_array, floor_height, foot_points, leg_stature, unit

MARKER_RADIUS = 0.007      # m, a standard 14 mm marker
KNEE_HALF_WIDTH = 0.050    # m, half an adult knee's width (Plug-in-Gait asks for it per subject)
ANKLE_HALF_WIDTH = 0.035
ELBOW_HALF_WIDTH = 0.032
SHOULDER_DROP = 0.050      # m, glenohumeral centre below the acromion marker
HEAD_TOP = 0.09            # m, head top above the head band's centre
HEAD_BASE = 0.08           # m, the skull's base (BVH "Head" joint) below it

REQUIRED = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "CLAV", "STRN", "LSHO", "LELB", "LWRA", "LWRB", "RSHO",
            "RELB", "RWRA", "RWRB", "LFWT", "RFWT", "LBWT", "RBWT", "LKNE", "LANK", "LHEE", "LTOE", "RKNE", "RANK",
            "RHEE", "RTOE")


def read_c3d(path: Path) -> tuple[dict[str, np.ndarray], float]:
    """Marker trajectories (name -> T x 3, metres, y up; gaps filled linearly) and the frame rate."""
    import c3d

    path = Path(path)
    try:
        with path.open("rb") as handle, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the reader warns about absent optional parameters
            reader = c3d.Reader(handle)
            labels = [label.strip().split(":")[-1] for label in reader.point_labels]
            frames = np.array([points for _, points, _ in reader.read_frames()], dtype=np.float64)
            rate = float(reader.point_rate)
            unit = str(reader.get("POINT:UNITS").string_value).strip().lower() if reader.get("POINT:UNITS") else "mm"
    except (OSError, ValueError, AssertionError, EOFError) as exc:
        raise InputError(path, f"cannot read the C3D file: {exc}") from None
    if frames.ndim != 3 or len(frames) < 2:
        raise InputError(path, "the C3D file has fewer than two frames of point data")
    scale = {"mm": 0.001, "cm": 0.01, "m": 1.0}.get(unit, 0.001)
    markers = {}
    for k, label in enumerate(labels):
        xyz = frames[:, k, :3] * scale
        missing = (frames[:, k, 3] < 0) | ~np.isfinite(xyz).all(1) | (np.abs(xyz).sum(1) == 0)
        if missing.all():
            continue
        if missing.any():
            t = np.arange(len(xyz))
            xyz = np.stack([np.interp(t, t[~missing], xyz[~missing, c]) for c in range(3)], -1)
        markers[label] = np.stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]], -1)  # z up -> y up, right-handed
    absent = [m for m in REQUIRED if m not in markers]
    if absent:
        raise InputError(path, f"not a Plug-in-Gait marker set: missing {', '.join(absent)}")
    return markers, rate


def _perpendicular(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The part of ``v`` square to ``axis`` (both T x 3, axis unit), normalised."""
    return unit(v - (v * axis).sum(-1, keepdims=True) * axis)


def hip_centres(m: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Left and right hip joint centres (Harrington 2007, metres)."""
    asis = (m["LFWT"] + m["RFWT"]) / 2
    psis = (m["LBWT"] + m["RBWT"]) / 2
    left = unit(m["LFWT"] - m["RFWT"])
    forward = _perpendicular(asis - psis, left)
    up = np.cross(forward, left)
    width = np.linalg.norm(m["LFWT"] - m["RFWT"], axis=-1, keepdims=True)
    depth = np.linalg.norm(asis - psis, axis=-1, keepdims=True)
    back = (-0.24 * depth - 0.0099) * forward
    down = (-0.30 * width - 0.0109) * up
    side = (0.33 * width + 0.0073) * left
    return asis + back + down + side, asis + back + down - side


def _leg(m: dict[str, np.ndarray], side: str, hip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    knee_marker, ankle_marker = m[f"{side}KNE"], m[f"{side}ANK"]
    shank = unit(knee_marker - ankle_marker)
    foot = unit(m[f"{side}TOE"] - m[f"{side}HEE"])
    # shank x foot points to the body's left; medial is toward the body's midline.
    medial = np.cross(shank, foot) * (-1.0 if side == "L" else 1.0)
    thigh = unit(hip - knee_marker)
    knee = knee_marker + (KNEE_HALF_WIDTH + MARKER_RADIUS) * _perpendicular(medial, thigh)
    ankle = ankle_marker + (ANKLE_HALF_WIDTH + MARKER_RADIUS) * _perpendicular(medial, unit(knee - ankle_marker))
    return knee, ankle


def _arm(m: dict[str, np.ndarray], side: str, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    shoulder = m[f"{side}SHO"] - (SHOULDER_DROP + MARKER_RADIUS) * up
    wrist = (m[f"{side}WRA"] + m[f"{side}WRB"]) / 2
    elbow_marker = m[f"{side}ELB"]
    upper, fore = unit(elbow_marker - shoulder), unit(wrist - elbow_marker)
    flexion = np.cross(upper, fore) * (1.0 if side == "L" else -1.0)  # medial for a bent elbow
    bent = np.clip((np.linalg.norm(flexion, axis=-1, keepdims=True) - 0.25) / 0.25, 0.0, 1.0)
    bar = unit(m[f"{side}WRB"] - m[f"{side}WRA"])  # radial (thumb) side to ulnar side: medial, palm forward
    medial = _perpendicular(bent * unit(flexion) + (1 - bent) * bar, upper)
    elbow = elbow_marker + (ELBOW_HALF_WIDTH + MARKER_RADIUS) * medial
    return shoulder, elbow, wrist


def h36m_from_markers(m: dict[str, np.ndarray]) -> np.ndarray:
    """T x 17 x 3 H36M-17 joints (VideoPose3D order) from Plug-in-Gait markers."""
    left_hip, right_hip = hip_centres(m)
    pelvis = (left_hip + right_hip) / 2
    thorax = (m["C7"] + m["CLAV"]) / 2
    trunk_up = unit(thorax - (m["T10"] + m["STRN"]) / 2)
    band = (m["LFHD"] + m["RFHD"] + m["LBHD"] + m["RBHD"]) / 4
    head_up = unit(band - thorax)
    right_knee, right_ankle = _leg(m, "R", right_hip)
    left_knee, left_ankle = _leg(m, "L", left_hip)
    left_arm = _arm(m, "L", trunk_up)
    right_arm = _arm(m, "R", trunk_up)
    return np.stack([pelvis, right_hip, right_knee, right_ankle, left_hip, left_knee, left_ankle,
                     (pelvis + thorax) / 2, thorax, band - HEAD_BASE * head_up, band + HEAD_TOP * head_up,
                     *left_arm, *right_arm], axis=1)


def feet_from_markers(m: dict[str, np.ndarray], h36m: np.ndarray) -> np.ndarray:
    """T x 4 x 3 in ``skeleton.FEET`` order: the heel markers, and toe tips placed beyond the toe
    markers (which sit over the second metatarsal head, the ball of the foot) by the foot template."""
    size = leg_stature(h36m)
    floor = floor_height(np.stack([m["LHEE"], m["RHEE"], m["LTOE"], m["RTOE"]]))
    tips = [foot_points(h36m[:, knee], h36m[:, ankle], m[f"{side}TOE"], "ball", size, floor)["tip"]
            for side, knee, ankle in (("L", 5, 6), ("R", 2, 3))]
    return feet_array((m["LHEE"], m["RHEE"]), tips)
