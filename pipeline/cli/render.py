"""`dance3d qc` and `dance3d render`: a segment's QC video, a 3D clip, a group's scene."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pipeline.cli.messages import complain, say
from pipeline.core.errors import Dance3dError, InputError


def add_qc(sub: argparse._SubParsersAction) -> None:
    qc = sub.add_parser("qc", help="render a segment's QC video (boxes, skeletons, track ids, timecodes)",
                        description="Render data/qc/<segment_id>.mp4 from the segment's tracks, read straight from "
                                    "its downloaded video (with audio), and print its path. A QC video newer than "
                                    "its tracks is kept. The review page does the same on first request; set "
                                    "track.qc_videos: true to have the track stage render every segment's.")
    qc.add_argument("segments", nargs="+", help="segment ids (see data/segments/index.parquet or `dance3d status`)")
    qc.set_defaults(handler=render_qc)


def add_render(sub: argparse._SubParsersAction) -> None:
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
    render.set_defaults(handler=render_motion)


def render_qc(root: Path, args: argparse.Namespace) -> int:
    from pipeline.core.params import load_params, stage_params
    from pipeline.pose.qc import qc_video

    kp_min_score = float(stage_params(load_params(root / "params.yaml"), "track").get("kp_min_score", 0.2))
    failed = 0
    for segment_id in args.segments:
        try:
            print(qc_video(root, segment_id, kp_min_score=kp_min_score).relative_to(root))
        except Dance3dError as exc:
            say(exc)
            failed += 1
    return 2 if failed else 0


def motion_clips(motion: Path) -> list:
    """Every clip of a motion file (data/pose3d, data/smooth or data/motion24); another file is
    refused with what it is and what to give instead."""
    from pipeline.core.storage import read_schema
    from pipeline.motion.motionfile import read_clips

    columns = set(read_schema(motion).names)
    if "joints" not in columns or "interpolated" not in columns:
        raise InputError(motion, "is a world file (data/world): give it with --smpl, or give its segment's "
                                 "data/motion24 file" if "smpl_poses" in columns else
                         "is not a motion file (data/pose3d, data/smooth or data/motion24): it has no joints column")
    return read_clips(motion)


def contact_rules(root: Path):
    """The project's contact rules (params.yaml ``ground``; the package's outside a project): a motion
    file is grounded here as the ground stage grounds it."""
    from pipeline.core.params import project_or_default_params, stage_params
    from pipeline.motion.world.contact import ContactRules

    return ContactRules.from_params(stage_params(project_or_default_params(root), "ground"))


def clip_of(motion: Path, clip_id: str, clips: list | None = None):
    """One clip of a motion file (of ``clips``, its clips when already read), or None after saying
    which clips there are."""
    clips = {c.clip_id: c for c in (motion_clips(motion) if clips is None else clips)}
    if clip_id not in clips:
        print(f"dance3d: {motion}: no clip {clip_id!r}; clips: {', '.join(clips) or 'none'}", file=sys.stderr)
    return clips.get(clip_id)


def world_clip_of(path: Path, clip_id: str | None):
    """One retargeted clip of a world file, or None after saying why."""
    from pipeline.motion.world.worldfile import read_world

    try:
        clips = {c.clip_id: c for c in read_world(path)}
    except Dance3dError as exc:
        say(exc)
        return None
    clip = clips.get(clip_id)
    if clip is None:
        print(f"dance3d: {path}: no clip {clip_id!r}; clips: {', '.join(clips) or 'none'}", file=sys.stderr)
    elif clip.smpl_poses is None:
        print(f"dance3d: {path}: clip {clip_id} has no SMPL motion", file=sys.stderr)
        return None
    return clip


def render_motion(root: Path, args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.core.paths import AUDIO
    from pipeline.core.storage import read_meta
    from pipeline.motion.render3d import render_clip

    if args.group:
        return render_group_scene(root, args.group, args.out)
    if args.motion is None or args.clip_id is None:
        return complain("dance3d render: give MOTION CLIP_ID OUT, or --group SEGMENT OUT")
    if args.smpl:
        return render_smpl(root, args)
    clip = clip_of(args.motion, args.clip_id)
    if clip is None:
        return 2
    meta = read_meta(args.motion)
    fps = float(meta.get("fps", 24.0))
    audio = root / AUDIO / f"{meta.get('segment_id', '')}.flac"  # the segment's normalised audio
    if args.world:
        from pipeline.motion.motionfile import read_clips
        from pipeline.motion.world.scene import ground_in_scene

        grounded = ground_in_scene(read_clips(args.motion), args.clip_id, fps, contact_rules(root))
        world = grounded.joints if grounded.feet is None else np.concatenate([grounded.joints, grounded.feet], 1)
        hands = None
        if clip.hands is not None:
            from pipeline.motion.hands import H36M_WRISTS, world_hands

            hands = world_hands(clip.hands, clip.hand_presence, grounded.camera.rotation,
                                grounded.joints[:, list(H36M_WRISTS)])
        render_clip(world, clip.time, fps, args.out, audio=audio, title=args.clip_id, contact=grounded.contact,
                    hands=hands)
    else:
        joints = clip.joints if clip.feet is None else np.concatenate([clip.joints, clip.feet], 1)
        render_clip(joints, clip.time, fps, args.out, audio=audio, title=args.clip_id)
    print(f"wrote {args.out}")
    return 0


def render_smpl(root: Path, args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.core.paths import AUDIO
    from pipeline.core.storage import read_meta
    from pipeline.motion.render3d import render_clip
    from pipeline.motion.smpl.bvh import clip_skeleton_motion
    from pipeline.motion.smpl.hands import rests_from_facts, smplh_hand_points

    clip = world_clip_of(args.motion, args.clip_id)
    if clip is None:
        return 2
    meta = read_meta(args.motion)
    smpl = clip_skeleton_motion(clip)
    fingers = None
    if len(smpl.spec) == 52:  # SMPL-H: the body's 22 joints, the fingers with their tips
        fingers = smplh_hand_points(smpl.local, smpl.joints, rests_from_facts(clip.facts["smpl_hands"]))
    world = clip.joints if clip.feet is None else np.concatenate([clip.joints, clip.feet], 1)
    render_clip(world, clip.time, float(meta.get("fps", 24.0)), args.out,
                audio=root / AUDIO / f"{meta.get('segment_id', '')}.flac", title=f"{args.clip_id} + SMPL",
                contact=clip.contact, smpl=smpl.joints[:, :22 if fingers is not None else 24], hands=clip.hands,
                smpl_hands=fingers)
    print(f"wrote {args.out}: the world skeleton with the SMPL skeleton in yellow"
          + (" (SMPL-H: its fingers by forward kinematics)" if fingers is not None else ""))
    return 0


def render_group_scene(root: Path, segment_id: str, out: Path) -> int:
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
        say(exc)
        return 2
    print(f"wrote {out}: {len(clips)} dancers")
    return 0
