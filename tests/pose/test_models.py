"""ONNX models: golden outputs, the registry, and the RTMPose SimCC decoder."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from pipeline.core.errors import InputError, ModelMissingError
from pipeline.pose.models import fetch
from pipeline.pose.models.detector import Detections, RTMDetDetector, largest
from pipeline.pose.models.pose import (
    MoveNetPose,
    RTMPose,
    crop_transform,
    decode_simcc,
)
from pipeline.pose.models.session import create_session
from pipeline.pose.pose2dfile import COCO17


@pytest.fixture(scope="module")
def detector(models_dir: Path) -> RTMDetDetector:
    return RTMDetDetector(create_session(models_dir / "rtmdet_nano_person_end2end.onnx"), score_threshold=0.05)


@pytest.fixture(scope="module")
def movenet(models_dir: Path) -> MoveNetPose:
    return MoveNetPose(create_session(models_dir / "movenet_singlepose_lightning_4_dequant.onnx"))


def golden(models_dir: Path) -> list[dict]:
    return json.loads((models_dir / "reference_outputs.json").read_text())["images"]


def test_detector_and_pose_reproduce_the_golden_outputs(models_dir: Path, detector, movenet) -> None:
    shared = models_dir.parent
    checked = 0
    for ref in golden(models_dir):
        image = cv2.imread(str(shared / ref["file"]))
        assert image is not None, ref["file"]
        dets = detector.detect(image)
        expected = np.array(ref["detector"]["top_dets_xyxy_score"])
        assert np.abs(dets.boxes[: len(expected)] - expected[:, :4]).max() <= 2.0
        assert np.abs(dets.scores[: len(expected)] - expected[:, 4]).max() <= 0.01
        assert int((dets.scores >= 0.5).sum()) == ref["detector"]["num_with_score_ge_0.5"]
        if ref.get("pose_on_top_person"):
            kps = movenet.estimate(image, dets.boxes[:1]).keypoints[0]
            want = np.array([ref["pose_on_top_person"]["keypoints"][name] for name in COCO17])
            assert np.abs(kps[:, :2] - want[:, :2]).max() <= 3.0
            assert np.abs(kps[:, 2] - want[:, 2]).max() <= 0.05
            checked += 1
    assert checked == 2


def test_largest_keeps_the_k_biggest_boxes() -> None:
    boxes = np.array([[0, 0, 10, 10], [0, 0, 50, 50], [0, 0, 30, 30], [0, 0, 5, 5]], np.float32)
    top = largest(Detections(boxes, np.array([0.9, 0.6, 0.7, 0.99], np.float32)), 2)
    assert top.boxes[:, 2].tolist() == [50, 30]
    assert top.scores.tolist() == pytest.approx([0.6, 0.7])


def _simcc_model(path: Path, x_peaks: list[int], y_peaks: list[int], w: int = 192, h: int = 256) -> Path:
    """An ONNX graph with RTMPose's interface whose SimCC outputs peak where the test says."""
    sx = np.zeros((1, 17, w * 2), np.float32)
    sy = np.zeros((1, 17, h * 2), np.float32)
    for k in range(17):
        sx[0, k, x_peaks[k]] = 0.9
        sy[0, k, y_peaks[k]] = 0.7 if k % 2 else 0.95
    nodes = [
        helper.make_node("ReduceMean", ["input"], ["m"], axes=[1, 2, 3], keepdims=1),  # N x 1 x 1 x 1
        helper.make_node("Reshape", ["m", "shape"], ["m3"]),                           # N x 1 x 1
        helper.make_node("Mul", ["m3", "zero"], ["z"]),
        helper.make_node("Add", ["z", "cx"], ["simcc_x"]),
        helper.make_node("Add", ["z", "cy"], ["simcc_y"]),
    ]
    inits = [numpy_helper.from_array(sx, "cx"), numpy_helper.from_array(sy, "cy"),
             numpy_helper.from_array(np.zeros(1, np.float32), "zero"),
             numpy_helper.from_array(np.array([-1, 1, 1], np.int64), "shape")]
    graph = helper.make_graph(
        nodes, "tiny_rtmpose",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, ["N", 3, h, w])],
        [helper.make_tensor_value_info("simcc_x", TensorProto.FLOAT, ["N", 17, w * 2]),
         helper.make_tensor_value_info("simcc_y", TensorProto.FLOAT, ["N", 17, h * 2])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)
    onnx.checker.check_model(model)
    onnx.save(model, path)
    return path


def test_rtmpose_decoder_maps_simcc_peaks_back_to_the_image(tmp_path: Path) -> None:
    x_peaks = [20 * k + 10 for k in range(17)]
    y_peaks = [25 * k + 30 for k in range(17)]
    pose = RTMPose(create_session(_simcc_model(tmp_path / "tiny.onnx", x_peaks, y_peaks)))
    image = np.zeros((480, 640, 3), np.uint8)
    boxes = np.array([[100, 50, 220, 410], [400, 100, 460, 180]], np.float32)
    out = pose.estimate(image, boxes).keypoints  # both crops in one batched call
    assert out.shape == (2, 17, 3)
    for i, box in enumerate(boxes):
        m = crop_transform(box, 192, 256)
        crop_xy = np.column_stack([np.array(x_peaks) / 2, np.array(y_peaks) / 2])
        expected = (crop_xy - m[:, 2]) / m[0, 0]
        assert np.allclose(out[i, :, :2], expected, atol=1e-4)
        # a crop point at the crop centre is the box centre in the image
        centre = (np.array([96, 128]) - m[:, 2]) / m[0, 0]
        assert np.allclose(centre, [(box[0] + box[2]) / 2, (box[1] + box[3]) / 2])
    assert np.allclose(out[:, :, 2], np.where(np.arange(17) % 2, 0.7, 0.9))


def test_decode_simcc_takes_the_smaller_maximum() -> None:
    sx, sy = np.zeros((1, 1, 10)), np.zeros((1, 1, 12))
    sx[0, 0, 4], sy[0, 0, 9] = 0.8, 0.3
    assert decode_simcc(sx, sy).tolist() == [[[2.0, 4.5, pytest.approx(0.3)]]]


def test_missing_model_without_download_names_the_file_and_where_to_put_it(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(tmp_path / "empty"))
    with pytest.raises(ModelMissingError) as err:
        fetch.resolve_model("movenet-lightning", tmp_path)
    message = str(err.value)
    assert "\n" not in message
    assert "movenet_singlepose_lightning_4_dequant.onnx not found; put it in" in message
    assert str(tmp_path / "models") in message


def test_failed_download_is_one_clear_line(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(tmp_path / "empty"))
    monkeypatch.setenv("DANCE3D_DOWNLOAD_MIRROR", "http://127.0.0.1:9")  # nothing listens there
    with pytest.raises(ModelMissingError, match=r"rtmdet_nano_person_end2end\.onnx not found in .* download of "
                                                r"http://127\.0\.0\.1:9/raw\.githubusercontent\.com/.* failed"
                                                r".* by hand") as err:
        fetch.resolve_model("rtmdet-nano-person", tmp_path)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "models" / "rtmdet_nano_person_end2end.onnx").exists()


def test_download_with_a_wrong_checksum_is_refused(tmp_path, monkeypatch) -> None:
    from pipeline.pose.models import fetch

    fake = tmp_path / "m.onnx"
    fake.write_bytes(b"not the real model")
    route = dataclasses.replace(fetch.ROUTES["rtmdet-nano-person"][0], url=fake.as_uri())
    monkeypatch.setitem(fetch.ROUTES, "rtmdet-nano-person", (route,))
    monkeypatch.setenv("DANCE3D_MODELS", str(tmp_path / "empty"))
    with pytest.raises(ModelMissingError, match="checksum mismatch"):
        fetch.resolve_model("rtmdet-nano-person", tmp_path)
    assert not (tmp_path / "models" / "rtmdet_nano_person_end2end.onnx").exists()


def test_models_are_found_through_the_environment(models_dir: Path, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    assert fetch.resolve_model("rtmdet-nano-person", tmp_path) == models_dir / "rtmdet_nano_person_end2end.onnx"


def test_heatmap_peaks_are_refined_a_quarter_pixel_toward_the_larger_neighbour() -> None:
    from pipeline.pose.models.pose import decode_heatmaps

    heat = np.zeros((1, 2, 64, 48), np.float32)
    heat[0, 0, 20, 10], heat[0, 0, 20, 11] = 0.9, 0.5   # right neighbour larger: x + 0.25
    heat[0, 1, 5, 7], heat[0, 1, 4, 7] = 0.7, 0.2       # upper neighbour larger: y - 0.25
    out = decode_heatmaps(heat, stride=4)
    assert out[0, 0].tolist() == pytest.approx([10.25 * 4 + 1.5, 20 * 4 + 1.5, 0.9])
    assert out[0, 1].tolist() == pytest.approx([7 * 4 + 1.5, 4.75 * 4 + 1.5, 0.7])


def test_tinypose_beats_movenet_on_the_annotated_images(tmp_path, models_dir: Path, pose2d_eval_dir: Path,
                                                          monkeypatch) -> None:
    from pipeline.cli import main
    from tests.conftest import PROJECT

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    ap = {}
    files = ["--annotations", str(pose2d_eval_dir / "annotations.json"), "--images", str(pose2d_eval_dir / "images")]
    for model in ("movenet-lightning", "tinypose"):
        out = tmp_path / f"{model}.json"
        assert main(["--root", str(PROJECT), "eval", "pose2d", *files, "--pose-model", model, "--out", str(out)]) == 0
        ap[model] = json.loads(out.read_text())["scores"]["all"]["AP"]
    assert ap["tinypose"] > ap["movenet-lightning"] + 0.05  # measured: 0.470 against 0.352


def test_picodet_and_the_fused_detector_find_the_skier_once(models_dir: Path, media_dir: Path) -> None:
    from pipeline.pose.models.detector import FusedDetector, PicoDetDetector

    image = cv2.imread(str(media_dir / "images/human-pose.jpg"))  # one skier, 218 x 346
    pico = PicoDetDetector(create_session(models_dir / "picodet_s_320_pedestrian.onnx"), score_threshold=0.3)
    rtm = RTMDetDetector(create_session(models_dir / "rtmdet_nano_person_end2end.onnx"), score_threshold=0.3)
    for found in (pico.detect(image), FusedDetector([rtm, pico]).detect(image)):
        assert len(found) == 1  # NMS merges the two detectors' boxes of the same person
        x1, y1, x2, y2 = found.boxes[0]
        assert x2 - x1 > 150 and y2 - y1 > 250 and found.scores[0] >= 0.5
    assert len(FusedDetector([rtm, pico]).detect(cv2.imread(str(media_dir / "images/no_person_park.jpg")))) == 0


def test_the_device_picks_cuda_when_onnxruntime_has_it_and_says_how_to_get_it_when_not(monkeypatch) -> None:
    import onnxruntime as ort

    from pipeline.pose.models import session

    monkeypatch.setattr(ort, "get_available_providers", lambda: ["CUDAExecutionProvider", "CPUExecutionProvider"])
    assert session.providers("auto") == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    assert session.providers("cuda")[0] == "CUDAExecutionProvider"
    assert session.providers("cpu") == ["CPUExecutionProvider"]
    assert session.describe("auto").startswith("CUDA") and session.describe("cpu", 2).startswith("CPU, 2 threads")
    monkeypatch.setattr(ort, "get_available_providers", lambda: ["CPUExecutionProvider"])
    assert session.providers("auto") == ["CPUExecutionProvider"]
    with pytest.raises(RuntimeError, match=r"no CUDA.*\.\[gpu\]"):
        session.providers("cuda")
    with pytest.raises(ValueError, match="auto, cpu, cuda"):
        session.providers("gpu")


def test_the_pose2d_models_refuse_cuda_without_it_before_any_work(monkeypatch, models_dir: Path) -> None:
    import onnxruntime as ort

    from pipeline.pose.models.loading import model_files

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    monkeypatch.setattr(ort, "get_available_providers", lambda: ["CPUExecutionProvider"])
    root = Path(__file__).resolve().parents[2]
    files, _ = model_files(root, {"device": "cpu"})
    assert files.device == "cpu"
    # A stage gets one line naming the setting's file, not a traceback.
    with pytest.raises(InputError, match=r"params\.yaml: pose2d\.device 'cuda'.*no CUDA.*\.\[gpu\]"):
        model_files(root, {"device": "cuda"})
    with pytest.raises(InputError, match=r"params\.yaml: pose2d\.device 'gpu'.*auto, cpu, cuda"):
        model_files(root, {"device": "gpu"})


def in_a_process_of_its_own(code: str) -> dict:
    """Run ``code`` (which prints one JSON object) in a fresh Python: OpenVINO's native runtime is
    kept out of the test process, whose later forked workers it does not expect."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_openvino_runs_the_models_as_onnx_runtime_does_in_f32(models_dir: Path) -> None:
    # OpenVINO reads the same ONNX bytes (here BlazePose pruned of its mask, as the stage builds it)
    # and answers the same session calls; in f32 its outputs are ONNX Runtime's to rounding.
    result = in_a_process_of_its_own(f"""
import json
from pathlib import Path
import numpy as np
from pipeline.pose.models.loading import unused_outputs
from pipeline.pose.models.session import create_session
rng, out = np.random.default_rng(0), {{}}
for name, kind in (("tinypose_256x192.onnx", "tinypose"), ("blazepose_full.onnx", "blazepose")):
    pair = [create_session(Path({str(models_dir)!r}) / name, 1, unused_outputs=unused_outputs(kind),
                           runtime=runtime) for runtime in ("onnxruntime", "openvino")]
    port = pair[0].get_inputs()[0]
    feed = {{port.name: rng.uniform(0, 1, port.shape).astype(np.float32)}}
    gaps = [float(np.abs(a - b).max() / max(1.0, float(np.abs(a).max()))) for a, b in
            zip(*(s.run(None, feed) for s in pair))]
    out[kind] = {{"ports": [[(p.name, list(p.shape)) for p in s.get_outputs()] for s in pair],
                 "inputs": [[p.name for p in s.get_inputs()] for s in pair], "gap": max(gaps)}}
print(json.dumps(out))
""")
    for kind, found in result.items():
        assert found["ports"][0] == found["ports"][1] and found["inputs"][0] == found["inputs"][1], kind
        assert found["gap"] < 2e-3, (kind, found["gap"])


def test_auto_runs_each_model_where_it_was_measured_best_and_in_onnx_runtime_without_openvino(monkeypatch) -> None:
    from pipeline.pose.models import session

    monkeypatch.setattr(session, "RUNTIME_CHOICE", {"tinypose": ("openvino", "bf16")})
    monkeypatch.setattr(session, "openvino_available", lambda: True)
    assert session.choose_runtime("tinypose") == ("openvino", "bf16")
    assert session.choose_runtime("tinypose", precision="f32") == ("openvino", "f32")
    assert session.choose_runtime("blazepose") == ("onnxruntime", "f32")  # not measured faster
    assert session.choose_runtime("tinypose", runtime="onnxruntime") == ("onnxruntime", "f32")
    assert session.choose_runtime("blazepose", runtime="openvino") == ("openvino", "f32")
    # The package uninstalled: everything in ONNX Runtime, and asking for OpenVINO says how to get it.
    monkeypatch.setattr(session, "openvino_available", lambda: False)
    assert session.choose_runtime("tinypose") == ("onnxruntime", "f32")
    with pytest.raises(RuntimeError, match="pip install openvino"):
        session.choose_runtime("tinypose", runtime="openvino")
    with pytest.raises(RuntimeError, match="bf16.*openvino"):
        session.choose_runtime("tinypose", precision="bf16")


PARAMS = {"detector": "rtmdet-nano-person", "pose_model": "tinypose+blazepose-full"}  # params.yaml's defaults


def test_openvino_uninstalled_leaves_every_model_in_onnx_runtime(monkeypatch, models_dir: Path) -> None:
    import sys

    from pipeline.pose.models import session
    from pipeline.pose.models.loading import load_pose_models, model_files

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    monkeypatch.setitem(sys.modules, "openvino", None)  # import openvino now fails, as when not installed
    monkeypatch.setattr(session, "RUNTIME_CHOICE", {"tinypose": ("openvino", "f32")})
    root = Path(__file__).resolve().parents[2]
    files, hashes = model_files(root, {**PARAMS, "device": "cpu"})
    assert files.runtimes == () and not any(k.endswith("@runtime") for k in hashes)
    models = load_pose_models(files)
    assert type(models.pose.body.session).__name__ == "InferenceSession"
    with pytest.raises(InputError, match=r"params\.yaml: pose2d\.runtime 'openvino'.*pip install openvino"):
        model_files(root, {**PARAMS, "device": "cpu", "runtime": "openvino"})


def test_a_runtime_other_than_onnx_runtime_f32_is_an_input_of_every_pose2d_file(models_dir: Path,
                                                                                  monkeypatch) -> None:
    from pipeline.pose.models.loading import model_files

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    root = Path(__file__).resolve().parents[2]
    _, plain = model_files(root, {**PARAMS, "device": "cpu", "runtime": "onnxruntime"})
    files, hashes = model_files(root, {**PARAMS, "device": "cpu", "runtime": "openvino", "precision": "f32"})
    # ONNX Runtime's f32 adds nothing (files made before there was a choice are not redone) ...
    assert set(plain) == {"rtmdet-nano-person", "tinypose", "blazepose-full"}
    # ... another runtime is named beside each model's checksum, so its files are made anew.
    assert hashes == {**plain, **{f"{name}@runtime": "openvino-f32" for name in plain}}
    assert {runtime for _, runtime, _ in files.runtimes} == {"openvino"} and len(files.runtimes) == 3
    loaded = in_a_process_of_its_own(f"""
import json
from pipeline.pose.models.loading import ModelFiles, load_pose_models
models = load_pose_models(ModelFiles(**{dataclasses.asdict(files)!r}))
print(json.dumps([type(models.detector.session).__name__, type(models.pose.body.session).__name__]))
""")
    assert loaded == ["OpenVinoSession", "OpenVinoSession"]
