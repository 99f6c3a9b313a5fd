"""The spatio-temporal transformer lifter keeps the convolutions' interface: the frames at least
half the receptive field from either end, lifted in windows of the training window's length."""

import pytest
import torch

from pipeline.motion.lifting.transformer import SpatioTemporalTransformer


def _model() -> SpatioTemporalTransformer:
    torch.manual_seed(0)
    return SpatioTemporalTransformer(17, 17, receptive_field=9, chunk=4, dim=16, depth=1, heads=2).eval()


def test_it_lifts_the_frames_a_convolution_of_the_same_receptive_field_would() -> None:
    model = _model()
    for frames in (9, 12, 30, 31):
        assert model(torch.randn(2, frames, 17, 2)).shape == (2, frames - 8, 17, 3)
    with pytest.raises(ValueError, match="fewer than the receptive field"):
        model(torch.randn(1, 8, 17, 2))


def test_a_long_input_is_lifted_window_by_window_as_the_training_window_sees_it() -> None:
    model = _model()
    x = torch.randn(1, 40, 17, 2)
    with torch.no_grad():
        whole = model(x)
        second = model(x[:, 4: 4 + model.window])  # the second window: output frames 4..7 of the whole
    assert torch.allclose(whole[:, 4:8], second, atol=1e-5)


def test_it_learns_a_fixed_lift() -> None:
    model = _model().train()
    x = torch.randn(8, model.window, 17, 2)
    target = torch.cat([x[:, 4:8], x[:, 4:8, :, :1]], dim=-1)  # depth = x, a rule it can learn
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(60):
        loss = (model(x) - target).abs().mean()
        first = first if first is not None else loss.item()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    assert loss.item() < 0.5 * first
