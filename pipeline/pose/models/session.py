"""ONNX Runtime sessions on the device ``pose2d.device`` asks for: ``auto`` (CUDA when this
onnxruntime has it, i.e. onnxruntime-gpu is installed, else CPU), ``cpu`` or ``cuda``."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import onnxruntime as ort

DEVICES = ("auto", "cpu", "cuda")
CUDA, CPU = "CUDAExecutionProvider", "CPUExecutionProvider"


def providers(device: str = "auto") -> list[str]:
    """The execution providers for ``device``, best first."""
    if device not in DEVICES:
        raise ValueError(f"device {device!r}: use one of {', '.join(DEVICES)}")
    available = ort.get_available_providers()
    if device == "cuda" and CUDA not in available:
        raise RuntimeError(f"device 'cuda', but this onnxruntime ({ort.__version__}) has no CUDA "
                           f"(it offers {', '.join(available)}): install the gpu extra, "
                           "pip uninstall -y onnxruntime && pip install -e '.[gpu]'")
    return [CUDA, CPU] if device != "cpu" and CUDA in available else [CPU]


def describe(device: str = "auto", threads: int = 1) -> str:
    """Where the models run, for the log: 'CUDA (onnxruntime-gpu 1.x)' or 'CPU, 1 thread per session'."""
    if providers(device)[0] == CUDA:
        return f"CUDA (onnxruntime {ort.__version__}, device {ort.get_device()})"
    return f"CPU, {threads or 'all'} thread{'s' if threads != 1 else ''} per session (onnxruntime {ort.__version__})"


def create_session(path: Path, threads: int = 1, *, any_batch: bool = False,
                   unused_outputs: Callable[[str, tuple], bool] | None = None,
                   device: str = "auto") -> ort.InferenceSession:
    """A session with ``threads`` intra-op threads (0: onnxruntime's default) on ``device``; with
    ``any_batch``, on the model edited to take a batch of crops (``batching.any_batch``); with
    ``unused_outputs(name, shape)``, without those outputs and what only they need (``pruning``)."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = max(0, int(threads))
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    model: str | bytes = str(path)
    if any_batch:
        from pipeline.pose.models.batching import any_batch as edited

        model = edited(Path(path))
    if unused_outputs is not None:
        from pipeline.pose.models.pruning import without_outputs

        model = without_outputs(model if isinstance(model, bytes) else Path(path).read_bytes(), unused_outputs)
    return ort.InferenceSession(model, options, providers=providers(device))
