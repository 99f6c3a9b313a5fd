"""Adapting the shipped lifter to dance video (issue: 3D at the field's level, item 3): VideoPose3D's
semi-supervised recipe (``pipeline.motion.lifting.adapt``) against a supervised control.

Both start from the shipped lifter and fine-tune for the same steps on the shipped recipe's capture
(the ``full`` profile's sources, weights, held-out set and augmentation) at the same learning rate:
the control on the capture alone, the adapted one also on the 2D of real clips (reprojection and
bone-length prior), so the difference between them is the video's. Scored on:

- the held-out protocol (the 40 sequences, clean and noisy 2D): must not get worse;
- real clips, held out by video (``--hold-out``: video id prefixes never adapted on) and adapted on:
  per clip, the reprojection error of the lifted 3D (body sizes, the median frame), the variation of
  its bone lengths over the clip (coefficient of variation, the median bone) and its jitter (the
  joints' median acceleration, m/s^2, at the clip's rate).

Each model is written as an ONNX to ``--out-models``. With ``--project`` (a finished project, e.g. one
kept by ``benchmarks/pipeline.py --set mixed --keep DIR``), each model, the shipped one too, is put
in a copy of it as ``models/lifter.onnx``, lift, smooth, resample and ground run again, and
``dance3d eval sync`` scores ``--sync`` (a segment of dancers in sync) beside ``reports/smooth.json``.

Usage: DANCE3D_MOCAP=../shared/mocap python -m benchmarks.lifter_adapt --clean data/clean \\
           --clean /tmp/mixed/data/clean --hold-out group_trio [--steps 800] \\
           [--project /tmp/mixed --sync group_trio_office_music_000]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.storage import item_files, write_json
from pipeline.motion.lifting.adapt import AdaptConfig, VideoSampler, adapt_lifter, video_clips, video_reprojection
from pipeline.motion.lifting.convert import model_from_onnx
from pipeline.motion.lifting.data import PairSampler
from pipeline.motion.lifting.evaluate import split
from pipeline.motion.mocap.skeleton import bone_lengths
from pipeline.motion.shipped import SHIPPED_LIFTER
from stages.train_lifter import config_from_params


def clip_figures(model, clips) -> dict[str, dict]:
    """Per clip: reprojection (body sizes), bone-length variation (CV of the median bone), jitter (m/s^2)."""
    from functools import partial

    from pipeline.motion.lifting.infer import Lifter

    lifter = Lifter.from_torch(model, "centred")
    lift = partial(lifter.lift, width=1, height=1, flip=True)  # centred input: the frame size is not used
    reprojection = video_reprojection(model, clips)
    out = {}
    for clip in clips:
        pose = lift([clip.xy])[0][:, :17]
        bones = bone_lengths(pose)
        acceleration = np.linalg.norm(np.diff(pose, 2, axis=0), axis=-1) * clip.fps ** 2
        out[clip.name] = {"reprojection": round(reprojection[clip.name], 4),
                          "bone_cv": round(float(np.median(bones.std(0) / bones.mean(0))), 4),
                          "jitter_m_s2": round(float(np.median(acceleration)), 2), "frames": len(clip.xy)}
    return out


def in_pipeline(project: Path, lifter: Path, sync: str, work: Path) -> dict:
    """``lifter`` as the lifter of a copy of ``project``: the motion stages again, eval sync and smooth's report."""
    import shutil
    import subprocess
    import sys

    work.mkdir(parents=True, exist_ok=True)
    copy = Path(tempfile.mkdtemp(prefix="adapt-", dir=work))
    for name in ("pipeline", "stages", "params.yaml", "models", "data/clean"):
        (shutil.copytree if (project / name).is_dir() else shutil.copy)(project / name, copy / name)
    for name in ("metrics", "reports"):
        (copy / name).mkdir()
    shutil.copy(lifter, copy / "models/lifter.onnx")
    for stage in ("lift", "smooth", "resample", "ground"):
        subprocess.run([sys.executable, "-m", f"stages.{stage}"], cwd=copy, check=True, capture_output=True)
    subprocess.run([sys.executable, "-m", "pipeline.cli", "eval", "sync", f"data/world/{sync}.parquet", "--out",
                    "sync.json"], cwd=copy, check=True, capture_output=True)
    out = {"eval_sync": [p["ratio"] for p in json.loads((copy / "sync.json").read_text())["pairs"]],
           "smooth_report": json.loads((copy / "reports/smooth.json").read_text())}
    shutil.rmtree(copy)
    return out


def summary(figures: dict[str, dict], held_out: tuple[str, ...]) -> dict:
    """Frame-weighted means over the held-out videos' clips and the adapted-on ones."""
    out = {}
    for group, keep in (("held_out_videos", True), ("adapted_on_videos", False)):
        rows = [v for k, v in figures.items() if k.startswith(held_out) == keep]
        if rows:
            w = np.array([r["frames"] for r in rows], float)
            out[group] = {key: round(float(np.average([r[key] for r in rows], weights=w)), 4)
                          for key in ("reprojection", "bone_cv", "jitter_m_s2")} | {"clips": len(rows)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clean", type=Path, action="append", required=True,
                        help="a folder of clean files (data/clean) whose 2D to adapt on (repeatable)")
    parser.add_argument("--hold-out", action="append", default=[],
                        help="segment id prefix never adapted on, only scored (repeatable)")
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument("--variant", action="append", default=[],
                        help="NAME:REPROJECTION:BONE[:VELOCITY] weights of a run to make (repeatable; default "
                             "supervised:0:0 and adapted:1:1); runs already in --out are kept")
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/lifter_adapt.json"))
    parser.add_argument("--project", type=Path, help="a finished project to run each model's motion stages in")
    parser.add_argument("--sync", default="group_trio_office_music_000", help="the segment eval sync scores")
    parser.add_argument("--out-models", type=Path, default=Path.home() / ".cache/dance3d/adapt")
    args = parser.parse_args()

    from pipeline.motion.lifting import train as training

    section = stage_params(load_params("params.yaml"), "train_lifter")
    cfg = config_from_params(with_profile({**section, "profile": "full"}, "train_lifter"))
    train, val = split(training.load_mocap(args.mocap, cfg), cfg.holdout)
    files = [f for folder in args.clean for f in item_files(folder)]
    held_out = tuple(args.hold_out)
    clips = video_clips(files)
    adapt_on = [c for c in clips if not c.name.startswith(held_out)]
    print(f"{len(clips)} clips ({sum(len(c.xy) for c in clips)} frames), adapting on {len(adapt_on)} "
          f"({sum(len(c.xy) for c in adapt_on)} frames); {len(train)} capture sequences", flush=True)

    start = model_from_onnx(SHIPPED_LIFTER)
    results = {"protocol": __doc__.split("\n\n")[1], "steps": args.steps, "held_out_prefixes": list(held_out),
               "clips": {c.name: len(c.xy) for c in clips}, "models": {}}
    if args.out.exists():
        results["models"] = json.loads(args.out.read_text())["models"]
    results["models"]["shipped"] = {"clips": clip_figures(start, clips)}
    results["models"]["shipped"]["summary"] = summary(results["models"]["shipped"]["clips"], held_out)
    if args.project:
        results["models"]["shipped"]["pipeline"] = in_pipeline(args.project, SHIPPED_LIFTER, args.sync, args.out_models)
    print(json.dumps(results["models"]["shipped"]["summary"]), flush=True)
    base = AdaptConfig(steps=args.steps)
    variants = [v.split(":") for v in args.variant or ("supervised:0:0", "adapted:1:1")]
    for name, reprojection, bone, *velocity in variants:
        acfg = replace(base, reprojection_weight=float(reprojection), bone_weight=float(bone),
                       velocity_weight=float(velocity[0]) if velocity else 0.0)
        model = model_from_onnx(SHIPPED_LIFTER)
        rf = model.receptive_field
        capture = PairSampler(train, rf + cfg.chunk - 1, cfg.augment, acfg.seed, cfg.input_norm, rf, cfg.feet,
                              cfg.source_weights)
        video = VideoSampler(adapt_on, rf + cfg.chunk - 1, rf, acfg.seed)
        result = adapt_lifter(model, acfg, capture, video)
        figures = clip_figures(result.model, clips)
        heldout = training.evaluate(result.model, val, cfg)["heldout"]
        tail = {k: round(float(np.mean(v[-100:])), 4) for k, v in result.losses.items() if v}
        results["models"][name] = {"config": acfg.__dict__, "train_seconds": round(result.seconds, 1),
                                   "final_losses": tail, "clean": heldout["clean"], "noisy": heldout["noisy"],
                                   "sources": {k: v["clean"] for k, v in heldout["sources"].items()},
                                   "clips": figures, "summary": summary(figures, held_out)}
        args.out_models.mkdir(parents=True, exist_ok=True)
        training.export_onnx(result.model, args.out_models / f"lifter_{name}.onnx",
                             {"adapted_from": SHIPPED_LIFTER.name, "adapt": json.dumps(acfg.__dict__)},
                             input_norm=cfg.input_norm)
        if args.project:
            results["models"][name]["pipeline"] = in_pipeline(args.project, args.out_models / f"lifter_{name}.onnx",
                                                              args.sync, args.out_models)
        print(name, json.dumps({k: results["models"][name][k] for k in ("train_seconds", "final_losses", "summary")}),
              f"held-out clean {heldout['clean']['mpjpe_mm']:.1f} / {heldout['clean']['p_mpjpe_mm']:.1f}, "
              f"noisy {heldout['noisy']['mpjpe_mm']:.1f} / {heldout['noisy']['p_mpjpe_mm']:.1f}", flush=True)
        write_json(args.out, results)


if __name__ == "__main__":
    main()
