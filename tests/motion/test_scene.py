"""Group scenes: every dancer of a segment in one world frame, on one floor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.motion.lifting.geometry import look_at, to_camera
from pipeline.motion.motionfile import MotionClip
from pipeline.motion.world.contact import capture_contact
from pipeline.motion.world.grounding import ground_motion
from pipeline.motion.world.scene import ground_scene

FPS = 24.0


def _filmed(world: np.ndarray, feet: np.ndarray, rotation: np.ndarray, position: np.ndarray, clip_id: str,
            too_far: float = 1.0) -> MotionClip:
    """A dancer as the lift stage would give them, but exact: camera-frame pose, root path, heels and
    toes, their contact probabilities and the directions they are seen in; pose and path ``too_far``
    times as large, as a lifter that made the body that much too large would place it (same image)."""
    joints, heels_toes = to_camera(world, rotation, position), to_camera(feet, rotation, position)
    root = joints[:, 0]
    n = len(world)
    contact = capture_contact(feet, FPS).astype(np.float32)
    rays = heels_toes / np.linalg.norm(heels_toes, axis=-1, keepdims=True)
    return MotionClip(clip_id, int(clip_id[-3]), np.arange(n, dtype=np.int32), np.arange(n) / FPS,
                      ((joints - root[:, None]) * too_far).astype(np.float32), np.zeros(n, bool), np.zeros(n, np.int8),
                      (root * too_far).astype(np.float32), ((heels_toes - root[:, None]) * too_far).astype(np.float32),
                      contact, rays.astype(np.float32))


@pytest.fixture(scope="module")
def duo(mocap_dir: Path) -> tuple[list[MotionClip], np.ndarray, np.ndarray]:
    """Two dancers 1.6 m apart, the second 1.5 m further back, both dancing a ChoreoNet take, filmed
    by a phone at 1.2 m pitched 10 degrees down; the second lifted 15 % too large. Returns the
    clips, the true roots in camera coordinates (2 x T x 3) and world up in camera coordinates."""
    from pipeline.motion.mocap.sources import load_source, resample

    takes = [resample(seq, FPS) for seq in load_source(mocap_dir, "choreonet_c3d")[:2]]
    frames = 720  # 30 s: the planted points spread over a metre or two, which the tilt needs
    offsets = [np.array([-0.8, 0.0, 0.0]), np.array([0.8, 0.0, -1.5])]
    position = np.array([0.0, 1.2, 5.0])
    rotation = look_at(position, position + [0.0, -np.tan(np.radians(10.0)), -1.0])
    clips, roots = [], []
    for k, (take, off, too_far) in enumerate(zip(takes, offsets, (1.0, 1.15))):
        shift = take.h36m[:frames, 0].mean(0) * [1, 0, 1] - off
        body, feet = take.h36m[:frames] - shift, take.feet[:frames] - shift
        clips.append(_filmed(body, feet, rotation, position, f"vid_000_{k + 1}_0", too_far))
        roots.append(to_camera(body[:, 0], rotation, position))
    roots = np.stack(roots)
    return clips, roots, rotation @ np.array([0.0, 1.0, 0.0])


def _group_error(roots: np.ndarray, truth: np.ndarray) -> float:
    """Mean distance (m) of every dancer's root from the truth after one similarity transform of the
    whole group: where the dancers are relative to each other, whatever the group's scale."""
    from pipeline.motion.world.evaluate import similarity

    s, r, t = similarity(roots.reshape(-1, 3), truth.reshape(-1, 3))
    return float(np.linalg.norm(s * roots @ r.T + t - truth, axis=-1).mean())


def test_two_dancers_share_one_floor_and_stand_where_they_are_relative_to_each_other(duo) -> None:
    clips, truth, up = duo
    alone = np.stack([ground_motion(c, FPS).root_camera for c in clips])
    scene = ground_scene(clips, FPS)
    together = np.stack([g.root_camera for g in scene.clips])
    # Alone, the dancer lifted too large stands 15 % too far; in the scene the floor puts them back.
    assert _group_error(alone, truth) > 0.15
    assert _group_error(together, truth) < 0.1
    assert scene.scales[1] / scene.scales[0] == pytest.approx(1 / 1.15, rel=0.06)
    assert np.degrees(np.arccos(np.clip(scene.frame.camera.up @ up, -1, 1))) < 1.0
    # One world frame: y up, both dancers' planted points on y = 0, the group's centre at the origin.
    for grounded in scene.clips:
        assert np.abs(grounded.feet[..., 1][grounded.planted]).max() < 1e-6
    centre = np.concatenate([g.joints[:, 0] for g in scene.clips]).mean(0)
    assert abs(centre[0]) < 1e-6 and abs(centre[2]) < 1e-6
    gap = (scene.clips[1].joints[:, 0] - scene.clips[0].joints[:, 0]).mean(0) / np.mean(scene.scales)
    assert np.linalg.norm(gap[[0, 2]] - [1.6, -1.5]) < 0.25  # 1.6 m right, 1.5 m further from the camera


def test_a_scene_without_any_planted_point_seen_grounds_each_dancer_alone(duo) -> None:
    from dataclasses import replace

    clips, _, _ = duo
    blind = [replace(c, feet_rays=None) for c in clips]
    scene = ground_scene(blind, FPS)
    assert scene.scales == [1.0, 1.0]
    for grounded, clip in zip(scene.clips, blind):
        assert np.allclose(grounded.joints, ground_motion(clip, FPS).joints)


def test_eval_group_scores_synthetic_groups_and_the_scene_beats_dancers_grounded_alone(mocap_dir: Path, tmp_path: Path,
                                                                                       capsys) -> None:
    import json

    from pipeline.cli import main
    from stages.train_contact import SHIPPED as CONTACT
    from stages.train_lifter import SHIPPED as LIFTER

    out = tmp_path / "group.json"
    code = main(["eval", "group", "--mocap", str(mocap_dir), "--model", str(LIFTER), "--contact", str(CONTACT),
                 "--groups", "1", "--seconds", "6", "--out", str(out)])
    assert code == 0
    report = capsys.readouterr().out
    assert report.splitlines()[0].split()[:4] == ["dancers", "method", "position", "m"]
    result = json.loads(out.read_text())
    synthetic = [row for row in result["runs"] if row["method"] == "scene" and not row.get("real")]
    assert [row["dancers"] for row in synthetic] == [2, 3, 4, 5, 6]
    scene, alone = result["scene"]["all"], result["baseline"]["all"]
    assert scene["position_m"] < alone["position_m"] and scene["floor_deg"] < alone["floor_deg"]
    assert scene["order_pairs"] > 0 and 0.0 <= scene["order_right"] <= 1.0
    # The real duets beside them: both partners of the held-out salsa takes, one camera each here.
    assert result["protocol"]["real_groups"] == [[f"cmu_salsa_60_61/{lead}_{take}_scaled" for lead in ("60", "61")]
                                                  for take in ("14", "15")]
    assert result["scene"]["real"]["runs"] == 2 and "real: groups captured together" in report


def test_partners_captured_together_keep_their_real_places(mocap_dir: Path) -> None:
    from pipeline.motion.mocap.sources import load_source
    from pipeline.motion.world.group_eval import captured_together, place_together

    pairs = captured_together(load_source(mocap_dir, "cmu_salsa_60_61"))
    assert len(pairs) == 14 and all(a.frames == b.frames for a, b in pairs)
    lead, follow = pairs[0]
    placed, spots = place_together([lead, follow])
    truth = np.linalg.norm(lead.h36m[:, 0] - follow.h36m[:, 0], axis=-1)
    assert np.allclose(np.linalg.norm(placed[0].body[:, 0] - placed[1].body[:, 0], axis=-1), truth)
    assert abs(min(np.percentile(p.body[:, 17:, 1], 5) for p in placed)) < 0.05  # standing on y = 0
    assert np.allclose(spots.shape, (2, 2))


def test_a_formation_keeps_dancers_apart_but_together() -> None:
    from pipeline.motion.world.group_eval import MAX_GAP, MIN_GAP, formation

    rng = np.random.default_rng(0)
    for n in (2, 3, 4, 5, 6):
        spots = formation(n, rng)
        gaps = np.linalg.norm(spots[:, None] - spots[None], axis=-1) + np.eye(n) * 1e9
        assert gaps.min() >= MIN_GAP and (gaps.min(1) <= MAX_GAP).all() and np.allclose(spots.mean(0), 0)


def test_dancers_in_sync_agree_at_the_same_instant_and_not_when_shifted(mocap_dir: Path, tmp_path: Path,
                                                                         capsys) -> None:
    from pipeline.cli import main
    from pipeline.motion.mocap.sources import load_source, resample
    from pipeline.motion.quality import sync_ratio
    from pipeline.motion.world.grounding import ground_clip
    from pipeline.motion.world.segment import world_clip
    from pipeline.motion.world.worldfile import write_world

    dance = resample(load_source(mocap_dir, "choreonet_c3d")[0], FPS).h36m[:240]
    rel = dance - dance[:, :1]
    # The same steps by a dancer 10 % smaller, facing elsewhere, with their own small errors.
    turn = np.array([[np.cos(0.7), 0.0, np.sin(0.7)], [0.0, 1.0, 0.0], [-np.sin(0.7), 0.0, np.cos(0.7)]])
    other = 0.9 * rel @ turn.T + np.random.default_rng(1).normal(0, 0.01, rel.shape)
    assert sync_ratio(rel, other, FPS)["ratio"] < 0.3
    late = np.concatenate([other[24:], other[-24:]])          # one second behind
    assert sync_ratio(rel, late, FPS)["ratio"] > 0.6
    # `dance3d eval sync` reads a world file and reports each pair of clips.
    n = len(rel)
    clips = [world_clip(f"vid_000_{k}_0", k, np.arange(n, dtype=np.int32), np.arange(n) / FPS,
                        ground_clip(pose, None, FPS)) for k, pose in ((1, rel), (2, other))]
    path = tmp_path / "vid_000.parquet"
    write_world(path, clips, {"segment_id": "vid_000", "fps": FPS}, fingerprint="x", params={}, inputs={})
    assert main(["eval", "sync", str(path)]) == 0
    line = capsys.readouterr().out.splitlines()[1].split()
    assert line[:3] == ["vid_000_1_0", "vid_000_2_0", "10.0"] and float(line[-1]) < 0.3


def _first_frames(grounded, n: int):
    """A grounded clip's first ``n`` frames."""
    from dataclasses import replace

    cut = {f: getattr(grounded, f)[:n] for f in ("joints", "contact", "rotations_6d", "feet", "planted",
                                                  "contact_probability") if getattr(grounded, f) is not None}
    return replace(grounded, **cut)


def test_the_group_render_shows_the_video_beside_every_dancer_on_the_floor(duo, tmp_path: Path, capsys) -> None:
    import cv2

    from pipeline.cli import main
    from pipeline.ingest.media import Frame
    from pipeline.motion.render_group import render_group
    from pipeline.motion.world.segment import world_clip

    clips, _, _ = duo
    scene = ground_scene(clips, FPS)
    world = [world_clip(c.clip_id, c.track_id, c.frame[:48], c.time[:48], _first_frames(g, 48))
             for c, g in zip(clips, scene.clips)]

    class Video:  # a segment's video: 30 fps, the frame turning brighter
        def iter_frames(self):
            for k in range(60):
                yield Frame(k, k / 30.0, np.full((360, 640, 3), 4 * k, np.uint8))

    out = tmp_path / "group.mp4"
    render_group(Video(), world, FPS, out, title="vid_000")
    video = cv2.VideoCapture(str(out))
    frames = int(video.get(cv2.CAP_PROP_FRAME_COUNT))
    video.set(cv2.CAP_PROP_POS_FRAMES, 47)
    ok, image = video.read()
    assert frames == 48 and ok and image.shape[0] == 480
    # Left: the video frame at 47 / 24 s (the 58th at 30 fps); right: the floor with both dancers' colours.
    assert abs(float(image[100:300, 100:500].mean()) - 4 * 58) < 6
    floor = image[:, -480:]
    assert (np.abs(floor.astype(int) - (80, 200, 255)).sum(-1) < 60).sum() > 50
    assert (np.abs(floor.astype(int) - (255, 160, 60)).sum(-1) < 60).sum() > 50
    # Without a world file, one line naming it.
    assert main(["--root", str(tmp_path), "render", "--group", "vid_000", str(out)]) == 2
    assert "no world file for this segment" in capsys.readouterr().err

