"""Per-model CPU runtime table: milliseconds per crop (batch 1) for each 2D model in ONNX Runtime
and in OpenVINO (f32, and bf16 where the CPU has it), at 1 and 2 threads, on the machine it runs on;
and how far each runtime's outputs are from ONNX Runtime's on the same input.

Usage: DANCE3D_MODELS=../shared/models python -m benchmarks.runtimes [--rounds 7] [--calls 30]
                                           [--models rtmdet-nano-person,tinypose,blazepose-full]
                                           [--out benchmarks/results/runtimes.json]

Every configuration is timed in each round, the configurations in turn, so a noisy machine slows
them alike; the figure is the median over rounds of the mean of ``--calls`` calls, after warm-up.
The input is the first frame of the shared MusePose clip resized to each model's input size
(scaled to [0, 1] for BlazePose, standardised for the channels-first models): real pixels for the
timing and the output gaps, not the stage's letterbox or crops, which `eval pose2d` measures.
BlazePose is built without its unused segmentation output, as the stage builds it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from pipeline.core.storage import write_json
from pipeline.pose.models.fetch import resolve_model
from pipeline.pose.models.loading import unused_outputs
from pipeline.pose.models.registry import get_spec
from pipeline.pose.models.session import create_session, openvino_available

CONFIGS = (("onnxruntime", "f32"), ("openvino", "f32"), ("openvino", "bf16"))


def _feed(session, image: np.ndarray, size: tuple[int, int]) -> dict:
    """The session's input filled from a real image resized to the model's input ``size`` (w, h)."""
    import cv2

    port = session.get_inputs()[0]
    channels_last = port.shape[-1] == 3
    w, h = size
    tensor = cv2.resize(image, (w, h)).astype(np.float32) / 255.0
    # BlazePose (channels last) takes [0, 1]; the channels-first models a standardised image.
    tensor = tensor if channels_last else ((tensor - 0.45) / 0.225).transpose(2, 0, 1)
    return {port.name: np.ascontiguousarray(tensor[None])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", default="rtmdet-nano-person,tinypose,blazepose-full")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--calls", type=int, default=30)
    parser.add_argument("--media", type=Path, default=Path(os.environ.get("DANCE3D_MEDIA", "../shared/media")))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/runtimes.json"))
    args = parser.parse_args()
    if not openvino_available():
        raise SystemExit("the openvino package is not installed: nothing to compare")
    from pipeline.ingest.media import iter_frames

    image = next(iter(iter_frames(args.media / "videos/dance_single_music_musepose.mp4"))).image
    sessions = {}
    for name in args.models.split(","):
        spec = get_spec(name)
        path = resolve_model(name)
        for runtime, precision in CONFIGS:
            for threads in (1, 2):
                session = create_session(Path(path), threads, unused_outputs=unused_outputs(spec.kind), runtime=runtime,
                                         precision=precision, device="cpu")
                feed = _feed(session, image, spec.input_size)
                outputs = [o.name for o in session.get_outputs()]
                for _ in range(5):
                    session.run(outputs, feed)
                sessions[(name, runtime, precision, threads)] = (session, feed, outputs)
    times: dict[tuple, list[float]] = {key: [] for key in sessions}
    for _ in range(args.rounds):
        for key, (session, feed, outputs) in sessions.items():
            started = time.perf_counter()
            for _ in range(args.calls):
                session.run(outputs, feed)
            times[key].append(1000 * (time.perf_counter() - started) / args.calls)
    rows = []
    for (name, runtime, precision, threads), values in times.items():
        session, feed, outputs = sessions[(name, runtime, precision, threads)]
        reference, _, _ = sessions[(name, "onnxruntime", "f32", threads)]
        mine, theirs = session.run(outputs, feed), reference.run(outputs, feed)
        pairs = [(np.asarray(a, np.float64), np.asarray(b, np.float64)) for a, b in zip(mine, theirs)]
        # A detector's NMS output may keep another number of boxes: then no element-wise gap.
        gap = max((float(np.max(np.abs(a - b))) for a, b in pairs if a.shape == b.shape and a.size), default=0.0) \
            if all(a.shape == b.shape for a, b in pairs) else float("nan")
        base = statistics.median(times[(name, "onnxruntime", "f32", threads)])
        ms = statistics.median(values)
        rows.append({"model": name, "runtime": runtime, "precision": precision, "threads": threads,
                     "ms_per_crop": round(ms, 2), "speed_vs_onnxruntime": round(base / ms, 2),
                     "max_abs_output_gap": round(gap, 5)})
    import onnxruntime
    import openvino

    result = {"rows": rows, "rounds": args.rounds, "calls": args.calls,
              "versions": {"onnxruntime": onnxruntime.__version__, "openvino": openvino.__version__},
              "machine": f"{platform.machine()} {platform.processor() or ''}, {os.cpu_count()} cores".strip()}
    print(f"{'model':22s} {'runtime':12s} {'prec':5s} {'thr':>3s} {'ms/crop':>8s} {'speed':>6s} {'max gap':>9s}")
    for r in rows:
        print(f"{r['model']:22s} {r['runtime']:12s} {r['precision']:5s} {r['threads']:3d} {r['ms_per_crop']:8.2f} "
              f"{r['speed_vs_onnxruntime']:6.2f} {r['max_abs_output_gap']:9.5f}")
    write_json(args.out, result)
    print(json.dumps(result["versions"]))


if __name__ == "__main__":
    main()
