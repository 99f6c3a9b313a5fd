"""``dance3d eval world``: world-frame motion on motion capture, through the corpus's own code path.

Protocol:

- every sequence (of a known-source folder: the train_lifter split's held-out ones) is resampled
  to ``VIDEO_FPS`` (30, a video rate) and cut to its first ``seconds``;
- it is filmed by ten cameras: five pitches (-20, -10, 0, 10, 20 degrees; > 0 looks down) x two
  set-ups, a portrait phone at 1.2 m, 3 m away, and a landscape camera on a 2 m stand, 5 m away
  (the lifter protocol's; headings 0, 72, ... 288 degrees, one per camera), with noisy 2D (a pose
  model of expected OKS 0.80, 2 % of joints missing), heels and toes included;
- the 2D then takes the corpus's path: the lift stage (the 2D denoised, lifter, per-frame root, contact
  model: ``lifting.infer.lift_clips``), the smooth stage (HP filter, lambda 1), the resample stage (24 fps)
  and the world grounding (``grounding.ground_clip``); the capture is resampled to the same frames;
- the capture's planted heels and toe tips are ``contact.capture_contact``'s; its floor is their
  standing level (y = 0).

Metrics (WHAM's and GVHMR's definitions where the field has one), per run, then medians per
source and over all:

- W-MPJPE100 / WA-MPJPE100 (mm): world joints in chunks of 100 frames, after a similarity
  alignment of the chunk's first two frames / of the whole chunk;
- RTE (%): root path error after one rigid alignment of the whole path, over the true path length;
- root (mm): the camera-frame root path after one scale and offset;
- jitter (m/s^3): the mean third difference of the world joints (the capture's beside it);
- foot sliding (mm per frame at 30 fps): the heels' and toe tips' motion on frames where the
  capture's moves less than 1 cm per frame at 30 fps (the capture's own beside it);
- contact F1 of the planted flags (each point; all four pooled) and the share planted;
- up error (degrees), planted-foot height (mm: median |height| of the truly planted points),
  the largest limb-length CV before the one-skeleton fit and how far that fit moved the joints;
- beside the medians over all runs, those over the runs that keep the feet in view (90 % of the
  heel and toe points inside the image): looking up 10-20 degrees from a phone's or a stand's height
  puts the feet below the frame, where a real pose model would not see them.

Baseline beside each figure: the same path without the contact model (contact by the ankle rule,
the per-frame root, the floor at the lowest foot point's 5th percentile).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pipeline.core.errors import InputError
from pipeline.motion.lifting.evaluate import Camera, add_pose_noise, camera_pose, split, view
from pipeline.motion.lifting.infer import LiftModels, LiftOptions, lift_clips
from pipeline.motion.mocap.sources import MocapSequence, first_seconds, load_folder, resample
from pipeline.motion.motionfile import MotionClip
from pipeline.motion.resample import interpolate_linear, resample_clip
from pipeline.motion.smoothing import smooth_clip
from pipeline.motion.world.contact import ContactRules, capture_contact, standing_level
from pipeline.motion.world.gravity import up_error_deg
from pipeline.motion.world.grounding import GroundedClip, ground_clip
from pipeline.motion.world.scene import ground_scene
from pipeline.motion.world.trajectory import align_scale_offset
from pipeline.pose.keyframes import drawn_between, keyframe_step

VIDEO_FPS = 30.0
CORPUS_FPS = 24.0
PITCHES = (-20.0, -10.0, 0.0, 10.0, 20.0)
CAMERAS = tuple(Camera(f"{setup}_{pitch:+g}", 72.0 * k + (36.0 if setup == "stand" else 0.0), h, d, w, ht,
                       pitch_deg=pitch)
                for k, pitch in enumerate(PITCHES)
                for setup, h, d, w, ht in (("phone", 1.2, 3.0, 1080, 1920), ("stand", 2.0, 5.0, 1920, 1080)))
SLIDE_STILL = 0.01 * VIDEO_FPS  # m/s: WHAM's "true foot moves < 1 cm per frame" at 30 fps
FEET_SEEN = 0.9  # a run "keeps the feet in view" when this share of heel and toe points lies inside the image


@dataclass(frozen=True)
class PoseInput:
    """How the protocol makes the 2D the lifter sees from a filmed sequence: the pose-model noise
    (``noise``; ``frame_noise`` of its variance new on every frame, the rest drifting, as in
    ``add_pose_noise``), then keyframes at ``pose_fps`` as the pose2d stage poses them (0: every frame)."""

    noise: bool = True
    frame_noise: float = 1.0
    pose_fps: float = 0.0

    def keypoints(self, xy: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(T x J x 2) pixels -> (T x J x 3) keypoints with score 1."""
        xy = add_pose_noise(xy, rng, frame_share=self.frame_noise) if self.noise else xy
        keypoints = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], -1)
        return drawn_between(keypoints, keyframe_step(VIDEO_FPS, self.pose_fps))

    def describe(self) -> dict:
        return {"noisy_2d": self.noise, "frame_noise": self.frame_noise, "pose_fps": self.pose_fps,
                "pose_step": keyframe_step(VIDEO_FPS, self.pose_fps)}


def similarity(source: np.ndarray, target: np.ndarray, scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """s, R, t minimising |s R x + t - y| over point sets (N x 3), Umeyama."""
    mu_x, mu_y = source.mean(0), target.mean(0)
    x, y = source - mu_x, target - mu_y
    u, d, vt = np.linalg.svd(y.T @ x / len(x))
    sign = np.eye(3)
    sign[2, 2] = np.sign(np.linalg.det(u @ vt)) or 1.0
    rotation = u @ sign @ vt
    s = float(np.trace(np.diag(d) @ sign) / max((x ** 2).sum() / len(x), 1e-12)) if scale else 1.0
    return s, rotation, mu_y - s * rotation @ mu_x


def w_mpjpe(pred: np.ndarray, true: np.ndarray, chunk: int = 100, whole: bool = False) -> float:
    """W-MPJPE100 (first two frames aligned) or, with ``whole``, WA-MPJPE100 (each chunk aligned), mm."""
    errors = []
    for start in range(0, len(pred), chunk):
        p, t = pred[start: start + chunk], true[start: start + chunk]
        if len(p) < 2:
            continue
        fit = (p, t) if whole else (p[:2], t[:2])
        s, r, shift = similarity(fit[0].reshape(-1, 3), fit[1].reshape(-1, 3))
        aligned = s * p @ r.T + shift
        errors.append(np.linalg.norm(aligned - t, axis=-1).mean())
    return 1000 * float(np.mean(errors)) if errors else float("nan")


def rte_percent(pred_root: np.ndarray, true_root: np.ndarray) -> float:
    """Root translation error: mean distance after one rigid alignment, % of the true path length."""
    _, r, shift = similarity(pred_root, true_root, scale=False)
    length = float(np.linalg.norm(np.diff(true_root, axis=0), axis=-1).sum())
    return 100 * float(np.linalg.norm(pred_root @ r.T + shift - true_root, axis=-1).mean()) / max(length, 1e-6)


def jitter(joints: np.ndarray, fps: float) -> float:
    """Mean norm of the joints' third difference, m/s^3."""
    if len(joints) < 4:
        return float("nan")
    third = joints[3:] - 3 * joints[2:-1] + 3 * joints[1:-2] - joints[:-3]
    return float(np.linalg.norm(third, axis=-1).mean() * fps ** 3)


def foot_sliding(pred: np.ndarray, true: np.ndarray, fps: float) -> float:
    """WHAM's foot sliding in mm per frame at 30 fps: the foot points' motion (T x P x 3) on the
    frames where the true points move slower than 1 cm per 30 fps frame."""
    still = np.linalg.norm(np.diff(true, axis=0), axis=-1) * fps < SLIDE_STILL
    moved = np.linalg.norm(np.diff(pred, axis=0), axis=-1) * fps / VIDEO_FPS
    return 1000 * float(moved[still].mean()) if still.any() else float("nan")


def f1(estimate: np.ndarray, truth: np.ndarray) -> float:
    hits = float((estimate & truth).sum())
    total = float(estimate.sum() + truth.sum())
    return 2 * hits / total if total else float("nan")


@dataclass(frozen=True)
class Truth:
    joints: np.ndarray   # T x 17 x 3 world, y up, floor (the standing level) at 0
    feet: np.ndarray     # T x 4 x 3
    planted: np.ndarray  # T x 4 bool
    up_cam: np.ndarray   # 3, world up in camera coordinates
    root_cam: np.ndarray  # T x 3 the root in the camera frame


def _truth(seq: MocapSequence, camera: Camera, times: np.ndarray) -> Truth:
    """The capture at ``times`` (s) of the filmed clip."""
    level = standing_level(seq.feet, seq.fps)
    t_src = np.arange(seq.frames) / seq.fps

    joints, feet = interpolate_linear(times, t_src, seq.h36m), interpolate_linear(times, t_src, seq.feet)
    planted = capture_contact(seq.feet, seq.fps, level)
    near = np.clip(np.rint(times * seq.fps).astype(int), 0, seq.frames - 1)
    rotation, position = camera_pose(seq.h36m, camera)
    shift = np.array([0.0, level, 0.0])
    return Truth(joints - shift, feet - shift, planted[near], rotation @ np.array([0.0, 1.0, 0.0]),
                 (joints[:, 0] - position) @ rotation.T)


def scores(grounded: GroundedClip, truth: Truth, root_cam: np.ndarray | None, fps: float) -> dict:
    """Every metric of one run (module docstring)."""
    pred, feet = grounded.joints, grounded.feet
    row = {"w_mpjpe100_mm": w_mpjpe(pred, truth.joints), "wa_mpjpe100_mm": w_mpjpe(pred, truth.joints, whole=True),
           "rte_percent": rte_percent(pred[:, 0], truth.joints[:, 0]),
           "jitter": jitter(pred, fps), "jitter_capture": jitter(truth.joints, fps),
           "up_deg": up_error_deg(grounded.camera, truth.up_cam),
           "cv_before": grounded.cv_before, "fit_moved_mm": 1000 * grounded.fit_moved}
    if root_cam is not None:
        row["root_aligned_mm"] = 1000 * float(np.linalg.norm(align_scale_offset(root_cam, truth.root_cam)
                                                             - truth.root_cam, axis=-1).mean())
    if feet is not None:
        row["foot_sliding_mm"] = foot_sliding(feet, truth.feet, fps)
        row["foot_sliding_capture_mm"] = foot_sliding(truth.feet, truth.feet, fps)
        row["planted_height_mm"] = (1000 * float(np.median(np.abs(feet[..., 1][truth.planted])))
                                    if truth.planted.any() else float("nan"))
        planted = grounded.planted if grounded.planted is not None else np.repeat(grounded.contact, 2, axis=1)[
            :, [0, 2, 1, 3]]  # the ankle rule: a foot's contact for both its points
        row["contact_f1"] = f1(planted, truth.planted)
        for k, name in enumerate(("left_heel", "right_heel", "left_toe", "right_toe")):
            row[f"contact_f1_{name}"] = f1(planted[:, k], truth.planted[:, k])
        row["planted_share"] = float(planted.mean())
        row["planted_share_capture"] = float(truth.planted.mean())
    return row


def path_options(lift: LiftOptions, rules: ContactRules) -> dict:
    """The lift and ground options a result was made with, for its protocol."""
    return {"denoise_2d": lift.denoise, "min_score": lift.min_score, "flip": lift.flip,
            "contact_rules": {"threshold": rules.threshold, "min_frames": rules.min_frames, "hold": rules.hold}}


def path_from_params(params: Mapping, denoise: float | None = None) -> tuple[LiftOptions, ContactRules]:
    """A project's lift options and contact rules (params.yaml ``lift`` and ``ground``), as its corpus
    is made; ``denoise`` in place of its own lambda if given."""
    from pipeline.core.params import stage_params

    lift = LiftOptions.from_params(stage_params(params, "lift"))
    if denoise is not None:
        lift = replace(lift, denoise=float(denoise))
    return lift, ContactRules.from_params(stage_params(params, "ground"))


def at_corpus_rate(lifted, lamb: float = 1.0, clip_id: str = "run", track_id: int = 1) -> MotionClip:
    """A lifted clip (``infer.LiftedClip``, at ``VIDEO_FPS``) as the smooth and resample stages leave
    it: HP-filtered, at ``CORPUS_FPS``."""
    n = len(lifted.joints)
    clip = MotionClip(clip_id, track_id, np.arange(n, dtype=np.int32), np.arange(n) / VIDEO_FPS, lifted.joints,
                      np.zeros(n, bool), np.zeros(n, np.int8), lifted.root, lifted.feet, lifted.contact,
                      lifted.feet_rays)
    return resample_clip(smooth_clip(clip, lamb), CORPUS_FPS)


def film_and_ground(models: LiftModels, seq: MocapSequence, camera: Camera, rng: np.random.Generator,
                    lamb: float = 1.0, pose_input: PoseInput = PoseInput(), lift: LiftOptions = LiftOptions(),
                    rules: ContactRules = ContactRules()) -> dict[str, dict]:
    """One run: ``seq`` (at ``VIDEO_FPS``) filmed by ``camera``, its 2D made as ``pose_input`` says,
    through the corpus's path, scored with the contact model (``learned``) and without (``baseline``)."""
    body = np.concatenate([seq.h36m, seq.feet], 1)
    xy, _ = view(body, np.concatenate([seq.coco, seq.feet], 1), camera)
    feet = xy[:, 17:]
    in_frame = float(((feet >= 0) & (feet <= [camera.width, camera.height])).all(-1).mean())
    keypoints = pose_input.keypoints(xy, rng)
    (lifted,) = lift_clips(models, [keypoints[:, :17]], [keypoints[:, 17:]], camera.width, camera.height,
                           VIDEO_FPS, lift)
    clip = at_corpus_rate(lifted, lamb)
    truth = _truth(seq, camera, clip.time)
    out = {}
    for name, probability in (("learned", clip.contact), ("baseline", None)):
        if name == "learned" and probability is None:
            continue
        if name == "learned":  # the ground stage's path: a scene of one
            grounded = ground_scene([clip], CORPUS_FPS, rules).clips[0]
        else:
            grounded = ground_clip(clip.joints, clip.root, CORPUS_FPS, clip.feet, probability, feet_rays=clip.feet_rays)
        out[name] = {**scores(grounded, truth, grounded.root_camera, CORPUS_FPS), "feet_in_frame": in_frame}
    return out


def evaluate_world(models: LiftModels, sequences: list[MocapSequence], seconds: float = 20.0,
                   seed: int = 0, progress=None, pose_input: PoseInput = PoseInput(),
                   lift: LiftOptions = LiftOptions(), rules: ContactRules = ContactRules(),
                   cameras: tuple[Camera, ...] = CAMERAS) -> dict:
    """Medians per source and over all, for each variant (``learned``, ``baseline``), and by pitch
    (of the pitches ``cameras`` has: the protocol's ten by default)."""
    rng = np.random.default_rng(seed)
    runs: list[dict] = []
    for seq in sequences:
        seq = first_seconds(resample(seq, VIDEO_FPS), seconds)
        if seq.frames < 2 * VIDEO_FPS:
            continue
        for camera in cameras:
            for variant, row in film_and_ground(models, seq, camera, rng, pose_input=pose_input, lift=lift,
                                                rules=rules).items():
                runs.append({"source": seq.source, "sequence": seq.name, "pitch": camera.pitch_deg,
                             "variant": variant, **row})
            if progress:
                progress()

    def medians(rows: list[dict]) -> dict:
        keys = [k for k in rows[0] if k not in ("source", "sequence", "pitch", "variant")]
        return {k: round(float(np.nanmedian([r[k] for r in rows])), 4) for k in keys}

    result: dict = {"protocol": {"sequences": len({r["sequence"] for r in runs}), "cameras": len(cameras),
                                 "seconds_each": seconds, "video_fps": VIDEO_FPS, "corpus_fps": CORPUS_FPS,
                                 **pose_input.describe(), **path_options(lift, rules)}}
    for variant in dict.fromkeys(r["variant"] for r in runs):
        rows = [r for r in runs if r["variant"] == variant]
        result[variant] = {"all": medians(rows),
                           **{s: medians([r for r in rows if r["source"] == s])
                              for s in dict.fromkeys(r["source"] for r in rows)},
                           "by_pitch": {f"{p:+g}": medians([r for r in rows if r["pitch"] == p]) for p in PITCHES
                                        if any(c.pitch_deg == p for c in cameras)}}
        # Looking up from a phone's or a stand's height, the feet leave the frame (at -20 degrees on most
        # frames): a real pose model would not see them. The runs that keep the feet in view:
        seen = [r for r in rows if r["feet_in_frame"] >= FEET_SEEN]
        if seen:
            result[variant]["feet_in_view"] = {**medians(seen), "runs": len(seen), "of": len(rows)}
    return result


def evaluate_folder(lifter: Path, contact: Path | None, mocap: Path, *, heldout_only: bool = True,
                    seconds: float = 20.0, threads: int = 2, progress=None,
                    pose_input: PoseInput = PoseInput(), lift: LiftOptions = LiftOptions(),
                    rules: ContactRules = ContactRules()) -> dict:
    """``dance3d eval world`` on a folder ``load_folder`` reads: a folder of the known sources is cut
    to the train_lifter split's held-out sequences; a folder of your own capture is used whole."""
    from pipeline.motion.lifting.infer import load_models

    sequences = load_folder(mocap)
    held = split(sequences)[1] if heldout_only else []
    sequences = held or sequences
    lacking = [s.name for s in sequences if s.feet is None]
    if lacking:
        raise InputError(mocap, f"{len(lacking)} sequences ({', '.join(lacking[:3])}) have no heels and toes, "
                                "which the world metrics need (add 'feet' to a joint-position .npz)")
    for path in (lifter, contact):
        if path is not None and not Path(path).is_file():
            raise InputError(path, "no such model")
    models = load_models(str(lifter), str(contact) if contact else "", threads)
    result = evaluate_world(models, sequences, seconds, progress=progress, pose_input=pose_input, lift=lift,
                            rules=rules)
    result["protocol"].update(lifter=str(lifter), contact_model=str(contact) if contact else "none",
                              mocap=str(mocap), split="held-out sequences of the train_lifter split" if held
                              else "every sequence")
    return result


REPORT_KEYS = (("W-MPJPE100 mm", "w_mpjpe100_mm"), ("WA-MPJPE100 mm", "wa_mpjpe100_mm"), ("RTE %", "rte_percent"),
               ("root mm", "root_aligned_mm"), ("jitter m/s3", "jitter"), ("sliding mm/f", "foot_sliding_mm"),
               ("contact F1", "contact_f1"), ("up deg", "up_deg"), ("planted h mm", "planted_height_mm"),
               ("limb CV", "cv_before"))


def format_report(result: dict) -> str:
    """One line per source and variant, the baseline under the learned path; the capture's own
    sliding and jitter at the end of each line."""
    head = f"{'source':26s} {'variant':9s} " + " ".join(f"{name:>14s}" for name, _ in REPORT_KEYS)
    lines = [head + f" {'capture: slide':>15s} {'jitter':>7s}"]
    learned, baseline = result.get("learned", {}), result.get("baseline", {})
    for source in [s for s in (learned or baseline) if s not in ("by_pitch", "feet_in_view")] + ["feet_in_view"]:
        for variant, table in (("learned", learned), ("baseline", baseline)):
            row = table.get(source)
            if not row:
                continue
            label = f"feet in view ({row['runs']}/{row['of']})" if source == "feet_in_view" else source
            cells = " ".join(f"{row.get(key, float('nan')):14.3g}" for _, key in REPORT_KEYS)
            lines.append(f"{label:26s} {variant:9s} {cells} {row.get('foot_sliding_capture_mm', float('nan')):15.3g} "
                         f"{row.get('jitter_capture', float('nan')):7.3g}")
    by_pitch = (learned or baseline).get("by_pitch", {})
    lines.append("up error by pitch (deg): " + ", ".join(f"{p}: {r['up_deg']:.1f}" for p, r in by_pitch.items()))
    return "\n".join(lines)
