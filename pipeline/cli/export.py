"""`dance3d export bvh | aistpp | edge | finedance | gdance`: motion for animation tools and for trainers."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli.messages import complain, say
from pipeline.cli.render import clip_of, contact_rules, motion_clips, world_clip_of
from pipeline.core.errors import Dance3dError


def add_export(sub: argparse._SubParsersAction) -> None:
    export = sub.add_parser("export", help="export motion for animation tools (bvh) and trainers "
                                           "(aistpp, edge, finedance, gdance)")
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
                          "SMPL's names, rest offsets times smpl_scaling, T-pose rest, the world file's frame; with "
                          "hands, SMPL-H's 52 joints, the fingers on the clip's own rest hands); with --all every "
                          "dancer of the segment, where they danced")
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
    finedance = export_sub.add_parser(
        "finedance", help="every dancer's clip on the SMPL-H skeleton, fingers too, in FineDance's layout (LODGE)",
        description="Write the corpus's dancers (data/world, data/audio) as FineDance lays out its dances, for "
                    "LODGE and the whole-body generators trained on FineDance: motion/<name>.npy (T x 315 at 30 "
                    "fps: the root position, then SMPL-H's 52 joints as 6D rotations, y up), music_wav/<name>.wav, "
                    "music_npy/<name>.npy (T x 35 FineDance's music features, the beat column from dance3d's "
                    "beats), splits/{train,test}.txt (the corpus's split by video) and names.csv. LODGE: point "
                    "data/code/preprocess.py at OUT/motion and OUT/music_npy.",
        epilog="fingers come from pose2d.hands (flat where it was off); --template re-solves them onto a joint "
               "template's flat hands: FineDance's smplx_neu_J_1.npy (its licence forbids redistribution, so "
               "dance3d does not ship it) makes LODGE's forward kinematics put the fingers where the corpus's "
               "world hands are")
    finedance.add_argument("out", type=Path, help="the folder to write")
    finedance.add_argument("--template", type=Path, metavar="J.npy",
                           help="joint positions (52 x 3 SMPL-H or 55 x 3 SMPL-X) of the body LODGE's forward "
                                "kinematics poses; default: the fingers relative to each clip's own rest hand")
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
    bvh.set_defaults(handler=export_bvh)
    aistpp.set_defaults(handler=export_aistpp)
    edge.set_defaults(handler=export_edge)
    finedance.set_defaults(handler=export_finedance)
    gdance.set_defaults(handler=export_gdance)


def export_bvh(root: Path, args: argparse.Namespace) -> int:
    return _export_smpl_bvh(args) if args.smpl else _export_world_bvh(root, args)


def _export_world_bvh(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.storage import read_meta
    from pipeline.motion.world.scene import ground_scene

    if args.all == (args.clip_id is not None):
        return complain("dance3d export bvh: give MOTION CLIP_ID OUT.bvh, or MOTION --all OUT_FOLDER")
    clips = motion_clips(args.motion)
    if args.clip_id is not None and clip_of(args.motion, args.clip_id, clips) is None:
        return 2
    fps = float(read_meta(args.motion).get("fps", 24.0))
    # The corpus's grounding: in the segment's scene, one skeleton, the contact-anchored root, feet on the floor.
    scene = ground_scene(clips, fps, contact_rules(root))
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
    from pipeline.motion.smpl.bvh import clip_skeleton_motion
    from pipeline.motion.world.worldfile import read_world

    if args.all == (args.clip_id is not None):
        return complain("dance3d export bvh --smpl: give WORLD CLIP_ID OUT.bvh, or WORLD --all OUT_FOLDER")
    if args.all:  # every dancer of the segment, in its one scene
        try:
            clips = [c for c in read_world(args.motion) if c.smpl_poses is not None]
        except Dance3dError as exc:
            say(exc)
            return 2
        args.out.mkdir(parents=True, exist_ok=True)
        outs = [(c, args.out / f"{c.clip_id}.bvh") for c in clips]
    else:
        clip = world_clip_of(args.motion, args.clip_id)
        if clip is None:
            return 2
        outs = [(clip, args.out)]
    fps = float(read_meta(args.motion).get("fps", 24.0))
    for clip, out in outs:
        scale = float(clip.facts["smpl_scaling"])
        motion = clip_skeleton_motion(clip)
        write_bvh(out, motion, fps)
        tree = "SMPL-H skeleton (52 joints, fingers too)" if len(motion.spec) == 52 else "SMPL skeleton"
        print(f"wrote {out}: {len(clip.smpl_poses)} frames at {fps:g} fps on the {tree} (scale {scale:.3f}), "
              f"from frame {int(clip.frame[0])} ({clip.time[0]:.2f} s)")
    return 0


def _exported(root: Path, name: str, run, empty: str):
    """What an export wrote, given the corpus's val share; None after one line saying why not."""
    from pipeline.core.params import load_params, stage_params

    val_fraction = float(stage_params(load_params(root / "params.yaml"), "shard").get("val_fraction", 0.2))
    try:
        written = run(val_fraction)
    except Dance3dError as exc:
        say(exc)
        return None
    if not written:
        complain(f"dance3d export {name}: {empty}")
        return None
    return written


def export_aistpp(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.aistpp import export

    sequences = _exported(root, "aistpp", lambda val: export(root, args.out, val, args.fps),
                          "no clip has SMPL motion and audio: run `dvc repro ground audio`")
    if sequences is None:
        return 2
    frames = sum(len(s.poses) for s in sequences)
    print(f"wrote {args.out}: {len(sequences)} sequences ({sum(s.split == 'train' for s in sequences)} train), "
          f"{frames} frames at {args.fps:g} fps ({frames / args.fps / 60:.1f} minutes); names.csv maps them to clips")
    return 0


def export_edge(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.edge import export

    slices = _exported(root, "edge", lambda val: export(root, args.out, val, args.length, args.stride),
                       f"no clip has SMPL motion and audio {args.length:g} s long: run `dvc repro ground audio`")
    if slices is None:
        return 2
    train = sum(s.split == "train" for s in slices)
    print(f"wrote {args.out}: {len(slices)} slices of {args.length:g} s from {len({s.sequence for s in slices})} "
          f"sequences ({train} train, {len(slices) - train} test)")
    return 0


def export_finedance(root: Path, args: argparse.Namespace) -> int:
    from pipeline.export.finedance import FINEDANCE_FPS, export, read_template

    try:
        template = None if args.template is None else read_template(args.template)
    except Dance3dError as exc:
        say(exc)
        return 2
    sequences = _exported(root, "finedance", lambda val: export(root, args.out, val, template),
                          "no clip has SMPL motion and audio: run `dvc repro ground audio`")
    if sequences is None:
        return 2
    frames = sum(len(s.motion) for s in sequences)
    print(f"wrote {args.out}: {len(sequences)} sequences ({sum(s.split == 'train' for s in sequences)} train, "
          f"{sum(s.hands for s in sequences)} with hands), {frames / FINEDANCE_FPS / 60:.1f} minutes at "
          f"{FINEDANCE_FPS:g} fps; names.csv maps them to clips")
    return 0


def export_gdance(root: Path, args: argparse.Namespace) -> int:
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


