"""``dance3d export edge``: the corpus as EDGE's data preparation leaves AIST++, ready for its
``AISTPPDataset``, with dance3d's own foot contacts and beats.

EDGE (Tseng et al., CVPR 2023) slices each sequence into 5 s windows every 0.5 s and reads, per
split folder (``train``, ``test``):

- ``motions_sliced/<seq>_slice<i>.pkl``: ``pos`` (300 x 3, the path over ``smpl_scaling``, y up)
  and ``q`` (300 x 72 axis-angle) at 60 fps;
- ``wavs_sliced/<seq>_slice<i>.wav``: the same 5 s of music;
- ``baseline_feats/<seq>_slice<i>.npy``: 150 x 35 at 30 fps (onset envelope, MFCC-20,
  chroma-CENS-12, onset peaks, beats), librosa at 15360 Hz with a hop of 512 as EDGE computes them,
  but the beat column holds dance3d's beats instead of a second librosa tracker's.

Beside them, what EDGE computes for itself when it loads the data, with dance3d's contacts:

- ``edge_features/<seq>_slice<i>.npy``: 150 x 151 at 30 fps, EDGE's model input before its
  normaliser: contacts of the left and right ankles and feet (4; dance3d's planted flags instead
  of EDGE's "foot moves < 1 cm a frame" rule), the root position (3) and the 24 joints' rotations
  in 6D (144), all turned from y up to z up as EDGE turns AIST++.

The split is the corpus's split by video (its held-out split is EDGE's ``test``).
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.core.paths import AUDIO, AUDIO_FEATURES
from pipeline.core.storage import atomic_path
from pipeline.export.aistpp import AIST_FPS, Sequence, corpus_sequences
from pipeline.motion.smpl.kinematics import from_axis_angle, to_6d_rows

EDGE_FPS = 30.0
HOP = 512
FEATURE_SR = int(EDGE_FPS) * HOP  # EDGE's baseline features: 15360 Hz, one hop a frame
Z_UP = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # +90 degrees about x: (x, y, z) -> (x, -z, y)
FOLDERS = {"train": "train", "val": "test"}


@dataclass(frozen=True)
class Slice:
    name: str
    split: str        # EDGE's folder: train or test
    sequence: str
    start: int        # first frame at 60 fps


def slice_starts(frames: int, fps: float, length: float, stride: float) -> list[int]:
    """First frames of EDGE's windows: ``length`` s every ``stride`` s while a whole one fits."""
    window, step = int(length * fps), int(stride * fps)
    return list(range(0, frames - window + 1, step))


def edge_features(poses: np.ndarray, trans: np.ndarray, scaling: float, planted: np.ndarray) -> np.ndarray:
    """T x 151 EDGE's motion vector: contacts (4), root position on the unit body (3), 6D rotations
    (24 x 6), turned from y up to z up (the root's rotation and position both)."""
    local = from_axis_angle(poses)
    local[:, 0] = Z_UP @ local[:, 0]
    root = (np.asarray(trans, np.float64) / scaling) @ Z_UP.T
    six = to_6d_rows(local).reshape(len(local), -1)
    return np.concatenate([np.asarray(planted, np.float64), root, six], axis=1).astype(np.float32)


def music_features(y: np.ndarray, beat_times: np.ndarray, start: float) -> np.ndarray:
    """frames x 35 EDGE's baseline music features of mono audio at FEATURE_SR; the beat column marks
    ``beat_times`` (seconds on the clock where ``y`` starts at ``start``)."""
    import librosa

    envelope = librosa.onset.onset_strength(y=y, sr=FEATURE_SR, hop_length=HOP)
    mfcc = librosa.feature.mfcc(y=y, sr=FEATURE_SR, n_mfcc=20, hop_length=HOP).T
    chroma = librosa.feature.chroma_cens(y=y, sr=FEATURE_SR, hop_length=HOP, n_chroma=12).T
    frames = len(envelope)
    peaks = np.zeros(frames, np.float32)
    peaks[librosa.onset.onset_detect(onset_envelope=envelope, sr=FEATURE_SR, hop_length=HOP)] = 1.0
    beats = np.zeros(frames, np.float32)
    index = np.rint((np.asarray(beat_times) - start) * EDGE_FPS).astype(int)
    beats[index[(index >= 0) & (index < frames)]] = 1.0
    return np.concatenate([envelope[:, None], mfcc[:frames], chroma[:frames], peaks[:, None], beats[:, None]],
                          axis=1).astype(np.float32)


@dataclass(frozen=True)
class SegmentMusic:
    """A segment's normalised audio, decoded once: as it is (for the wav slices), at FEATURE_SR
    (for the music features), and its beats."""

    audio: np.ndarray       # mono, at ``rate``
    rate: int
    low: np.ndarray         # mono, at FEATURE_SR
    beat_times: np.ndarray  # seconds, segment clock

    def features(self, begin: float, seconds: float) -> np.ndarray:
        """EDGE's 35 music features of ``seconds`` from ``begin`` (segment clock), a row a frame."""
        clip = self.low[int(round(begin * FEATURE_SR)):][: int(seconds * FEATURE_SR)]
        return music_features(clip, self.beat_times, begin)[: int(round(seconds * EDGE_FPS))]


def segment_music(root: Path, segment_id: str) -> SegmentMusic:
    import librosa

    from pipeline.music.audio import read_mono
    from pipeline.music.featurefile import read_features

    audio, rate = read_mono(root / AUDIO / f"{segment_id}.flac")
    low = librosa.resample(audio, orig_sr=rate, target_sr=FEATURE_SR, res_type="soxr_hq")
    return SegmentMusic(audio, rate, low, read_features(root / AUDIO_FEATURES / f"{segment_id}.parquet").beat_times)


def export(root: Path, out: Path, val_fraction: float, length: float = 5.0, stride: float = 0.5) -> list[Slice]:
    """Write EDGE's prepared layout of the corpus under ``out``; the slices written."""
    import soundfile

    sequences = corpus_sequences(root, val_fraction, AIST_FPS)
    for folder in FOLDERS.values():
        for kind in ("motions_sliced", "wavs_sliced", "baseline_feats", "edge_features"):
            (out / folder / kind).mkdir(parents=True, exist_ok=True)
    written: list[Slice] = []
    by_segment: dict[str, list[Sequence]] = {}
    for seq in sequences:
        by_segment.setdefault(seq.segment_id, []).append(seq)
    for segment_id, seqs in sorted(by_segment.items()):
        music = segment_music(root, segment_id)
        rate = music.rate
        for seq in seqs:
            motion = edge_features(seq.poses, seq.trans, seq.scaling, seq.planted)[::int(AIST_FPS / EDGE_FPS)]
            for i, first in enumerate(slice_starts(len(seq.poses), AIST_FPS, length, stride)):
                begin = seq.start_time + first / AIST_FPS
                piece = music.audio[int(round(begin * rate)):][: int(length * rate)]
                if len(piece) < int(length * rate):
                    break  # EDGE keeps as many motion slices as there are whole music slices
                name, folder = f"{seq.name}_slice{i}", out / FOLDERS[seq.split]
                window = slice(first, first + int(length * AIST_FPS))
                data = {"pos": seq.trans[window] / seq.scaling, "q": seq.poses[window]}
                with atomic_path(folder / "motions_sliced" / f"{name}.pkl") as tmp:
                    tmp.write_bytes(pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL))
                with atomic_path(folder / "wavs_sliced" / f"{name}.wav") as tmp:
                    soundfile.write(tmp, piece, rate, format="WAV")
                feats = music.features(begin, length)
                edge_first = first // int(AIST_FPS / EDGE_FPS)
                for kind, array in (("baseline_feats", feats),
                                    ("edge_features", motion[edge_first: edge_first + int(length * EDGE_FPS)])):
                    with atomic_path(folder / kind / f"{name}.npy") as tmp, open(tmp, "wb") as f:
                        np.save(f, array)
                written.append(Slice(name, FOLDERS[seq.split], seq.name, first))
    return written
