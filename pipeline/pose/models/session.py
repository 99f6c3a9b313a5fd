"""ONNX Runtime sessions: CUDA when onnxruntime-gpu is installed, else CPU."""

from __future__ import annotations

from pathlib import Path

import onnxruntime as ort


def providers() -> list[str]:
    available = ort.get_available_providers()
    return [p for p in ("CUDAExecutionProvider", "CPUExecutionProvider") if p in available]


def create_session(path: Path, threads: int = 1, *, any_batch: bool = False) -> ort.InferenceSession:
    """A session with ``threads`` intra-op threads (0: onnxruntime's default); with ``any_batch``,
    on the model edited to take a batch of crops (``batching.any_batch``)."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = max(0, int(threads))
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    if any_batch:
        from pipeline.pose.models.batching import any_batch as edited

        return ort.InferenceSession(edited(Path(path)), options, providers=providers())
    return ort.InferenceSession(str(path), options, providers=providers())
