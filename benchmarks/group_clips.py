"""The shared group-dance clips through the whole pipeline: the duet, the trio and the line dance
(MEDIA.md's last section, third-party footage: measurements only), each one segment, in a
scratch project; then what a user looks at: the proposed manifests (who is kept and why), each
segment's scene (dancers, scales, tilt), `dance3d eval sync` per pair, a group render per segment
and the group windows of the corpus.

Usage: python -m benchmarks.group_clips [--media DIR] [--out DIR]   (about 8 minutes on 2 cores)

Every stage runs as `dvc repro` runs it (`python -m stages.<name>` in the project folder).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

CLIPS = (("trio", "group_trio_office_music.mp4", 8.9), ("duet", "group_duet_music.mp4", 15.0),
         ("line", "group_linedance_crowd_music.mp4", 42.0))
STAGES = ("download", "trim", "pose2d", "track", "clean", "train_lifter", "train_contact", "lift", "smooth",
          "resample", "ground", "audio", "shard")
CODE = Path(__file__).resolve().parents[1]


def make_project(out: Path, media: Path) -> Path:
    """A scratch dance3d project: this checkout's code and params, the group clips as sources."""
    shutil.rmtree(out, ignore_errors=True)
    (out / "manifests").mkdir(parents=True)
    (out / "annotations").mkdir()
    for name in ("pipeline", "stages"):
        shutil.copytree(CODE / name, out / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(CODE / "params.yaml", out / "params.yaml")
    (out / "manifests/sources.csv").write_text(
        "video_id,url\n" + "".join(f"{vid},file://{(media / 'videos' / name).resolve()}\n" for vid, name, _ in CLIPS))
    (out / "annotations/segments.csv").write_text(
        "video_id,start,end,label,note\n" + "".join(f"{vid},0.0,{end},dance,whole clip\n" for vid, _, end in CLIPS))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--media", type=Path, default=Path(os.environ.get("DANCE3D_MEDIA", "../shared/media")))
    parser.add_argument("--out", type=Path, default=Path("/tmp/dance3d_group_clips"))
    args = parser.parse_args()
    root = make_project(args.out, args.media)
    for stage in STAGES:
        started = time.monotonic()
        subprocess.run([sys.executable, "-m", f"stages.{stage}"], cwd=root, check=True,
                       env={**os.environ, "TQDM_DISABLE": "1"})
        print(f"{stage}: {time.monotonic() - started:.1f} s", flush=True)
    dance3d = [sys.executable, "-m", "pipeline.cli", "--root", str(root)]
    subprocess.run([*dance3d, "manifests", "seed"], cwd=root, check=True)
    for vid, _, _ in CLIPS:
        segment = f"{vid}_000"
        print(f"\n== {segment}: proposed manifest")
        print("".join(line for line in (root / "manifests/tracks" / f"{segment}.csv").read_text().splitlines(True)
                      if not line.startswith("#")))
        from pipeline.core.storage import read_meta
        from pipeline.motion.world.worldfile import read_world

        world = root / "data/world" / f"{segment}.parquet"
        print("scene:", json.dumps(read_meta(world)["scene"]))
        for clip in read_world(world):
            x, _, z = clip.joints[:, 0].mean(0)
            print(f"  {clip.clip_id}: {len(clip.frame) / 24:.1f} s, scale {clip.facts['scene_scale']:.3f}, "
                  f"stands at x {x:+.2f} m, z {z:+.2f} m")
        subprocess.run([*dance3d, "eval", "sync", str(world)], cwd=root, check=True)
        subprocess.run([*dance3d, "render", "--group", segment, str(root / f"{segment}_scene.mp4")], cwd=root,
                       check=True)
    metrics = json.loads((root / "metrics/corpus.json").read_text())
    print("\ngroup windows:", json.dumps(metrics.get("group_windows")))


if __name__ == "__main__":
    main()
