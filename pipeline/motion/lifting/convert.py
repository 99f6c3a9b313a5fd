"""Convert an official VideoPose3D checkpoint (``model_pos`` state dict) to the lifter ONNX.

The architecture is read from the weights' shapes (joints in and out, channels, filter
widths), then checked key by key against the model it implies; anything else is refused
with the reason.
"""

from __future__ import annotations

from pathlib import Path

import torch

from pipeline.core.errors import InputError
from pipeline.motion.lifting.model import TemporalModel


def infer_architecture(state: dict) -> dict:
    """joints_in, joints_out, channels and filter widths implied by a ``model_pos`` state dict."""
    try:
        expand = state["expand_conv.weight"]
        shrink = state["shrink.weight"]
    except KeyError as exc:
        raise ValueError(f"missing {exc.args[0]!r}: not a VideoPose3D TemporalModel state dict") from None
    if expand.dim() != 3 or shrink.dim() != 3:
        raise ValueError("expand_conv.weight and shrink.weight must be Conv1d weights (3 dimensions)")
    channels, in_features, first_width = expand.shape
    if in_features % 2 or shrink.shape[0] % 3:
        raise ValueError(f"expand_conv takes {in_features} inputs and shrink gives {shrink.shape[0]} outputs; "
                         "expected 2 x joints in and 3 x joints out")
    widths = [first_width]
    i = 0
    while f"layers_conv.{2 * i}.weight" in state:
        widths.append(state[f"layers_conv.{2 * i}.weight"].shape[-1])
        i += 1
    return {"joints_in": in_features // 2, "joints_out": shrink.shape[0] // 3, "channels": channels,
            "filter_widths": tuple(int(w) for w in widths)}


def load_official_state(path: Path) -> dict:
    """The ``model_pos`` state dict of a checkpoint file (tensors only; no code is unpickled)."""
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except Exception as exc:
        raise InputError(path, f"cannot read the checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(checkpoint, dict) or "model_pos" not in checkpoint:
        if isinstance(checkpoint, dict):
            keys = ", ".join(sorted(map(str, checkpoint))[:8])
        else:
            keys = type(checkpoint).__name__
        raise InputError(path, f"not a VideoPose3D checkpoint: no 'model_pos' entry (found: {keys})")
    return {k.removeprefix("module."): v for k, v in checkpoint["model_pos"].items()}


def model_from_state(state: dict, source: Path | str = "checkpoint") -> TemporalModel:
    try:
        arch = infer_architecture(state)
        model = TemporalModel(arch["joints_in"], arch["joints_out"], arch["filter_widths"], arch["channels"], 0.0)
    except ValueError as exc:
        raise InputError(source, f"wrong checkpoint layout: {exc}") from None
    expected = {k: v.shape for k, v in model.state_dict().items()}
    given = {k: v.shape for k, v in state.items() if not k.endswith("num_batches_tracked")}
    missing = sorted(k for k in expected if k not in state and not k.endswith("num_batches_tracked"))
    unexpected = sorted(k for k in given if k not in expected)
    wrong = sorted(f"{k} {tuple(given[k])} (expected {tuple(expected[k])})" for k in given
                   if k in expected and given[k] != expected[k])
    if missing or unexpected or wrong:
        parts = []
        if missing:
            parts.append("missing " + ", ".join(missing[:5]) + (" ..." if len(missing) > 5 else ""))
        if unexpected:
            parts.append("unexpected " + ", ".join(unexpected[:5]) + (" ..." if len(unexpected) > 5 else ""))
        if wrong:
            parts.append("wrong shape " + "; ".join(wrong[:5]))
        raise InputError(source, "wrong checkpoint layout: " + "; ".join(parts))
    model.load_state_dict(state, strict=False)
    model.eval()
    return model


def convert_videopose3d(checkpoint: Path, out: Path) -> TemporalModel:
    """Official checkpoint -> lifter ONNX (the COCO-input model: 17 COCO joints in, 17 H36M out)."""
    from pipeline.motion.lifting.train import export_onnx

    model = model_from_state(load_official_state(Path(checkpoint)), checkpoint)
    export_onnx(model, out, {"converted_from": Path(checkpoint).name})
    return model


def model_from_onnx(path: Path) -> TemporalModel:
    """A lifter ONNX exported by dance3d back as a ``TemporalModel`` with the same outputs.

    The export folds each batch norm into the convolution before it, so the convolutions take the
    ONNX's weights and biases and every batch norm becomes the identity (mean 0, variance 1 - eps):
    exact in evaluation mode. Fine-tuning such a model must keep its batch norms in evaluation mode
    (``freeze_batch_norm``), since their batch statistics are gone."""
    import onnx
    from onnx import numpy_helper

    try:
        proto = onnx.load(str(path))
    except Exception as exc:
        raise InputError(path, f"cannot read the ONNX ({type(exc).__name__}: {exc})") from None
    meta = {p.key: p.value for p in proto.metadata_props}
    if "filter_widths" not in meta:
        raise InputError(path, "no filter_widths in the ONNX metadata: not a lifter exported by dance3d")
    weights = {i.name: torch.from_numpy(numpy_helper.to_array(i).copy()) for i in proto.graph.initializer}
    convs = [(weights[n.input[1]], weights[n.input[2]]) for n in proto.graph.node
             if n.op_type == "Conv" and len(n.input) == 3]
    widths = tuple(int(w) for w in meta["filter_widths"].split(","))
    expand, shrink = convs[0][0], convs[-1][0]
    model = TemporalModel(expand.shape[1] // 2, shrink.shape[0] // 3, widths, expand.shape[0], 0.0)
    blocks = [(model.expand_conv, model.expand_bn), *zip(model.layers_conv, model.layers_bn)]
    if len(convs) != len(blocks) + 1:
        raise InputError(path, f"{len(convs)} convolutions in the ONNX; filter widths {widths} imply {len(blocks) + 1}")
    with torch.no_grad():
        for (conv, bn), (weight, bias) in zip(blocks, convs):
            conv.weight.copy_(weight)
            bn.weight.fill_(1.0)
            bn.bias.copy_(bias)
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
        model.shrink.weight.copy_(shrink)
        model.shrink.bias.copy_(convs[-1][1])
    model.eval()
    return model


def freeze_batch_norm(model: torch.nn.Module) -> None:
    """Batch norms in evaluation mode (running statistics, no updates) while the rest trains."""
    for module in model.modules():
        if isinstance(module, torch.nn.BatchNorm1d):
            module.eval()
