"""Parallel workers on cold numba caches never crash (the librosa/numba cache race).

numba's on-disk cache is a read-modify-write of one index file per function, without a
lock: two processes compiling at once can leave an index that points at the other
process's machine code, and every later process that loads it segfaults. The test runs
the audio stage's feature code and the smooth stage's HP filter in two processes at
once on cold caches, three times, then once alone; every process must exit cleanly.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import PROJECT, ffmpeg

pytestmark = pytest.mark.slow

WORKER = """
import sys
from pathlib import Path
import numpy as np
from pipeline.music.audio import LoudnessOptions, compute_features, load_for_features, normalise_loudness
from pipeline.motion.smoothing import hp_trend
wav, out = Path(sys.argv[1]), Path(sys.argv[1] + ".normalised.wav")
normalise_loudness(wav, out, LoudnessOptions())  # what the audio stage's worker does, in its order
features = compute_features(load_for_features(out))
assert features.frames > 0 and len(features.beat_times) > 0
trend = hp_trend(np.random.default_rng(0).normal(size=(500, 17, 3)), 1.0)
assert trend.shape == (500, 17, 3)
"""


def _clear_in_tree_caches() -> None:
    """Cold start for caches kept next to the code (numba's default place)."""
    import librosa

    for root in (Path(librosa.__file__).parent, PROJECT / "pipeline"):
        for path in root.rglob("__pycache__/*.nb[ic]"):
            path.unlink(missing_ok=True)


def _start(wav: Path, env: dict) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", WORKER, str(wav)], cwd=PROJECT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _finish(proc: subprocess.Popen) -> tuple[int, str]:
    out, _ = proc.communicate(timeout=600)
    return proc.returncode, out[-2000:]


def test_two_workers_on_cold_caches_three_times_then_one_alone(tmp_path: Path, media_dir: Path) -> None:
    wavs = []
    for name in ("dance_single_music_musepose", "movement_single_speech_taiji"):  # two demo segments
        wav = tmp_path / f"{name}.wav"
        ffmpeg("-i", str(media_dir / "videos" / f"{name}.mp4"), "-vn", "-c:a", "pcm_s16le", str(wav))
        wavs.append(wav)
    env = {**os.environ, "PYTHONPATH": str(PROJECT)}
    env.pop("NUMBA_CACHE_DIR", None)
    results = []
    for trial in range(3):
        _clear_in_tree_caches()
        env["DANCE3D_CACHE_DIR"] = str(tmp_path / f"cache-{trial}")  # a cold project cache each trial
        procs = [_start(wav, env) for wav in wavs]
        results += [(trial, *_finish(p)) for p in procs]
    results.append(("alone", *_finish(_start(wavs[0], env))))  # reuses what the last trial left behind
    crashed = [(trial, code, out) for trial, code, out in results if code != 0]
    assert not crashed, f"{len(crashed)} of {len(results)} worker processes died: {crashed[:2]}"
