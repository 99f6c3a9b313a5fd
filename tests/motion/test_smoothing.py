"""Hodrick-Prescott filter (statsmodels is the reference) and 24 fps cubic resampling."""

from __future__ import annotations

import numpy as np
import pytest
from statsmodels.tsa.filters.hp_filter import hpfilter

from pipeline.motion.lifting.infer import denoise_2d
from pipeline.motion.resample import grid_frames, resample_cubic
from pipeline.motion.smoothing import hp_lambda_at, hp_trend


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


def test_a_lambda_given_at_30_fps_smooths_alike_at_other_rates() -> None:
    # The same noisy motion sampled at 30 and at 60 fps: with lambda scaled by the rate's fourth
    # power the two trends agree where their frames meet; with one lambda for both they do not.
    def motion(fps: float) -> np.ndarray:
        t = np.arange(int(10 * fps)) / fps
        return (np.sin(2 * np.pi * 1.5 * t) + 0.5 * np.sin(2 * np.pi * 6.0 * t))[:, None]

    at_30 = hp_trend(motion(30.0), 10.0)[:, 0]
    scaled = hp_trend(motion(60.0), hp_lambda_at(10.0, 60.0, 30.0))[::2, 0]
    same = hp_trend(motion(60.0), 10.0)[::2, 0]
    inner = slice(30, -30)  # away from the ends, where the filter is one-sided
    assert np.abs(scaled - at_30)[inner].max() < 0.03
    assert np.abs(same - at_30)[inner].max() > 0.1


def test_denoising_the_2d_takes_frame_noise_out_and_keeps_the_dance() -> None:
    # A wrist swinging once a second (60 px: two beats at 120 bpm), seen by a pose model with 4 px of
    # frame-to-frame noise. (Lambda 10 at 30 fps passes 98 % of a 1 Hz swing, 77 % at 2 Hz, 39 % at 3 Hz.)
    t = np.arange(300) / 30.0
    path = np.stack([320 + 60 * np.sin(2 * np.pi * t), 240 + 30 * np.cos(2 * np.pi * t)], -1)[:, None]
    noisy = path + np.random.default_rng(0).normal(0, 4.0, path.shape)
    error_before = np.linalg.norm(noisy - path, axis=-1).mean()
    error_after = np.linalg.norm(denoise_2d(noisy, 30.0, 10.0) - path, axis=-1).mean()
    assert error_after < 0.6 * error_before
    assert np.abs(denoise_2d(path, 30.0, 10.0) - path)[10:-10].max() < 6.0  # the swing itself is kept
    assert denoise_2d(noisy, 30.0, 0.0) is noisy  # 0: the 2D as the pose model gave it
    holed = noisy.copy()
    holed[5, 0, 0] = np.nan
    assert np.isfinite(denoise_2d(holed, 30.0, 10.0)[6:]).all()  # a hole stays where it is


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
