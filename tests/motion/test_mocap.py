"""Motion capture in canonical form: every source parses to a sane human."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.motion.lifting.geometry import look_at, project, to_camera
from pipeline.motion.mocap.skeleton import bone_lengths, coco_from_h36m
from pipeline.motion.mocap.sources import MARKER_SOURCES, SOURCES, load_source, resample
from pipeline.motion.quality import LIMBS

# CMU 85: jumps, flips and breakdance floor work (MOCAP.md §14).
ACROBATICS = ("backflip", "cartwheel", "crawl", "roll", "getup", "sideflip", "spinkick", "humanoid3d_spin", "005_06",
              "mocap_recovery_c3d/85_")


@pytest.fixture(scope="module")
def sequences(mocap_dir: Path) -> dict:
    return {source: load_source(mocap_dir, source) for source in SOURCES}


@pytest.mark.parametrize("source", SOURCES)
def test_every_source_gives_a_human_with_rigid_limbs_and_head_up(sequences: dict, source: str) -> None:
    seqs = sequences[source]
    assert seqs
    for seq in seqs:
        assert seq.h36m.shape == seq.coco.shape == (seq.frames, 17, 3)
        assert np.isfinite(seq.h36m).all() and np.isfinite(seq.coco).all()
        limbs = bone_lengths(seq.h36m)[:, LIMBS]
        cv = limbs.std(0) / limbs.mean(0)
        # Forward kinematics keeps bones rigid; Tang's marker-like data and joint centres estimated
        # from skin markers (ChoreoNet, CMU and HDM05's C3D) vary a little (MOCAP.md §8, §8b, §14).
        assert cv.max() < (0.2 if source in ("tang2018_ballroom", *MARKER_SOURCES) else 1e-6), seq.name
        head_up = (seq.h36m[:, 10, 1] > seq.h36m[:, 0, 1]).mean()
        if any(a in seq.name for a in ACROBATICS):
            assert head_up > 0.3, seq.name
            continue
        assert head_up > 0.95, seq.name
        height = np.median(seq.h36m[:, 10, 1] - np.minimum(seq.h36m[:, 3, 1], seq.h36m[:, 6, 1]))
        assert 0.8 < height < 2.0, (seq.name, height)


# Median thigh / shin / upper arm / forearm (cm), from MOCAP.md's independent parse check.
DOCUMENTED_LIMBS = {"bandai_namco_1": (39, 41, 24, 22), "cmu_subject05_iclone": (48, 50, 25, 26),
                    "perfume": (37, 37, 26, 22), "dancedb_ucy": (44, 41, 27, 25)}


@pytest.mark.parametrize("source", sorted(DOCUMENTED_LIMBS))
def test_limb_lengths_match_the_documented_figures(sequences: dict, source: str) -> None:
    lengths = np.median(np.concatenate([bone_lengths(s.h36m)[:, LIMBS] for s in sequences[source]]), 0) * 100
    measured = lengths[[0, 1, 4, 5]]  # right thigh, shin; left upper arm, forearm
    assert np.abs(measured - DOCUMENTED_LIMBS[source]).max() <= 1.5, measured


def test_left_is_left(sequences: dict) -> None:
    # Standing still and facing the way the hips say, the left wrist and ankle are on the left.
    for source in ("perfume", "bandai_namco_2_subset", "cmu_subject05_iclone", "choreonet_c3d", "bandai_namco_2_more",
                   "cmu_salsa_60_61", "mocap_recovery_c3d"):
        seq = sequences[source][0]
        h = seq.h36m[0]
        left = h[4] - h[1]
        assert np.dot(h[13] - h[16], left) > 0 and np.dot(h[6] - h[3], left) > 0


def test_left_agrees_with_the_facing_on_most_frames_of_every_source(sequences: dict) -> None:
    # MOCAP.md §10: the left hip lies to the left of the way the toes point (0.92-1.0 of frames per source;
    # acrobatics aside, where the toes point anywhere).
    for source, seqs in sequences.items():
        upright = [s for s in seqs if not any(a in s.name for a in ACROBATICS)]
        h = np.concatenate([s.h36m for s in upright])
        feet = np.concatenate([s.feet for s in upright])
        facing = ((feet[:, 2] + feet[:, 3]) - (feet[:, 0] + feet[:, 1])) * [1.0, 0.0, 1.0]
        left = h[:, 4] - h[:, 1]
        on_left = np.cross(facing, left)[:, 1] > 0  # y up, right-handed: facing x left points up
        assert on_left.mean() > 0.9, (source, on_left.mean())


def test_the_salsa_is_rescaled_to_adult_size_with_both_partners_in_one_room(sequences: dict) -> None:
    seqs = {s.name.split("/")[1][:5]: s for s in sequences["cmu_salsa_60_61"]}
    assert len(seqs) == 28
    leg = np.median(np.concatenate([bone_lengths(s.h36m)[:, LIMBS][:, :2].sum(1) for s in seqs.values()]))
    assert 0.80 < leg < 0.90, leg  # the adult sources' thigh + shank: 0.74-0.98 m
    lead, follow = seqs["60_01"], seqs["61_01"]
    assert lead.frames == follow.frames
    apart = np.linalg.norm((lead.h36m[:, 0] - follow.h36m[:, 0])[:, [0, 2]], axis=-1)
    # MOCAP.md: 1.6 units apart at the first frame, 0.55 at frame 2000 (about 2.1 and 0.7 m here).
    assert abs(apart[0] - 1.6 * 1.32) < 0.1 and abs(apart[2000] - 0.55 * 1.32) < 0.1, apart[[0, 2000]]


def test_face_points_sit_around_the_head(sequences: dict) -> None:
    seq = sequences["perfume"][0]
    coco = coco_from_h36m(seq.h36m)
    head = seq.h36m[:, 9]
    for k in range(5):
        distance = np.linalg.norm(coco[:, k] - head, axis=-1)
        assert np.all((distance > 0.02) & (distance < 0.2))
    left = seq.h36m[:, 4] - seq.h36m[:, 1]
    assert (np.einsum("ti,ti->t", coco[:, 1] - coco[:, 2], left) > 0).mean() > 0.99  # left eye on the left


def test_projection_round_trip(sequences: dict) -> None:
    seq = sequences["dancedb_ucy"][0]
    points = seq.coco[:50]
    rotation = look_at(np.array([0.5, 1.6, 4.0]), np.array([0.0, 1.0, 0.0]))
    cam = to_camera(points, rotation, np.array([0.5, 1.6, 4.0]))
    xy = project(cam, 1000.0, 1280, 720)
    # Lift with the ground-truth depth: unproject and return to the world.
    back_cam = np.concatenate([(xy - [640, 360]) / 1000.0 * cam[..., 2:3], cam[..., 2:3]], -1)
    world = back_cam @ rotation + np.array([0.5, 1.6, 4.0])
    assert np.abs(world - points).max() < 1e-9


def test_resampling_keeps_duration(sequences: dict) -> None:
    seq = sequences["animated_drawings_fair"][0]
    slow = resample(seq, 25.0)
    assert slow.fps == 25.0
    assert abs(slow.frames / 25.0 - seq.frames / seq.fps) < 1 / 25


def test_joint_centres_from_markers_lie_inside_the_body(sequences: dict, mocap_dir: Path) -> None:
    from pipeline.motion.mocap.markers import hip_centres, read_c3d

    seq = sequences["choreonet_c3d"][0]
    markers, rate = read_c3d(mocap_dir / "choreonet_c3d" / f"{seq.name.split('/')[1]}.c3d")
    assert rate == 80.0 and seq.fps == 80.0
    left_hip, right_hip = hip_centres(markers)
    # Hip centres sit below the waist markers (the dancer is mostly upright) and a hip's width apart.
    for hip, side in ((left_hip, "L"), (right_hip, "R")):
        waist = (markers[f"{side}FWT"][:, 1] + markers[f"{side}BWT"][:, 1]) / 2
        assert (hip[:, 1] < waist).mean() > 0.99
    width = np.linalg.norm(left_hip - right_hip, axis=-1)
    assert np.all((width > 0.12) & (width < 0.25)), width.min()
    # Knees and ankles move medially from the lateral markers: the joints are closer together.
    h = seq.h36m
    assert np.median(np.linalg.norm(h[:, 2] - h[:, 5], axis=-1)) < np.median(
        np.linalg.norm(markers["RKNE"] - markers["LKNE"], axis=-1)) - 0.05
    # Left and right limbs agree within 15 % (the markers themselves differ by up to 10 % in this
    # take: shoulder-to-elbow marker distance 33.8 cm left, 30.8 cm right).
    limbs = np.median(bone_lengths(h)[:, LIMBS], 0)
    assert np.all(np.abs(limbs[[0, 1, 4, 5]] / limbs[[2, 3, 6, 7]] - 1) < 0.15), limbs


def test_the_two_choreonet_dancers_differ_in_size(sequences: dict) -> None:
    # The held-out split takes the ll_/mm_ files as an unseen performer: their legs are longer.
    seqs = sequences["choreonet_c3d"]
    thigh = {s.name: np.median(bone_lengths(s.h36m)[:, LIMBS][:, 0]) for s in seqs}
    second = [v for k, v in thigh.items() if k.split("/")[1].startswith(("ll_", "mm_"))]
    first = [v for k, v in thigh.items() if k.split("/")[1][0].isdigit()]
    assert len(second) == 22 and len(first) == 11
    assert min(second) > max(first) + 0.03


def test_an_unreadable_c3d_names_the_file(tmp_path: Path) -> None:
    from pipeline.core.errors import InputError
    from pipeline.motion.mocap.markers import read_c3d

    bad = tmp_path / "take.c3d"
    bad.write_bytes(b"not a c3d file at all" * 40)
    with pytest.raises(InputError, match=r"take\.c3d: cannot read the C3D file"):
        read_c3d(bad)


@pytest.mark.parametrize("source", SOURCES)
def test_every_source_has_heels_behind_the_ankles_and_toe_tips_ahead(sequences: dict, source: str) -> None:
    for seq in sequences[source]:
        assert seq.feet.shape == (seq.frames, 4, 3) and np.isfinite(seq.feet).all()
        for ankle, heel, toe in ((6, 0, 2), (3, 1, 3)):  # left, right (skeleton.FEET order)
            a, h, t = seq.h36m[:, ankle], seq.feet[:, heel], seq.feet[:, toe]
            foot = np.linalg.norm(t - h, axis=-1)
            along = ((a - h) * (t - h)).sum(-1) / foot ** 2  # the ankle's place along heel -> toe
            size = 0.6 if "5yr_old" in seq.name or "8yr_old" in seq.name else 1.0
            assert 0.15 * size < np.median(foot) < 0.33, (seq.name, np.median(foot))
            assert 0.0 < np.median(along) < 0.6, (seq.name, np.median(along))
        # Feet reach the floor: the lowest heel and toe are near the lowest point of the body.
        if not any(a in seq.name for a in ACROBATICS):
            low = np.percentile(seq.feet[..., 1], 2)
            assert np.percentile(seq.feet[:, :, 1], 5, axis=0).max() - low < 0.1, seq.name


def test_a_foot_placed_from_its_ball_stands_flat_like_the_template() -> None:
    from pipeline.motion.mocap.skeleton import FOOT_TEMPLATE, foot_points

    size = 1.7
    ankle = np.array([[0.0, 0.039 * size, 0.0]])
    knee = ankle + [0.0, 0.45, 0.0]
    ball = ankle + np.array([FOOT_TEMPLATE["ball"][0], FOOT_TEMPLATE["ball"][1], 0.0]) * size
    points = foot_points(knee, ankle, ball, "ball", size)
    for name in ("heel", "tip"):
        x, y = FOOT_TEMPLATE[name]
        np.testing.assert_allclose(points[name][0], ankle[0] + np.array([x, y, 0.0]) * size, atol=1e-9)
    # A foot pointed 40 degrees further (the shank still upright): heel and tip turn with it.
    c, s = np.cos(np.radians(-40)), np.sin(np.radians(-40))
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pointed = foot_points(knee, ankle, ankle + (ball - ankle) @ turn.T, "ball", size)
    for name in ("heel", "tip"):
        np.testing.assert_allclose(pointed[name] - ankle, (points[name] - ankle) @ turn.T, atol=1e-9)
    # With the floor known, toes that would pass below the sole bend up at the ball instead.
    on_ball = foot_points(knee, ankle, ankle + (ball - ankle) @ turn.T, "ball", size, floor=pointed["ball"][0, 1])
    assert on_ball["tip"][0, 1] >= pointed["ball"][0, 1] - 1e-9
    np.testing.assert_allclose(np.linalg.norm(on_ball["tip"] - on_ball["ball"]),
                               np.linalg.norm(pointed["tip"] - pointed["ball"]))


def test_a_joint_file_may_carry_feet_and_says_when_they_do_not_fit(tmp_path: Path, sequences: dict) -> None:
    from pipeline.core.errors import InputError
    from pipeline.motion.mocap.sources import load_joints_npz

    seq = sequences["perfume"][0]
    np.savez(tmp_path / "take.npz", joints=seq.h36m[:50], fps=seq.fps, feet=seq.feet[:50])
    np.testing.assert_allclose(load_joints_npz(tmp_path / "take.npz").feet, seq.feet[:50])
    np.savez(tmp_path / "short.npz", joints=seq.h36m[:50], fps=seq.fps, feet=seq.feet[:40])
    with pytest.raises(InputError, match=r"short\.npz: 'feet' must be finite, 50 x 4 x 3"):
        load_joints_npz(tmp_path / "short.npz")
