"""Benchmark for the 2D stage with the configured models (params.yaml's pose2d section).

Measures, side by side in one run (median of --runs), on a one-dancer clip and on a
five-person clip (two dancers above three seated musicians, built from the shared media):
  (a) the pose2d + track work of the stages: streamed decode, detection, people, pose, tracking,
      on a view of the whole clip at its own size, as the stage works on segment views
  (b) a naive loop: decode a frame, detect, choose people, pose each, single thread, no overlap
  (c) pure model time: the time spent inside ONNX Runtime's ``run`` during (b)
and the peak RSS of the pose2d+track work on a short and a long input (the clip looped;
--short / --long seconds, 10 and 60 by default).

With ``--code DIR`` (repeatable: e.g. a worktree of an older commit, and this one), the stage work
(a) of each code tree with its own params.yaml is timed instead, side by side in one run: each
clip, each run, the trees in turn, each in a fresh process (models loaded and warmed up first,
not timed); the speed of each tree is the first tree's time over its own, and ``real_time`` the
clip's length over its time.

Usage: DANCE3D_MODELS=../shared/models DANCE3D_MEDIA=../shared/media python benchmarks/pose2d.py
       [--pose-model movenet-lightning --detector rtmdet-nano-person] (another configuration)
       [--code /tmp/old_tree --code .] (code trees side by side)
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.core.params import load_params, stage_params  # noqa: E402
from pipeline.ingest.media import ffmpeg_exe, iter_frames, probe  # noqa: E402
from pipeline.ingest.segmentvideo import SegmentVideo  # noqa: E402
from pipeline.pose.models.loading import load_pose_models, worker_files  # noqa: E402
from pipeline.pose.pose2d import Pose2dOptions, collect_poses, estimate_segment, find_people, lift_dark  # noqa: E402
from pipeline.pose.tracking import assign_tracks  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


class TimedSession:
    """An ONNX Runtime session that adds the time of every ``run`` to a shared counter."""

    def __init__(self, session, counter: list[float]) -> None:
        self._session, self._counter = session, counter

    def run(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return self._session.run(*args, **kwargs)
        finally:
            self._counter[0] += time.perf_counter() - t0

    def __getattr__(self, name):
        return getattr(self._session, name)


def _wrap_sessions(obj, counter: list[float], seen: set | None = None) -> None:
    seen = seen if seen is not None else set()
    if id(obj) in seen or not hasattr(obj, "__dict__"):
        return
    seen.add(id(obj))
    for key, value in vars(obj).items():
        if type(value).__name__ == "InferenceSession":
            setattr(obj, key, TimedSession(value, counter))
        elif isinstance(value, list):
            for item in value:
                _wrap_sessions(item, counter, seen)
        else:
            _wrap_sessions(value, counter, seen)


def configured(overrides: dict) -> tuple[dict, Pose2dOptions]:
    params = {**stage_params(load_params(ROOT / "params.yaml"), "pose2d"), **overrides}
    return params, Pose2dOptions.from_params(params)


def load_models(params: dict):
    files = worker_files(ROOT, params)
    return load_pose_models(files)


@functools.lru_cache(maxsize=None)
def whole_view(clip: Path) -> SegmentVideo:
    """The whole clip as one segment view at its own size, probed once (by the untimed warm-up)."""
    return SegmentVideo.whole(clip, probe(clip))


def stage_work(clip: Path, fps: float, models, opts: Pose2dOptions) -> int:
    # As the stage runs: on a segment view, whose decoder skips the frames no keyframe shows.
    poses, frames = collect_poses(estimate_segment(whole_view(clip), fps, models.detector, models.pose, opts))
    assign_tracks(poses.frame, poses.box, poses.keypoints)
    return frames


def naive_loop(clip: Path, models, opts: Pose2dOptions) -> int:
    n = 0
    for frame in iter_frames(clip):
        image = lift_dark(frame.image, opts.dark_mean)
        find_people(image, models.detector.detect(image), models.pose, opts)
        n += 1
    return n


def timed(fn, *args) -> tuple[float, int]:
    t0 = time.perf_counter()
    n = fn(*args)
    return time.perf_counter() - t0, n


def peak_rss_child(clip: Path, fps: float, overrides: dict) -> float:
    """Peak RSS (MiB) of a fresh process doing the pose2d+track work on ``clip``."""
    code = ("import resource,sys,json;from pathlib import Path;sys.path.insert(0,%r);"
            "from benchmarks.pose2d import configured,load_models,stage_work;"
            "p,o=configured(json.loads(%r));stage_work(Path(%r),%r,load_models(p),o);"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)") % (
        str(ROOT), json.dumps(overrides), str(clip), fps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return int(out.strip().splitlines()[-1]) / 1024


def five_people(media: Path, out: Path, seconds: float = 10) -> Path:
    """Two dancers side by side above the raga trio (the composite of the 2D issue)."""
    videos = media / "videos"
    subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-y", "-stream_loop", "-1",
                    "-i", str(videos / "dance_solo_384x496_30fps.mp4"),
                    "-i", str(videos / "musicians_trio_music_raga.mp4"),
                    "-filter_complex", "[0:v]fps=25,scale=355:560,split[a][b];[b]hflip[c];[a][c]hstack[top];"
                    "[1:v]fps=25,scale=-2:280,pad=710:280:(ow-iw)/2:0[bot];[top][bot]vstack,format=yuv420p[v]",
                    "-map", "[v]", "-t", str(seconds), "-c:v", "libx264", "-preset", "ultrafast", str(out)], check=True)
    return out


def measure(clip: Path, models, opts: Pose2dOptions, runs: int) -> dict:
    info = probe(clip)
    counter = [0.0]
    _wrap_sessions(models, counter)
    stage_work(clip, info.fps, models, opts)  # warm up
    a, b, c = [], [], []
    for _ in range(runs):  # interleaved, so machine noise hits all three alike
        a.append(timed(stage_work, clip, info.fps, models, opts)[0])
        counter[0] = 0.0
        b.append(timed(naive_loop, clip, models, opts)[0])
        c.append(counter[0])
    ma, mb, mc = statistics.median(a), statistics.median(b), statistics.median(c)
    return {"clip": f"{clip.name} ({info.width}x{info.height}, {info.frames} frames)",
            "a_stage_fps": round(info.frames / ma, 1), "b_naive_fps": round(info.frames / mb, 1),
            "c_model_only_fps": round(info.frames / mc, 1), "a_over_b_speed": round(mb / ma, 2),
            "a_wall_over_c_model_time": round(ma / mc, 2)}


# The tree's own stage work (its benchmarks/pose2d.py, so its own params.yaml), as peak_rss_child runs it.
TREE_RUN = """
import json, sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from benchmarks.pose2d import configured, load_models, stage_work
params, opts = configured(json.loads(sys.argv[4]))
models = load_models(params)
clip, fps = Path(sys.argv[2]), float(sys.argv[3])
stage_work(clip, fps, models, opts)  # warm up
t0 = time.perf_counter()
frames = stage_work(clip, fps, models, opts)
print(json.dumps({"seconds": time.perf_counter() - t0, "frames": frames}))
"""


def tree_seconds(code: Path, clip: Path, fps: float, overrides: dict) -> tuple[float, int]:
    """The stage work of the code tree ``code`` (its params.yaml) on ``clip``, in a fresh process."""
    out = subprocess.run([sys.executable, "-c", TREE_RUN, str(code), str(clip), str(fps), json.dumps(overrides)],
                         capture_output=True, text=True, check=True).stdout
    result = json.loads(out.strip().splitlines()[-1])
    return result["seconds"], result["frames"]


def compare_trees(codes: list[Path], clips: dict[str, Path], overrides: dict, runs: int) -> dict:
    report = {}
    for name, clip in clips.items():
        info = probe(clip)
        times: dict[int, list[float]] = {i: [] for i in range(len(codes))}
        for _ in range(runs):
            for i, code in enumerate(codes):  # in turn, so machine noise hits every tree alike
                seconds, frames = tree_seconds(code, clip, info.fps, overrides)
                times[i].append(seconds)
        medians = [statistics.median(times[i]) for i in range(len(codes))]
        report[name] = {"clip": f"{clip.name} ({info.width}x{info.height}, {frames} frames at {info.fps:g} fps)",
                        **{str(code): {"seconds": round(m, 2), "fps": round(frames / m, 1),
                                       "real_time": round(frames / info.fps / m, 2),
                                       "speed_over_first": round(medians[0] / m, 2)}
                           for code, m in zip(codes, medians)}}
        print(json.dumps({name: report[name]}), flush=True)
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--detector", default=None)
    parser.add_argument("--pose-model", default=None)
    parser.add_argument("--short", type=float, default=10, help="seconds of the short memory run")
    parser.add_argument("--long", type=float, default=60, help="seconds of the long memory run")
    parser.add_argument("--rss-runs", type=int, default=3, help="memory runs per length (median)")
    parser.add_argument("--code", type=Path, action="append", default=None,
                        help="a code tree whose stage work to time (repeatable: side by side, the first is the base)")
    parser.add_argument("--out", type=Path, default=None, help="also write the report as JSON here")
    args = parser.parse_args()
    overrides = {k: v for k, v in (("detector", args.detector), ("pose_model", args.pose_model)) if v}
    media = Path(os.environ["DANCE3D_MEDIA"])
    one = media / "videos/dance_single_music_musepose.mp4"
    if args.code:
        with tempfile.TemporaryDirectory() as tmp:
            clips = {"one_dancer": one, "five_people": five_people(media, Path(tmp) / "five_people.mp4", seconds=4)}
            report = {"codes": [str(c.resolve()) for c in args.code], "runs": args.runs,
                      "clips": compare_trees([c.resolve() for c in args.code], clips, overrides, args.runs)}
        _save(report, args.out)
        return
    params, opts = configured(overrides)
    report = {"detector": params["detector"], "pose_model": params["pose_model"], "runs": args.runs}
    with tempfile.TemporaryDirectory() as tmp:
        five = five_people(media, Path(tmp) / "five_people.mp4", seconds=4)
        report["one_dancer"] = measure(one, load_models(params), opts, args.runs)
        report["five_people"] = measure(five, load_models(params), opts, args.runs)
        short, long_ = Path(tmp) / "short.mp4", Path(tmp) / "long.mp4"
        for out, seconds in ((short, args.short), (long_, args.long)):
            subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-y", "-stream_loop", "5", "-i", str(one),
                            "-t", str(seconds), "-an", "-c:v", "libx264", "-preset", "ultrafast", str(out)], check=True)
        fps = probe(one).fps
        rss10 = statistics.median(peak_rss_child(short, fps, overrides) for _ in range(args.rss_runs))
        rss60 = statistics.median(peak_rss_child(long_, fps, overrides) for _ in range(args.rss_runs))
    report.update({f"peak_rss_{args.short:g}s_mib": round(rss10, 1), f"peak_rss_{args.long:g}s_mib": round(rss60, 1),
                   "rss_ratio_long_over_short": round(rss60 / rss10, 3)})
    _save(report, args.out)


def _save(report: dict, out: Path | None) -> None:
    print(json.dumps(report, indent=2))
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
