"""pose2d and track stages on real clips: coverage, geometry, two dancers, bad input."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipeline.annotate.clipfile import read_clean
from pipeline.core.errors import ModelMissingError
from pipeline.core.failures import read_failures
from pipeline.core.storage import read_meta
from pipeline.ingest.media import probe
from pipeline.pose.models.detector import Detections, RTMDetDetector
from pipeline.pose.models.pose import MoveNetPose
from pipeline.pose.models.session import create_session
from pipeline.pose.pose2d import Pose2dOptions, collect_poses, estimate_segment, find_people, lift_dark
from pipeline.pose.pose2dfile import COCO17, read_pose2d
from pipeline.pose.trackfile import read_tracks
from tests.conftest import (
    ffmpeg,
    make_test_video,
    run_stages,
    set_params,
    write_sources,
)


@pytest.fixture(scope="module")
def models(models_dir: Path):
    det = RTMDetDetector(create_session(models_dir / "rtmdet_nano_person_end2end.onnx"))
    pose = MoveNetPose(create_session(models_dir / "movenet_singlepose_lightning_4_dequant.onnx"))
    return det, pose


def test_dancer_found_in_nearly_every_frame_with_keypoints_in_the_box(dance_clip: Path, models) -> None:
    poses, frames = collect_poses(estimate_segment(dance_clip, 24.0, *models, Pose2dOptions()))
    frame, boxes, kps = poses.frame, poses.box, poses.keypoints
    assert frames == 288
    assert len(np.unique(frame)) >= 0.95 * frames
    confident = kps[:, :, 2] >= 0.3
    inside = ((kps[:, :, 0] >= boxes[:, None, 0] - 5) & (kps[:, :, 0] <= boxes[:, None, 2] + 5)
              & (kps[:, :, 1] >= boxes[:, None, 1] - 5) & (kps[:, :, 1] <= boxes[:, None, 3] + 5))
    assert inside[confident].mean() >= 0.97
    # She faces the camera: her left shoulder and hip are on the image's right.
    top = poses.person == 0
    assert (kps[top, 5, 0] > kps[top, 6, 0]).mean() >= 0.9
    assert (kps[top, 11, 0] > kps[top, 12, 0]).mean() >= 0.9


def test_golden_frame_from_the_stream_has_left_and_right_the_right_way(media_dir: Path, models_dir: Path,
                                                                          models) -> None:
    ref = next(r for r in json.loads((models_dir / "reference_outputs.json").read_text())["images"]
               if r["file"].endswith("dance_frame100.jpg"))
    want = np.array([ref["pose_on_top_person"]["keypoints"][n][:2] for n in COCO17])
    clip = media_dir / "videos/dance_solo_384x496_30fps.mp4"
    result = next(fp for fp in estimate_segment(clip, 30.0, *models, Pose2dOptions()) if fp.frame == 100)
    got = result.keypoints[0, :, :2]
    assert np.median(np.linalg.norm(got - want, axis=1)) <= 5.0  # JPEG vs video decode differ a little
    for left, right in ((5, 6), (7, 8), (9, 10), (11, 12), (13, 14), (15, 16)):
        assert np.linalg.norm(got[left] - want[left]) < np.linalg.norm(got[left] - want[right])


def test_det_every_carries_boxes_between_detections(dance_clip: Path, models) -> None:
    poses, _ = collect_poses(estimate_segment(dance_clip, 24.0, *models, Pose2dOptions(det_every=4)))
    detected, frame = poses.detected, poses.frame
    assert detected[frame % 4 == 0].all() and not detected[frame % 4 != 0].any()
    assert len(np.unique(frame)) >= 0.95 * 288


@pytest.fixture
def two_dancers(tmp_path: Path, media_dir: Path) -> Path:
    """Two real dancers side by side (built with ffmpeg from the shared clips), 6 s."""
    out = tmp_path / "duo.mp4"
    ffmpeg("-i", str(media_dir / "videos/dance_single_music_musepose.mp4"),
           "-i", str(media_dir / "videos/dance_solo_384x496_30fps.mp4"),
           "-filter_complex", "[0:v]fps=24,scale=-2:496[a];[1:v]fps=24[b];[a][b]hstack=inputs=2[v]",
           "-map", "[v]", "-map", "0:a", "-t", "6", "-c:v", "libx264", "-preset", "ultrafast",
           "-c:a", "aac", str(out))
    return out


def test_two_dancers_side_by_side_give_exactly_two_long_tracks_that_never_swap(
        project: Path, two_dancers: Path, models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("duo", two_dancers)])
    set_params(project, "trim", unannotated="whole")
    set_params(project, "pose2d", workers=2)
    run_stages(project, "download", "trim", "pose2d", "track")
    tracks = read_tracks(project / "data/tracks/duo_000.parquet")
    boxes, ids, n_frames = tracks.box, tracks.track_id, tracks.frames_total
    long_tracks = [t for t in np.unique(ids[ids >= 0]) if (ids == t).sum() >= 0.8 * n_frames]
    assert len(long_tracks) == 2
    middle = round(1080 * 496 / 1920 / 2) * 2  # the seam: the left clip is scaled to 280 x 496
    centres = (boxes[:, 0] + boxes[:, 2]) / 2
    sides = {t: set(np.where(centres[ids == t] < middle, "left", "right")) for t in long_tracks}
    assert sorted(map(tuple, sides.values())) == [("left",), ("right",)]  # each id stays on its side
    assert not (project / "data/qc").exists()  # QC videos are made on request
    from pipeline.cli import main

    assert main(["--root", str(project), "qc", "duo_000"]) == 0
    qc = probe(project / "data/qc/duo_000.mp4")
    assert qc.has_audio and qc.frames == n_frames


def test_segment_without_people_is_an_empty_result_not_a_failure(project: Path, tmp_path: Path,
                                                                   models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("pattern", make_test_video(tmp_path / "pattern.mp4", seconds=2))])
    set_params(project, "trim", unannotated="whole")
    set_params(project, "track", qc_videos=True)  # the track stage renders every QC video
    run_stages(project, "download", "trim", "pose2d", "track")
    assert len(read_pose2d(project / "data/pose2d/pattern_000.parquet").poses) == 0
    assert read_failures(project / "data/pose2d") == []
    assert probe(project / "data/qc/pattern_000.mp4").frames == 50


def test_corrupt_packets_in_the_middle_are_skipped(project: Path, media_dir: Path, models_dir: Path,
                                                    monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("solo", media_dir / "videos/dance_solo_384x496_30fps.mp4")])
    (project / "annotations/segments.csv").write_text("video_id,start,end\nsolo,0,4\n")
    run_stages(project, "download", "trim")
    source = project / "data/raw/solo.mp4"  # the segment's frames are read from it
    data = bytearray(source.read_bytes())
    inside = len(data) // 9  # about 2 s into the 18 s file
    data[inside:inside + 3000] = bytes(np.random.default_rng(0).integers(0, 256, 3000, dtype=np.uint8))
    source.write_bytes(bytes(data))
    run_stages(project, "pose2d")
    poses = read_pose2d(project / "data/pose2d/solo_000.parquet").poses
    assert len(set(poses.frame)) >= 0.8 * 120


def test_a_long_segment_is_posed_in_parts_by_both_workers_and_joined_as_one_pass(
        project: Path, media_dir: Path, models_dir: Path, monkeypatch, caplog) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("solo", media_dir / "videos/dance_solo_384x496_30fps.mp4")])
    (project / "annotations/segments.csv").write_text("video_id,start,end\nsolo,0,4\n")
    out = project / "data/pose2d/solo_000.parquet"
    set_params(project, "pose2d", workers=2, part_seconds=0)
    run_stages(project, "download", "trim", "pose2d")
    one = read_pose2d(out)
    out.unlink()
    set_params(project, "pose2d", part_seconds=1)  # four parts of about a second
    with caplog.at_level("INFO"):
        run_stages(project, "pose2d")
    assert "pose2d: 4 items, 0 up to date, 4 to do" in caplog.text
    joined = read_pose2d(out)
    assert joined.fingerprint == one.fingerprint and joined.segment == one.segment
    assert np.array_equal(joined.poses.frame, one.poses.frame)
    assert np.array_equal(joined.poses.keypoints, one.poses.keypoints)
    assert np.array_equal(joined.poses.interpolated_mask(), one.poses.interpolated_mask())
    assert sorted(p.name for p in (project / "data/pose2d").iterdir()) == ["_failures.parquet", "solo_000.parquet"]


def test_missing_model_stops_the_stage_with_one_line(project: Path, tmp_path: Path, models_dir: Path,
                                                      monkeypatch) -> None:
    only_detector = tmp_path / "only-detector"
    only_detector.mkdir()
    (only_detector / "rtmdet_nano_person_end2end.onnx").symlink_to(models_dir / "rtmdet_nano_person_end2end.onnx")
    monkeypatch.setenv("DANCE3D_MODELS", str(only_detector))
    with pytest.raises(ModelMissingError) as err:
        run_stages(project, "pose2d")
    message = str(err.value)
    assert "\n" not in message
    # TinyPose ships in the package; the feet model is the one missing.
    assert message.startswith("model blazepose-full: blazepose_full.onnx not found; "
                              f"put it in {only_detector} or {project / 'models'}")
    assert "dance3d models fetch blazepose-full" in message


def test_the_default_models_put_heels_toes_and_world_landmarks_in_the_data_and_clean_keeps_the_feet(
        project: Path, media_dir: Path, models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    write_sources(project, [("solo", media_dir / "videos/dance_solo_384x496_30fps.mp4")])
    (project / "annotations/segments.csv").write_text("video_id,start,end\nsolo,0,3\n")
    run_stages(project, "download", "trim", "pose2d", "track")
    tracks = read_tracks(project / "data/tracks/solo_000.parquet")
    (project / "manifests/tracks").mkdir()
    (project / "manifests/tracks/solo_000.csv").write_text(  # the annotator keeps her (she barely moves here)
        "track_id,start,end,keep,note,frames,mean_score,box_height,motion,reason\n"
        + "".join(f"{t},{tracks.time[tracks.of(t)][0]:.3f},{tracks.time[tracks.of(t)][-1]:.3f},yes,,,,,,\n"
                  for t in tracks.ids))
    run_stages(project, "clean")
    pose2d = read_pose2d(project / "data/pose2d/solo_000.parquet")
    poses = pose2d.poses
    assert len(set(poses.frame)) >= 0.95 * 90
    assert (poses.person == 0).sum() == len(set(poses.frame))  # one dancer: one box per frame
    hashes = read_meta(project / "data/pose2d/solo_000.parquet")["inputs"]
    assert {"rtmdet-nano-person", "tinypose", "blazepose-full"} <= set(hashes)
    # Heels and toes are confident and hang below the ankles (she stands), within a foot's length.
    height = poses.box[:, 3] - poses.box[:, 1]
    assert (poses.feet[:, :, 2] > 0.5).mean() >= 0.9
    for foot, ankle in ((0, 15), (1, 16), (2, 15), (3, 16)):
        reach = np.linalg.norm(poses.feet[:, foot, :2] - poses.keypoints[:, ankle, :2], axis=1) / height
        assert np.median(reach) < 0.1
    clean = read_clean(project / "data/clean/solo_000.parquet")
    clip = clean.clips[0]
    rows = tracks.of(clip.track_id)
    shared = np.isin(clip.frame, tracks.frame[rows]) & ~clip.interpolated
    by_frame = {int(f): r for f, r in zip(tracks.frame[rows], rows)}
    picked = [by_frame[int(f)] for f in clip.frame[shared]]
    assert np.allclose(clip.feet[shared], tracks.feet[picked])
    assert not hasattr(poses, "world") and not hasattr(clip, "world")  # BlazePose's world landmarks: none read them


def test_a_weak_box_is_a_person_only_when_its_pose_confirms_one(media_dir: Path, default_models) -> None:
    models, opts = default_models
    image = cv2.imread(str(media_dir / "images/dance_frame100.jpg"))
    h, w = image.shape[:2]
    dancer = models.detector.detect(image).boxes[0]
    wall = np.array([0, 0, 0.12 * w, 0.3 * h], np.float32)  # a corner of the room
    lap = np.array([dancer[0], (dancer[1] + dancer[3]) / 2, dancer[2], dancer[3]], np.float32)  # her legs only
    weak = opts.confirm_score + 0.02
    people, batch = find_people(image, Detections(np.stack([dancer, wall]), np.array([weak, weak], np.float32)),
                                models.pose, opts)
    assert len(people) == 1 and np.allclose(people.boxes[0], dancer)  # confirmed by her skeleton; the wall is not
    people, _ = find_people(image, Detections(np.stack([dancer, lap]), np.array([0.9, weak], np.float32)),
                            models.pose, opts)
    assert len(people) == 1  # a weak box inside a sure person is a part of that person
    people, _ = find_people(image, Detections(wall[None], np.array([0.9], np.float32)), models.pose, opts)
    assert len(people) == 0  # even a sure box needs a confident joint (a box around a poster has none)
    people, _ = find_people(image, Detections(lap[None], np.array([0.9], np.float32)), models.pose, opts)
    assert len(people) == 1  # ... and that is all it needs: half a dancer is still a person
    none, _ = find_people(image, Detections(np.stack([dancer]), np.array([weak], np.float32)), models.pose,
                          replace(opts, confirm_score=0.0))
    assert len(none) == 0  # confirmation off: weak boxes are not people


class CountingPose:
    """A body model that records the boxes it is asked to pose and gives each a confident pose
    (every joint at its box's top-left corner + 10 px)."""

    def __init__(self) -> None:
        self.boxes: list = []

    def estimate(self, image, boxes):
        from pipeline.pose.models.pose import PoseBatch

        self.boxes += [tuple(b) for b in boxes]
        kps = np.zeros((len(boxes), 17, 3), np.float32)
        kps[:, :, :2] = np.asarray(boxes, np.float32).reshape(-1, 1, 4)[:, :, :2] + 10
        kps[:, :, 2] = 0.8
        return PoseBatch.body_only(kps)


def test_with_top_k_sure_people_a_smaller_weak_box_is_not_posed_and_a_larger_one_still_is() -> None:
    """Only the top_k largest people are kept: once top_k sure people are posed, a weak box no
    larger than the smallest of them (a bystander in the crowd) cannot be kept, so the body model
    is not run on it; a larger weak box (someone close and cut off) still is, and may be kept."""
    sure_a, sure_b = [0, 0, 100, 300], [200, 0, 290, 280]
    small_weak, large_weak = [400, 0, 450, 100], [500, 0, 700, 400]
    dets = Detections(np.array([sure_a, sure_b, small_weak, large_weak], np.float32),
                      np.array([0.9, 0.8, 0.3, 0.25], np.float32))
    opts = Pose2dOptions(top_k=2, confirm_score=0.15, confirm_joints=6, min_joints=1)
    pose = CountingPose()
    people, batch = find_people(np.zeros((400, 800, 3), np.uint8), dets, pose, opts)
    assert tuple(np.float32(small_weak)) not in pose.boxes and len(pose.boxes) == 3
    assert people.boxes.tolist() == [large_weak, sure_a]  # the two largest, the confirmed weak one first
    assert np.allclose(batch.keypoints[:, 0, :2], [[510, 10], [10, 10]])


def test_a_weak_box_far_smaller_than_the_dancer_is_not_posed_unless_no_share_is_asked() -> None:
    """A bystander far behind a dancer (a weak box under confirm_min_share of the tallest sure
    person's height) is not worth a pose: clean would propose their track keep=no ("small")."""
    dancer, far, nearer = [0, 0, 150, 400], [300, 100, 330, 160], [400, 100, 440, 200]  # 400, 60, 100 px tall
    dets = Detections(np.array([dancer, far, nearer], np.float32), np.array([0.9, 0.3, 0.3], np.float32))
    image = np.zeros((400, 800, 3), np.uint8)
    for share, posed in ((0.2, [dancer, nearer]), (0.0, [dancer, far, nearer])):
        pose = CountingPose()
        opts = Pose2dOptions(confirm_score=0.15, confirm_joints=6, min_joints=1, confirm_min_share=share)
        people, _ = find_people(image, dets, pose, opts)
        assert sorted(pose.boxes) == sorted(tuple(np.float32(b)) for b in posed)
        assert people.boxes.tolist()[:2] == [dancer, nearer]


def test_a_very_dark_frame_is_brightened_so_the_dancer_is_found(media_dir: Path, default_models) -> None:
    models, opts = default_models
    image = cv2.imread(str(media_dir / "images/dance_frame100.jpg"))
    dark = (image.astype(np.float32) * 0.012).round().astype(np.uint8)  # mean pixel value about 2
    assert len(find_people(dark, models.detector.detect(dark), models.pose, opts)[0]) == 0
    lifted = lift_dark(dark, opts.dark_mean)
    assert lifted.mean() > 40
    people, _ = find_people(lifted, models.detector.detect(lifted), models.pose, opts)
    assert len(people) >= 1
    assert lift_dark(image, opts.dark_mean) is image  # a normal frame is left alone


def test_between_detections_the_detector_runs_after_all_where_someone_is_lost_weak_or_overlapping() -> None:
    from pipeline.pose.models.detector import Detections
    from pipeline.pose.pose2d import Pose2dOptions, needs_detection

    opts = Pose2dOptions(det_every=5, confirm_joint_score=0.3, redetect_joints=6, redetect_overlap=0.3)
    two = Detections(np.array([[0, 0, 100, 200], [300, 0, 400, 200]], np.float32), np.array([0.9, 0.8], np.float32))
    sure = np.full((2, 17, 3), 0.9, np.float32)
    assert not needs_detection(two, two, sure, opts)                       # two clear dancers apart: carry on
    one = Detections(two.boxes[:1], two.scores[:1])
    assert needs_detection(two, one, sure[:1], opts)                       # one was lost
    weak = sure.copy()
    weak[1, 5:, 2] = 0.1                                                   # five joints left at 0.3
    assert needs_detection(two, two, weak, opts)
    close = Detections(np.array([[0, 0, 100, 200], [40, 0, 140, 200]], np.float32), two.scores)  # IoU 0.43
    assert needs_detection(two, close, sure, opts)
    assert not needs_detection(two, close, sure, Pose2dOptions(det_every=5, redetect_joints=0))  # on demand: off
