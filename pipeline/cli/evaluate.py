"""`dance3d eval WHAT`: quality measured on data the user brings (annotated images, beats, motion
capture, their own corpus), each printed as a table and optionally written as JSON."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pipeline.cli.messages import complain, say
from pipeline.core.errors import Dance3dError


def add_eval(sub: argparse._SubParsersAction) -> None:
    evaluate = sub.add_parser("eval", help="measure quality on data you bring (pose2d, hands, beats, lifter, world...)",
                              description="Quality measures against your own annotated data.")
    evaluate_sub = evaluate.add_subparsers(dest="what", required=True, metavar="WHAT")
    pose2d = evaluate_sub.add_parser(
        "pose2d", help="the detector and pose model on COCO-style annotated images (pycocotools)",
        description="Run the pose2d stage's detector and top-down pose model (params.yaml's pose2d section, "
                    "or the options below) on every image of a COCO keypoint annotation file and report COCO "
                    "keypoint AP/AR (pycocotools), detection recall and false positives per image at IoU 0.5, "
                    "PCK@0.2 of the torso and per-joint errors, overall and per 'source' and 'eval_tier' field "
                    "of the images. --gt-boxes scores the pose model alone on the annotated boxes.")
    pose2d.add_argument("--annotations", type=Path, required=True, help="COCO keypoint JSON")
    pose2d.add_argument("--images", type=Path, required=True, help="folder holding the images' file_name")
    pose2d.add_argument("--gt-boxes", action="store_true", help="pose the annotated boxes (no detector)")
    pose2d.add_argument("--detector", default=None,
                        help="registry name, or several joined by '+' to fuse them (default: params.yaml)")
    pose2d.add_argument("--pose-model", default=None,
                        help="registry name, or body+feet models joined by '+' (default: params.yaml)")
    pose2d.add_argument("--det-score", type=float, default=None, help="detector threshold (default: params.yaml)")
    pose2d.add_argument("--confirm-score", type=float, default=None,
                        help="weaker boxes down to this count when the pose confirms them; 0: off "
                             "(default: params.yaml)")
    pose2d.add_argument("--dark-mean", type=float, default=None,
                        help="brighten images darker than this mean pixel value; 0: never (default: params.yaml)")
    pose2d.add_argument("--runtime", choices=("auto", "onnxruntime", "openvino"), default=None,
                        help="the CPU runtime of the models (default: params.yaml's pose2d.runtime)")
    pose2d.add_argument("--precision", choices=("auto", "f32", "bf16"), default=None,
                        help="OpenVINO's inference precision (default: params.yaml's pose2d.precision)")
    _json_out(pose2d)
    hands = evaluate_sub.add_parser(
        "hands", help="the hand landmark model on annotated hand images (PCK, error in pixels, 3D error)",
        description="Find each image's hands from the body (the pose2d stage's detector and body model, a region "
                    "beyond each confident wrist along its forearm) and MediaPipe's palm detector, the surer of two "
                    "on one spot kept (--regions body+palm, the default), from either alone (palm alone is "
                    "MediaPipe's own pipeline, the peer) or on the annotated boxes (the hand model alone), run "
                    "MediaPipe's hand landmark model there and score it per dataset: PCK at 0.2 of the "
                    "hand box over every labelled joint (a hand not found misses all its joints), the mean error in "
                    "pixels of the hands found, hands found against annotated, and the root-aligned 3D error where "
                    "an annotation has 3D points. Protocol: pipeline/pose/evaluate_hands.py.")
    hands.add_argument("--annotations", type=Path, required=True, help="hand annotations JSON (hand_eval's layout)")
    hands.add_argument("--images", type=Path, required=True, help="folder holding the images' file paths")
    hands.add_argument("--regions", choices=("body+palm", "body", "palm", "annotated"), default="body+palm",
                       help="where hands are looked for (palm alone: MediaPipe's own pipeline, the peer)")
    hands.add_argument("--min-presence", type=float, default=0.5, help="the model's presence for a hand found")
    hands.add_argument("--passes", type=int, default=None,
                       help="the hand model's passes on a body's hand (default: params.yaml's pose2d.hand_passes)")
    _json_out(hands)
    beats = evaluate_sub.add_parser(
        "beats", help="both beat trackers against beat annotations (mir_eval), per file",
        description="Track beats with both trackers (rnn: madmom's RNN beats and bars, the default; librosa) and "
                    "score them against human annotations with mir_eval (F-measure +-70 ms, CMLt, AMLt, Cemgil, "
                    "Goto, tempo error; downbeat F-measure when the annotation has bar positions; beats before 5 s "
                    "ignored), next to the first dance3d tracker (librosa on the motion-rate onset envelope); per "
                    "file and the mean. Give --audio/--beats pairs (repeatable) or --dir.",
        epilog="annotation format: one beat per line, 'time' or 'time bar_position' (1 = downbeat), "
               "separated by spaces, commas or semicolons; '#' starts a comment.")
    beats.add_argument("--audio", type=Path, action="append", default=[],
                       help="any audio (or video) file ffmpeg reads (repeatable, each with its --beats)")
    beats.add_argument("--beats", type=Path, action="append", default=[], help="its annotation file")
    beats.add_argument("--dir", type=Path, default=None,
                       help="a folder of audio files, each with its annotation of the same name (.beats or .txt)")
    _json_out(beats)
    segments = evaluate_sub.add_parser(
        "segments", help="proposed dance segments against the human rows of annotations/segments.csv",
        description="Score the propose_segments stage's proposals (data/segment_proposals) against the human "
                    "segments of every video that has both: segments found (IoU >= 0.5), proposals that are "
                    "right, and the mean start and end errors in seconds, next to the baseline of the whole "
                    "video as one segment. Propose for annotated videos too (the stage does) to measure.")
    _json_out(segments)
    lifter = evaluate_sub.add_parser(
        "lifter", help="a 2D->3D lifter on motion capture seen by fixed virtual cameras (MPJPE, P-MPJPE)",
        description="Project every sequence of a motion-capture folder through ten fixed cameras (five headings; a "
                    "portrait phone at 1.2 m, 3 m away, and a landscape camera on a 2 m stand, 5 m away; 26 mm-"
                    "equivalent lens), lift the clean and the noisy 2D (pose-model noise of expected OKS 0.80, 2% "
                    "of joints missing) as the lift stage does, and report MPJPE, N-MPJPE (the size forgiven) and "
                    "P-MPJPE (mm) per source next to the mean-pose baseline. Protocol: "
                    "pipeline/motion/lifting/evaluate.py.",
        epilog="motion capture: a folder of the known sources (as $DANCE3D_MOCAP; only the train_lifter split's "
               "held-out sequences are scored unless --all), one source folder, or a folder of Plug-in-Gait "
               ".c3d files and .npz files holding 'joints' (T x 17 x 3, Human3.6M order, metres, y up) and 'fps'.")
    lifter.add_argument("--mocap", type=Path, required=True, help="the motion-capture folder")
    lifter.add_argument("--model", type=Path, default=None, help="the lifter ONNX (default: params.yaml lift.model)")
    lifter.add_argument("--all", action="store_true", help="score every sequence, also those the lifter trained on")
    lifter.add_argument("--no-flip", action="store_true", help="no flip averaging (the lift stage's flip_tta)")
    lifter.add_argument("--seconds", type=float, default=60.0, help="at most this much of each sequence (default 60)")
    lifter.add_argument("--denoise-2d", type=float, default=0.0, metavar="LAMBDA", help="denoise the 2D first as the "
                        "lift stage does with this lambda (default 0: the lifter alone; the lift stage's: 10)")
    _json_out(lifter)
    world = evaluate_sub.add_parser(
        "world", help="world-frame motion on motion capture, through the corpus's own path (W-MPJPE, RTE, contact F1)",
        description="Film every sequence of a motion-capture folder with ten pitched cameras (-20 to +20 degrees; "
                    "a portrait phone at 1.2 m, 3 m away, and a landscape camera on a 2 m stand, 5 m away) with "
                    "noisy 2D (expected OKS 0.80), run it through the corpus's path (lift with the contact model, "
                    "HP smoothing, 24 fps, world grounding) and report per source: W-MPJPE100 and WA-MPJPE100 (mm), "
                    "RTE (% of path length), the root path after one scale and offset (mm), jitter, foot sliding "
                    "(mm per frame at 30 fps), contact F1 of the heels and toe tips, up error, planted-foot height "
                    "and the limb-length CV before the one-skeleton fit; beside each, the same path without the "
                    "contact model. Protocol: pipeline/motion/world/evaluate.py.",
        epilog="motion capture: as for `eval lifter` (held-out sequences of the known sources unless --all); "
               "sequences need heels and toe tips ('feet' in a joint-position .npz).")
    _capture_eval_options(world, seconds=20.0)
    world.add_argument("--pose-fps", type=float, default=0.0,
                       help="pose the 2D on keyframes at this rate and draw the frames between, as pose2d.fps does "
                            "(default 0: every frame)")
    world.add_argument("--clean-2d", action="store_true", help="no 2D noise (what keyframes alone lose)")
    world.add_argument("--frame-noise", type=float, default=1.0,
                       help="the share of the 2D noise's variance drawn afresh on every frame; the rest drifts "
                            "over about a second (default 1: all of it, the protocol's figures)")
    group = evaluate_sub.add_parser(
        "group", help="groups of dancers in one scene, on synthetic groups of motion capture (position, order, floor)",
        description="Make dance groups of 2-6 held-out motion-capture takes placed on one floor (spots 0.8-2 m apart,"
                    " in up to three rows), film each with one camera (a landscape phone at 1.2 m or a camera on a 2 "
                    "m stand, pitched -20 to +20 degrees, the nearest spot 3-4.5 m away, each take's travel on top) "
                    "with noisy 2D in which joints behind a nearer dancer are hidden, run every dancer through the "
                    "corpus's path (lift with the contact model, HP smoothing, 24 fps) and ground the group in one "
                    "scene. Reports per group size: each dancer's position relative to the group after one similarity"
                    " transform (m), the share of pairs ordered right front-to-back, and the floor's angle error; "
                    "beside it, each dancer grounded alone and placed by their own root path. Protocol: "
                    "pipeline/motion/world/group_eval.py.",
        epilog="motion capture: as for `eval world` (held-out sequences of the known sources unless --all).")
    _capture_eval_options(group, seconds=15.0)
    group.add_argument("--groups", type=int, default=8, help="groups of each size, 2 to 6 dancers (default 8)")
    sync = evaluate_sub.add_parser(
        "sync", help="3D consistency on real video: dancers in sync, same instant against shifted by 1-3 s",
        description="For every pair of clips of a world file (data/world/<segment>.parquet) that overlap in time: "
                    "the mean joint distance of their poses at the same instant, after the rotation and scale that "
                    "align them, against the same with one of them shifted by 1, 1.5, 2, 2.5 and 3 s. For dancers "
                    "who perform the same choreography in sync, the ratio (same / shifted) is small when their 3D "
                    "poses are consistent, and falls as the lifter and the grounding improve; near 1, the poses "
                    "agree no better in sync than out of it (or the dancers do not dance the same steps).")
    sync.add_argument("world", type=Path, help="a world file, data/world/<segment_id>.parquet")
    _json_out(sync)
    smpl = evaluate_sub.add_parser(
        "smpl", help="what retargeting onto the SMPL skeleton keeps: joint error, foot sliding, joint ranges",
        description="Retarget every clip of data/world (or, with --mocap, every sequence of a motion-capture folder "
                    "with heels and toes: real proportions, no lifting error) onto the SMPL tree and compare forward "
                    "kinematics (SMPL rest offsets x the clip's scale) with the joints: per mapped point median and "
                    "95th percentile (mm), foot sliding of ankles and balls of the feet where they stand before and "
                    "after (mm a frame at 30 fps), frames with a joint outside its human range; beside it the "
                    "unrotated rest skeleton at the hips, and the error on the SMPL tree given the clip's own bone "
                    "lengths (the inverse kinematics alone: the rest is SMPL's neutral proportions). Protocol: "
                    "pipeline/motion/smpl/evaluate.py.")
    smpl.add_argument("--mocap", type=Path, default=None, help="a motion-capture folder instead of data/world")
    smpl.add_argument("--seconds", type=float, default=0.0, help="with --mocap, the first seconds of each (0: all)")
    _json_out(smpl)
    evaluate.set_defaults(handler=run_eval)


def run_eval(root: Path, args: argparse.Namespace) -> int:
    try:
        if args.what == "pose2d":
            from pipeline.pose.evaluate import format_table

            result = _eval_pose2d(root, args)
        elif args.what == "hands":
            from pipeline.pose.evaluate_hands import format_table

            result = _eval_hands(root, args)
        elif args.what == "lifter":
            from pipeline.motion.lifting.evaluate import evaluate_onnx
            from pipeline.motion.lifting.evaluate import format_report as format_table

            model, _, lift, _ = _corpus_path(root, args, contact=False)  # the project's, else the shipped lifter
            result = evaluate_onnx(model, args.mocap, heldout_only=not args.all, flip=not args.no_flip,
                                   max_seconds=args.seconds, denoise=lift.denoise)
        elif args.what == "world":
            from pipeline.motion.world.evaluate import PoseInput, evaluate_folder
            from pipeline.motion.world.evaluate import format_report as format_table

            model, contact, lift, rules = _corpus_path(root, args)
            result = evaluate_folder(model, contact, args.mocap, heldout_only=not args.all, seconds=args.seconds,
                                     pose_input=PoseInput(not args.clean_2d, args.frame_noise, args.pose_fps),
                                     lift=lift, rules=rules)
        elif args.what == "group":
            from pipeline.motion.world.group_eval import evaluate_group_folder
            from pipeline.motion.world.group_eval import format_report as format_table

            model, contact, lift, rules = _corpus_path(root, args)
            result = evaluate_group_folder(model, contact, args.mocap, heldout_only=not args.all, groups=args.groups,
                                           seconds=args.seconds, lift=lift, rules=rules)
        elif args.what == "sync":
            from pipeline.motion.world.group_eval import format_sync as format_table
            from pipeline.motion.world.group_eval import sync_pairs

            result = sync_pairs(args.world)
        elif args.what == "smpl":
            from pipeline.motion.smpl.evaluate import capture_clips, evaluate, world_clips
            from pipeline.motion.smpl.evaluate import format_report as format_table

            result = evaluate(capture_clips(args.mocap, args.seconds) if args.mocap else world_clips(root))
        elif args.what == "segments":
            from pipeline.pose.propose import evaluate_project, format_table

            result = evaluate_project(root)
        else:
            from pipeline.music.evaluate import evaluate_files, format_table, pairs_in

            pairs = list(zip(args.audio, args.beats)) + (pairs_in(args.dir) if args.dir else [])
            if not pairs or len(args.audio) != len(args.beats):
                return complain("dance3d eval beats: give --audio A --beats B (as many pairs as you like) or --dir D "
                                "with audio files and their .beats annotations")
            result = evaluate_files(pairs)
    except Dance3dError as exc:
        say(exc)
        return 2
    print(format_table(result))
    if args.out:
        args.out.write_text(json.dumps(result, indent=2) + "\n")
    return 0


def _eval_pose2d(root: Path, args: argparse.Namespace) -> dict:
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.pose.evaluate import evaluate_pose2d, read_coco
    from pipeline.pose.models.loading import load_pose_models, model_files
    from pipeline.pose.pose2d import Pose2dOptions

    coco = read_coco(args.annotations)  # a bad file is named before any model loads
    params = stage_params(project_or_default_params(root), "pose2d")
    for key, value in (("detector", args.detector), ("pose_model", args.pose_model), ("det_score", args.det_score),
                       ("confirm_score", args.confirm_score), ("dark_mean", args.dark_mean),
                       ("runtime", args.runtime), ("precision", args.precision)):
        if value is not None:
            params[key] = value
    files, hashes = model_files(root, params)
    models = load_pose_models(files)
    describe = {"detector": params.get("detector", "rtmdet-nano-person"),
                "pose_model": params.get("pose_model", "movenet-lightning"), "det_score": files.det_score,
                "crop_padding": files.crop_padding, "model_sha256": hashes}
    opts = Pose2dOptions.from_params(params)
    describe.update(confirm_score=opts.confirm_score, dark_mean=opts.dark_mean)
    return evaluate_pose2d(args.annotations, args.images, models.detector, models.pose, gt_boxes=args.gt_boxes,
                           opts=opts, describe=describe, coco=coco)


def _eval_hands(root: Path, args: argparse.Namespace) -> dict:
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.pose.evaluate_hands import evaluate_hands, load_models, read_hand_annotations

    read_hand_annotations(args.annotations)  # a bad file is named before any model loads
    params = stage_params(project_or_default_params(root), "pose2d")
    params = {**params, **({"hand_passes": args.passes} if args.passes else {})}
    return evaluate_hands(args.annotations, args.images, regions=args.regions, min_presence=args.min_presence,
                          **load_models(root, params, args.regions),
                          describe={"hand_model": "hand-landmark-full", "pose_model": params.get("pose_model")})


def _json_out(parser: argparse.ArgumentParser) -> None:
    """--out: every eval command can also write its result as JSON (run_eval writes it)."""
    parser.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")


def _capture_eval_options(parser: argparse.ArgumentParser, seconds: float) -> None:
    """The options every evaluation on motion capture through the corpus's path takes."""
    parser.add_argument("--mocap", type=Path, required=True, help="the motion-capture folder")
    parser.add_argument("--model", type=Path, default=None, help="the lifter ONNX (default: params.yaml lift.model)")
    parser.add_argument("--contact", type=Path, default=None,
                        help="the contact model ONNX (default: params.yaml lift.contact_model)")
    parser.add_argument("--all", action="store_true", help="use every sequence, also those the models trained on")
    parser.add_argument("--seconds", type=float, default=seconds,
                        help=f"at most this much of each sequence (default {seconds:g})")
    parser.add_argument("--denoise-2d", type=float, default=None, metavar="LAMBDA", help="the 2D's HP lambda as at 30 "
                        "fps before lifting (default: params.yaml lift.denoise_2d, as the lift stage; 0: none). The "
                        "other lift and ground options are params.yaml's too, as the corpus is made")
    _json_out(parser)


def _corpus_path(root: Path, args: argparse.Namespace, contact: bool = True) -> tuple:
    """The lifter and (with ``contact``) the contact model: the options', else params.yaml lift's, else (a fresh
    clone) the shipped ones, saying so; then the project's lift options and contact rules (``path_from_params``)."""
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.motion.shipped import SHIPPED_CONTACT, SHIPPED_LIFTER, model_or_shipped
    from pipeline.motion.world.evaluate import path_from_params

    params = project_or_default_params(root)
    lift = stage_params(params, "lift")
    model, contact_model = args.model, args.contact if contact else None
    if model is None:
        model, notice = model_or_shipped(root / lift.get("model", "models/lifter.onnx"), SHIPPED_LIFTER, "lifter")
        if notice:
            print(f"dance3d: {notice}", file=sys.stderr)
    if contact and contact_model is None and lift.get("contact_model"):
        contact_model, notice = model_or_shipped(root / lift["contact_model"], SHIPPED_CONTACT, "contact model")
        if notice:
            print(f"dance3d: {notice}", file=sys.stderr)
    return (model, contact_model, *path_from_params(params, args.denoise_2d))
