"""Benchmark for incremental re-runs and the Ray executor (issue: scale-out).

(1) Incremental: process two videos through download .. clean and audio, add a third, re-run
    everything: the re-run's wall time against processing the third video alone (fresh project).
(2) Executor: the same stages on the demo videos with `executor: ray` (local Ray, 2 CPUs)
    against `executor: local`, each in a fresh project.
Medians of --runs; everything side by side in one run.

Usage: DANCE3D_MEDIA=../shared/media DANCE3D_MODELS=../shared/models python benchmarks/incremental.py
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PROJECT = Path(__file__).resolve().parents[1]
STAGES = ("download", "trim", "pose2d", "track", "clean", "audio")
VIDEOS = {"solo": "dance_solo_384x496_30fps.mp4", "taiji": "movement_single_speech_taiji.mp4",
          "dance": "dance_single_music_musepose.mp4"}
SEGMENTS = {"solo": "solo,0,9", "taiji": "taiji,0.5,12", "dance": "dance,0,12"}


def make(root: Path, videos: list[str], **common) -> Path:
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    params = yaml.safe_load((PROJECT / "params.yaml").read_text())
    params["common"].update(common)
    (root / "params.yaml").write_text(yaml.safe_dump(params))
    write(root, videos)
    return root


def write(root: Path, videos: list[str]) -> None:
    media = Path(os.environ["DANCE3D_MEDIA"]) / "videos"
    rows = "".join(f"{v},{media / VIDEOS[v]}\n" for v in videos)
    (root / "manifests/sources.csv").write_text("video_id,url\n" + rows)
    (root / "annotations/segments.csv").write_text("video_id,start,end\n" + "".join(f"{SEGMENTS[v]}\n" for v in videos))


def run_all(root: Path) -> float:
    import importlib

    t0 = time.perf_counter()
    for stage in STAGES:
        importlib.import_module(f"stages.{stage}").run(root)
    return time.perf_counter() - t0


def main() -> None:
    import logging

    logging.disable(logging.INFO)
    os.environ.setdefault("TQDM_DISABLE", "1")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    rerun, alone, local, ray_times = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            base = Path(tmp) / f"inc{i}"
            grown = make(base, ["solo", "taiji"])
            run_all(grown)
            write(grown, ["solo", "taiji", "dance"])
            rerun.append(run_all(grown))
            alone.append(run_all(make(Path(tmp) / f"alone{i}", ["dance"])))
            local.append(run_all(make(Path(tmp) / f"local{i}", list(VIDEOS), executor="local", workers=2)))
            ray_times.append(run_all(make(Path(tmp) / f"ray{i}", list(VIDEOS), executor="ray", workers=2,
                                          ray={"address": "", "num_cpus": 2})))
            shutil.rmtree(base, ignore_errors=True)
    import ray

    ray.shutdown()
    report = {
        "runs": args.runs, "stages": list(STAGES),
        "rerun_after_adding_one_video_s": round(statistics.median(rerun), 2),
        "that_video_alone_s": round(statistics.median(alone), 2),
        "incremental_ratio": round(statistics.median(rerun) / statistics.median(alone), 3),
        "local_executor_s": round(statistics.median(local), 2),
        "ray_executor_s": round(statistics.median(ray_times), 2),
        "ray_over_local": round(statistics.median(ray_times) / statistics.median(local), 3),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
