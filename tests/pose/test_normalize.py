"""Model inputs by lookup table: the same float32 values as the arithmetic, bit for bit."""

from __future__ import annotations

import numpy as np

from pipeline.pose.models.detector import MEAN_BGR, STD_BGR, letterbox
from pipeline.pose.models.normalize import channel_table, to_tensor
from pipeline.pose.models.pose import IMAGENET_MEAN, IMAGENET_STD


def test_a_table_gives_exactly_what_the_arithmetic_gives_in_either_channel_order() -> None:
    pictures = np.random.default_rng(0).integers(0, 256, (3, 32, 24, 3), dtype=np.uint8)
    bgr = ((pictures.astype(np.float32) - MEAN_BGR) / STD_BGR).transpose(0, 3, 1, 2)
    assert np.array_equal(to_tensor(pictures, channel_table(MEAN_BGR, STD_BGR)), bgr)
    rgb = ((pictures[..., ::-1].astype(np.float32) / 255.0 - IMAGENET_MEAN) / IMAGENET_STD).transpose(0, 3, 1, 2)
    got = to_tensor(pictures, channel_table(IMAGENET_MEAN, IMAGENET_STD, divide=255.0, swap_rb=True), swap_rb=True)
    assert np.array_equal(got, rgb) and got.flags["C_CONTIGUOUS"] and got.dtype == np.float32


def test_the_detectors_letterbox_pads_and_normalises_as_before() -> None:
    image = np.random.default_rng(1).integers(0, 256, (90, 160, 3), dtype=np.uint8)
    box = letterbox(image, (64, 64))
    assert box.tensor.shape == (1, 3, 64, 64) and box.scale == 0.4
    assert np.allclose(box.tensor[0, :, 40:, :], ((114 - MEAN_BGR) / STD_BGR)[:, None, None])  # padding below
