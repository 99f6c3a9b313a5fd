"""Killed runs, resumed runs, repeated runs, incremental runs and retries."""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from pipeline.core.failures import read_failures
from pipeline.ingest.catalog import read_ledger
from tests.conftest import PROJECT, run_stages, set_params, write_sources

OUTPUTS = ("data/segments", "data/pose2d", "data/tracks", "data/clean")


def digests(root: Path) -> dict[str, str]:
    return {f"{folder}/{p.name}": hashlib.sha256(p.read_bytes()).hexdigest()
            for folder in OUTPUTS for p in sorted((root / folder).glob("*"))
            if p.is_file() and not p.name.startswith("_")}


def mtimes(root: Path) -> dict[str, int]:
    """Per-item outputs (catalogues such as the segment index are rewritten by design)."""
    return {f"{folder}/{p.name}": p.stat().st_mtime_ns for folder in OUTPUTS
            for p in sorted((root / folder).glob("*"))
            if p.is_file() and not p.name.startswith("_") and p.name != "index.parquet"}


def new_project(root: Path, media_dir: Path, videos: list[tuple[str, str]], annotations: str) -> Path:
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    write_sources(root, [(vid, media_dir / "videos" / name) for vid, name in videos])
    (root / "annotations/segments.csv").write_text("video_id,start,end\n" + annotations)
    set_params(root, "trim", fps=10)  # a third of the solo clip's frames: resuming is under test, not pose
    return root


SOLO = [("solo", "dance_solo_384x496_30fps.mp4")]
SOLO_SEGMENTS = "solo,0,2\nsolo,2,4\nsolo,4,6\nsolo,6,8\n"


def _run_and_kill(root: Path, stage: str, after: float, env: dict) -> bool:
    """Whether the stage was still running ``after`` seconds in, and so was killed."""
    proc = subprocess.Popen([sys.executable, "-m", f"stages.{stage}"], cwd=root, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        proc.wait(timeout=after)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the whole job, ffmpeg children included, like a crash
        proc.wait()
        return True


@pytest.mark.slow
def test_sigkill_at_any_point_then_resume_gives_byte_identical_outputs(tmp_path: Path, media_dir: Path,
                                                                       models_dir: Path) -> None:
    env = {**os.environ, "DANCE3D_MODELS": str(models_dir), "PYTHONPATH": str(PROJECT)}
    clean = new_project(tmp_path / "clean", media_dir, SOLO, SOLO_SEGMENTS)
    took = {}
    for stage in ("download", "trim", "pose2d", "track", "clean"):
        started = time.perf_counter()
        subprocess.run([sys.executable, "-m", f"stages.{stage}"], cwd=clean, env=env, check=True,
                       capture_output=True)
        took[stage] = time.perf_counter() - started
    reference = digests(clean)
    assert len(reference) == 4 * 3 + 1  # 4 segments x (pose2d, tracks, clean) + the index (segments are views)

    killed = []
    for i, share in enumerate((0.3, 0.6, 0.9)):  # of each stage's own uninterrupted run
        root = new_project(tmp_path / f"killed{i}", media_dir, SOLO, SOLO_SEGMENTS)
        subprocess.run([sys.executable, "-m", "stages.download"], cwd=root, env=env, check=True, capture_output=True)
        for stage in ("trim", "pose2d", "track"):
            if _run_and_kill(root, stage, share * took[stage], env):
                killed.append(stage)
            for path in (root / "data").rglob("*.parquet"):  # nothing truncated is ever visible
                if not path.name.startswith("."):
                    pq.read_metadata(path)
            subprocess.run([sys.executable, "-m", f"stages.{stage}"], cwd=root, env=env, check=True,
                           capture_output=True)
        subprocess.run([sys.executable, "-m", "stages.clean"], cwd=root, env=env, check=True, capture_output=True)
        assert not list((root / "data").rglob(".tmp-*"))
        assert digests(root) == reference, f"killed at {share:.0%} of each stage's run"
    assert {"trim", "pose2d", "track"} <= set(killed), killed  # every stage was interrupted at least once


@pytest.mark.slow
def test_two_full_runs_are_byte_identical(tmp_path: Path, media_dir: Path, models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    roots = [new_project(tmp_path / f"run{i}", media_dir, SOLO + [("dance", "dance_single_music_musepose.mp4")],
                         "solo,0,2\ndance,1,3\n") for i in range(2)]
    for root in roots:
        run_stages(root, "download", "trim", "pose2d", "track", "clean", "audio")
    assert digests(roots[0]) == digests(roots[1])
    feats = [hashlib.sha256((r / "data/audio_features/dance_000.parquet").read_bytes()).hexdigest() for r in roots]
    assert feats[0] == feats[1]


@pytest.mark.slow
def test_adding_a_video_processes_only_that_video(tmp_path: Path, media_dir: Path, models_dir: Path,
                                                  monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    root = new_project(tmp_path / "p", media_dir, SOLO + [("taiji", "movement_single_speech_taiji.mp4")],
                       "solo,0,2\ntaiji,1,3\n")
    stages = ("download", "trim", "pose2d", "track", "clean")
    run_stages(root, *stages)
    before = mtimes(root)
    ledger_rows = len(read_ledger(root / "data/raw"))
    (root / "manifests/sources.csv").write_text((root / "manifests/sources.csv").read_text()
                                                + f"dance,{media_dir / 'videos/dance_single_music_musepose.mp4'}\n")
    (root / "annotations/segments.csv").write_text("video_id,start,end\nsolo,0,2\ntaiji,1,3\ndance,1,3\n")
    run_stages(root, *stages)
    after = mtimes(root)
    redone = {k for k in before if after.get(k) != before[k]}
    added = set(after) - set(before)
    assert redone == set()  # nothing of the first two videos was touched
    assert {k.split("/")[-1].split(".")[0] for k in added} == {"dance_000"}
    assert sorted(k.split("/")[1] for k in added) == ["clean", "pose2d", "tracks"]  # segments: an index row
    assert len(read_ledger(root / "data/raw")) == ledger_rows + 1


def test_retry_reruns_only_the_failed_items(tmp_path: Path, media_dir: Path, models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    root = new_project(tmp_path / "p", media_dir, SOLO + [("taiji", "movement_single_speech_taiji.mp4")],
                       "solo,0,2\ntaiji,2,4\n")
    run_stages(root, "download", "trim")
    good = root / "data/raw/solo.mp4"
    bad = root / "data/raw/taiji.mp4"  # the download taiji_000 is read from
    original = bad.read_bytes()
    bad.write_bytes(b"not a video any more")
    set_params(root, "pose2d", max_failure_ratio=1.0)
    run_stages(root, "pose2d")
    failures = [asdict(f) for f in read_failures(root / "data/pose2d")]
    assert [f["item"] for f in failures] == ["taiji_000"]
    assert "taiji.mp4: not a readable media file" in failures[0]["message"]
    kept = (root / "data/pose2d/solo_000.parquet").stat().st_mtime_ns
    bad.write_bytes(original)  # the annotator fixed the file
    out = subprocess.run([sys.executable, "-m", "pipeline.cli", "--root", str(root), "retry", "pose2d"],
                         capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(PROJECT)})
    assert out.returncode == 0, out.stderr
    assert "retrying 1 items: taiji_000" in out.stdout
    assert (root / "data/pose2d/taiji_000.parquet").exists()
    assert (root / "data/pose2d/solo_000.parquet").stat().st_mtime_ns == kept
    assert read_failures(root / "data/pose2d") == []
    assert good.exists()
