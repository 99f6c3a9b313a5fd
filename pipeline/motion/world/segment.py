"""The ground stage's work on one segment: every clip of its 24 fps motion grounded in one scene
(``scene.ground_scene``) and written as the segment's world file (``worldfile``). Apart from
``grounding``, which the scene and the world file both build on, so neither loops back to it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pipeline.motion.motionfile import read_motion
from pipeline.motion.world.contact import ContactRules
from pipeline.motion.world.scene import ground_scene
from pipeline.motion.world.worldfile import world_clip, write_world


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
