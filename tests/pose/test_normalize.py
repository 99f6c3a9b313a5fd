"""Model inputs by lookup table: the same float32 values as the arithmetic, bit for bit."""

from __future__ import annotations

import numpy as np

from pipeline.pose.models.detector import MEAN_BGR, STD_BGR, letterbox
from pipeline.pose.models.normalize import IMAGENET, IMAGENET_MEAN_RGB, IMAGENET_STD_RGB, InputTable


def test_a_table_gives_exactly_what_the_arithmetic_gives_in_either_channel_order() -> None:
    pictures = np.random.default_rng(0).integers(0, 256, (3, 32, 24, 3), dtype=np.uint8)
    bgr = ((pictures.astype(np.float32) - MEAN_BGR) / STD_BGR).transpose(0, 3, 1, 2)
    assert np.array_equal(InputTable(tuple(MEAN_BGR), tuple(STD_BGR))(pictures), bgr)
    unit = pictures[..., ::-1].astype(np.float32) / 255.0
    rgb = ((unit - IMAGENET_MEAN_RGB) / IMAGENET_STD_RGB).transpose(0, 3, 1, 2)
    got = IMAGENET(pictures)
    assert np.array_equal(got, rgb) and got.flags["C_CONTIGUOUS"] and got.dtype == np.float32


def test_the_detectors_letterbox_pads_and_normalises_as_before() -> None:
    image = np.random.default_rng(1).integers(0, 256, (90, 160, 3), dtype=np.uint8)
    box = letterbox(image, (64, 64))
    assert box.tensor.shape == (1, 3, 64, 64) and box.scale == 0.4
    assert np.allclose(box.tensor[0, :, 40:, :], ((114 - MEAN_BGR) / STD_BGR)[:, None, None])  # padding below
