"""Benchmark for the 2D stage (issue: 2D pose).

Measures, side by side in one run on the shared dance clip (median of --runs):
  (a) the pose2d + track work of the stages: streamed decode, detection, pose, tracking
  (b) a naive loop: decode a frame, detect, one pose call per crop, single thread, no overlap
  (c) pure model time: the same ONNX calls on inputs decoded and preprocessed beforehand
and the peak RSS of the pose2d+track work on a 10 s and a 60 s input (the clip looped).

Usage: DANCE3D_MODELS=../shared/models DANCE3D_MEDIA=../shared/media python benchmarks/pose2d.py
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.ingest.media import ffmpeg_exe, iter_frames, probe  # noqa: E402
from pipeline.pose.models.detector import RTMDetDetector, largest  # noqa: E402
from pipeline.pose.models.pose import MoveNetPose, crop_transform, warp  # noqa: E402
from pipeline.pose.models.session import create_session  # noqa: E402
from pipeline.pose.pose2d import Pose2dOptions, collect_poses, estimate_segment  # noqa: E402
from pipeline.pose.tracking import assign_tracks  # noqa: E402


def load_models(models: Path):
    det = RTMDetDetector(create_session(models / "rtmdet_nano_person_end2end.onnx", 1))
    pose = MoveNetPose(create_session(models / "movenet_singlepose_lightning_4_dequant.onnx", 1))
    return det, pose


def stage_work(clip: Path, fps: float, det, pose) -> int:
    poses, frames = collect_poses(estimate_segment(clip, fps, det, pose, Pose2dOptions()))
    assign_tracks(poses.frame, poses.box, poses.keypoints)
    return frames


def naive_loop(clip: Path, det, pose) -> int:
    n = 0
    for frame in iter_frames(clip):
        dets = largest(det.detect(frame.image), 5)
        for box in dets.boxes:
            pose.estimate(frame.image, box[None])
        n += 1
    return n


def predecode(clip: Path, det, pose) -> list:
    inputs = []
    for frame in iter_frames(clip):
        box = det.preprocess(frame.image)
        dets = largest(det.infer(box), 5)
        crops = []
        for b in dets.boxes:
            m = crop_transform(b, 192, 192, 1.25)
            crops.append(np.ascontiguousarray(warp(frame.image, m, 192, 192)[:, :, ::-1])[None])
        inputs.append((box.tensor, crops))
    return inputs


def model_only(inputs: list, det, pose) -> int:
    for tensor, crops in inputs:
        det.session.run([det.output_name], {det.input_name: tensor})
        for crop in crops:
            pose.session.run(None, {pose.input_name: crop})
    return len(inputs)


def timed(fn, *args) -> tuple[float, int]:
    t0 = time.perf_counter()
    n = fn(*args)
    return time.perf_counter() - t0, n


def peak_rss_child(clip: Path, fps: float, models: Path) -> float:
    """Peak RSS (MiB) of a fresh process doing the pose2d+track work on ``clip``."""
    code = ("import resource,sys;from pathlib import Path;sys.path.insert(0,%r);"
            "from benchmarks.pose2d import load_models,stage_work;"
            "d,p=load_models(Path(%r));stage_work(Path(%r),%r,d,p);"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)") % (
        str(Path(__file__).resolve().parents[1]), str(models), str(clip), fps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return int(out.strip().splitlines()[-1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    models = Path(os.environ["DANCE3D_MODELS"])
    clip = Path(os.environ["DANCE3D_MEDIA"]) / "videos/dance_single_music_musepose.mp4"
    info = probe(clip)
    det, pose = load_models(models)
    inputs = predecode(clip, det, pose)
    stage_work(clip, info.fps, det, pose)  # warm up
    a, b, c = [], [], []
    for _ in range(args.runs):  # interleaved, so machine noise hits all three alike
        a.append(timed(stage_work, clip, info.fps, det, pose)[0])
        b.append(timed(naive_loop, clip, det, pose)[0])
        c.append(timed(model_only, inputs, det, pose)[0])
    frames = info.frames
    ma, mb, mc = statistics.median(a), statistics.median(b), statistics.median(c)
    with tempfile.TemporaryDirectory() as tmp:
        short, long_ = Path(tmp) / "10s.mp4", Path(tmp) / "60s.mp4"
        for out, seconds in ((short, 10), (long_, 60)):
            subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-y", "-stream_loop", "5", "-i", str(clip),
                            "-t", str(seconds), "-an", "-c:v", "libx264", "-preset", "ultrafast", str(out)], check=True)
        rss10 = statistics.median(peak_rss_child(short, info.fps, models) for _ in range(3))
        rss60 = statistics.median(peak_rss_child(long_, info.fps, models) for _ in range(3))
    report = {
        "clip": f"{clip.name} ({info.width}x{info.height}, {frames} frames)",
        "runs": args.runs,
        "a_stage_fps": round(frames / ma, 1),
        "b_naive_fps": round(frames / mb, 1),
        "c_model_only_fps": round(frames / mc, 1),
        "a_over_b_speed": round(mb / ma, 2),
        "a_wall_over_c_wall": round(ma / mc, 2),
        "peak_rss_10s_mib": round(rss10, 1),
        "peak_rss_60s_mib": round(rss60, 1),
        "rss_ratio_60s_over_10s": round(rss60 / rss10, 3),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
