"""`dance3d models fetch | convert-videopose3d`: the models from their sources."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli.messages import say
from pipeline.core.errors import Dance3dError


def add_models(sub: argparse._SubParsersAction) -> None:
    models = sub.add_parser("models", help="model utilities (fetch, convert-videopose3d)")
    models_sub = models.add_subparsers(dest="action", required=True, metavar="ACTION")
    fetch = models_sub.add_parser(
        "fetch", help="download the default models from their sources, checksum and output verified",
        description="Download each model from its source (sha256 checked), convert it where the source is "
                    "not ONNX (MoveNet: Google's TF-Hub TFLite; BlazePose: the TFLite in the pinned mediapipe "
                    "wheel from PyPI, sha256 checked; both with tf2onnx in a virtual environment "
                    "of their own, built once in ~/.cache/dance3d/converters; needs pip and a few minutes), "
                    "and verify the result by its outputs on a fixed test card. "
                    "DANCE3D_DOWNLOAD_MIRROR=<base url> fetches https://host/path from "
                    "<base url>/host/path instead.")
    fetch.add_argument("names", nargs="*",
                       help="registry names (default: the models params.yaml's pose2d section runs: the detector, the "
                            "pose models, and with hands on the hand models)")
    fetch.add_argument("--to", type=Path, default=None, help="target folder (default: the project's models/)")
    fetch.add_argument("--force", action="store_true", help="fetch again even if a verified file is present")
    convert = models_sub.add_parser(
        "convert-videopose3d", help="convert an official VideoPose3D checkpoint to the lifter ONNX",
        description="Load an official VideoPose3D checkpoint (e.g. pretrained_h36m_detectron_coco.bin: 17 COCO "
                    "joints in, 17 Human3.6M joints out) and export it as the ONNX lifter the lift stage uses. "
                    "Needs the `train` extra (torch). The official weights are CC BY-NC 4.0.")
    convert.add_argument("checkpoint", type=Path, help="the VideoPose3D .bin checkpoint")
    convert.add_argument("out", type=Path, help="the .onnx file to write (lift.model reads it)")
    fetch.set_defaults(handler=fetch_models)
    convert.set_defaults(handler=convert_videopose3d)


def fetch_models(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.params import load_params, stage_params
    from pipeline.core.stage import setup_logging
    from pipeline.pose.models.fetch import fetch_model
    from pipeline.pose.models.loading import models_run

    setup_logging()
    names = args.names
    if not names:
        names = models_run(stage_params(load_params(root / "params.yaml"), "pose2d"))
    folder = args.to or root / "models"
    failed = 0
    for name in names:
        try:
            path = fetch_model(name, folder, force=args.force)
            print(f"{name}: {path} (verified by its outputs)")
        except Dance3dError as exc:
            say(exc)
            failed += 1
    return 2 if failed else 0


def convert_videopose3d(root: Path, args: argparse.Namespace) -> int:
    from pipeline.motion.lifting.convert import convert_videopose3d as convert

    try:
        model = convert(args.checkpoint, args.out)
    except Dance3dError as exc:
        say(exc)
        return 2
    print(f"wrote {args.out} (receptive field {model.receptive_field} frames)")
    return 0
