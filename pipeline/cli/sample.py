"""`dance3d sample`: dance generated for a music file by the trained model."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli.messages import complain


def add_sample(sub: argparse._SubParsersAction) -> None:
    sample = sub.add_parser("sample", help="generate dance for a music file with the trained model",
                            description="Continue a seed pose (the first frames of a corpus window) for N frames "
                                        "to the music of an audio file, with models/tsmt.pt, and write a motion "
                                        "file that `dance3d render` draws.")
    sample.add_argument("music", type=Path, help="an audio file (any format ffmpeg reads)")
    sample.add_argument("out", type=Path, help="the motion Parquet file to write")
    sample.add_argument("--frames", type=int, default=240, help="frames to generate at 24 fps (default 240)")
    sample.add_argument("--model", type=Path, default=Path("models/tsmt.pt"), help="the trained model (train stage)")
    sample.add_argument("--corpus", type=Path, default=Path("data/corpus"), help="where the seed window comes from")
    sample.add_argument("--seed-frames", type=int, default=24, help="frames of the seed pose (default 24)")
    sample.add_argument("--temperature", type=float, default=0.0, help="0: most likely bins; > 0: sample")
    sample.set_defaults(handler=generate_dance)


def generate_dance(root: Path, args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from pipeline.core.storage import write_parquet
    from pipeline.motion.motionfile import MotionClip, clips_to_table
    from pipeline.music.audio import features_of_file
    from pipeline.train.dataset import WindowDataset
    from pipeline.train.loop import load_model
    from pipeline.train.model import generate

    corpus = args.corpus if args.corpus.is_absolute() else root / args.corpus
    model_path = args.model if args.model.is_absolute() else root / args.model
    if not model_path.is_file():
        return complain(f"dance3d: {model_path}: no trained model; the train stage makes it (dvc repro train), "
                        "or give one with --model")
    seed_row = next(iter(WindowDataset(corpus / "train", shuffle=False)), None) or \
        next(iter(WindowDataset(corpus / "val", shuffle=False)), None)
    if seed_row is None:
        return complain(f"dance3d: {corpus}: no corpus windows to take a seed pose from")
    model = load_model(model_path)
    feats = features_of_file(args.music)
    total = args.seed_frames + args.frames
    if feats.frames < total:
        return complain(f"dance3d: {args.music}: {feats.frames / 24:.1f} s of music is too short for {total} frames")
    audio = torch.from_numpy(np.concatenate([feats.mfcc[:total, :26], feats.beat[:total, None]], -1).astype(np.float32))
    motion = generate(model, seed_row["motion"][: args.seed_frames], audio, args.frames, args.temperature,
                      torch.Generator().manual_seed(0)).numpy().reshape(-1, 17, 3)
    frames = np.arange(len(motion))
    clip = MotionClip("sample", 0, frames, frames / 24, motion, np.zeros(len(motion), bool),
                      np.zeros(len(motion), np.int8))
    write_parquet(clips_to_table([clip]), args.out, schema_version=1,
                  extra={"fps": 24, "seed_window": seed_row["window_id"], "music": str(args.music)})
    print(f"wrote {args.out} ({len(motion)} frames; draw it with: dance3d render {args.out} sample out.mp4)")
    return 0
