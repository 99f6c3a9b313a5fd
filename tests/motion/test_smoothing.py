"""Hodrick-Prescott filter (statsmodels is the reference) and 24 fps cubic resampling."""

from __future__ import annotations

import numpy as np
import pytest
from statsmodels.tsa.filters.hp_filter import hpfilter

from pipeline.motion.resample import grid_frames, resample_cubic
from pipeline.motion.smoothing import hp_trend


def reference(y: np.ndarray, lamb: float) -> np.ndarray:
    return np.column_stack([hpfilter(y[:, k], lamb)[1] for k in range(y.shape[1])])


@pytest.mark.parametrize("n", [3, 4, 5, 7, 100, 1500])
@pytest.mark.parametrize("lamb", [1.0, 10.0])
def test_hp_trend_equals_statsmodels_on_random_series(n: int, lamb: float) -> None:
    y = np.random.default_rng(n).normal(size=(n, 51)).cumsum(0)
    assert np.abs(hp_trend(y, lamb) - reference(y, lamb)).max() < 1e-8


def test_hp_trend_equals_statsmodels_on_real_motion(mocap_dir) -> None:
    from pipeline.motion.mocap.sources import load_source

    seq = load_source(mocap_dir, "dancedb_ucy")[0]
    y = seq.h36m.reshape(seq.frames, -1)
    assert np.abs(hp_trend(y, 1.0) - reference(y, 1.0)).max() < 1e-8
    # all series of a clip at once keep their shape
    assert hp_trend(seq.h36m, 1.0).shape == seq.h36m.shape


def test_hp_trend_removes_jitter_but_keeps_a_line() -> None:
    t = np.arange(200, dtype=float)
    line = 0.01 * t
    assert np.allclose(hp_trend(line[:, None], 1.0)[:, 0], line, atol=1e-10)  # D annihilates lines
    noisy = line + np.random.default_rng(0).normal(0, 0.01, 200)
    smooth = hp_trend(noisy[:, None], 1.0)[:, 0]
    assert np.abs(np.diff(smooth, 2)).mean() < 0.5 * np.abs(np.diff(noisy, 2)).mean()


@pytest.mark.parametrize("fps", [24000 / 1001, 25.0, 30000 / 1001, 30.0, 50.0, 60000 / 1001, 60.0])
def test_resampling_reproduces_cubics_on_an_exact_24_fps_grid(fps: float) -> None:
    times = 1.37 + np.arange(int(7.3 * fps)) / fps  # a clip starting mid-segment
    cubic = np.column_stack([0.3 * times ** 3 - times ** 2 + 2 * times - 1, -0.1 * times ** 3 + 0.5 * times])
    frames, values = resample_cubic(times, cubic)
    new_times = frames / 24
    assert new_times[0] >= times[0] - 1e-9 and new_times[-1] <= times[-1] + 1e-9  # no extrapolation
    assert frames[0] == int(np.ceil(1.37 * 24))
    assert np.array_equal(np.diff(frames), np.ones(len(frames) - 1, dtype=int))  # every grid point, in order
    expected = np.column_stack([0.3 * new_times ** 3 - new_times ** 2 + 2 * new_times - 1,
                                -0.1 * new_times ** 3 + 0.5 * new_times])
    assert np.abs(values - expected).max() < 1e-9
    assert len(frames) == int(np.floor(times[-1] * 24 + 1e-6)) - int(np.ceil(times[0] * 24 - 1e-6)) + 1


def test_grid_frames_include_exact_endpoints() -> None:
    assert list(grid_frames(1.0, 2.0)) == list(range(24, 49))
    assert list(grid_frames(1.0 + 1e-9, 1.5)) == list(range(24, 37))


def test_sight_rays_survive_the_motion_file_smoothing_and_resampling_as_unit_directions(tmp_path) -> None:
    from pipeline.motion.motionfile import MotionClip, read_motion, write_motion
    from pipeline.motion.resample import resample_clip
    from pipeline.motion.smoothing import smooth_clip
    from pipeline.motion.world.trajectory import sight_rays

    n = 60
    rng = np.random.default_rng(0)
    xy = np.array([540.0, 1500.0]) + np.cumsum(rng.normal(0, 3, (n, 4, 2)), 0)   # heels and toes, pixels
    rays = sight_rays(xy, 1200.0, 1080, 1920).astype(np.float32)
    joints = rng.normal(0, 0.3, (n, 17, 3)).astype(np.float32)
    clip = MotionClip("vid_000_1_0", 1, np.arange(n, dtype=np.int32), np.arange(n) / 30.0, joints,
                      np.zeros(n, bool), np.zeros(n, np.int8), feet_rays=rays)
    bare = MotionClip("vid_000_2_0", 2, np.arange(n, dtype=np.int32), np.arange(n) / 30.0, joints,
                      np.zeros(n, bool), np.zeros(n, np.int8))
    path = tmp_path / "m.parquet"
    write_motion(path, [smooth_clip(clip, 1.0), bare], {"segment_id": "vid_000", "fps": 30.0},
                 fingerprint="x", params={}, inputs={})
    kept, without = read_motion(path).clips
    assert np.array_equal(kept.feet_rays, rays) and without.feet_rays is None  # observations: not smoothed
    at24 = resample_clip(kept, 24.0)
    assert np.allclose(np.linalg.norm(at24.feet_rays, axis=-1), 1.0, atol=1e-6)
    # A ray points where its pixel is: the centre pixel looks straight ahead.
    assert np.allclose(sight_rays(np.array([540.0, 960.0]), 1200.0, 1080, 1920), [0.0, 0.0, 1.0])
