"""A long segment's 2D in parts: where the parts begin and end, and that joined they are one pass."""

import numpy as np

from pipeline.pose.parts import join_parts, part_path, plan_parts
from pipeline.pose.pose2dfile import Poses, SegmentInfo, write_pose2d


def test_a_short_segment_is_one_part():
    assert plan_parts(300, 24.0, 3, 15.0) == [(0, 300)]       # 12.5 s
    assert plan_parts(2400, 24.0, 3, 0.0) == [(0, 2400)]      # 0: never


def test_parts_share_one_keyframe_and_cover_every_frame():
    spans = plan_parts(1000, 25.0, 3, 15.0)  # 40 s: three parts
    assert len(spans) == 3
    assert spans[0][0] == 0 and spans[-1][1] == 1000
    for (_, end), (start, _) in zip(spans, spans[1:]):
        assert start == end - 1 and start % 3 == 0  # the shared frame is a keyframe


def fake_poses(frames: range, tag: float) -> Poses:
    n = len(frames)
    return Poses(frame=np.array(frames), time=np.array(frames) / 25.0, person=np.zeros(n, int),
                 box=np.full((n, 4), tag), box_score=np.ones(n), keypoints=np.full((n, 17, 3), tag),
                 detected=np.ones(n, bool), feet=np.zeros((n, 4, 3)),
                 interpolated=np.zeros(n, bool))


def test_joined_parts_give_each_frame_once_the_shared_one_from_the_later_part(tmp_path):
    spans = [(0, 7), (6, 13), (12, 20)]
    out = tmp_path / "seg.parquet"
    paths = []
    for k, (a, b) in enumerate(spans):
        paths.append(part_path(out, k))
        write_pose2d(paths[-1], fake_poses(range(a, b), float(k)), SegmentInfo("seg", 25.0, b - a, 64, 48),
                     fingerprint="x", params={}, inputs={})
    assert all(p.name.startswith(".") for p in paths)  # no later stage reads a part
    joined = join_parts(paths, spans)
    assert joined.frame.tolist() == list(range(20))
    assert joined.keypoints[6, 0, 0] == 1.0 and joined.keypoints[12, 0, 0] == 2.0


def test_a_segment_posed_in_parts_gives_the_poses_of_one_pass(dance_clip, default_models, tmp_path):
    from pipeline.ingest.segmentvideo import SegmentVideo
    from pipeline.pose.pose2d import Pose2dOptions, collect_poses, estimate_segment

    models, _ = default_models
    view = SegmentVideo(dance_clip, 2.0, 24, 50, 1080, 1920)
    opts = Pose2dOptions(fps=8)  # every 3rd frame posed
    one = collect_poses(estimate_segment(view, 24.0, models.detector, models.pose, opts))[0]
    spans = plan_parts(50, 24.0, 3, 0.7)
    assert len(spans) == 3
    paths = []
    for k, span in enumerate(spans):
        part, frames = collect_poses(estimate_segment(view, 24.0, models.detector, models.pose, opts, span))
        assert frames == span[1] - span[0]
        paths.append(part_path(tmp_path / "seg.parquet", k))
        write_pose2d(paths[-1], part, SegmentInfo("seg", 24.0, frames, 1080, 1920), fingerprint="x", params={},
                     inputs={})
    joined = join_parts(paths, spans)
    for name in ("frame", "person", "box", "keypoints", "feet", "detected", "interpolated"):
        assert np.array_equal(getattr(joined, name), np.asarray(getattr(one, name), getattr(joined, name).dtype)), name


def test_a_segment_is_joined_only_when_every_part_is_done_and_a_done_part_is_kept_until_then(tmp_path):
    from fractions import Fraction

    from pipeline.core.itemstage import WorkItem
    from pipeline.ingest.segmentvideo import SegmentVideo
    from pipeline.pose.parts import join_segment, part_items
    from pipeline.pose.pose2d import Pose2dJob, Pose2dOptions
    from pipeline.pose.pose2dfile import read_pose2d

    out = tmp_path / "seg.parquet"
    segment = SegmentInfo("seg", 25.0, 20, 64, 48)
    job = Pose2dJob(SegmentVideo(tmp_path / "raw.mp4", 0.0, Fraction(25), 20, 64, 48), out, segment,
                    Pose2dOptions(), {}, {}, "fp-whole")
    whole = WorkItem("seg", "fp-whole", (out,), job, size=0.8)
    parts = part_items(whole, [(0, 7), (6, 13), (12, 20)])
    assert [p.item_id for p in parts] == ["seg~0", "seg~1", "seg~2"]
    assert len({p.fingerprint for p in parts}) == 3 and [p.size for p in parts] == [0.28, 0.28, 0.32]

    def done(k: int) -> None:  # what pose_segment writes for a part
        a, b = parts[k].payload.span
        write_pose2d(parts[k].outputs[0], fake_poses(range(a, b), float(k)), SegmentInfo("seg", 25.0, b - a, 64, 48),
                     fingerprint=parts[k].fingerprint, params={}, inputs={})

    done(0)
    done(2)  # part 1 failed
    assert join_segment(whole, parts) is None
    assert not out.exists() and parts[0].outputs[0].exists() and parts[2].outputs[0].exists()
    done(1)  # the retry
    assert join_segment(whole, parts) == {"frames": 20, "detections": 20, "frames_with_people": 20}
    joined = read_pose2d(out)
    assert joined.fingerprint == "fp-whole" and joined.segment == segment
    assert joined.poses.frame.tolist() == list(range(20))
    assert not any(p.outputs[0].exists() for p in parts)
