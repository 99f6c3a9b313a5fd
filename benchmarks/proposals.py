"""Proposed dance segments: boundary error on assembled videos with known cuts, and the verdict on
every shared clip, with the time it takes.

    python benchmarks/proposals.py [--json out.json]

Needs DANCE3D_MEDIA (the shared clips) and DANCE3D_MODELS. Protocol: the propose_segments stage's
code and default params on (a) videos assembled from the shared clips, whose dance part and cut
points are known, and (b) each shared clip alone, whose truth is "all dance" for the one dance
clip and "no dance" for the others. Boundary error: |start - true start| and |end - true end| of
the proposal that overlaps the dance most. Baseline: the whole video as one segment
(trim.unannotated: whole, the previous default for videos without rows).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.core.params import load_params, stage_params  # noqa: E402
from pipeline.ingest.media import probe  # noqa: E402
from pipeline.pose.models.loading import load_pose_models, model_names, worker_files  # noqa: E402
from pipeline.pose.pose2d import Pose2dOptions  # noqa: E402
from pipeline.pose.propose import ProposeOptions, boundary_errors, propose, timeline  # noqa: E402
from tests.pose.test_propose import PARTS, assemble  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ASSEMBLED = {
    "talk, musicians, dance, card": (PARTS, [(16.0, 28.0)]),
    "card, dance, musicians, talk": ([("card", 4), ("videos/dance_single_music_musepose.mp4", 12),
                                      ("videos/musicians_trio_music_raga.mp4", 8),
                                      ("videos/movement_single_speech_taiji.mp4", 8)], [(4.0, 16.0)]),
    "dance, card, dance (two routines)": ([("videos/dance_single_music_musepose.mp4", 10), ("card", 3),
                                           ("videos/dance_single_music_musepose.mp4", 8)],
                                          [(0.0, 10.0), (13.0, 21.0)]),
}
CLIPS = {"videos/dance_single_music_musepose.mp4": "dance", "videos/movement_single_speech_taiji.mp4": "no dance",
         "videos/musicians_trio_music_raga.mp4": "no dance",
         "videos/performance_audience_music_whitehouse.mp4": "no dance",
         "videos/dance_solo_384x496_30fps.mp4": "no dance (dance without sound)"}


def still_then_dance(media: Path, out: Path, still: float = 5.5) -> Path:
    """One shot, no cut: the dancer's first frame held for ``still`` seconds (off the 1-s grid), then her dance; music
    (Vibe Ace) throughout. The boundary must come from the motion cue alone."""
    from tests.conftest import ffmpeg

    ffmpeg("-t", "12", "-i", str(media / "videos/dance_single_music_musepose.mp4"),
           "-i", str(media / "music/music_vibe_ace_kevin_macleod.ogg"),
           "-filter_complex", f"[0:v]scale=360:640,fps=25,tpad=start_duration={still}:start_mode=clone,"
                              "format=yuv420p[v]",
           "-map", "[v]", "-map", "1:a:0", "-t", str(12 + still), "-c:v", "libx264", "-preset", "veryfast",
           "-c:a", "aac", str(out))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    media = Path(os.environ["DANCE3D_MEDIA"])
    params = load_params(ROOT / "params.yaml")
    opts = ProposeOptions.from_params(stage_params(params, "propose_segments"))
    pose_params = stage_params(params, "pose2d")
    pose_params = {**pose_params, "pose_model": model_names(pose_params["pose_model"])[0]}
    files = worker_files(ROOT, pose_params)
    models = load_pose_models(files)
    pose_opts = dataclasses.replace(Pose2dOptions.from_params(pose_params), confirm_score=0.0)
    rows = []

    def run(name: str, path: Path, truth: list[tuple[float, float]], expected: str) -> None:
        info = probe(path)
        started = time.perf_counter()
        found = propose(timeline(path, info, models, opts, pose_opts), opts)
        seconds = time.perf_counter() - started
        spans = [(s.start, s.end) for s in found.segments]
        row = {"video": name, "expected": expected, "duration_s": round(info.duration, 2), "proposals": spans,
               "proposed_s": round(sum(e - s for s, e in spans), 2), "x_real_time": round(info.duration / seconds, 2),
               **boundary_errors(spans, truth),
               "whole_video": boundary_errors([(0.0, info.duration)], truth) if truth else None}
        rows.append(row)
        print(f"{name:45} {expected:30} proposals {spans}  found {row['found']}/{len(truth)}  "
              f"err start {row['start_error_s']} end {row['end_error_s']}  {row['x_real_time']}x real time",
              flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        for name, (parts, truth) in ASSEMBLED.items():
            video = assemble(media, Path(tmp) / f"{len(rows)}.mp4", parts)
            run(name, video, truth, f"dance at {truth}")
        run("still 5.5 s, then dance (one shot, music)", still_then_dance(media, Path(tmp) / "still.mp4"),
            [(5.5, 17.5)], "dance at [(5.5, 17.5)]")
    for clip, expected in CLIPS.items():
        truth = [(0.0, probe(media / clip).duration)] if expected == "dance" else []
        run(Path(clip).stem, media / clip, truth, expected)
    matched = [r for r in rows if r["start_error_s"] is not None]
    summary = {"protocol": __doc__.split("Protocol: ")[1].strip(), "videos": rows,
               "mean_start_error_s": round(sum(r["start_error_s"] for r in matched) / len(matched), 3),
               "mean_end_error_s": round(sum(r["end_error_s"] for r in matched) / len(matched), 3),
               "false_proposal_s_on_no_dance_clips": round(sum(r["proposed_s"] for r in rows
                                                              if r["expected"].startswith("no dance")), 2)}
    print(json.dumps({k: v for k, v in summary.items() if k not in ("videos", "protocol")}))
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
