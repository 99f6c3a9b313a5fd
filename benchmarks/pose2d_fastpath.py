"""The 2D fast path on video: the models on keyframes only (``pose2d.fps``, the frames between
interpolated) and the detector on every k-th posed frame (``pose2d.det_every``, boxes carried by
the keypoints in between), against the models and the detector on every frame (issue: real-time 2D).

For each clip and each configuration, side by side in one run (configurations alternate, medians
of --runs for the time), the pose2d + track work of the stage is run and compared with the
reference (``fps: 0, det_every: 1``, the rest of params.yaml's pose2d section):

- ``fps``: frames per wall-second, and ``speed``: the reference's time over this one;
- ``posed``: the share of people (rows) the models posed (on keyframes, and the people who came or
  went between two keyframes whose people differ: ``pose_changes``, ``changes_only``);
  ``detected``: the share of frames with a box from the detector (every k-th posed frame, on
  demand, and newcomers found between keyframes);
- ``people``: people found per frame (the reference's beside it);
- ``oks``: mean OKS of each of the reference's people against the configuration's person matched
  to it in that frame (Hungarian on OKS; a reference person with no match counts 0). OKS as COCO
  defines it (its 17 sigmas), with the reference's keypoints of score >= 0.3 as the truth and its
  box area x 0.53 as the object's area (the usual stand-in for a segmented area);
- ``feet``: the heels' and toes' distance from the reference's (its points of score >= 0.3),
  in shares of the reference's box height, mean and 90th percentile over the matched people;
- ``id_switches``: after tracking both, how often the configuration's track matched to one of the
  reference's tracks changes to another (frames without a match are skipped).

The clips: the one-dancer MusePose clip, the five-person composite (benchmarks/pose2d.py), and the
shared group clips (the trio, the duet, the first --linedance seconds of the line dance, which
pans). Images are not affected: a single image is always a detected frame.

Usage: DANCE3D_MODELS=../shared/models DANCE3D_MEDIA=../shared/media \\
       python -m benchmarks.pose2d_fastpath [--config fps=12,det_every=5 --config det_every=5 ...]
       [--runs 1] [--out r.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from benchmarks.pose2d import configured, five_people, load_models
from pipeline.ingest.media import ffmpeg_exe, probe
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.pose.pose2d import collect_poses, estimate_segment
from pipeline.pose.pose2dfile import COCO_SIGMAS
from pipeline.pose.tracking import assign_tracks

VISIBLE = 0.3
REFERENCE = "fps=0,det_every=1"  # the models pose every frame, the detector runs on every frame
DEFAULT = "params.yaml"  # the configuration as params.yaml has it
DEFAULT_CONFIGS = [DEFAULT, "fps=8,changes_only=1", "fps=8,pose_changes=0", "fps=12"]


def oks(truth: np.ndarray, area: float, other: np.ndarray) -> float:
    """COCO's OKS of ``other`` (17 x 3) against ``truth`` (17 x 3; its joints of score >= 0.3)."""
    seen = truth[:, 2] >= VISIBLE
    if not seen.any():
        return float("nan")
    d2 = ((truth[:, :2] - other[:, :2]) ** 2).sum(-1)
    e = d2 / (2 * COCO_SIGMAS) ** 2 / max(area, 1.0) / 2
    return float(np.exp(-e[seen]).mean())


def overrides(config: str) -> dict:
    """``det_every=5,redetect_joints=0`` -> {"det_every": 5, "redetect_joints": 0}."""
    pairs = (item.split("=", 1) for item in config.split(",") if item)
    return {key.strip(): float(value) if "." in value else int(value) for key, value in pairs}


def run(clip: Path, models, opts) -> tuple[float, dict]:
    info = probe(clip)
    fps, view = info.fps, SegmentVideo.whole(clip, info)  # as the stage runs: on a segment view
    detected = [0, 0, 0, 0]  # frames with a detected box, frames seen, people posed, people seen

    def counted(frames):
        for frame in frames:
            people = len(frame.scores)
            detected[0] += bool(np.any(frame.detected))
            detected[1] += 1
            detected[2] += int(np.sum(~np.broadcast_to(np.asarray(frame.interpolated, bool), (people,))))
            detected[3] += people
            yield frame

    start = time.perf_counter()
    poses, frames = collect_poses(counted(estimate_segment(view, fps, models.detector, models.pose, opts)))
    tracks = assign_tracks(poses.frame, poses.box, poses.keypoints)
    return time.perf_counter() - start, {"frame": poses.frame, "box": poses.box, "kp": poses.keypoints,
                                         "feet": poses.feet,
                                         "track": tracks, "frames": frames,
                                         "detected": detected[0] / max(detected[1], 1),
                                         "posed": detected[2] / max(detected[3], 1)}


def compare(ref: dict, run_: dict) -> dict:
    """Mean OKS, feet error, people per frame and id switches of ``run_`` against ``ref``."""
    scores, pairs, feet = [], [], []
    for f in range(ref["frames"]):
        a, b = np.flatnonzero(ref["frame"] == f), np.flatnonzero(run_["frame"] == f)
        if not len(a):
            continue
        table = np.zeros((len(a), len(b)))
        for i, ia in enumerate(a):
            box = ref["box"][ia]
            area = 0.53 * float((box[2] - box[0]) * (box[3] - box[1]))
            for j, jb in enumerate(b):
                table[i, j] = np.nan_to_num(oks(ref["kp"][ia], area, run_["kp"][jb]))
        got = np.zeros(len(a))
        if len(b):
            rows, cols = linear_sum_assignment(-table)
            got[rows] = table[rows, cols]
            pairs += [(ref["track"][a[r]], run_["track"][b[c]]) for r, c in zip(rows, cols) if table[r, c] > 0.5]
            for r, c in zip(rows, cols):
                truth, height = ref["feet"][a[r]], float(ref["box"][a[r]][3] - ref["box"][a[r]][1])
                seen = truth[:, 2] >= VISIBLE
                if table[r, c] > 0.5 and seen.any():
                    miss = np.linalg.norm(truth[seen, :2] - run_["feet"][b[c]][seen, :2], axis=1)
                    feet += list(miss / max(height, 1.0))
        scores += [s for s, ia in zip(got, a) if (ref["kp"][ia][:, 2] >= VISIBLE).any()]
    switches = 0
    for track in {t for t, _ in pairs if t >= 0}:
        seen = [o for t, o in pairs if t == track and o >= 0]
        switches += sum(1 for x, y in zip(seen, seen[1:]) if x != y)
    return {"oks": round(float(np.mean(scores)), 4) if scores else float("nan"),
            "feet": [round(float(np.mean(feet)), 4), round(float(np.quantile(feet, 0.9)), 4)] if feet else None,
            "people": round(len(run_["frame"]) / max(run_["frames"], 1), 3),
            "people_reference": round(len(ref["frame"]) / max(ref["frames"], 1), 3),
            "id_switches": switches}


def clips(media: Path, tmp: Path, linedance: float) -> list[Path]:
    videos = media / "videos"
    line = tmp / "group_linedance_first.mp4"
    subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-y", "-i", str(videos / "group_linedance_crowd_music.mp4"),
                    "-t", str(linedance), "-an", "-c:v", "libx264", "-preset", "ultrafast", "-crf", "12", str(line)],
                   check=True)
    return [videos / "dance_single_music_musepose.mp4", five_people(media, tmp / "five_people.mp4", seconds=4),
            videos / "group_trio_office_music.mp4", videos / "group_duet_music.mp4", line]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", action="append", default=None,
                        help=f"pose2d overrides, key=value[,key=value], or {DEFAULT} (default: "
                             + ", ".join(DEFAULT_CONFIGS) + f"); the reference is {REFERENCE}")
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--linedance", type=float, default=12.0, help="seconds of the line dance")
    parser.add_argument("--clip", default="", help="only the clips whose file name contains this")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    names = [REFERENCE] + [c for c in (args.config or DEFAULT_CONFIGS) if c != REFERENCE]
    configs = {name: configured({**overrides(REFERENCE), **overrides(name)} if name != DEFAULT else {})
               for name in names}
    ref = names[0]
    models = load_models(configs[ref][0])
    report: dict = {"params": configs[ref][0], "clips": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for clip in clips(Path(os.environ["DANCE3D_MEDIA"]), Path(tmp), args.linedance):
            if args.clip not in clip.name:
                continue
            times: dict[str, list[float]] = {k: [] for k in names}
            results: dict[str, dict] = {}
            run(clip, models, configs[ref][1])  # warm up
            for _ in range(args.runs):
                for k in names:
                    seconds, results[k] = run(clip, models, configs[k][1])
                    times[k].append(seconds)
            ref_time = statistics.median(times[ref])
            info = probe(clip)
            rows = {}
            for k in names:
                t = statistics.median(times[k])
                rows[k] = {"fps": round(results[k]["frames"] / t, 1), "speed": round(ref_time / t, 2),
                           "real_time": round(results[k]["frames"] / t / info.fps, 2),
                           "detected": round(results[k]["detected"], 3), "posed": round(results[k]["posed"], 3),
                           **compare(results[ref], results[k])}
            report["clips"][f"{clip.name} ({info.width}x{info.height}, {results[ref]['frames']} frames)"] = rows
            print(json.dumps({clip.name: rows}), flush=True)
    text = json.dumps(report, indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
