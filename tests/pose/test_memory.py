"""The 2D stage's memory does not grow with the video's length."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import PROJECT, ffmpeg

CHILD = """
import resource, sys
from pathlib import Path
sys.path.insert(0, {root!r})
from benchmarks.pose2d import configured, load_models, stage_work
params, opts = configured({{"pose_model": "movenet-lightning"}})
stage_work(Path({clip!r}), 24.0, load_models(params), opts)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


@pytest.mark.slow
def test_peak_memory_of_pose2d_does_not_grow_with_the_video_length(tmp_path: Path, media_dir: Path,
                                                                     models_dir: Path) -> None:
    # Full-HD frames through three threads: glibc's adaptive mmap threshold used to keep every
    # freed frame buffer in the heap, and peak RSS grew by about 7 MB per second of video.
    peaks = {}
    for seconds in (4, 16):
        clip = tmp_path / f"{seconds}s.mp4"
        ffmpeg("-stream_loop", "3", "-i", str(media_dir / "videos/dance_single_music_musepose.mp4"), "-t",
               str(seconds), "-an", "-c:v", "libx264", "-preset", "ultrafast", str(clip))
        out = subprocess.run([sys.executable, "-c", CHILD.format(root=str(PROJECT), clip=str(clip))],
                             capture_output=True, text=True, check=True).stdout
        peaks[seconds] = int(out.strip().splitlines()[-1]) / 1024
    assert peaks[16] <= 1.1 * peaks[4], peaks
