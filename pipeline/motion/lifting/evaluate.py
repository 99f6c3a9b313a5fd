"""The held-out protocol for a 2D->3D lifter: whole motion-capture sequences seen by fixed
virtual cameras, lifted exactly as the lift stage lifts a clip, scored per source.

Protocol (``dance3d eval lifter`` and the train_lifter stage's metrics):

- sequences are resampled to ``fps`` (25) and lifted whole (edge-padded, as in the lift
  stage), at most ``max_seconds`` of each;
- ten fixed cameras: five headings (0, 72, 144, 216, 288 degrees around the middle of the
  dancer's path) x two set-ups, a portrait phone held at 1.2 m, 3 m away, and a landscape
  camera on a 2 m stand, 5 m away (both pushed back by how far the dancer travels from the
  middle); both have a phone's 26 mm-equivalent focal length and look at 1 m above the floor;
- clean 2D (the projected keypoints) and noisy 2D: per-joint Gaussian noise scaled by the
  COCO keypoint sigmas and the person's size, the error of a pose model whose expected OKS
  is 0.80, with 2 % of joints missing (carried over from the previous frame, as the lift
  stage's gap filling does), drawn with a fixed seed;
- MPJPE (mm, root-relative, camera frame), N-MPJPE (after a per-frame scale: the size a
  single camera cannot see) and P-MPJPE (after a per-frame similarity alignment), per source and
  over all frames; every source and camera weighs by its frames;
- baseline: the mean pose, i.e. the evaluated set's own mean root-relative pose in each
  camera (an oracle: it knows the test set's average), for scale;
- a lifter with feet gets the heels and toe tips too, noisy with the sigma of COCO-WholeBody's
  foot points; MPJPE and P-MPJPE stay on the 17 body joints (comparable with any lifter) and
  the feet get their own root-relative error beside the mean pose's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.core.errors import InputError
from pipeline.motion.lifting.geometry import look_at, mpjpe, n_mpjpe, p_mpjpe, project, to_camera
from pipeline.motion.mocap.sources import MocapSequence, first_seconds, keypoints_and_joints, resample
from pipeline.motion.world.trajectory import assumed_focal
from pipeline.pose.pose2dfile import COCO_SIGMAS

# The held-out sequences of the shared motion capture (name prefixes): whole performers where
# a source names them (Perfume's Kashiyuka, DanceDB's Olivia, the 8-year-old of AnimatedDrawings,
# ChoreoNet's second dancer, files ll_* and mm_*, whose limb lengths differ from the numbered
# files'), else whole takes (CMU 05's takes 10-19, Tang's rumba 8, Bandai's dance, DeepMimic's
# dance_b). No window of a held-out take is ever trained on.
HOLDOUT = ("perfume/kashiyuka", "dancedb_ucy/olivia", "cmu_subject05_iclone/005_1", "tang2018_ballroom/DANCE_R_8",
           "bandai_namco_1/dataset-1_dance", "animated_drawings_fair/8yr_old", "deepmimic/humanoid3d_dance_b",
           "choreonet_c3d/ll_", "choreonet_c3d/mm_")


# Held out of the sources added later (MOCAP.md §12-14), scored in a table of their own so that the
# figures on HOLDOUT's 40 sequences stay comparable across lifters: both partners of the salsa takes
# 14 and 15 (a real duet for ``eval group``), one whole content of Bandai's dataset-2 (every style),
# and HDM05's actor mm. No window of them is trained on either.
HOLDOUT_LATER = ("cmu_salsa_60_61/60_14", "cmu_salsa_60_61/61_14", "cmu_salsa_60_61/60_15", "cmu_salsa_60_61/61_15",
                 "bandai_namco_2_more/dataset-2_raise-up-both-hands", "mocap_recovery_c3d/HDM_mm")


def split(sequences: list[MocapSequence], holdout: tuple[str, ...] = HOLDOUT,
          later: tuple[str, ...] = HOLDOUT_LATER) -> tuple[list, list]:
    """(train, held out): whole sequences whose name starts with a ``holdout`` prefix are held out;
    those starting with a ``later`` prefix are in neither (``held_out_later`` gives them)."""
    val = [s for s in sequences if s.name.startswith(holdout)]
    train = [s for s in sequences if not s.name.startswith((*holdout, *later))]
    return train, val


def held_out_later(sequences: list[MocapSequence], later: tuple[str, ...] = HOLDOUT_LATER) -> list[MocapSequence]:
    return [s for s in sequences if s.name.startswith(later)]


# Noise of std level * k * s per axis (k = 2 sigma, s = sqrt of the keypoints' box area) gives an
# expected OKS of 1 / (1 + level^2) per joint: 0.80 at level 0.5.
OKS80_NOISE = 0.5
# COCO-17's sigmas, then the feet's: COCO-WholeBody gives its heels and big toes 0.066-0.094; 0.08 for all four.
KEYPOINT_SIGMAS = np.concatenate([COCO_SIGMAS, np.full(4, 0.08)])


@dataclass(frozen=True)
class Camera:
    name: str
    heading_deg: float
    height_m: float
    distance_m: float
    width: int
    height: int
    focal_equiv_mm: float = 26.0   # 35 mm-equivalent focal length (a phone's main camera)
    pitch_deg: float | None = None  # None: look at 1 m above the floor; else level heading, pitched (> 0: down)

    @property
    def focal_px(self) -> float:
        return assumed_focal(self.width, self.height, self.focal_equiv_mm)


PROTOCOL_CAMERAS = tuple(
    Camera(f"{setup}_{heading}", heading, h, d, w, ht)
    for heading in (0, 72, 144, 216, 288)
    for setup, h, d, w, ht in (("phone", 1.2, 3.0, 1080, 1920), ("stand", 2.0, 5.0, 1920, 1080)))


def camera_pose(seq_h36m: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera rotation and position of ``camera`` for a sequence: set around the middle
    of the dancer's path and far enough that the dancer never comes nearer than its distance."""
    root = seq_h36m[:, 0]
    centre = (root.min(0) + root.max(0)) / 2
    travel = float(np.max(np.linalg.norm((root - centre)[:, [0, 2]], axis=-1)))
    floor = float(np.min(seq_h36m[:, [3, 6], 1]))
    yaw = np.radians(camera.heading_deg)
    position = centre + (camera.distance_m + travel) * np.array([np.sin(yaw), 0.0, np.cos(yaw)])
    position[1] = floor + camera.height_m
    if camera.pitch_deg is None:
        target = np.array([centre[0], floor + 1.0, centre[2]])
    else:
        target = position + np.array([-np.sin(yaw), -np.tan(np.radians(camera.pitch_deg)), -np.cos(yaw)])
    return look_at(position, target), position


def view(seq_h36m: np.ndarray, seq_coco: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Project a sequence through ``camera`` (``camera_pose``): returns pixel COCO keypoints
    (T x 17 x 2) and camera-frame H36M joints (T x 17 x 3); 21 each with the feet after them."""
    rotation, position = camera_pose(seq_h36m, camera)
    coco_cam = to_camera(seq_coco, rotation, position)
    h36m_cam = to_camera(seq_h36m, rotation, position)
    return project(coco_cam, camera.focal_px, camera.width, camera.height), h36m_cam


def add_pose_noise(xy: np.ndarray, rng: np.random.Generator, level: float = OKS80_NOISE,
                   drop: float = 0.02, frame_share: float = 1.0, slow_frames: float = 12.0) -> np.ndarray:
    """Per-joint noise of a pose model (std level * 2 sigma_j * s, s the person's box size per
    frame) and missing joints carried over from the previous frame.

    ``frame_share`` of the noise's variance is drawn afresh on every frame; the rest drifts slowly
    (white noise smoothed over ``slow_frames``, a Gaussian's sigma, rescaled to unit variance), as a
    real pose model's error on video mostly does: it follows the person's look, which changes
    slowly (``dance3d eval world --frame-noise``; docs/pipeline/pose2d.md, "2D speed")."""
    span = xy[:, :17].max(1) - xy[:, :17].min(1)
    size = np.sqrt(np.maximum(span[:, 0] * span[:, 1], 1.0))[:, None, None]
    sigmas = KEYPOINT_SIGMAS[: xy.shape[1]]
    unit = rng.normal(0.0, 1.0, xy.shape)
    if frame_share < 1.0:
        from scipy.ndimage import gaussian_filter1d

        slow = gaussian_filter1d(rng.normal(0.0, 1.0, xy.shape), slow_frames, axis=0, mode="reflect")
        slow /= max(float(slow.std()), 1e-9)
        unit = np.sqrt(frame_share) * unit + np.sqrt(1.0 - frame_share) * slow
    noisy = xy + unit * level * 2 * sigmas[None, :, None] * size
    dropped = rng.random(xy.shape[:2]) < drop
    for t in range(1, len(noisy)):
        noisy[t, dropped[t]] = noisy[t - 1, dropped[t]]
    return noisy


PROTOCOL_FPS = 25.0  # the rate every sequence is filmed at

# (clips of pixel keypoints, width, height) -> root-relative 3D clips, as Lifter.lift
LiftFn = Callable[[list[np.ndarray], int, int], list[np.ndarray]]


def evaluate_lifter(lift: LiftFn, sequences: list[MocapSequence], *, fps: float = PROTOCOL_FPS,
                    max_seconds: float = 60.0, cameras: tuple[Camera, ...] = PROTOCOL_CAMERAS, seed: int = 0,
                    feet: bool = False) -> dict:
    """The protocol above: {"clean": {...}, "noisy": {...}, "sources": {...}, "protocol": {...}};
    ``feet``: the lifter takes and returns the heels and toe tips after the 17 joints."""
    rng = np.random.default_rng(seed)
    sequences = [first_seconds(resample(s, fps), max_seconds) for s in sequences]
    per: dict[str, dict[str, list]] = {}
    for camera in cameras:
        views = [view(*keypoints_and_joints(s, feet)[::-1], camera) for s in sequences]
        targets = [h - h[:, :1] for _, h in views]
        mean_pose = np.concatenate(targets).mean(0)
        for condition in ("clean", "noisy"):
            inputs = [xy if condition == "clean" else add_pose_noise(xy, rng) for xy, _ in views]
            preds = lift(inputs, camera.width, camera.height)
            for seq, pred, target in zip(sequences, preds, targets):
                bucket = per.setdefault(seq.source, {}).setdefault(condition, [])
                mean = np.broadcast_to(mean_pose, target.shape)
                row = [len(target), mpjpe(pred[:, :17], target[:, :17]), p_mpjpe(pred[:, :17], target[:, :17]),
                       mpjpe(mean[:, :17], target[:, :17]), p_mpjpe(mean[:, :17], target[:, :17]),
                       n_mpjpe(pred[:, :17], target[:, :17])]
                if feet:
                    row += [mpjpe(pred[:, 17:], target[:, 17:]), mpjpe(mean[:, 17:], target[:, 17:])]
                bucket.append(tuple(row))
    return summarise(per, sequences, fps, max_seconds, cameras)


def _weighted(rows: list[tuple]) -> dict:
    arr = np.array(rows, dtype=np.float64)
    w = arr[:, 0] / arr[:, 0].sum()
    keys = ("mpjpe_mm", "p_mpjpe_mm", "mean_pose_mpjpe_mm", "mean_pose_p_mpjpe_mm", "n_mpjpe_mm", "feet_mpjpe_mm",
            "mean_pose_feet_mpjpe_mm")[: arr.shape[1] - 1]
    return {k: round(1000 * float((arr[:, i + 1] * w).sum()), 1) for i, k in enumerate(keys)}


def summarise(per: dict, sequences: list[MocapSequence], fps: float, max_seconds: float,
              cameras: tuple[Camera, ...]) -> dict:
    result: dict = {"sources": {}}
    for condition in ("clean", "noisy"):
        result[condition] = _weighted([r for source in per.values() for r in source[condition]])
    for source, rows in sorted(per.items()):
        mine = [s for s in sequences if s.source == source]
        result["sources"][source] = {"sequences": len(mine), "seconds": round(sum(s.frames for s in mine) / fps, 1),
                                     "clean": _weighted(rows["clean"]), "noisy": _weighted(rows["noisy"])}
    result["protocol"] = {"sequences": len(sequences), "seconds": round(sum(len(s.h36m) for s in sequences) / fps, 1),
                          "fps": fps, "max_seconds_per_sequence": max_seconds,
                          "cameras": [c.name for c in cameras], "noise": f"OKS {1 / (1 + OKS80_NOISE ** 2):.2f}, "
                                                                       "2% joints missing"}
    return result


def evaluate_onnx(model: Path, mocap: Path, *, heldout_only: bool = True, flip: bool = True,
                  max_seconds: float = 60.0, threads: int = 2, denoise: float = 0.0) -> dict:
    """``dance3d eval lifter``: an exported lifter on a motion-capture folder (``load_folder``).
    With ``heldout_only``, a folder of the known sources is cut to the train_lifter split's
    held-out sequences (a folder of your own capture is used whole). ``denoise``: the 2D is
    denoised first, as the lift stage does (``infer.denoise_2d``; 0, the protocol's own: the lifter alone)."""
    from pipeline.motion.lifting.infer import denoise_2d, load_lifter
    from pipeline.motion.mocap.sources import load_folder

    sequences = load_folder(mocap)
    if not Path(model).is_file():
        raise InputError(model, "no such lifter (train it with `dvc repro train_lifter` or pass --model)")
    held = split(sequences)[1] if heldout_only else []
    if held:
        sequences = held
    lifter = load_lifter(str(model), threads)
    if lifter.feet:
        lacking = [s.name for s in sequences if s.feet is None]
        if lacking:
            raise InputError(mocap, f"{len(lacking)} sequences ({', '.join(lacking[:3])}) have no heels and toes, "
                                    f"which lifter {model} takes (add 'feet' to a joint-position .npz)")
    def lift(clips: list[np.ndarray], width: int, height: int) -> list[np.ndarray]:
        return lifter.lift([denoise_2d(c, PROTOCOL_FPS, denoise) for c in clips], width, height, flip=flip)

    result = evaluate_lifter(lift, sequences, fps=PROTOCOL_FPS, max_seconds=max_seconds, feet=lifter.feet)
    result["protocol"].update(model=str(model), mocap=str(mocap), flip=flip, denoise_2d=denoise,
                              split="held-out sequences of the train_lifter split" if held else "every sequence")
    return result


def format_report(result: dict) -> str:
    """A plain-text table: one line per source, clean and noisy, beside the mean pose."""
    lines = [f"{'source':28s} {'seq':>4s} {'sec':>6s} | {'MPJPE':>6s} {'N-MPJPE':>7s} {'P-MPJPE':>7s} | noisy "
             f"{'MPJPE':>6s} {'P-MPJPE':>7s} | mean pose {'MPJPE':>6s} {'P-MPJPE':>7s}"]
    rows = [(name, r) for name, r in result["sources"].items()]
    rows.append(("all", {"sequences": result["protocol"]["sequences"], "seconds": result["protocol"]["seconds"],
                         "clean": result["clean"], "noisy": result["noisy"]}))
    feet = "feet_mpjpe_mm" in result["clean"]
    if feet:
        lines[0] += f" | feet {'clean':>6s} {'noisy':>6s} {'mean':>6s}"
    for name, r in rows:
        c, n = r["clean"], r["noisy"]
        lines.append(f"{name:28s} {r['sequences']:4d} {r['seconds']:6.0f} | {c['mpjpe_mm']:6.1f} "
                     f"{c['n_mpjpe_mm']:7.1f} {c['p_mpjpe_mm']:7.1f} |       {n['mpjpe_mm']:6.1f} "
                     f"{n['p_mpjpe_mm']:7.1f} |           "
                     f"{c['mean_pose_mpjpe_mm']:6.1f} {c['mean_pose_p_mpjpe_mm']:7.1f}")
        if feet:
            lines[-1] += (f" |      {c['feet_mpjpe_mm']:6.1f} {n['feet_mpjpe_mm']:6.1f} "
                          f"{c['mean_pose_feet_mpjpe_mm']:6.1f}")
    return "\n".join(lines)
