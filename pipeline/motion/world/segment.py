"""The ground stage's work on one segment: every clip of its 24 fps motion grounded in one scene
(``scene.ground_scene``), retargeted onto SMPL (and SMPL-H's fingers where it has hands) and written
as the segment's world file (``worldfile``, which only stores what is made here)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.motion.hands import H36M_WRISTS, world_hands
from pipeline.motion.motionfile import read_motion
from pipeline.motion.smpl.hands import rest_facts, retarget_hands
from pipeline.motion.smpl.kinematics import to_axis_angle
from pipeline.motion.smpl.retarget import retarget
from pipeline.motion.world.contact import ContactRules
from pipeline.motion.world.grounding import GroundedClip
from pipeline.motion.world.scene import ground_scene
from pipeline.motion.world.worldfile import WorldClip, write_world


@dataclass(frozen=True)
class GroundJob:
    motion24: Path
    out: Path
    rules: ContactRules       # when a heel or toe tip is planted
    params: dict
    inputs: dict
    fingerprint: str


def ground_segment(job: GroundJob) -> dict:
    """Ground every clip of a segment's 24 fps motion in one scene (``scene.ground_scene``);
    writes the segment's world file."""
    motion = read_motion(job.motion24)
    scene = ground_scene(motion.clips, motion.fps, job.rules)
    clips = [world_clip(clip.clip_id, clip.track_id, clip.frame, clip.time, grounded, scale, clip.hands,
                        clip.hand_presence)
             for clip, grounded, scale in zip(motion.clips, scene.clips, scene.scales)]
    segment = {k: motion.meta.get(k) for k in ("segment_id", "fps", "source_fps", "width", "height")}
    segment["scene"] = {"pitch_deg": round(scene.frame.camera.pitch_deg, 2),
                        "roll_deg": round(scene.frame.camera.roll_deg, 2),
                        "shared_floor": scene.shared, "clips": len(clips)}
    write_world(job.out, clips, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"clips": len(clips), "learned": sum(c.planted is not None for c in clips)}


def world_clip(clip_id: str, track_id: int, frame: np.ndarray, time: np.ndarray, grounded: GroundedClip,
               scene_scale: float = 1.0, hands: np.ndarray | None = None,
               hand_presence: np.ndarray | None = None) -> WorldClip:
    """A grounded clip as the world file stores it, retargeted onto the SMPL tree; with the motion's
    wrist-relative ``hands`` (and their presence), its hands in the world."""
    smpl = retarget(grounded.joints, grounded.feet)
    local, hand_poses = smpl.local, None
    facts = {"bone_lengths": [round(float(x), 6) for x in grounded.bone_lengths],
             "pitch_deg": round(grounded.pitch_deg, 2), "roll_deg": round(grounded.roll_deg, 2),
             "bone_cv_before": round(grounded.cv_before, 5), "fit_moved_mm": round(1000 * grounded.fit_moved, 2),
             "contact_share": round(float(grounded.contact.mean()), 4),
             "contact_learned": grounded.planted is not None,
             "skate_before_m_s": round(grounded.skate_before, 5), "skate_after_m_s": round(grounded.skate_after, 5),
             "scene_scale": round(float(scene_scale), 4), "smpl_scaling": round(smpl.scale, 6)}
    if hands is not None:
        hands = world_hands(hands, hand_presence, grounded.camera.rotation, grounded.joints[:, list(H36M_WRISTS)])
        fingers = retarget_hands(smpl.local, hands, hand_presence)
        local, hand_poses = fingers.local, fingers.poses
        facts["smpl_hands"] = rest_facts(fingers.rests)
    return WorldClip(clip_id, track_id, frame, time, grounded.joints, grounded.feet, grounded.contact,
                     grounded.planted, grounded.contact_probability, grounded.rotations_6d, facts,
                     to_axis_angle(local), smpl.trans, hands, hand_presence, hand_poses)
