"""``dance3d eval beats``: the beat tracker against human beat annotations, with mir_eval.

Protocol (mir_eval's defaults, as in the MIREX beat task): beats before 5 s are ignored
in both lists; F-measure with a +-70 ms window, CMLt and AMLt (continuity, any metrical
level allowed for AMLt: double, half, off-beat), Cemgil and Goto; tempo error of the
median inter-beat interval. Downbeat F-measure where the annotation gives bar positions.
Every figure is reported per file for both trackers (``rnn``, ``librosa``) and for the first
dance3d tracker (librosa on the motion-rate onset envelope) side by side, and as their means.
"""

from __future__ import annotations

import re
from pathlib import Path

import librosa
import mir_eval
import numpy as np

from pipeline.core.errors import InputError
from pipeline.music.beats import RNN_SR, TRACKERS, describe, tempo_of, track_beats, track_beats_motion_rate

_SPLIT = re.compile(r"[\s,;]+")
PROTOCOL = ("mir_eval.beat.evaluate (MIREX): beats before 5 s ignored in both lists, F-measure window +-70 ms, "
            "CMLt/AMLt continuity, tempo error of the median inter-beat interval; downbeat F-measure where the "
            "annotation gives bar positions")


def read_beat_annotations(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Beat times (s) and, when every line has a second column, bar positions (1 = downbeat).

    One beat per line: ``time`` or ``time position`` (whitespace, comma or semicolon); blank
    lines and ``#`` comments are skipped.
    """
    times, positions = [], []
    for number, line in enumerate(Path(path).read_text().splitlines(), start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        fields = _SPLIT.split(text)
        try:
            times.append(float(fields[0]))
            positions.append(float(fields[1]) if len(fields) > 1 else None)
        except ValueError:
            raise InputError(path, f"expected a beat time in seconds (and an optional bar position), got {text!r}",
                             number) from None
        if len(times) > 1 and times[-1] <= times[-2]:
            raise InputError(path, f"beat times must increase ({times[-1]} after {times[-2]})", number)
    if len(times) < 2:
        raise InputError(path, "needs at least two beats")
    bars = None if any(p is None for p in positions) else np.asarray(positions)
    return np.asarray(times), bars


def score(reference: np.ndarray, estimated: np.ndarray, ref_downbeats: np.ndarray | None = None,
          est_downbeats: np.ndarray | None = None) -> dict[str, float]:
    ref, est = mir_eval.beat.trim_beats(reference), mir_eval.beat.trim_beats(np.asarray(estimated, float))
    scores = mir_eval.beat.evaluate(reference, np.asarray(estimated, float))
    ref_tempo, est_tempo = tempo_of(ref), tempo_of(est)
    out = {"F-measure": scores["F-measure"], "CMLt": scores["Correct Metric Level Total"],
           "AMLt": scores["Any Metric Level Total"], "Cemgil": scores["Cemgil"], "Goto": scores["Goto"],
           "tempo_annotated_bpm": round(ref_tempo, 2), "tempo_estimated_bpm": round(est_tempo, 2),
           "tempo_error": round(abs(est_tempo - ref_tempo) / ref_tempo, 4) if ref_tempo else float("nan")}
    if ref_downbeats is not None and est_downbeats is not None:
        out["downbeat_F-measure"] = mir_eval.beat.f_measure(mir_eval.beat.trim_beats(ref_downbeats),
                                                            mir_eval.beat.trim_beats(np.asarray(est_downbeats)))
    return {k: (round(float(v), 4) if isinstance(v, (float, np.floating)) else v) for k, v in out.items()}


def evaluate_beats(audio: Path, annotations: Path, fps: float = 24.0) -> dict:
    """Scores of both trackers and of the first dance3d tracker on one annotated audio file."""
    from pipeline.music.audio import HOP, feature_rate

    reference, bars = read_beat_annotations(annotations)
    try:
        y = librosa.load(str(audio), sr=RNN_SR, mono=True)[0]
    except Exception as exc:  # audioread / soundfile raise several types, audioread's without a message
        reason = " ".join(str(exc).split()) or f"no audio decoder reads it ({type(exc).__name__})"
        raise InputError(audio, f"cannot read the audio: {reason}") from None
    ref_down = reference[bars == 1] if bars is not None else None
    out = {"audio": str(audio), "annotations": str(annotations), "annotated_beats": int(len(reference))}
    for tracker in TRACKERS:
        beats = track_beats(y, RNN_SR, tracker)
        out[tracker] = score(reference, beats.times, ref_down, beats.downbeats if ref_down is not None else None)
        out[tracker]["beats_per_bar"] = beats.beats_per_bar
    y_motion = librosa.resample(y, orig_sr=RNN_SR, target_sr=feature_rate(fps), res_type="soxr_hq")
    onset = librosa.onset.onset_strength(y=y_motion, sr=fps * HOP, hop_length=HOP)
    out[f"previous_{fps:g}fps_envelope"] = score(reference, track_beats_motion_rate(onset, fps, HOP))
    return out


def evaluate_files(pairs: list[tuple[Path, Path]], fps: float = 24.0) -> dict:
    """Every (audio, annotations) pair scored, and each method's mean over the files."""
    files = [evaluate_beats(audio, beats, fps) for audio, beats in pairs]
    methods = [k for k in files[0] if isinstance(files[0][k], dict)] if files else []
    mean = {}
    for method in methods:  # scores only: a mean tempo or bar length says nothing
        keys = dict.fromkeys(k for f in files for k in f[method] if k not in ("beats_per_bar",) and "bpm" not in k)
        mean[method] = {k: round(float(np.nanmean([f[method].get(k, np.nan) for f in files])), 4) for k in keys}
    return {"protocol": PROTOCOL, "trackers": {t: describe(t) for t in TRACKERS}, "files": files, "mean": mean}


def pairs_in(folder: Path) -> list[tuple[Path, Path]]:
    """Audio files of a folder with the annotation of the same name (``.beats`` or ``.txt``)."""
    out = []
    for audio in sorted(folder.iterdir()):
        if audio.suffix.lower() in (".beats", ".txt") or audio.is_dir():
            continue
        for ext in (".beats", ".txt"):
            if audio.with_suffix(ext).exists():
                out.append((audio, audio.with_suffix(ext)))
                break
    return out


def format_table(result: dict) -> str:
    methods = list(result["mean"])
    lines = [f"protocol: {result['protocol']}"]
    for entry in [*result["files"], {"audio": f"mean of {len(result['files'])} files", **result["mean"]}]:
        keys = [k for k in entry[methods[0]]] if methods else []
        keys += [k for m in methods for k in entry[m] if k not in keys]
        width = max(len(k) for k in keys)
        head = entry["audio"] if "annotations" not in entry else \
            f"{entry['audio']} against {entry['annotations']} ({entry['annotated_beats']} beats)"
        lines += ["", head, f"{'':{width}}  " + "  ".join(f"{m:>22}" for m in methods)]
        for key in keys:
            lines.append(f"{key:{width}}  " + "  ".join(f"{entry[m].get(key, ''):>22}" for m in methods))
    return "\n".join(lines)
