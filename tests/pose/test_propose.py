"""Proposed dance segments on a video assembled from the shared media, with known cut points."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.ingest.catalog import read_index
from pipeline.pose.propose import ProposeOptions, Timeline, boundary_errors, propose
from pipeline.pose.proposed import read_proposals
from stages import download, propose_segments, trim
from tests.conftest import ffmpeg, set_params

# (file or "card", seconds used): the dance is the third part; the cuts are at 8, 16 and 28 s.
PARTS = [("videos/movement_single_speech_taiji.mp4", 8),   # one person moving, over speech
         ("videos/musicians_trio_music_raga.mp4", 8),      # three seated musicians, music
         ("videos/dance_single_music_musepose.mp4", 12),   # one dancer, music
         ("card", 4)]                                      # a silent title card
DANCE = (16.0, 28.0)


def assemble(media_dir: Path, out: Path, parts: list[tuple[str, float]] = PARTS) -> Path:
    """The parts one after the other at 640x360 (letterboxed), 25 fps, 44.1 kHz stereo; "card" is a
    plain-colour title card over silence."""
    args, chains = [], []
    for i, (name, seconds) in enumerate(parts):
        if name == "card":
            args += ["-f", "lavfi", "-t", str(seconds), "-i", "color=c=0x203060:s=640x360:r=25",
                     "-f", "lavfi", "-t", str(seconds), "-i", "anullsrc=r=44100:cl=stereo"]
        else:
            args += ["-t", str(seconds), "-i", str(media_dir / name)]
    n = 0
    for i, (name, _) in enumerate(parts):
        if name == "card":
            chains.append(f"[{n}:v]format=yuv420p,setsar=1[v{i}];[{n + 1}:a]anull[a{i}]")
            n += 2
        else:
            chains.append(f"[{n}:v]scale=640:360:force_original_aspect_ratio=decrease,pad=640:360:(ow-iw)/2:"
                          f"(oh-ih)/2,fps=25,setsar=1,format=yuv420p[v{i}];"
                          f"[{n}:a]aresample=44100,aformat=channel_layouts=stereo[a{i}]")
            n += 1
    chains.append("".join(f"[v{i}][a{i}]" for i in range(len(parts))) + f"concat=n={len(parts)}:v=1:a=1[v][a]")
    ffmpeg(*args, "-filter_complex", ";".join(chains), "-map", "[v]", "-map", "[a]", "-c:v", "libx264",
           "-preset", "veryfast", "-crf", "23", "-c:a", "aac", str(out))
    return out


@pytest.fixture(scope="module")
def proposed_project(media_dir: Path, models_dir: Path, tmp_path_factory, monkeypatch_module) -> Path:
    """A project whose one source is the assembled video, after download and propose_segments."""
    import shutil

    from tests.conftest import PROJECT

    root = tmp_path_factory.mktemp("propose") / "project"
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    video = assemble(media_dir, root.parent / "talk_musicians_dance_card.mp4")
    (root / "manifests/sources.csv").write_text(f"video_id,url\nassembled,{video}\n")
    monkeypatch_module.setenv("DANCE3D_MODELS", str(models_dir))
    download.run(root)
    propose_segments.run(root)
    return root


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


def test_the_dance_shot_is_proposed_within_a_second_of_its_cuts(proposed_project: Path) -> None:
    found = read_proposals(proposed_project / "data/segment_proposals/assembled.parquet")
    spans = [(s["start"], s["end"]) for s in found["segments"]]
    scores = boundary_errors(spans, [DANCE])
    print(f"proposals {spans}; boundary error: start {scores['start_error_s']} s, end {scores['end_error_s']} s")
    assert scores["found"] == 1 and scores["right"] == len(spans) == 1
    assert scores["start_error_s"] <= 1.0 and scores["end_error_s"] <= 1.0
    assert [round(c) for c in found["cuts"]] == [8, 16, 28]  # the scene-cut detector finds every cut
    assert found["segments"][0]["reason"].startswith("music")


def test_every_shot_has_a_verdict_and_a_reason(proposed_project: Path) -> None:
    shots = read_proposals(proposed_project / "data/segment_proposals/assembled.parquet")["shots"]
    assert [s["verdict"] for s in shots] == ["no dance", "no dance", "dance", "no dance"]
    assert shots[0]["reason"] == "no music (silence, speech or noise)"  # the talk: a person moves, no music
    assert shots[3]["reason"] == "nobody seen"                           # the title card
    summary = (proposed_project / "data/segment_proposals/segments.csv").read_text()
    assert '\nassembled,16.000,28.000,"music' in summary


def test_trim_accepts_proposals_only_for_videos_without_human_rows(proposed_project: Path) -> None:
    set_params(proposed_project, "trim", unannotated="proposals")
    annotations = proposed_project / "annotations/segments.csv"
    trim.run(proposed_project)
    [segment] = read_index(proposed_project / "data/segments").values()
    assert (segment["segment_id"], segment["start"], segment["label"]) == ("assembled_000", 16.0, "proposed")
    assert abs(segment["end"] - 28.0) < 0.05
    annotations.write_text("video_id,start,end,label,note\nassembled,17.0,20.0,dance,a human row wins\n")
    try:
        trim.run(proposed_project)
        [segment] = read_index(proposed_project / "data/segments").values()
        assert (segment["start"], segment["label"]) == (17.0, "dance")
    finally:
        annotations.unlink()


def _timeline(music: str, moving: str, cuts: list[float]) -> Timeline:
    n = len(music)
    on = np.array([c == "#" for c in music])
    return Timeline(float(n), cuts, np.where(on, -20.0, -80.0), np.where(on, 0.9, 0.1), np.where(on, 0.1, 0.6),
                    np.ones(n), np.array([0.2 if c == "#" else 0.01 for c in moving]))


def test_short_gaps_are_bridged_runs_snap_to_cuts_and_short_runs_are_dropped() -> None:
    opts = ProposeOptions(min_seconds=4, max_gap=2, edge_snap=3)
    #                  0         1         2
    #                  0123456789012345678901234
    tl = _timeline("#########################", "..########.#######...##..", cuts=[20.0])
    segments = [(s.start, s.end) for s in propose(tl, opts).segments]
    # The gap at 10 s is bridged; 2 s from either cut, the run takes the cut's times; after the cut at
    # 20 s, the 2-s run is too short.
    assert segments == [(0.0, 20.0)]


def test_eval_segments_scores_proposals_against_human_rows_beside_the_whole_video(proposed_project: Path) -> None:
    import subprocess
    import sys

    annotations = proposed_project / "annotations/segments.csv"
    annotations.write_text("video_id,start,end\nassembled,16.0,28.0\n")
    try:
        out = subprocess.run([sys.executable, "-m", "pipeline.cli", "eval", "segments"], cwd=proposed_project,
                             capture_output=True, text=True, check=True).stdout
    finally:
        annotations.unlink()
    assert "| assembled | 1 | 1 | 1 | 1 | 0.0 | 0.0 | 16.0 / 4.0 |" in out


def test_status_counts_the_proposals(proposed_project: Path) -> None:
    from pipeline.status import summarise

    assert "propose_segments: 1 proposed dance segments (0.2 min) in 1 videos" in summarise(proposed_project)
