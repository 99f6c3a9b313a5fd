"""``dance3d export gdance``: the corpus's groups as AIOZ-GDANCE lays out its group dances, for
group choreography trainers (AIOZ's GCD and the EDGE-based group models read this layout).

A group sequence is a run of a segment's frames where the same two or more dancers are all in
view; it ends where one leaves or joins. Each is named ``<segment>_<start>_<end>`` (frames at
30 fps on the segment's clock, as AIOZ-GDANCE names its sequences) and written as:

- ``motions_smpl/<name>.pkl``: ``smpl_poses`` (D x T x 72 axis-angle, the root first),
  ``root_trans`` (D x T x 3, metres, y up: each dancer's pelvis in the segment's one scene, its
  height over the dancer's ``smpl_scaling`` so the unit SMPL body the trainers run forward
  kinematics on stands on the floor), ``smpl_trans`` (the pelvis as it is), ``smpl_scaling`` (D),
  ``contacts`` (D x T x 4: dancer's planted left and right ankle and ball), and ``meta``
  (``orig_start``, ``orig_end``, the segment, video, clip and track ids), at 30 fps;
- ``musics/<name>.wav``: the music under it;
- ``baseline_feats/<name>.npy``: T x 35 music features (EDGE's set, dance3d's beats), in place of
  AIOZ-GDANCE's Jukebox features, which need the Jukebox weights;
- ``split_sequence_names.txt`` (train: the file AIOZ's loader reads by default),
  ``train_split_sequence_names.txt``, ``test_split_sequence_names.txt``: the corpus's split by
  video (its held-out split is the test split).
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.core.paths import AUDIO
from pipeline.core.storage import atomic_path
from pipeline.corpus.groups import MIN_DANCERS
from pipeline.corpus.windows import split_of
from pipeline.export.aistpp import resample, resample_flags, retargeted_segments, write_wav

GDANCE_FPS = 30.0


@dataclass(frozen=True)
class GroupSequence:
    name: str
    segment_id: str
    video_id: str
    split: str
    clip_ids: tuple[str, ...]
    track_ids: tuple[int, ...]
    start_time: float       # s, segment clock
    poses: np.ndarray       # D x T x 72
    trans: np.ndarray       # D x T x 3, the scene's frame
    scaling: np.ndarray     # D
    planted: np.ndarray     # D x T x 4 bool
    fps: float

    @property
    def root_trans(self) -> np.ndarray:
        """The pelvis path for the unit SMPL body: height over each dancer's scale, x/z kept."""
        out = self.trans.copy()
        out[..., 1] /= self.scaling[:, None]
        return out


def group_spans(frames: list[np.ndarray], min_frames: int) -> list[tuple[int, int, tuple[int, ...]]]:
    """Runs of frames (start, end exclusive, which clips) where the same ``MIN_DANCERS`` or more
    clips are all present, at least ``min_frames`` long; ``frames``: each clip's frame numbers."""
    if len(frames) < MIN_DANCERS:
        return []
    first, end = min(int(f[0]) for f in frames), max(int(f[-1]) + 1 for f in frames)
    present = np.zeros((len(frames), end - first), bool)
    for i, f in enumerate(frames):
        present[i, np.asarray(f, int) - first] = True
    change = np.flatnonzero(np.any(present[:, 1:] != present[:, :-1], axis=0)) + 1
    spans = []
    for a, b in zip(np.r_[0, change], np.r_[change, present.shape[1]]):
        who = tuple(int(i) for i in np.flatnonzero(present[:, a]))
        if len(who) >= MIN_DANCERS and b - a >= min_frames:
            spans.append((first + int(a), first + int(b), who))
    return spans


def corpus_groups(root: Path, val_fraction: float, min_seconds: float = 2.0,
                  fps: float = GDANCE_FPS) -> list[GroupSequence]:
    """Every group sequence of the world files whose dancers all have SMPL motion."""
    from pipeline.motion.smpl.checks import foot_planted

    out = []
    for world_file, seg, rate, clips in retargeted_segments(root):
        for start, end, who in group_spans([c.frame for c in clips], int(np.ceil(min_seconds * rate))):
            dancers = [clips[i] for i in who]
            moved = []
            for c in dancers:
                rows = slice(start - int(c.frame[0]), end - int(c.frame[0]))
                poses, trans = resample(c.smpl_poses[rows], c.smpl_trans[rows], rate, fps)
                planted = resample_flags(foot_planted(c.contact[rows], None if c.planted is None else c.planted[rows]),
                                         rate, fps, len(poses))
                moved.append((poses, trans, planted))
            first = int(round(start / rate * fps))
            frames = len(moved[0][0])
            out.append(GroupSequence(
                f"{world_file.stem}_{first}_{first + frames}", world_file.stem, seg["video_id"],
                split_of(seg["video_id"], val_fraction), tuple(c.clip_id for c in dancers),
                tuple(int(c.track_id) for c in dancers), start / rate,
                np.stack([m[0] for m in moved]).astype(np.float32), np.stack([m[1] for m in moved]).astype(np.float32),
                np.array([float(c.facts["smpl_scaling"]) for c in dancers], np.float32),
                np.stack([m[2] for m in moved]), fps))
    return out


def export(root: Path, out: Path, val_fraction: float, min_seconds: float = 2.0) -> list[GroupSequence]:
    """Write the AIOZ-GDANCE layout of the corpus's groups under ``out``; the sequences written."""
    from pipeline.export.edge import SegmentMusic, segment_music

    sequences = corpus_groups(root, val_fraction, min_seconds)
    for folder in ("motions_smpl", "musics", "baseline_feats"):
        (out / folder).mkdir(parents=True, exist_ok=True)
    music: dict[str, SegmentMusic] = {}
    for seq in sequences:
        data = {"smpl_poses": seq.poses, "root_trans": seq.root_trans, "smpl_trans": seq.trans,
                "smpl_scaling": seq.scaling, "contacts": seq.planted.astype(np.float32),
                "meta": {"orig_start": int(seq.name.split("_")[-2]), "orig_end": int(seq.name.split("_")[-1]),
                         "fps": seq.fps, "segment_id": seq.segment_id, "video_id": seq.video_id,
                         "clip_ids": list(seq.clip_ids), "track_ids": list(seq.track_ids)}}
        with atomic_path(out / "motions_smpl" / f"{seq.name}.pkl") as tmp:
            tmp.write_bytes(pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL))
        flac = root / AUDIO / f"{seq.segment_id}.flac"
        frames = seq.poses.shape[1]
        write_wav(out / "musics" / f"{seq.name}.wav", flac, seq.start_time, frames / seq.fps)
        if seq.segment_id not in music:
            music[seq.segment_id] = segment_music(root, seq.segment_id)
        feats = music[seq.segment_id].features(seq.start_time, frames / seq.fps)
        with atomic_path(out / "baseline_feats" / f"{seq.name}.npy") as tmp, open(tmp, "wb") as f:
            np.save(f, feats)
    train = sorted(s.name for s in sequences if s.split == "train")
    test = sorted(s.name for s in sequences if s.split != "train")
    for name, names in (("split_sequence_names.txt", train), ("train_split_sequence_names.txt", train),
                        ("test_split_sequence_names.txt", test)):
        (out / name).write_text("".join(f"{n}\n" for n in names))
    return sequences
