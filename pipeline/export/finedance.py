"""``dance3d export finedance``: the corpus's dancers in FineDance's layout, with their fingers, for
LODGE (Li et al., CVPR 2024) and the whole-body generators trained on FineDance.

FineDance (Li et al., ICCV 2023) keeps one file of each kind per sequence, all of one name:

- ``motion/<name>.npy``: T x 315 float32 at 30 fps: the root position (3), then SMPL-H's 52 joints
  (22 body joints, then the left and the right hand's index, middle, pinky, ring and thumb, three
  joints each) as 6D rotations, the first two rows of each rotation matrix (PyTorch3D's
  ``matrix_to_rotation_6d``), y up, metres on the unit body;
- ``music_wav/<name>.wav``: the music of the same span;
- ``music_npy/<name>.npy``: T x 35 FineDance's music features, one row a motion frame (onset
  envelope, MFCC-20, chroma-CENS-12, onset peaks, beats: librosa at 15360 Hz with a hop of 512, as
  FineDance's ``pre_music.py`` and EDGE compute them), the beat column holding dance3d's beats.

Beside them, ``splits/{train,test}.txt`` (the corpus's split by video: FineDance's own test list
names its own sequences) and ``names.csv`` (each sequence's clip, source and licence).

The root: FineDance's forward kinematics (LODGE's ``smplfk.SMPLX_Skeleton``) poses a joint template
and adds the root position to every joint, so the pelvis lands at the template's pelvis plus the
root. The root written is the SMPL pelvis path over ``smpl_scaling`` (the unit body), less the
template's pelvis when one is given. LODGE's ``preprocess.py`` puts the body on its floor itself.

The fingers: relative to the clip's own rest hand, as the corpus keeps them; with ``template`` (the
joint positions of a body with flat hands, such as FineDance's ``smplx_neu_J_1.npy``) they and the
wrists are solved again from the world hands onto the template's rest hands, which is what its
forward kinematics expects. A dancer without hands gets flat ones (zero rotations).

Names: ``d3d`` and eight hex digits of the clip id, stable. None holds a capital M (LODGE's
``preprocess.py`` drops the first character of such a name) or is one of FineDance's own numbers.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.core.storage import atomic_path
from pipeline.corpus.windows import split_of
from pipeline.export.aistpp import resample, retargeted_segments, write_names
from pipeline.export.edge import EDGE_FPS, segment_music
from pipeline.motion.smpl.hands import retarget_hands, template_rest
from pipeline.motion.smpl.kinematics import from_axis_angle, to_6d_rows, to_axis_angle

FINEDANCE_FPS = EDGE_FPS  # 30
FOLDERS = ("motion", "music_wav", "music_npy", "splits")
SPLITS = {"train": "train.txt", "val": "test.txt"}


@dataclass(frozen=True)
class FineDanceSequence:
    name: str
    clip_id: str
    segment_id: str
    video_id: str
    split: str
    start_time: float      # s, segment clock
    motion: np.ndarray     # T x 315 float32
    hands: bool            # the fingers were seen (False: flat)


def sequence_name(clip_id: str) -> str:
    return "d3d" + hashlib.sha1(clip_id.encode()).hexdigest()[:8]


def smplh_poses(clip, template: np.ndarray | None) -> tuple[np.ndarray, bool]:
    """T x 156 SMPL-H axis-angle (22 body joints, 30 finger joints) of a world clip, its fingers
    relative to the clip's own rest hands or, with ``template``, to the template's; and whether it
    has hands."""
    seen = clip.hands is not None and clip.smpl_hand_poses is not None and np.isfinite(clip.smpl_hand_poses).all()
    if not seen:
        return np.concatenate([clip.smpl_poses[:, :66], np.zeros((len(clip.smpl_poses), 90))], axis=1), False
    if template is None:
        return np.concatenate([clip.smpl_poses[:, :66], clip.smpl_hand_poses], axis=1), True
    rests = (template_rest(template, 0), template_rest(template, 1))
    solved = retarget_hands(from_axis_angle(clip.smpl_poses), clip.hands, clip.hand_presence, rests)
    return np.concatenate([to_axis_angle(solved.local)[:, :66], solved.poses], axis=1), True


def motion_vector(poses: np.ndarray, trans: np.ndarray, scaling: float, pelvis: np.ndarray | None) -> np.ndarray:
    """T x 315 FineDance's motion: root position on the unit body (less the template's ``pelvis``),
    then the 52 joints' 6D rotations (first two rows of each matrix)."""
    root = np.asarray(trans, np.float64) / scaling - (0.0 if pelvis is None else np.asarray(pelvis, np.float64))
    six = to_6d_rows(from_axis_angle(poses)).reshape(len(poses), -1)
    return np.concatenate([root, six], axis=1).astype(np.float32)


def export(root: Path, out: Path, val_fraction: float, template: np.ndarray | None = None
           ) -> list[FineDanceSequence]:
    """Write FineDance's layout of the corpus under ``out``; the sequences written. ``template``:
    52 x 3 or 55 x 3 joint positions of a body with flat hands (``motion.smpl.hands.template_rest``)."""
    import soundfile

    if template is not None:
        template_rest(template, 0)  # refuse a template of the wrong shape before writing anything
    for folder in FOLDERS:
        (out / folder).mkdir(parents=True, exist_ok=True)
    written: list[FineDanceSequence] = []
    for world_file, seg, rate, clips in retargeted_segments(root):
        if not clips:
            continue
        music = segment_music(root, world_file.stem)
        for clip in clips:
            poses, seen = smplh_poses(clip, template)
            poses, trans = resample(poses, clip.smpl_trans, rate, FINEDANCE_FPS)
            start = float(clip.time[0])
            frames = min(len(poses), int((len(music.audio) / music.rate - start) * FINEDANCE_FPS))
            if frames < 1:
                continue
            seconds = frames / FINEDANCE_FPS
            features = music.features(start, seconds)
            frames = min(frames, len(features))
            motion = motion_vector(poses[:frames], trans[:frames], float(clip.facts["smpl_scaling"]),
                                   None if template is None else template[0])
            name = sequence_name(clip.clip_id)
            with atomic_path(out / "motion" / f"{name}.npy") as tmp, open(tmp, "wb") as f:
                np.save(f, motion)
            with atomic_path(out / "music_npy" / f"{name}.npy") as tmp, open(tmp, "wb") as f:
                np.save(f, features[:frames].astype(np.float32))
            piece = music.audio[int(round(start * music.rate)):][: int(round(frames / FINEDANCE_FPS * music.rate))]
            with atomic_path(out / "music_wav" / f"{name}.wav") as tmp:
                soundfile.write(tmp, piece, music.rate, format="WAV")
            written.append(FineDanceSequence(name, clip.clip_id, world_file.stem, seg["video_id"],
                                             split_of(seg["video_id"], val_fraction), start, motion, seen))
    for split, file in SPLITS.items():
        (out / "splits" / file).write_text("".join(f"{s.name}\n" for s in sorted(written, key=lambda s: s.name)
                                                   if s.split == split))
    write_names(root, out / "names.csv", written, ("frames", "fps", "hands"),
                lambda s: (len(s.motion), f"{FINEDANCE_FPS:g}", "yes" if s.hands else "no"))
    return written


def read_template(path: Path) -> np.ndarray:
    """A joint template (``.npy``, 52 x 3 or 55 x 3), or one error naming the file and what is wrong."""
    from pipeline.core.errors import Dance3dError

    try:
        joints = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise Dance3dError(f"{path}: not a joint template (.npy of 52 x 3 or 55 x 3 joint positions): {exc}") from None
    try:
        template_rest(joints, 0)
    except ValueError as exc:
        raise Dance3dError(f"{path}: {exc}") from None
    return np.asarray(joints, np.float64)
