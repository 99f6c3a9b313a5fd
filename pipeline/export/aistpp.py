"""``dance3d export aistpp``: the corpus's dancers as AIST++ lays out its motions, so the field's
trainers' own data preparation (EDGE's ``create_dataset.py``, Bailando's ``_prepro_aistpp.py``)
reads them as they read AIST++.

Per clip (one dancer, its whole span), a sequence named like AIST++'s
(``g<genre>_s<situation>_cAll_d<dancer>_m<music>_ch<choreography>``, underscores split it):

- ``motions/<sequence>.pkl``: ``smpl_poses`` (T x 72 axis-angle), ``smpl_trans`` (T x 3, metres,
  y up, the world file's frame) and ``smpl_scaling`` (shape (1,)), float32, at ``fps`` (AIST++'s
  60 by default: rotations slerped, the path linear, from the corpus's rate);
- ``wavs/<sequence>.wav`` (EDGE) and ``all_musics/<music>.wav`` (Bailando): the clip's music,
  the segment's loudness-normalised audio from the clip's first frame, as long as the motion;
- ``splits/crossmodal_{train,val,test}.txt`` and ``ignore_list.txt``: the corpus's split by video
  (dance3d has one held-out split: it is both val and test);
- ``names.csv``: each sequence's clip, segment, video, split, start time and source licence.

AIST++'s trans are centimetres with a scaling near 100; here metres with a scaling near 1: both
give ``smpl_trans / smpl_scaling`` on the unit body, which is what EDGE and Bailando use.
"""

from __future__ import annotations

import csv
import hashlib
import pickle
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from pipeline.core.paths import AUDIO, RAW, SEGMENTS, WORLD
from pipeline.core.storage import atomic_path, item_files
from pipeline.corpus.windows import split_of
from pipeline.ingest.catalog import read_index, read_ledger

AIST_FPS = 60.0
SPLIT_FILES = {"train": ("crossmodal_train.txt",), "val": ("crossmodal_val.txt", "crossmodal_test.txt")}


@dataclass(frozen=True)
class Sequence:
    name: str
    music: str
    clip_id: str
    segment_id: str
    video_id: str
    split: str
    start_time: float     # s, segment clock
    poses: np.ndarray     # T x 72
    trans: np.ndarray     # T x 3
    scaling: float
    fps: float
    planted: np.ndarray   # T x 4 bool: left ankle, right ankle, left ball, right ball (EDGE's contact joints)


def sequence_name(clip_id: str, genre: str = "DN") -> tuple[str, str]:
    """An AIST++-style name for a clip and its music id: stable, from a hash of the clip id."""
    digest = hashlib.sha1(clip_id.encode()).hexdigest()
    music = f"m{digest[:6]}"
    return f"g{genre}_sFM_cAll_d{int(digest[6:8], 16) % 100:02d}_{music}_ch{int(digest[8:10], 16) % 100:02d}", music


def resample(poses: np.ndarray, trans: np.ndarray, fps: float, to_fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Axis-angle poses (T x 72) slerped and the path (T x 3) interpolated linearly from ``fps`` to
    ``to_fps``, over the same span (the last frame no later than the last source frame)."""
    frames = len(poses)
    if frames < 2 or to_fps == fps:
        return poses.copy(), trans.copy()
    src = np.arange(frames) / fps
    dst = np.arange(int(np.floor((frames - 1) * to_fps / fps + 1e-9)) + 1) / to_fps
    rot = np.asarray(poses, np.float64).reshape(frames, -1, 3)
    out = np.stack([Slerp(src, Rotation.from_rotvec(rot[:, j]))(dst).as_rotvec() for j in range(rot.shape[1])], 1)
    path = np.stack([np.interp(dst, src, trans[:, k]) for k in range(3)], 1)
    return out.reshape(len(dst), -1), path


def resample_flags(flags: np.ndarray, fps: float, to_fps: float, frames: int) -> np.ndarray:
    """``frames`` rows of per-frame flags (T x k) at ``to_fps``: each from the nearest source frame."""
    src = np.minimum(np.rint(np.arange(frames) * fps / to_fps).astype(int), len(flags) - 1)
    return np.asarray(flags)[src]


def retargeted_segments(root: Path) -> Iterator[tuple[Path, dict, float, list]]:
    """(world file, its index row, its frame rate, its clips with SMPL motion) of every segment
    that has audio: what the exports read."""
    from pipeline.core.storage import read_meta
    from pipeline.motion.world.worldfile import read_world

    segments = read_index(root / SEGMENTS)
    for world_file in item_files(root / WORLD):
        seg = segments.get(world_file.stem)
        if seg is None or not (root / AUDIO / f"{world_file.stem}.flac").exists():
            continue
        clips = [c for c in read_world(world_file) if c.smpl_poses is not None and np.isfinite(c.smpl_poses).all()]
        yield world_file, seg, float(read_meta(world_file).get("fps", 24.0)), clips


def corpus_sequences(root: Path, val_fraction: float, fps: float = AIST_FPS, genre: str = "DN") -> list[Sequence]:
    """Every clip of the world files that has its SMPL motion and its segment's audio."""
    from pipeline.motion.smpl.checks import foot_planted

    out = []
    for world_file, seg, rate, clips in retargeted_segments(root):
        for clip in clips:
            poses, trans = resample(clip.smpl_poses, clip.smpl_trans, rate, fps)
            name, music = sequence_name(clip.clip_id, genre)
            planted = resample_flags(foot_planted(clip.contact, clip.planted), rate, fps, len(poses))
            out.append(Sequence(name, music, clip.clip_id, world_file.stem, seg["video_id"],
                                split_of(seg["video_id"], val_fraction), float(clip.time[0]),
                                poses.astype(np.float32), trans.astype(np.float32),
                                float(clip.facts["smpl_scaling"]), fps, planted))
    return out


def write_wav(path: Path, flac: Path, start: float, seconds: float) -> None:
    """``seconds`` of a FLAC file from ``start`` as 16-bit PCM WAV at its own rate (44.1 kHz)."""
    import subprocess

    from pipeline.ingest.media import ffmpeg_exe

    with atomic_path(path) as tmp:
        subprocess.run([ffmpeg_exe(), "-v", "error", "-y", "-ss", f"{start:.6f}", "-i", str(flac),
                        "-t", f"{seconds:.6f}", "-c:a", "pcm_s16le", "-f", "wav", str(tmp)], check=True)


def export(root: Path, out: Path, val_fraction: float, fps: float = AIST_FPS, genre: str = "DN") -> list[Sequence]:
    """Write the AIST++ layout of the corpus under ``out``; the sequences written."""
    sequences = corpus_sequences(root, val_fraction, fps, genre)
    for folder in ("motions", "wavs", "all_musics", "splits"):
        (out / folder).mkdir(parents=True, exist_ok=True)
    for seq in sequences:
        data = {"smpl_poses": seq.poses, "smpl_trans": seq.trans, "smpl_scaling": np.array([seq.scaling], np.float32)}
        with atomic_path(out / "motions" / f"{seq.name}.pkl") as tmp:
            tmp.write_bytes(pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL))
        wav = out / "wavs" / f"{seq.name}.wav"
        write_wav(wav, root / AUDIO / f"{seq.segment_id}.flac", seq.start_time, len(seq.poses) / seq.fps)
        shutil.copyfile(wav, out / "all_musics" / f"{seq.music}.wav")  # Bailando looks music up by its id
    for split, files in SPLIT_FILES.items():
        names = sorted(s.name for s in sequences if s.split == split)
        for name in files:
            (out / "splits" / name).write_text("".join(f"{n}\n" for n in names))
    (out / "ignore_list.txt").write_text("")
    (out / "splits" / "ignore_list.txt").write_text("")
    write_names(root, out / "names.csv", sequences, ("frames", "fps", "smpl_scaling"),
                lambda s: (len(s.poses), f"{s.fps:g}", f"{s.scaling:.6f}"))
    return sequences


def write_names(root: Path, path: Path, sequences: list, columns: tuple[str, ...],
                values: Callable[[Any], tuple]) -> None:
    """An export's ``names.csv``: each sequence's name, clip, segment, video, split and start time,
    then its ``columns`` (``values(sequence)``), then its video's url and licence from the ledger."""
    ledger = {r["video_id"]: r for r in read_ledger(root / RAW).values()}
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["sequence", "clip_id", "segment_id", "video_id", "split", "start_time", *columns, "url",
                         "licence"])
        for s in sorted(sequences, key=lambda s: s.name):
            video = ledger.get(s.video_id, {})
            writer.writerow([s.name, s.clip_id, s.segment_id, s.video_id, s.split, f"{s.start_time:.6f}", *values(s),
                             video.get("url", ""), video.get("licence", "")])
