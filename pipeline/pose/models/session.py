"""Sessions for the ONNX models, behind ONNX Runtime's calls (``get_inputs``, ``get_outputs``,
``run``) whichever runtime runs them.

The device (``pose2d.device``): ``auto`` (CUDA when this onnxruntime has it, i.e. onnxruntime-gpu is
installed, else CPU), ``cpu`` or ``cuda``. On the CPU a model may run in ONNX Runtime or in
OpenVINO's CPU runtime (``runtime``), in f32 or, where the CPU has it, bf16 (``precision``): OpenVINO
runs the same ONNX file, read from the same bytes, so a pruned or batch-edited model runs there too.
Which runtime a model gets by default is measured per model (``RUNTIME_CHOICE``,
``benchmarks/runtimes.py``); without the ``openvino`` package everything runs in ONNX Runtime.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import onnxruntime as ort

DEVICES = ("auto", "cpu", "cuda")
CUDA, CPU = "CUDAExecutionProvider", "CPUExecutionProvider"
RUNTIMES = ("auto", "onnxruntime", "openvino")
PRECISIONS = ("f32", "bf16")


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


def openvino_available() -> bool:
    try:
        import openvino  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class Port:
    """An input or output as ONNX Runtime describes it: a name and a shape (a string for a free dimension)."""
    name: str
    shape: list


class OpenVinoSession:
    """An ONNX model compiled by OpenVINO for the CPU, answering ONNX Runtime's session calls."""

    def __init__(self, model: str | bytes, threads: int = 1, precision: str = "f32") -> None:
        import openvino as ov

        core = ov.Core()
        network = core.read_model(model)
        config = {"INFERENCE_NUM_THREADS": max(0, int(threads)), "NUM_STREAMS": 1, "PERFORMANCE_HINT": "LATENCY",
                  "INFERENCE_PRECISION_HINT": precision}
        self.compiled = core.compile_model(network, "CPU", config)
        self.request = self.compiled.create_infer_request()

    @staticmethod
    def _port(port) -> Port:
        shape = [d.get_length() if d.is_static else "batch" for d in port.get_partial_shape()]
        return Port(port.get_any_name(), shape)

    def get_inputs(self) -> list[Port]:
        return [self._port(p) for p in self.compiled.inputs]

    def get_outputs(self) -> list[Port]:
        return [self._port(p) for p in self.compiled.outputs]

    def run(self, output_names: list[str] | None, feed: dict) -> list[np.ndarray]:
        results = self.request.infer(feed, share_inputs=False)
        by_name = {port.get_any_name(): value for port, value in results.items()}
        names = output_names or [p.get_any_name() for p in self.compiled.outputs]
        return [np.array(by_name[name], copy=True) for name in names]


# Measured per model on 2 cores (benchmarks/runtimes.py, docs/pipeline/pose2d.md "Runtimes"): the
# runtime and precision a model kind gets on the CPU when ``pose2d.runtime`` and ``precision`` are auto.
RUNTIME_CHOICE: dict[str, tuple[str, str]] = {}


def choose_runtime(kind: str, runtime: str = "auto", precision: str = "auto",
                   device: str = "auto") -> tuple[str, str]:
    """(runtime, precision) for a model of ``kind``. ``auto`` takes ``RUNTIME_CHOICE`` where OpenVINO
    is installed and the models run on the CPU, else ONNX Runtime in f32; a precision given
    (f32, bf16) overrides the measured one for the models OpenVINO runs."""
    if runtime not in RUNTIMES:
        raise ValueError(f"runtime {runtime!r}: use one of {', '.join(RUNTIMES)}")
    if precision not in ("auto", *PRECISIONS):
        raise ValueError(f"precision {precision!r}: use one of auto, {', '.join(PRECISIONS)}")
    on_cpu = providers(device)[0] == CPU
    measured = RUNTIME_CHOICE.get(kind, ("onnxruntime", "f32"))
    if runtime == "openvino":
        if not openvino_available():
            raise RuntimeError("runtime 'openvino', but the openvino package is not installed: pip install openvino")
        if not on_cpu:
            raise RuntimeError("runtime 'openvino' runs on the CPU; set pose2d.device: cpu")
        return "openvino", precision if precision != "auto" else measured[1]
    # openvino is imported only for a model that runs there: its native runtime is not loaded into a
    # process (and the workers it forks) that does not use it.
    if runtime == "auto" and on_cpu and measured[0] == "openvino" and openvino_available():
        return "openvino", precision if precision != "auto" else measured[1]
    if precision == "bf16":
        raise RuntimeError("precision 'bf16' needs the openvino runtime (ONNX Runtime runs f32 on the CPU)")
    return "onnxruntime", "f32"


def runtime_label(runtime: str, precision: str) -> str | None:
    """What a pose2d file records of its runtime (None for ONNX Runtime in f32, the choice files made
    before there was another: they are not redone)."""
    return None if (runtime, precision) == ("onnxruntime", "f32") else f"{runtime}-{precision}"


def create_session(path: Path, threads: int = 1, *, any_batch: bool = False,
                   unused_outputs: Callable[[str, tuple], bool] | None = None,
                   device: str = "auto", runtime: str = "onnxruntime", precision: str = "f32"):
    """A session with ``threads`` intra-op threads (0: the runtime's default) on ``device``; with
    ``any_batch``, on the model edited to take a batch of crops (``batching.any_batch``); with
    ``unused_outputs(name, shape)``, without those outputs and what only they need (``pruning``).
    ``runtime`` is ``onnxruntime`` or ``openvino`` (``choose_runtime`` resolves ``auto``)."""
    if runtime == "openvino":
        return OpenVinoSession(_model_bytes(path, any_batch, unused_outputs), threads, precision)
    options = ort.SessionOptions()
    options.intra_op_num_threads = max(0, int(threads))
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    return ort.InferenceSession(_model_bytes(path, any_batch, unused_outputs), options, providers=providers(device))


def _model_bytes(path: Path, any_batch: bool, unused_outputs: Callable[[str, tuple], bool] | None) -> str | bytes:
    """The model as a runtime reads it: its path, or its bytes after the edits asked for."""
    model: str | bytes = str(path)
    if any_batch:
        from pipeline.pose.models.batching import any_batch as edited

        model = edited(Path(path))
    if unused_outputs is not None:
        from pipeline.pose.models.pruning import without_outputs

        model = without_outputs(model if isinstance(model, bytes) else Path(path).read_bytes(), unused_outputs)
    return model
