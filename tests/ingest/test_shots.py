"""Hard cuts found from frames decoded for something else, as ffmpeg's own scdet run finds them."""

from __future__ import annotations

import re
import subprocess
from fractions import Fraction
from pathlib import Path

import pytest

from pipeline.ingest.media import ffmpeg_exe
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.ingest.shots import CutFinder
from tests.conftest import ffmpeg


@pytest.fixture(scope="module")
def three_shots(tmp_path_factory) -> Path:
    """Three shots of different test patterns, cut at 2.0 and 3.6 s (25 fps)."""
    out = tmp_path_factory.mktemp("shots") / "three_shots.mp4"
    sources = ["testsrc2=size=320x240:rate=25:duration=2", "mandelbrot=size=320x240:rate=25",
               "smptebars=size=320x240:rate=25:duration=1.4"]
    args = []
    for source in sources:
        args += ["-f", "lavfi", "-t", "2", "-i", source]
    graph = "".join(f"[{i}:v]trim=duration={d},setpts=PTS-STARTPTS,format=yuv420p[v{i}];"
                    for i, d in enumerate((2, 1.6, 1.4))) + "[v0][v1][v2]concat=n=3:v=1:a=0[v]"
    ffmpeg(*args, "-filter_complex", graph, "-map", "[v]", "-c:v", "libx264", "-preset", "veryfast", str(out))
    return out


def scdet_cli(path: Path, threshold: float) -> list[float]:
    """The reference: ffmpeg's command line running scdet on its own decode of the file."""
    proc = subprocess.run([ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", str(path), "-an", "-vf",
                           f"setpts=PTS-STARTPTS,scale=160:-2,scdet=threshold={threshold:g}:sc_pass=0",
                           "-f", "null", "-"], capture_output=True, text=True, check=True)
    found = re.findall(r"lavfi\.scd\.score:\s*([\d.]+),\s*lavfi\.scd\.time:\s*([\d.]+)", proc.stderr)
    return sorted({round(float(t), 3) for _, t in found if float(t) >= 0.5})


def test_cuts_found_in_a_sampled_decode_are_those_of_ffmpeg_scdet(three_shots: Path) -> None:
    finder = CutFinder(threshold=10.0)
    view = SegmentVideo(three_shots, 0.0, Fraction(4), 20, 160, 120)  # 4 frames a second are shown
    shown = sum(1 for _ in view.iter_frames(tap=finder.push))
    assert shown == 20
    assert finder.cuts() == scdet_cli(three_shots, 10.0) == [2.0, 3.6]


def test_a_threshold_above_every_score_finds_no_cut(three_shots: Path) -> None:
    finder = CutFinder(threshold=100.0)
    for _ in SegmentVideo(three_shots, 0.0, Fraction(4), 20, 160, 120).iter_frames(tap=finder.push):
        pass
    assert finder.cuts() == []


def test_cuts_found_from_only_the_frames_a_skipping_decoder_decodes_are_the_same(three_shots: Path) -> None:
    finder = CutFinder(threshold=10.0)
    seen = []

    def tap(frame) -> None:
        seen.append(frame.pts)
        finder.push(frame)

    view = SegmentVideo(three_shots, 0.0, Fraction(4), 20, 160, 120)
    shown = sum(1 for _ in view.iter_frames(tap=tap, keep=lambda k: True, tap_all=False))
    assert shown == 20
    assert len(seen) < 100  # of 123: the non-reference frames no shown frame needs were skipped
    assert finder.cuts() == [2.0, 3.6]
