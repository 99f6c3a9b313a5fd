"""Beats that are right: both trackers (madmom's RNN, the default, and librosa's), `dance3d eval beats`,
and the traps that cause octave errors."""

from __future__ import annotations

import json
from pathlib import Path

import librosa
import mir_eval
import numpy as np
import pytest
import soundfile as sf

from pipeline.cli import main
from pipeline.core.errors import InputError
from pipeline.music.audio import HOP
from pipeline.music.beats import TRACKERS, beat_flags, track_beats, track_beats_motion_rate
from pipeline.music.evaluate import read_beat_annotations
from tests.music.synthetic import SR, pieces

PIECES = {p.name: p for p in pieces()}


def _scores(piece, times) -> dict:
    return mir_eval.beat.evaluate(piece.beats, np.asarray(times, float))


def _previous(piece) -> np.ndarray:
    """The previous default: the tracker on the 24 fps onset envelope."""
    y = librosa.resample(piece.audio, orig_sr=SR, target_sr=24 * HOP)
    return track_beats_motion_rate(librosa.onset.onset_strength(y=y, sr=24 * HOP, hop_length=HOP), 24, HOP)


@pytest.mark.parametrize("tracker", TRACKERS)
@pytest.mark.parametrize("name", ["four_on_the_floor_124", "swing_110", "tempo_change_100_to_132", "waltz_90"])
def test_clear_pieces_get_their_beats_at_the_right_level(name: str, tracker: str) -> None:
    piece = PIECES[name]
    scores = _scores(piece, track_beats(piece.audio, SR, tracker).times)
    assert scores["F-measure"] >= 0.95 and scores["Correct Metric Level Total"] >= 0.9


def test_a_tempo_change_is_followed_not_averaged() -> None:
    piece = PIECES["tempo_change_100_to_132"]
    assert _scores(piece, track_beats(piece.audio, SR).times)["F-measure"] >= 0.95
    assert _scores(piece, _previous(piece))["F-measure"] < 0.8  # one global tempo cannot fit both halves


@pytest.mark.parametrize("tracker", TRACKERS)
@pytest.mark.parametrize("name", ["slow_with_strong_offbeats_70", "boom_chick_85.5"])
def test_octave_traps_land_on_a_related_metrical_level(name: str, tracker: str) -> None:
    # Loud off-beats make double tempo as plausible as the annotation: the beats must still be the
    # annotated ones or their doubles (AMLt), never drift.
    piece = PIECES[name]
    scores = _scores(piece, track_beats(piece.audio, SR, tracker).times)
    assert scores["Any Metric Level Total"] >= 0.9 and scores["F-measure"] >= 0.6


@pytest.mark.parametrize("name", ["boom_chick_85.5", "between_grid_lags_163"])
def test_full_resolution_fixes_tempos_between_the_motion_rate_lags(name: str) -> None:
    # At 24 Hz a beat period of 16.8 or 8.8 frames cannot be represented; the old tracker drifted off.
    piece = PIECES[name]
    new, old = _scores(piece, track_beats(piece.audio, SR, "librosa").times), _scores(piece, _previous(piece))
    assert new["F-measure"] >= old["F-measure"] + 0.3


def test_the_rnn_tracker_holds_a_tempo_between_grid_lags_that_librosa_takes_at_two_thirds() -> None:
    piece = PIECES["between_grid_lags_163"]
    rnn, dp = (_scores(piece, track_beats(piece.audio, SR, t).times) for t in ("rnn", "librosa"))
    assert rnn["F-measure"] >= 0.95 and dp["F-measure"] < 0.5


@pytest.mark.parametrize(("name", "tracker"), [("four_on_the_floor_124", "librosa"), ("swing_110", "librosa"),
                                               ("waltz_90", "librosa"), ("swing_110", "rnn"), ("waltz_90", "rnn")])
def test_downbeats_start_the_bars(name: str, tracker: str) -> None:
    # The synthetic bar is marked only by a 1.3x louder kick on beat 1 (beat 3 has a kick too): the
    # RNN, which learnt bars from real music, puts four-on-the-floor's bars on beat 3.
    piece = PIECES[name]
    beats = track_beats(piece.audio, SR, tracker)
    assert beats.beats_per_bar == (3 if name.startswith("waltz") else 4)
    trim = mir_eval.beat.trim_beats
    score = mir_eval.beat.f_measure(trim(piece.downbeats), trim(beats.downbeats))
    assert score >= 0.95 and set(beats.downbeats) <= set(beats.times)


def test_beat_flags_sit_on_the_nearest_frame_of_the_grid() -> None:
    flags = beat_flags(np.array([0.0, 0.52, 1.0, 99.0]), frames=30, fps=24)
    assert np.flatnonzero(flags).tolist() == [0, 12, 24]  # 0.52 s is 12.48 frames; 99 s is past the end


def test_eval_beats_reports_both_trackers_per_file_and_their_mean(tmp_path: Path, capsys) -> None:
    for name in ("boom_chick_85.5", "between_grid_lags_163"):
        piece = PIECES[name]
        sf.write(tmp_path / f"{name}.wav", piece.audio, SR)
        positions = np.arange(len(piece.beats)) % 4 + 1
        (tmp_path / f"{name}.beats").write_text(
            "# time position\n" + "".join(f"{t:.4f} {p}\n" for t, p in zip(piece.beats, positions)))
    out = tmp_path / "r.json"
    assert main(["eval", "beats", "--dir", str(tmp_path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "F-measure" in printed and "AMLt" in printed and "mean of 2 files" in printed
    result = json.loads(out.read_text())
    lags, boom = result["files"]  # in name order
    assert set(boom) >= {"rnn", "librosa", "previous_24fps_envelope"}
    assert boom["rnn"]["tempo_annotated_bpm"] == pytest.approx(85.5, abs=0.5) and "downbeat_F-measure" in boom["rnn"]
    assert lags["rnn"]["F-measure"] > lags["librosa"]["F-measure"] > lags["previous_24fps_envelope"]["F-measure"]
    mean = result["mean"]["rnn"]["F-measure"]
    assert mean == pytest.approx((boom["rnn"]["F-measure"] + lags["rnn"]["F-measure"]) / 2, abs=1e-3)
    assert "CC BY-NC-SA" in result["trackers"]["rnn"]


def test_a_bad_annotation_line_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "x.beats"
    path.write_text("0.5\n1.0\nabc\n")
    with pytest.raises(InputError, match=r"x\.beats:3: expected a beat time"):
        read_beat_annotations(path)
    path.write_text("0.5 1\n0.4 2\n")
    with pytest.raises(InputError, match=r"x\.beats:2: beat times must increase"):
        read_beat_annotations(path)


def test_real_music_smoke(media_dir: Path) -> None:
    y, sr = librosa.load(str(media_dir / "music/music_vibe_ace_kevin_macleod.ogg"), sr=22050, mono=True)
    beats = track_beats(y, sr)
    assert 60 <= beats.tempo <= 200
    expected = len(y) / sr * beats.tempo / 60
    assert 0.8 * expected <= len(beats.times) <= 1.1 * expected
    assert np.all(np.diff(beats.times) > 0) and set(beats.downbeats) <= set(beats.times)


def test_the_rnn_runs_on_chunks_that_track_as_well_as_the_whole_signal() -> None:
    """Memory stays bounded on long segments: the networks see 60 s chunks with 10 s of context
    either side; the stitched activations follow the whole signal's and the beats score as well."""
    from madmom.audio.signal import Signal

    from pipeline.music.beats import RNN_HOP, RNN_SR, _rnn_processors, activations

    names = ("tempo_change_100_to_132", "swing_110", "waltz_90")
    offsets = np.cumsum([0.0] + [len(PIECES[n].audio) / SR for n in names[:-1]])
    truth = np.concatenate([PIECES[n].beats + t for n, t in zip(names, offsets)])
    y = librosa.resample(np.concatenate([PIECES[n].audio for n in names]), orig_sr=SR, target_sr=RNN_SR)
    network, decode = _rnn_processors()[:2]  # 100 s: two chunks
    whole = np.asarray(network(Signal(y, sample_rate=RNN_SR, num_channels=1)))
    chunked = activations(network, y)
    assert len(chunked) == len(whole) == int(np.ceil(len(y) / RNN_HOP))
    assert np.corrcoef(whole, chunked)[0, 1] > 0.99
    f_whole, f_chunked = (mir_eval.beat.f_measure(truth, decode(a)) for a in (whole, chunked))
    assert f_chunked >= f_whole - 0.01 and f_chunked > 0.95
