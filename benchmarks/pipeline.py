"""Benchmark for the whole pipeline, download -> shard (issue: corpus scale).

Every stage runs as `dvc repro` runs it (`python -m stages.<name>` in the project folder), in
a fresh temporary project holding a copy of the code under test, on a set of videos:

- ``demo``: the demo sources and segments of the code tree (local copies from DANCE3D_MEDIA);
- ``long``: a long single-dancer video assembled from the shared clips (every dance and
  movement clip fitted into 1280 x 720, twice over, about 94 s) and a 20 s composite of five people (two dancers,
  three seated musicians), each processed whole;
- ``mixed``: the solo dancer with music and the three group-dance clips with music (a duet, a trio,
  a line dance of four to six with bystanders and a panning camera), each processed whole;
- ``groups``: the mixed set without the solo dancer (issue 50's figure for group dance).

Per stage and in total it reports wall time, its share of the whole wall, video-seconds per
wall-second (of the segmented video the stages work on; download counts the downloaded duration), CPU use in cores
(user + system time of the stage and its children / wall), peak memory (resident set of the
stage's whole process tree, sampled every 50 ms) and bytes written per minute of source
video. The footprint line sums everything under data/ except the downloads and the corpus,
against the bytes downloaded. train_lifter is run for the lift stage to have a model (it copies
the shipped lifter; trees older than the shipped lifter train a few steps), but counts in no
total: it does not depend on the videos.

With ``--cold``, each tree also runs the whole pipeline on a 3 s clip (the solo dancer with
music) in every round; a stage's wall there is its fixed cost (process start, imports, model
loading, numba compilation), reported apart, and the rest of its wall per second of video is its
per-second cost. Then every stage of that project is run once more, with nothing new to do: its
wall there (``again s``) is what a stage costs when DVC re-runs it for a change that does not
touch its items (a parameter that is not theirs, `dance3d run`).

Several ``--code`` trees (e.g. a worktree of an older commit) are run alternately in one
invocation, so their ratios are measured side by side on the same machine state; medians of
``--runs``. Their corpora are compared window by window at the end.

Usage:
  DANCE3D_MEDIA=../shared/media DANCE3D_MODELS=../shared/models DANCE3D_MOCAP=../shared/mocap \\
      python benchmarks/pipeline.py --set demo --code . --code /tmp/old --runs 3
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

STAGES = ("discover", "download", "propose_segments", "trim", "pose2d", "track", "clean", "train_lifter",
          "train_contact", "lift", "smooth", "resample", "ground", "audio", "shard")  # those a tree has
NOT_PER_VIDEO = {"train_lifter", "train_contact"}
MIXED_VIDEOS = ("dance_single_music_musepose.mp4", "group_duet_music.mp4", "group_trio_office_music.mp4",
                "group_linedance_crowd_music.mp4")
LONG_PARTS = ("dance_single_music_musepose.mp4", "movement_single_speech_taiji.mp4", "dance_solo_384x496_30fps.mp4")


def ffmpeg(*args: str) -> None:
    from pipeline.ingest.media import ffmpeg_exe

    subprocess.run([ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", *args], check=True)


def long_set(media: Path, out: Path) -> list[tuple[str, Path]]:
    """The long single-dancer video (each clip fitted into 1280 x 720, 30 fps, twice over) and the composite."""
    from benchmarks.pose2d import five_people

    videos = media / "videos"
    inputs: list[str] = []
    for _ in range(2):
        for name in LONG_PARTS:
            inputs += ["-i", str(videos / name)]
    n = len(inputs) // 2
    # The solo clip has no audio track: a silent one keeps the concatenation's streams aligned.
    chains = []
    for i in range(n):
        name = LONG_PARTS[i % len(LONG_PARTS)]
        chains.append(f"[{i}:v]scale=-2:720,pad=1280:720:(ow-iw)/2:0,fps=30,setsar=1,format=yuv420p[v{i}]")
        if name.startswith("dance_solo"):
            chains.append(f"anullsrc=r=44100:cl=stereo,atrim=duration=18.2[a{i}]")
        else:
            chains.append(f"[{i}:a]aresample=44100,aformat=channel_layouts=stereo[a{i}]")
    graph = ";".join(chains) + ";" + "".join(f"[v{i}][a{i}]" for i in range(n)) + f"concat=n={n}:v=1:a=1[v][a]"
    single = out / "long_single_dancer.mp4"
    ffmpeg(*inputs, "-filter_complex", graph, "-map", "[v]", "-map", "[a]", "-c:v", "libx264", "-preset", "veryfast",
           "-crf", "20", "-c:a", "aac", str(single))
    silent = five_people(media, out / "five_people_silent.mp4", seconds=20)
    group = out / "five_people.mp4"  # with the trio's music under it
    ffmpeg("-i", str(silent), "-stream_loop", "-1", "-i", str(videos / "musicians_trio_music_raga.mp4"),
           "-map", "0:v", "-map", "1:a", "-c:v", "copy", "-c:a", "aac", "-shortest", str(group))
    return [("long_single", single), ("five_people", group)]


def tiny_set(media: Path, out: Path) -> list[tuple[str, Path]]:
    """3 s of the solo dancer with music: what every stage costs before any video does."""
    clip = out / "tiny.mp4"
    ffmpeg("-i", str(media / "videos" / MIXED_VIDEOS[0]), "-t", "3", "-c:v", "libx264", "-preset", "veryfast",
           "-c:a", "aac", str(clip))
    return [("tiny", clip)]


def mixed_set(media: Path, groups_only: bool = False) -> list[tuple[str, Path]]:
    """The solo and group dance clips as they are, each one source (only the group clips: ``groups_only``)."""
    return [(Path(name).stem, media / "videos" / name) for name in MIXED_VIDEOS[int(groups_only):]]


def make_project(code: Path, root: Path, which: str, long_videos: list[tuple[str, Path]]) -> Path:
    root.mkdir(parents=True)
    for name in ("pipeline", "stages"):
        shutil.copytree(code / name, root / name, ignore=shutil.ignore_patterns("__pycache__"))
    params = yaml.safe_load((code / "params.yaml").read_text())
    params["download"]["local_copies"] = os.environ.get("DANCE3D_MEDIA", "")
    params["train_lifter"]["steps"] = 20
    params["train_lifter"]["mocap"] = os.environ["DANCE3D_MOCAP"]
    (root / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    (root / "manifests/tracks").mkdir(parents=True)
    (root / "annotations").mkdir()
    if which == "demo":
        shutil.copy(code / "manifests/sources.csv", root / "manifests/sources.csv")
        shutil.copy(code / "annotations/segments.csv", root / "annotations/segments.csv")
    else:
        rows = "".join(f"{vid},{path.as_uri()}\n" for vid, path in long_videos)
        (root / "manifests/sources.csv").write_text("video_id,url\n" + rows)
        (root / "annotations/segments.csv").write_text(
            "video_id,start,end\n" + "".join(f"{vid},0,{duration(path):.3f}\n" for vid, path in long_videos))
    return root


def duration(path: Path) -> float:
    from pipeline.ingest.media import probe

    return probe(path).duration


def tree_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) if path.exists() else 0


def data_sizes(root: Path) -> dict[str, int]:
    data = root / "data"
    return {d.name: tree_bytes(d) for d in sorted(data.iterdir()) if d.is_dir()} if data.exists() else {}


def run_stage(root: Path, stage: str) -> dict:
    """Run one stage in ``root``; wall, CPU, peak memory of its process tree, bytes it wrote."""
    env = {**os.environ, "PYTHONPATH": str(root), "TQDM_DISABLE": "1"}
    before = data_sizes(root)
    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", f"stages.{stage}"], cwd=root, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = [0]

    def sample() -> None:
        try:
            top = psutil.Process(proc.pid)
        except psutil.NoSuchProcess:
            return
        while proc.poll() is None:
            total = 0
            try:
                tree = [top, *top.children(recursive=True)]
            except psutil.Error:  # a child ended while being listed
                continue
            for p in tree:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            peak[0] = max(peak[0], total)
            time.sleep(0.05)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    _, err = proc.communicate()
    wall = time.perf_counter() - t0
    sampler.join()
    usage1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{stage} failed in {root} (exit {proc.returncode}):\n{err[-2000:]}")
    after = data_sizes(root)
    written = sum(max(0, after.get(k, 0) - before.get(k, 0)) for k in after)
    cpu = (usage1.ru_utime - usage0.ru_utime) + (usage1.ru_stime - usage0.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "peak_mib": peak[0] / 2 ** 20, "bytes": written}


def video_seconds(root: Path) -> tuple[float, float, int]:
    """(downloaded seconds, segmented seconds, downloaded bytes) of a finished project."""
    from pipeline.ingest.catalog import read_index, read_ledger

    ledger = read_ledger(root / "data/raw")
    raw = sum(float(r["duration"]) for r in ledger.values() if r["status"] == "ok")
    raw_bytes = sum((root / "data/raw" / r["path"]).stat().st_size for r in ledger.values() if r["status"] == "ok")
    seg = sum(float(r["end"]) - float(r["start"]) for r in read_index(root / "data/segments").values())
    return raw, seg, raw_bytes


def run_pipeline(code: Path, root: Path, which: str, long_videos, again: bool = False) -> dict:
    """The whole pipeline in a new project; with ``again``, every stage once more after it (nothing new to do)."""
    make_project(code, root, which, long_videos)
    stages = {stage: run_stage(root, stage) for stage in STAGES if (code / "stages" / f"{stage}.py").exists()}
    if again:
        for stage in stages:
            stages[stage]["again_s"] = run_stage(root, stage)["wall_s"]
    raw_s, seg_s, raw_bytes = video_seconds(root)
    sizes = data_sizes(root)
    intermediate = sum(v for k, v in sizes.items() if k not in ("raw", "corpus"))
    return {"stages": stages, "raw_seconds": raw_s, "segment_seconds": seg_s, "raw_bytes": raw_bytes,
            "intermediate_bytes": intermediate, "sizes": sizes}


def summarise(runs: list[dict], cold: list[dict] = ()) -> dict:
    first = runs[0]
    minutes = first["raw_seconds"] / 60
    out = {"raw_seconds": round(first["raw_seconds"], 2), "segment_seconds": round(first["segment_seconds"], 2),
           "stages": {}}
    for stage in first["stages"]:
        wall = statistics.median(r["stages"][stage]["wall_s"] for r in runs)
        cpu = statistics.median(r["stages"][stage]["cpu_s"] for r in runs)
        seconds = first["raw_seconds"] if stage == "download" else first["segment_seconds"]
        out["stages"][stage] = {
            "wall_s": round(wall, 2), "video_s_per_wall_s": round(seconds / wall, 2) if wall else None,
            "cpu_cores": round(cpu / wall, 2) if wall else None,
            "peak_mib": round(statistics.median(r["stages"][stage]["peak_mib"] for r in runs), 1),
            "mb_written_per_source_minute": round(first["stages"][stage]["bytes"] / 2 ** 20 / minutes, 2)}
        if cold and all(stage in c["stages"] for c in cold):
            fixed = statistics.median(c["stages"][stage]["wall_s"] for c in cold)
            out["stages"][stage]["cold_s"] = round(fixed, 2)
            out["stages"][stage]["again_s"] = round(statistics.median(c["stages"][stage]["again_s"] for c in cold), 2)
            out["stages"][stage]["wall_s_per_video_s"] = round(max(0.0, wall - fixed) / seconds, 4)
    total = [sum(r["stages"][s]["wall_s"] for s in r["stages"] if s not in NOT_PER_VIDEO) for r in runs]
    out["total"] = {"wall_s": round(statistics.median(total), 2),
                    "segment_s_per_wall_s": round(first["segment_seconds"] / statistics.median(total), 3),
                    "peak_mib": round(max(out["stages"][s]["peak_mib"] for s in out["stages"]), 1)}
    for stage, row in out["stages"].items():
        row["share"] = round(row["wall_s"] / out["total"]["wall_s"], 3) if stage not in NOT_PER_VIDEO else None
    out["footprint"] = {"downloaded_mib": round(first["raw_bytes"] / 2 ** 20, 2),
                        "intermediate_mib": round(first["intermediate_bytes"] / 2 ** 20, 2),
                        "intermediate_over_downloads": round(first["intermediate_bytes"] / first["raw_bytes"], 3),
                        "by_folder_mib": {k: round(v / 2 ** 20, 2) for k, v in first["sizes"].items()}}
    return out


def read_corpus(root: Path) -> dict[str, dict]:
    """Window id -> its row (nested lists as Python lists)."""
    import pyarrow.parquet as pq

    rows = {}
    for f in sorted((root / "data/corpus").glob("*/shard-*.parquet")):
        for row in pq.read_table(f).to_pylist():
            rows[row["window_id"]] = row
    return rows


def compare_corpora(a: Path, b: Path) -> dict:
    """Window by window: which windows both have, and how far their motion and features differ."""
    ca, cb = read_corpus(a), read_corpus(b)
    common = sorted(set(ca) & set(cb))
    out = {"windows": [len(ca), len(cb)], "common": len(common)}
    for column, scale, unit in (("motion", 1000.0, "mm"), ("mfcc", 1.0, ""), ("onset", 1.0, ""), ("beat", 1.0, "")):
        if not common:
            break
        xa = np.array([ca[w][column] for w in common], dtype=float)
        xb = np.array([cb[w][column] for w in common], dtype=float)
        diff = np.abs(xa - xb) * scale
        if column == "motion":  # per joint: Euclidean distance
            diff = np.linalg.norm((xa - xb) * scale, axis=-1)
        out[column] = {"mean_abs": round(float(diff.mean()), 4), "p99_abs": round(float(np.quantile(diff, 0.99)), 4),
                       "max_abs": round(float(diff.max()), 4), "unit": unit}
    return out


def table(name: str, summary: dict) -> str:
    lines = [f"{name}: {summary['segment_seconds']} s of segments from {summary['raw_seconds']} s downloaded",
             "| stage | wall s | share | cold s | again s | wall s per video s | video s / wall s | CPU cores | "
             "peak MiB | MB written / source min |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for stage, s in summary["stages"].items():
        mark = " (not per video)" if stage in NOT_PER_VIDEO else ""
        share = f"{100 * s['share']:.1f} %" if s.get("share") is not None else ""
        lines.append(f"| {stage}{mark} | {s['wall_s']} | {share} | {s.get('cold_s', '')} | {s.get('again_s', '')} | "
                     f"{s.get('wall_s_per_video_s', '')} | {s['video_s_per_wall_s']} | {s['cpu_cores']} | "
                     f"{s['peak_mib']} | {s['mb_written_per_source_minute']} |")
    t, f = summary["total"], summary["footprint"]
    lines.append(f"| **download → shard** | {t['wall_s']} | | | | | {t['segment_s_per_wall_s']} | | "
                 f"{t['peak_mib']} | |")
    lines.append(f"intermediates {f['intermediate_mib']} MiB = {f['intermediate_over_downloads']}x the downloads "
                 f"({f['downloaded_mib']} MiB): {f['by_folder_mib']}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--set", choices=("demo", "long", "mixed", "groups"), default="demo",
                        help="which videos (see above)")
    parser.add_argument("--code", type=Path, action="append",
                        help="a code tree to run (repeatable; default: this checkout)")
    parser.add_argument("--runs", type=int, default=1, help="runs per code tree (medians are reported)")
    parser.add_argument("--json", type=Path, help="also write the results here")
    parser.add_argument("--cold", action="store_true",
                        help="also run each tree on a 3 s clip every round: the stages' fixed costs, apart, and "
                             "each stage once more with nothing new to do")
    parser.add_argument("--keep", type=Path, help="keep the projects in this folder (default: a temporary one)")
    args = parser.parse_args()
    for var in ("DANCE3D_MEDIA", "DANCE3D_MODELS", "DANCE3D_MOCAP"):
        if not os.environ.get(var):
            raise SystemExit(f"set {var} (see the usage in --help)")
    codes = [c.resolve() for c in (args.code or [Path(__file__).resolve().parents[1]])]
    work = Path(args.keep or tempfile.mkdtemp(prefix="dance3d-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    media = Path(os.environ["DANCE3D_MEDIA"])
    long_videos = {"long": lambda: long_set(media, work), "mixed": lambda: mixed_set(media),
                   "groups": lambda: mixed_set(media, groups_only=True)}.get(args.set, list)()
    tiny = tiny_set(media, work) if args.cold else []
    runs: dict[int, list[dict]] = {i: [] for i in range(len(codes))}
    colds: dict[int, list[dict]] = {i: [] for i in range(len(codes))}
    last_root: dict[int, Path] = {}
    for r in range(args.runs):
        for i, code in enumerate(codes):  # alternate the trees so both see the same machine state
            root = work / f"code{i}-run{r}"
            runs[i].append(run_pipeline(code, root, args.set, long_videos))
            if tiny:
                colds[i].append(run_pipeline(code, work / f"code{i}-cold{r}", "tiny", tiny, again=True))
                if not args.keep:
                    shutil.rmtree(work / f"code{i}-cold{r}", ignore_errors=True)
            if i in last_root and not args.keep:
                shutil.rmtree(last_root[i], ignore_errors=True)
            last_root[i] = root
    results = {"set": args.set, "runs": args.runs, "codes": [str(c) for c in codes],
               "summaries": [summarise(runs[i], colds[i]) for i in range(len(codes))], "raw_runs": runs}
    for code, summary in zip(codes, results["summaries"]):
        print(table(str(code), summary), end="\n\n", flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    if len(codes) > 1:
        results["corpus_vs_first"] = [compare_corpora(last_root[0], last_root[i]) for i in range(1, len(codes))]
        print(json.dumps(results["corpus_vs_first"], indent=2))
        if args.json:
            args.json.write_text(json.dumps(results, indent=2))
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
