"""The ``dance3d`` command."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from pathlib import Path

from pipeline.core.errors import Dance3dError, InputError
from pipeline.core.paths import FAILURE_DIRS
from stages import STAGES

DESCRIPTION = """\
dance3d turns dance videos into a 3D dance-motion corpus synced to music.

The pipeline is driven by DVC: edit manifests/sources.csv, annotations/segments.csv and
params.yaml, then run `dvc repro` in the project root. The commands below run single
stages outside DVC and summarise results.
"""

EPILOG = """\
examples:
  dance3d run download        fetch the sources listed in manifests/sources.csv
  dance3d run trim            cut the annotated dance segments
  dance3d status              what has been downloaded and cut, and what failed
  dance3d retry pose2d        re-run only the items pose2d recorded as failed
  dance3d review              open the annotators' review page at http://127.0.0.1:8765/ (trim mode: /trim)
  dance3d manifests seed      propose a track manifest for every tracked segment without one
  dance3d manifests check     validate manifests: every problem as file:line: reason
  dance3d render data/motion24/musepose_dance_000.parquet musepose_dance_000_1_0 clip.mp4
                              draw a 3D clip (front and side views) with its music
  dance3d export bvh data/motion24/musepose_dance_000.parquet musepose_dance_000_1_0 clip.bvh
                              one clip as BVH: y-up world frame, one skeleton, joint rotations
  dance3d eval pose2d --annotations person_keypoints.json --images images/
                              COCO keypoint AP, detection recall, PCK of the configured 2D models
  dance3d eval beats --audio song.ogg --beats song.beats
                              score the beat tracker against your annotations (mir_eval)
  dance3d eval segments       score the proposed dance segments against annotations/segments.csv
  dance3d eval world --mocap ../mocap
                              world motion through the corpus's path: W-MPJPE, RTE, foot sliding, contact F1
  dance3d eval lifter --mocap ../mocap
                              MPJPE / P-MPJPE of the lifter on motion capture through fixed virtual cameras
  dance3d models fetch        download, convert and verify the default detector and pose model
  dance3d models convert-videopose3d pretrained_h36m_detectron_coco.bin models/lifter.onnx
                              use the official VideoPose3D weights as the lifter
"""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dance3d", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=Path.cwd(),
                        help="project root holding params.yaml (default: the current folder)")
    parser.add_argument("--debug", action="store_true",
                        help="show a failing command's traceback (also DANCE3D_DEBUG=1)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser("run", help="run one pipeline stage outside DVC",
                         description="Run one stage on the project in --root, as `dvc repro` would.")
    run.add_argument("stage", choices=STAGES, help="the stage to run")
    review = sub.add_parser("review", help="a local web page for trimming videos and cleaning tracks",
                            description="Serve the review page. Tracks mode (/): watch each segment's QC video, "
                                        "edit its track manifest on a timeline and save it (checked like "
                                        "`dance3d manifests check`). Trim mode (/trim): play each downloaded "
                                        "video with its shots and proposed dance segments, and set, split, add "
                                        "or delete its rows of annotations/segments.csv with the same keys "
                                        "(checked as the trim stage checks). Loopback only unless --host says "
                                        "otherwise.")
    review.add_argument("--port", type=int, default=8765, help="the local port to serve the page on (default 8765)")
    review.add_argument("--host", default="127.0.0.1",
                        help="interface to listen on (default: loopback only). Any other (e.g. 0.0.0.0 for a "
                             "team on a lab server) requires a token, printed in the start-up addresses "
                             "(or taken from $DANCE3D_REVIEW_TOKEN)")
    review.add_argument("--token", action="store_true",
                        help="require the token on loopback too (always required elsewhere)")
    review.add_argument("--mode", choices=("tracks", "trim"), default="tracks",
                        help="the page to print first (both are served)")
    retry = sub.add_parser("retry", help="re-run only the items a stage recorded as failed",
                           description="Re-run the items listed in the stage's _failures.parquet, leaving the "
                                       "others as they are (for download and trim, whose finished items are "
                                       "always kept, this is a plain re-run).")
    retry.add_argument("stage", choices=sorted(FAILURE_DIRS), help="the stage whose failed items to run again")
    qc = sub.add_parser("qc", help="render a segment's QC video (boxes, skeletons, track ids, timecodes)",
                        description="Render data/qc/<segment_id>.mp4 from the segment's tracks, read straight from "
                                    "its downloaded video (with audio), and print its path. A QC video newer than "
                                    "its tracks is kept. The review page does the same on first request; set "
                                    "track.qc_videos: true to have the track stage render every segment's.")
    qc.add_argument("segments", nargs="+", help="segment ids (see data/segments/index.parquet or `dance3d status`)")
    sub.add_parser("status", help="summarise downloads, segments and failures",
                   description="Summarise the download ledger, the segment index and every stage's failures.")
    manifests = sub.add_parser("manifests", help="track manifests for annotators (seed, check)",
                               description="Track manifests: manifests/tracks/<segment_id>.csv. "
                                           "See docs/tutorials/annotating.md.")
    msub = manifests.add_subparsers(dest="action", required=True, metavar="ACTION")
    msub.add_parser("seed", help="write a proposal for every tracked segment that has no manifest",
                    description="Write manifests/tracks/<segment_id>.csv proposals for tracked segments without "
                                "one. Existing files are never overwritten.")
    check = msub.add_parser("check", help="validate manifests against their tracks",
                            description="Report every problem as file:line: reason. Exit code 1 on errors "
                                        "(warnings alone exit 0).")
    check.add_argument("files", nargs="*", type=Path, help="manifests to check (default: all)")
    render = sub.add_parser("render", help="draw a 3D motion clip, or a segment's group scene, to an mp4",
                            description="Draw one clip of a motion file (data/pose3d, data/smooth or data/motion24) "
                                        "as front and side views, with the segment's audio; or, with --group, a "
                                        "segment's scene: its video beside the floor seen from above, with every "
                                        "dancer where the ground stage put them (data/world) and their paths.",
                            usage="dance3d render [--world] MOTION CLIP_ID OUT | "
                                  "dance3d render --smpl WORLD CLIP_ID OUT | dance3d render --group SEGMENT OUT")
    render.add_argument("motion", type=Path, nargs="?", help="a motion Parquet file")
    render.add_argument("clip_id", nargs="?", help="the clip to draw (see the file's clip_id column)")
    render.add_argument("out", type=Path, help="the mp4 to write")
    render.add_argument("--group", metavar="SEGMENT", default=None,
                        help="draw this segment's scene (data/world/SEGMENT.parquet beside its video)")
    render.add_argument("--world", action="store_true",
                        help="draw the clip grounded in the world: y up over a floor grid, its path, feet in contact "
                             "(green), one skeleton, feet pinned (as the corpus's world_joints)")
    render.add_argument("--smpl", action="store_true",
                        help="MOTION is a world file (data/world): draw its clip with the SMPL skeleton's joints "
                             "(forward kinematics of smpl_poses, smpl_trans, smpl_scaling) in yellow over it")
    export = sub.add_parser("export", help="export motion for animation tools (bvh) and trainers (aistpp)")
    export_sub = export.add_subparsers(dest="format", required=True, metavar="FORMAT")
    bvh = export_sub.add_parser(
        "bvh", help="one clip as a BVH file (world frame, y up, metres, one skeleton)",
        description="Turn one clip of a motion file (data/pose3d, data/smooth or data/motion24) into a BVH file: "
                    "rotated from the camera frame into a y-up world frame (up from the body's long axis over "
                    "the clip) with the root's path where the file has it, the floor at y = 0, constant bone "
                    "lengths (the clip's medians, left and right averaged), joint rotations on that skeleton "
                    "(ZXY Euler angles), metres, the file's frame rate. "
                    "Blender: File > Import > Motion Capture (.bvh), scale 1.",
        epilog="the estimated camera pitch and roll and how far the skeleton fit moved the joints are printed")
    bvh.add_argument("motion", type=Path, help="a motion Parquet file")
    bvh.add_argument("clip_id", nargs="?", help="the clip to export (see the file's clip_id column)")
    bvh.add_argument("out", type=Path, help="the .bvh file to write (with --all: a folder)")
    bvh.add_argument("--smpl", action="store_true",
                     help="MOTION is a world file (data/world): write the clip on the SMPL skeleton (its 24 joints by "
                          "SMPL's names, rest offsets times smpl_scaling, T-pose rest, the world file's frame); with "
                          "--all every dancer of the segment, where they danced")
    bvh.add_argument("--all", action="store_true",
                     help="every clip of the file, one BVH per dancer (<clip_id>.bvh in the folder OUT), all in the "
                          "segment's one scene: import them together and the dancers stand where they danced")
    aistpp = export_sub.add_parser(
        "aistpp", help="every dancer's clip on the SMPL skeleton in AIST++'s layout (EDGE, Bailando)",
        description="Write the corpus's dancers (data/world, data/audio) as AIST++ lays out its motions: "
                    "motions/<sequence>.pkl (smpl_poses T x 72 axis-angle, smpl_trans T x 3 metres y up, "
                    "smpl_scaling), wavs/<sequence>.wav (EDGE), all_musics/<music>.wav (Bailando), "
                    "splits/crossmodal_{train,val,test}.txt (the corpus's split by video), names.csv "
                    "(each sequence's clip, source and licence). EDGE: copy the three split files into "
                    "EDGE's data/splits and run its data/create_dataset.py --dataset_folder OUT.",
        epilog="sequence names follow AIST++'s g.._s.._cAll_d.._m.._ch.. (a hash of the clip id: stable)")
    aistpp.add_argument("out", type=Path, help="the folder to write")
    aistpp.add_argument("--fps", type=float, default=60.0, help="frame rate of the motions (AIST++: 60)")
    edge = export_sub.add_parser(
        "edge", help="the corpus as EDGE's data preparation leaves it: 5 s slices, music features, 151-d motion",
        description="Write what EDGE's data/create_dataset.py makes of AIST++, from the corpus (data/world, "
                    "data/audio, data/audio_features): train/ and test/ (the corpus's split by video), each with "
                    "motions_sliced/*.pkl (pos, q at 60 fps), wavs_sliced/*.wav and baseline_feats/*.npy (150 x 35 "
                    "at 30 fps, the beat column from dance3d's beats), all 5 s slices every 0.5 s; and "
                    "edge_features/*.npy, EDGE's 151-d model input before its normaliser (contacts from dance3d's "
                    "planted feet, root, 6D rotations, z up). EDGE: train.py --data_path OUT --feature_type baseline.",
        epilog="EDGE computes its own contacts when it loads motions_sliced; edge_features carries dance3d's")
    edge.add_argument("out", type=Path, help="the folder to write")
    edge.add_argument("--length", type=float, default=5.0, help="slice length in seconds (EDGE: 5)")
    edge.add_argument("--stride", type=float, default=0.5, help="seconds between slices (EDGE: 0.5)")
    gdance = export_sub.add_parser(
        "gdance", help="the groups on the SMPL skeleton in AIOZ-GDANCE's layout (group choreography trainers)",
        description="Write the corpus's groups (data/world, data/audio) as AIOZ-GDANCE lays out its group dances: "
                    "one sequence per run of a segment where the same two or more dancers are all in view, named "
                    "<segment>_<start>_<end> (frames at 30 fps): motions_smpl/<name>.pkl (smpl_poses D x T x 72, "
                    "root_trans D x T x 3 in the segment's one scene, smpl_trans, smpl_scaling, contacts, meta), "
                    "musics/<name>.wav, baseline_feats/<name>.npy (T x 35) and split_sequence_names.txt "
                    "(train; train_/test_split_sequence_names.txt: the corpus's split by video).",
        epilog="root_trans: each pelvis's height is over its dancer's smpl_scaling, so the unit SMPL body stands on "
               "the floor; smpl_trans keeps it as it is")
    gdance.add_argument("out", type=Path, help="the folder to write")
    gdance.add_argument("--min-seconds", type=float, default=2.0, help="shortest group sequence to write (default 2)")
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
    evaluate = sub.add_parser("eval", help="measure quality on data you bring (pose2d, beats, segments, lifter, world)",
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
    pose2d.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
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
    beats.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
    segments = evaluate_sub.add_parser(
        "segments", help="proposed dance segments against the human rows of annotations/segments.csv",
        description="Score the propose_segments stage's proposals (data/segment_proposals) against the human "
                    "segments of every video that has both: segments found (IoU >= 0.5), proposals that are "
                    "right, and the mean start and end errors in seconds, next to the baseline of the whole "
                    "video as one segment. Propose for annotated videos too (the stage does) to measure.")
    segments.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
    lifter = evaluate_sub.add_parser(
        "lifter", help="a 2D->3D lifter on motion capture seen by fixed virtual cameras (MPJPE, P-MPJPE)",
        description="Project every sequence of a motion-capture folder through ten fixed cameras (five headings; a "
                    "portrait phone at 1.2 m, 3 m away, and a landscape camera on a 2 m stand, 5 m away; 26 mm-"
                    "equivalent lens), lift the clean and the noisy 2D (pose-model noise of expected OKS 0.80, 2%% "
                    "of joints missing) as the lift stage does, and report MPJPE and P-MPJPE (mm) per source next "
                    "to the mean-pose baseline. Protocol: pipeline/motion/lifting/evaluate.py.",
        epilog="motion capture: a folder of the known sources (as $DANCE3D_MOCAP; only the train_lifter split's "
               "held-out sequences are scored unless --all), one source folder, or a folder of Plug-in-Gait "
               ".c3d files and .npz files holding 'joints' (T x 17 x 3, Human3.6M order, metres, y up) and 'fps'.")
    lifter.add_argument("--mocap", type=Path, required=True, help="the motion-capture folder")
    lifter.add_argument("--model", type=Path, default=None, help="the lifter ONNX (default: params.yaml lift.model)")
    lifter.add_argument("--all", action="store_true", help="score every sequence, also those the lifter trained on")
    lifter.add_argument("--no-flip", action="store_true", help="no flip averaging (the lift stage's flip_tta)")
    lifter.add_argument("--seconds", type=float, default=60.0, help="at most this much of each sequence (default 60)")
    lifter.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
    world = evaluate_sub.add_parser(
        "world", help="world-frame motion on motion capture, through the corpus's own path (W-MPJPE, RTE, contact F1)",
        description="Film every sequence of a motion-capture folder with ten pitched cameras (-20 to +20 degrees; "
                    "a portrait phone at 1.2 m, 3 m away, and a landscape camera on a 2 m stand, 5 m away) with "
                    "noisy 2D (expected OKS 0.80), run it through the corpus's path (lift with the contact model, "
                    "HP smoothing, 24 fps, world grounding) and report per source: W-MPJPE100 and WA-MPJPE100 (mm), "
                    "RTE (%% of path length), the root path after one scale and offset (mm), jitter, foot sliding "
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
    sync.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
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
    smpl.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")
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
    fetch.add_argument("names", nargs="*", help="registry names (default: the detector and pose model in params.yaml)")
    fetch.add_argument("--to", type=Path, default=None, help="target folder (default: the project's models/)")
    fetch.add_argument("--force", action="store_true", help="fetch again even if a verified file is present")
    convert = models_sub.add_parser(
        "convert-videopose3d", help="convert an official VideoPose3D checkpoint to the lifter ONNX",
        description="Load an official VideoPose3D checkpoint (e.g. pretrained_h36m_detectron_coco.bin: 17 COCO "
                    "joints in, 17 Human3.6M joints out) and export it as the ONNX lifter the lift stage uses. "
                    "Needs the `train` extra (torch). The official weights are CC BY-NC 4.0.")
    convert.add_argument("checkpoint", type=Path, help="the VideoPose3D .bin checkpoint")
    convert.add_argument("out", type=Path, help="the .onnx file to write (lift.model reads it)")
    return parser


def _eval_pose2d(root: Path, args: argparse.Namespace) -> dict:
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.pose.evaluate import evaluate_pose2d
    from pipeline.pose.models.loading import load_pose_models, model_files
    from pipeline.pose.pose2d import Pose2dOptions

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
                           opts=opts, describe=describe)


def _eval(root: Path, args: argparse.Namespace) -> int:
    import json

    try:
        if args.what == "pose2d":
            from pipeline.pose.evaluate import format_table

            result = _eval_pose2d(root, args)
        elif args.what == "lifter":
            from pipeline.motion.lifting.evaluate import evaluate_onnx
            from pipeline.motion.lifting.evaluate import format_report as format_table

            model, _ = _lift_models(root, args, contact=False)  # the project's, else the shipped lifter
            result = evaluate_onnx(model, args.mocap, heldout_only=not args.all, flip=not args.no_flip,
                                   max_seconds=args.seconds)
        elif args.what == "world":
            from pipeline.motion.world.evaluate import PoseInput, evaluate_folder
            from pipeline.motion.world.evaluate import format_report as format_table

            model, contact = _lift_models(root, args)
            result = evaluate_folder(model, contact, args.mocap, heldout_only=not args.all, seconds=args.seconds,
                                     pose_input=PoseInput(not args.clean_2d, args.frame_noise, args.pose_fps))
        elif args.what == "group":
            from pipeline.motion.world.group_eval import evaluate_group_folder
            from pipeline.motion.world.group_eval import format_report as format_table

            model, contact = _lift_models(root, args)
            result = evaluate_group_folder(model, contact, args.mocap, heldout_only=not args.all, groups=args.groups,
                                           seconds=args.seconds)
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
                print("dance3d eval beats: give --audio A --beats B (as many pairs as you like) or --dir D with "
                      "audio files and their .beats annotations", file=sys.stderr)
                return 2
            result = evaluate_files(pairs)
    except Dance3dError as exc:
        _say(exc)
        return 2
    print(format_table(result))
    if args.out:
        args.out.write_text(json.dumps(result, indent=2) + "\n")
    return 0


def _capture_eval_options(parser: argparse.ArgumentParser, seconds: float) -> None:
    """The options every evaluation on motion capture through the corpus's path takes."""
    parser.add_argument("--mocap", type=Path, required=True, help="the motion-capture folder")
    parser.add_argument("--model", type=Path, default=None, help="the lifter ONNX (default: params.yaml lift.model)")
    parser.add_argument("--contact", type=Path, default=None,
                        help="the contact model ONNX (default: params.yaml lift.contact_model)")
    parser.add_argument("--all", action="store_true", help="use every sequence, also those the models trained on")
    parser.add_argument("--seconds", type=float, default=seconds,
                        help=f"at most this much of each sequence (default {seconds:g})")
    parser.add_argument("--out", type=Path, default=None, help="also write the result as JSON here")


def _lift_models(root: Path, args: argparse.Namespace, contact: bool = True) -> tuple[Path, Path | None]:
    """The lifter and (with ``contact``) the contact model: the options', else params.yaml lift's,
    else (a fresh clone, where train_lifter and train_contact have not run) the shipped ones, saying so."""
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.motion.shipped import SHIPPED_CONTACT, SHIPPED_LIFTER, model_or_shipped

    lift = stage_params(project_or_default_params(root), "lift")
    model, contact_model = args.model, args.contact if contact else None
    if model is None:
        model, notice = model_or_shipped(root / lift.get("model", "models/lifter.onnx"), SHIPPED_LIFTER, "lifter")
        if notice:
            print(f"dance3d: {notice}", file=sys.stderr)
    if contact and contact_model is None and lift.get("contact_model"):
        contact_model, notice = model_or_shipped(root / lift["contact_model"], SHIPPED_CONTACT, "contact model")
        if notice:
            print(f"dance3d: {notice}", file=sys.stderr)
    return model, contact_model


def _fetch_models(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.params import load_params, stage_params
    from pipeline.core.stage import setup_logging
    from pipeline.pose.models.fetch import fetch_model

    setup_logging()
    names = args.names
    if not names:
        pose2d = stage_params(load_params(root / "params.yaml"), "pose2d")
        from pipeline.pose.models.loading import DEFAULT_DETECTOR, DEFAULT_POSE_MODEL, model_names

        names = model_names(pose2d.get("detector", DEFAULT_DETECTOR)) + model_names(
            pose2d.get("pose_model", DEFAULT_POSE_MODEL))
    folder = args.to or root / "models"
    failed = 0
    for name in names:
        try:
            path = fetch_model(name, folder, force=args.force)
            print(f"{name}: {path} (verified by its outputs)")
        except Dance3dError as exc:
            _say(exc)
            failed += 1
    return 2 if failed else 0


def main(argv: list[str] | None = None) -> int:
    """The `dance3d` command. Every error a command meets ends here as one line naming what is wrong
    (the file and line where there is one) and a non-zero exit; ``--debug`` or DANCE3D_DEBUG=1 shows
    the traceback instead. Library warnings are kept from the terminal unless debugging."""
    args = _parser().parse_args(argv)
    debug = args.debug or os.environ.get("DANCE3D_DEBUG") == "1"
    if debug:
        os.environ["DANCE3D_DEBUG"] = "1"  # the handlers that go on after an error stop instead
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.simplefilter("ignore")
            return _dispatch(args)
    except KeyboardInterrupt:
        print(f"dance3d {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 -- the one place a command's errors become a sentence
        if debug:
            raise
        print(f"dance3d {args.command}: {one_line(exc)}", file=sys.stderr)
        return 2 if isinstance(exc, Dance3dError) else 1


def one_line(exc: BaseException) -> str:
    """An error as one line: dance3d's own say the file, line and reason; a library's are named by
    the file they were about, where they say it, with a pointer to --debug."""
    if isinstance(exc, Dance3dError):
        return " ".join(str(exc).split())
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file or folder"
    if isinstance(exc, (IsADirectoryError, NotADirectoryError, PermissionError)) and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{text} ({type(exc).__name__}; --debug shows where)"


def _say(exc: Dance3dError) -> None:
    """A handler that goes on after an error (the next segment, the next model) says it in one line;
    under --debug it stops there with the traceback."""
    if os.environ.get("DANCE3D_DEBUG") == "1":
        raise exc
    print(f"dance3d: {one_line(exc)}", file=sys.stderr)


def _dispatch(args: argparse.Namespace) -> int:
    root = args.root.resolve()
    if args.command == "run":
        from pipeline.core.stage import run_stage, setup_logging

        setup_logging()
        module = importlib.import_module(f"stages.{args.stage}")
        os.chdir(root)
        return run_stage(args.stage, module.run, root)
    if args.command == "sample":
        return _sample(root, args)
    if args.command == "render":
        return _render(root, args)
    if args.command == "export" and args.format == "aistpp":
        return _export_aistpp(root, args)
    if args.command == "export" and args.format == "edge":
        return _export_edge(root, args)
    if args.command == "export" and args.format == "gdance":
        return _export_gdance(root, args)
    if args.command == "export":
        return _export_smpl_bvh(args) if args.smpl else _export_bvh(args)
    if args.command == "eval":
        return _eval(root, args)
    if args.command == "models" and args.action == "fetch":
        return _fetch_models(root, args)
    if args.command == "models":
        from pipeline.motion.lifting.convert import convert_videopose3d

        try:
            model = convert_videopose3d(args.checkpoint, args.out)
        except Dance3dError as exc:
            _say(exc)
            return 2
        print(f"wrote {args.out} (receptive field {model.receptive_field} frames)")
        return 0
    if args.command == "manifests":
        return _manifests(root, args)
    if args.command == "review":
        return _review(root, args)
    if args.command == "retry":
        return _retry(root, args.stage)
    if args.command == "qc":
        return _qc(root, args)
    if args.command == "status":
        from pipeline.status import summarise

        print(summarise(root))
        return 0
    return 1


def _qc(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.params import load_params, stage_params
    from pipeline.pose.qc import qc_video

    kp_min_score = float(stage_params(load_params(root / "params.yaml"), "track").get("kp_min_score", 0.2))
    failed = 0
    for segment_id in args.segments:
        try:
            print(qc_video(root, segment_id, kp_min_score=kp_min_score).relative_to(root))
        except Dance3dError as exc:
            _say(exc)
            failed += 1
    return 2 if failed else 0


def _review(root: Path, args: argparse.Namespace) -> int:
    from pipeline.annotate.commands import proposal_options
    from pipeline.annotate.review.access import choose_token
    from pipeline.annotate.review.server import ReviewApp, serve
    from pipeline.core.params import load_params, stage_params

    params = load_params(root / "params.yaml")
    token = choose_token(args.host, args.token)
    app = ReviewApp(root, proposal_options(params), float(stage_params(params, "clean").get("min_clip_seconds", 2.0)),
                    token)
    server = serve(app, args.host, args.port)
    host = f"[{args.host}]" if ":" in args.host else args.host
    base = f"http://{host}:{server.server_address[1]}"
    login = f"?token={token}" if token else ""
    pages = [f"{base}/trim{login}  (trim videos)", f"{base}/{login}  (clean tracks)"]
    print("dance3d review: " + "\n                ".join(pages if args.mode == "trim" else pages[::-1])
          + ("\n(the token is needed once per browser; share these addresses only with your annotators)"
             if token else "") + "\n(Ctrl+C to stop)", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0


def _retry(root: Path, stage: str) -> int:
    from pipeline.core.failures import read_failures
    from pipeline.core.itemstage import only_items
    from pipeline.core.stage import run_stage, setup_logging

    setup_logging()
    failed = {f.item for f in read_failures(root / FAILURE_DIRS[stage])}
    if not failed:
        print(f"{stage}: no recorded failures")
        return 0
    print(f"{stage}: retrying {len(failed)} items: {', '.join(sorted(failed))}")
    module = importlib.import_module(f"stages.{stage}")
    os.chdir(root)
    with only_items(failed):
        return run_stage(stage, module.run, root)


def _sample(root: Path, args: argparse.Namespace) -> int:
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
    seed_row = next(iter(WindowDataset(corpus / "train", shuffle=False)), None) or \
        next(iter(WindowDataset(corpus / "val", shuffle=False)), None)
    if seed_row is None:
        print(f"dance3d: {corpus}: no corpus windows to take a seed pose from", file=sys.stderr)
        return 2
    model = load_model(model_path)
    feats = features_of_file(args.music)
    total = args.seed_frames + args.frames
    if feats.frames < total:
        print(f"dance3d: {args.music}: {feats.frames / 24:.1f} s of music is too short for {total} frames",
              file=sys.stderr)
        return 2
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


def _clip_of(motion: Path, clip_id: str):
    """One clip of a motion file, or None after saying which clips there are."""
    from pipeline.motion.motionfile import read_clips

    clips = {c.clip_id: c for c in read_clips(motion)}
    if clip_id not in clips:
        print(f"dance3d: {motion}: no clip {clip_id!r}; clips: {', '.join(clips) or 'none'}", file=sys.stderr)
    return clips.get(clip_id)


def _render(root: Path, args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.core.paths import AUDIO
    from pipeline.core.storage import read_meta
    from pipeline.motion.render3d import render_clip

    if args.group:
        return _render_group(root, args.group, args.out)
    if args.motion is None or args.clip_id is None:
        print("dance3d render: give MOTION CLIP_ID OUT, or --group SEGMENT OUT", file=sys.stderr)
        return 2
    if args.smpl:
        return _render_smpl(root, args)
    clip = _clip_of(args.motion, args.clip_id)
    if clip is None:
        return 2
    meta = read_meta(args.motion)
    fps = float(meta.get("fps", 24.0))
    audio = root / AUDIO / f"{meta.get('segment_id', '')}.flac"  # the segment's normalised audio
    if args.world:
        from pipeline.motion.motionfile import read_clips
        from pipeline.motion.world.scene import ground_in_scene

        grounded = ground_in_scene(read_clips(args.motion), args.clip_id, fps)
        world = grounded.joints if grounded.feet is None else np.concatenate([grounded.joints, grounded.feet], 1)
        render_clip(world, clip.time, fps, args.out, audio=audio, title=args.clip_id, contact=grounded.contact)
    else:
        joints = clip.joints if clip.feet is None else np.concatenate([clip.joints, clip.feet], 1)
        render_clip(joints, clip.time, fps, args.out, audio=audio, title=args.clip_id)
    print(f"wrote {args.out}")
    return 0


def _world_clip_of(path: Path, clip_id: str | None):
    """One retargeted clip of a world file, or None after saying why."""
    from pipeline.motion.world.worldfile import read_world

    try:
        clips = {c.clip_id: c for c in read_world(path)}
    except Dance3dError as exc:
        _say(exc)
        return None
    clip = clips.get(clip_id)
    if clip is None:
        print(f"dance3d: {path}: no clip {clip_id!r}; clips: {', '.join(clips) or 'none'}", file=sys.stderr)
    elif clip.smpl_poses is None:
        print(f"dance3d: {path}: clip {clip_id} has no SMPL motion", file=sys.stderr)
        return None
    return clip


def _render_smpl(root: Path, args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.core.paths import AUDIO
    from pipeline.core.storage import read_meta
    from pipeline.motion.render3d import render_clip
    from pipeline.motion.smpl.bvh import smpl_skeleton_motion

    clip = _world_clip_of(args.motion, args.clip_id)
    if clip is None:
        return 2
    meta = read_meta(args.motion)
    smpl = smpl_skeleton_motion(clip.smpl_poses, clip.smpl_trans, float(clip.facts["smpl_scaling"]))
    world = clip.joints if clip.feet is None else np.concatenate([clip.joints, clip.feet], 1)
    render_clip(world, clip.time, float(meta.get("fps", 24.0)), args.out,
                audio=root / AUDIO / f"{meta.get('segment_id', '')}.flac", title=f"{args.clip_id} + SMPL",
                contact=clip.contact, smpl=smpl.joints)
    print(f"wrote {args.out}: the world skeleton with the SMPL skeleton in yellow")
    return 0


def _render_group(root: Path, segment_id: str, out: Path) -> int:
    from pipeline.core.paths import AUDIO, RAW, SEGMENTS, WORLD
    from pipeline.core.storage import read_meta
    from pipeline.ingest.catalog import read_index
    from pipeline.ingest.segmentvideo import SegmentVideo
    from pipeline.motion.render_group import render_group
    from pipeline.motion.world.worldfile import read_world

    world = root / WORLD / f"{segment_id}.parquet"
    row = read_index(root / SEGMENTS).get(segment_id)
    try:
        if not world.exists():
            raise InputError(world, "no world file for this segment (run the ground stage first)")
        if row is None:
            raise InputError(root / SEGMENTS, f"segment {segment_id} is not in the index")
        clips = read_world(world)
        render_group(SegmentVideo.from_index(root / RAW, row), clips, float(read_meta(world)["fps"]), out,
                     audio=root / AUDIO / f"{segment_id}.flac", title=segment_id)
    except Dance3dError as exc:
        _say(exc)
        return 2
    print(f"wrote {out}: {len(clips)} dancers")
    return 0


def _export_bvh(args: argparse.Namespace) -> int:
    from pipeline.core.storage import read_meta
    from pipeline.motion.motionfile import read_clips
    from pipeline.motion.world.scene import ground_scene

    if args.all == (args.clip_id is not None):
        print("dance3d export bvh: give MOTION CLIP_ID OUT.bvh, or MOTION --all OUT_FOLDER", file=sys.stderr)
        return 2
    if args.clip_id is not None and _clip_of(args.motion, args.clip_id) is None:
        return 2
    fps = float(read_meta(args.motion).get("fps", 24.0))
    clips = read_clips(args.motion)
    # The corpus's grounding: in the segment's scene, one skeleton, the contact-anchored root, feet on the floor.
    scene = ground_scene(clips, fps)
    if not args.all:
        grounded = scene.clips[[c.clip_id for c in clips].index(args.clip_id)]
        print(f"wrote {args.out}: " + _write_bvh(grounded, fps, args.out))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    for clip, grounded, scale in zip(clips, scene.clips, scene.scales):
        out = args.out / f"{clip.clip_id}.bvh"
        print(f"wrote {out}: starts at frame {int(clip.frame[0])} ({clip.time[0]:.2f} s; in Blender, move its action "
              f"there), scale {scale:.3f} onto the scene's floor; " + _write_bvh(grounded, fps, out))
    return 0


def _export_smpl_bvh(args: argparse.Namespace) -> int:
    from pipeline.core.storage import read_meta
    from pipeline.motion.bvh_export import write_bvh
    from pipeline.motion.smpl.bvh import smpl_skeleton_motion
    from pipeline.motion.world.worldfile import read_world

    if args.all == (args.clip_id is not None):
        print("dance3d export bvh --smpl: give WORLD CLIP_ID OUT.bvh, or WORLD --all OUT_FOLDER", file=sys.stderr)
        return 2
    if args.all:  # every dancer of the segment, in its one scene
        try:
            clips = [c for c in read_world(args.motion) if c.smpl_poses is not None]
        except Dance3dError as exc:
            _say(exc)
            return 2
        args.out.mkdir(parents=True, exist_ok=True)
        outs = [(c, args.out / f"{c.clip_id}.bvh") for c in clips]
    else:
        clip = _world_clip_of(args.motion, args.clip_id)
        if clip is None:
            return 2
        outs = [(clip, args.out)]
    fps = float(read_meta(args.motion).get("fps", 24.0))
    for clip, out in outs:
        scale = float(clip.facts["smpl_scaling"])
        write_bvh(out, smpl_skeleton_motion(clip.smpl_poses, clip.smpl_trans, scale), fps)
        print(f"wrote {out}: {len(clip.smpl_poses)} frames at {fps:g} fps on the SMPL skeleton (scale {scale:.3f}), "
              f"from frame {int(clip.frame[0])} ({clip.time[0]:.2f} s)")
    return 0


def _exported(root: Path, name: str, run, empty: str):
    """What an export wrote, given the corpus's val share; None after one line saying why not."""
    from pipeline.core.params import load_params, stage_params

    val_fraction = float(stage_params(load_params(root / "params.yaml"), "shard").get("val_fraction", 0.2))
    try:
        written = run(val_fraction)
    except Dance3dError as exc:
        _say(exc)
        return None
    if not written:
        print(f"dance3d export {name}: {empty}", file=sys.stderr)
        return None
    return written


def _export_aistpp(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.aistpp import export

    sequences = _exported(root, "aistpp", lambda val: export(root, args.out, val, args.fps),
                          "no clip has SMPL motion and audio: run `dvc repro ground audio`")
    if sequences is None:
        return 2
    frames = sum(len(s.poses) for s in sequences)
    print(f"wrote {args.out}: {len(sequences)} sequences ({sum(s.split == 'train' for s in sequences)} train), "
          f"{frames} frames at {args.fps:g} fps ({frames / args.fps / 60:.1f} minutes); names.csv maps them to clips")
    return 0


def _export_edge(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.edge import export

    slices = _exported(root, "edge", lambda val: export(root, args.out, val, args.length, args.stride),
                       f"no clip has SMPL motion and audio {args.length:g} s long: run `dvc repro ground audio`")
    if slices is None:
        return 2
    train = sum(s.split == "train" for s in slices)
    print(f"wrote {args.out}: {len(slices)} slices of {args.length:g} s from {len({s.sequence for s in slices})} "
          f"sequences ({train} train, {len(slices) - train} test)")
    return 0


def _export_gdance(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.gdance import export

    groups = _exported(root, "gdance", lambda val: export(root, args.out, val, args.min_seconds),
                       f"no segment has two dancers in view together for {args.min_seconds:g} s with SMPL motion "
                       "and audio")
    if groups is None:
        return 2
    seconds = sum(g.poses.shape[1] / g.fps for g in groups)
    print(f"wrote {args.out}: {len(groups)} group sequences, {seconds:.1f} s, "
          f"{sum(g.poses.shape[0] for g in groups)} dancer tracks ({sum(g.split == 'train' for g in groups)} train)")
    return 0


def _write_bvh(grounded, fps: float, out: Path) -> str:
    """Write one grounded clip as BVH; what was written, in words."""
    import numpy as np

    from pipeline.motion.bvh_export import solve_rotations, write_bvh

    world = grounded.joints if grounded.feet is None else np.concatenate([grounded.joints, grounded.feet], 1)
    motion = solve_rotations(world)  # heels and toe tips become joints of their own
    write_bvh(out, motion, fps)
    moved = np.linalg.norm(motion.joints - world, axis=-1)
    return (f"{len(world)} frames, {len(motion.spec)} joints; camera pitch {grounded.pitch_deg:+.1f} "
            f"deg, roll {grounded.roll_deg:+.1f} deg; bone-length CV {grounded.cv_before:.1%} before the one skeleton, "
            f"which moved the joints {1000 * grounded.fit_moved:.1f} mm on average; feet on the floor "
            f"{grounded.contact.mean():.0%} of frames; the BVH's joints are {1000 * moved.mean():.1f} mm from the "
            f"grounded ones on average ({1000 * moved.max():.1f} mm at most)")


def _manifests(root: Path, args: argparse.Namespace) -> int:
    from pipeline.annotate.commands import check_manifests, proposal_options, seed_manifests
    from pipeline.core.params import load_params, stage_params

    params = load_params(root / "params.yaml")
    if args.action == "seed":
        written, kept = seed_manifests(root, proposal_options(params))
        for path in written:
            print(f"wrote {path.relative_to(root)}")
        print(f"{len(written)} manifests proposed, {len(kept)} existing left untouched")
        return 0
    min_clip = float(stage_params(params, "clean").get("min_clip_seconds", 2.0))
    files = [f if f.is_absolute() else Path.cwd() / f for f in args.files]
    problems = check_manifests(root, files, min_clip)
    for problem in problems:
        print(problem)
    errors = sum(1 for p in problems if not p.warning)
    print(f"{errors} errors, {len(problems) - errors} warnings")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
