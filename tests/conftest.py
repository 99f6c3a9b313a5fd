"""Shared fixtures: real assets through environment variables, small media made on the fly.

Real media, models and motion capture are found through DANCE3D_MEDIA, DANCE3D_MODELS and
DANCE3D_MOCAP. Where one is missing a test skips with the reason, unless
DANCE3D_REQUIRE_ASSETS=1 (set by CI), which turns that skip into a failure.
"""

from __future__ import annotations

import http.server
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from pipeline.ingest.media import ffmpeg_exe

PROJECT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session", autouse=True)
def _checkpoints_in_a_temporary_folder(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Training checkpoints go to $DANCE3D_CHECKPOINTS: the tests' own, never the user's cache
    (where a test's checkpoint would be resumed by a real run of the same config)."""
    os.environ["DANCE3D_CHECKPOINTS"] = str(tmp_path_factory.mktemp("checkpoints"))


def skip_or_fail(reason: str) -> None:
    """Skip a test whose real assets are missing here; in CI (DANCE3D_REQUIRE_ASSETS=1) fail it."""
    if os.environ.get("DANCE3D_REQUIRE_ASSETS") == "1":
        pytest.fail(reason + "; DANCE3D_REQUIRE_ASSETS=1 forbids skipping")
    pytest.skip(reason)


def _asset_dir(variable: str, must_contain: str) -> Path:
    value = os.environ.get(variable)
    path = Path(value) if value else None
    if path is None or not (path / must_contain).exists():
        skip_or_fail(f"{variable} is not set or lacks {must_contain} (point it at the real assets)")
    return path


@pytest.fixture(scope="session")
def media_dir() -> Path:
    return _asset_dir("DANCE3D_MEDIA", "videos/dance_single_music_musepose.mp4")


@pytest.fixture(scope="session")
def dance_clip(media_dir: Path) -> Path:
    return media_dir / "videos/dance_single_music_musepose.mp4"


def ffmpeg(*args: str) -> None:
    """Run the wheel's ffmpeg for building test fixtures."""
    subprocess.run([ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", *args], check=True)


def make_test_video(path: Path, *, seconds: float = 2.0, fps: str = "25", size: str = "320x240",
                    audio: bool = True, pattern: str = "testsrc2") -> Path:
    """A synthetic H.264 test-pattern video (lavfi ``pattern``; with a 440 Hz tone when ``audio``)."""
    args = ["-f", "lavfi", "-i", f"{pattern}=size={size}:rate={fps}:duration={seconds}"]
    if audio:
        args += ["-f", "lavfi", "-i", f"sine=frequency=440:sample_rate=44100:duration={seconds}"]
    args += ["-c:v", "libx264", "-preset", "ultrafast", "-pix_fmt", "yuv420p"]
    if audio:
        args += ["-c:a", "aac", "-shortest"]
    ffmpeg(*args, str(path))
    return path


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """An empty dance3d project (params.yaml copied from the repo) to run stages in."""
    root = tmp_path / "project"
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    return root


def set_params(root: Path, section: str, **values) -> None:
    """Override keys of one params.yaml section in a test project."""
    import yaml

    path = root / "params.yaml"
    params = yaml.safe_load(path.read_text())
    params.setdefault(section, {}).update(values)
    path.write_text(yaml.safe_dump(params, sort_keys=False))


@pytest.fixture(scope="session")
def models_dir() -> Path:
    return _asset_dir("DANCE3D_MODELS", "rtmdet_nano_person_end2end.onnx")


def posed_with_hands(project: Path, dance_clip: Path, hand_models: tuple[Path, ...], start: float,
                     seconds: float, work: Path) -> Path:
    """``project`` with pose2d.hands on and ``hand_models`` in its models/, its one segment
    (``solo_000``) ``seconds`` of the MusePose dancer from ``start`` at 540 x 960, posed and tracked;
    returns that clip (in ``work``)."""
    (project / "models").mkdir()
    for model in hand_models:
        (project / "models" / model.name).symlink_to(model)
    clip = work / "clip.mp4"
    ffmpeg("-ss", str(start), "-t", str(seconds), "-i", str(dance_clip), "-vf", "scale=540:960", "-c:v", "libx264",
           str(clip))
    write_sources(project, [("solo", clip)])
    (project / "annotations/segments.csv").write_text(f"video_id,start,end\nsolo,0,{seconds:g}\n")
    set_params(project, "pose2d", hands=True)
    run_stages(project, "download", "trim", "pose2d", "track")
    return clip


def write_sources(root: Path, rows: list[tuple[str, Path]]) -> None:
    """sources.csv of (video_id, local path) rows."""
    body = "".join(f"{vid},{path}\n" for vid, path in rows)
    (root / "manifests/sources.csv").write_text("video_id,url\n" + body)


def run_stages(root: Path, *names: str) -> None:
    import importlib

    for name in names:
        importlib.import_module(f"stages.{name}").run(root)


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    return _asset_dir("DANCE3D_MOCAP", "perfume/aachan.bvh")


class Mirror:
    """Serves ``files`` (URL path -> bytes) the way a mirror of the public hosts would: /<host>/<path>."""

    def __init__(self, files: dict[str, bytes]) -> None:
        self.files, self.requests = files, []
        mirror = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
                mirror.requests.append(self.path)
                body = mirror.files.get(self.path.split("?")[0])
                if body is None:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args) -> None:
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()


@pytest.fixture(scope="session")
def pose2d_eval_dir() -> Path:
    """COCO-style annotated images (annotations.json + images/) for 2D accuracy."""
    return _asset_dir("DANCE3D_POSE2D_EVAL", "annotations.json")


@pytest.fixture(scope="session")
def hand_eval_dir() -> Path:
    """Annotated hand images (annotations.json + images/, hand_eval's layout) for `eval hands`."""
    return _asset_dir("DANCE3D_HAND_EVAL", "annotations.json")


def _fetched(name: str) -> Path:
    """A model fetched from its route and converted once per machine (into the dance3d cache, as
    `dance3d models fetch` would into a project), outputs verified."""
    from pipeline.core.numba_cache import cache_root
    from pipeline.pose.models.fetch import FetchError, fetch_model

    try:
        return fetch_model(name, cache_root() / "test-models")
    except FetchError as exc:
        skip_or_fail(f"{name} could not be fetched and converted: {exc}")


@pytest.fixture(scope="session")
def hand_model() -> Path:
    """MediaPipe's hand landmark model, from the pinned mediapipe wheel."""
    return _fetched("hand-landmark-full")


@pytest.fixture(scope="session")
def hand_recrop_model() -> Path:
    """MediaPipe Holistic's hand re-crop model, from the pinned mediapipe wheel."""
    return _fetched("hand-recrop")


@pytest.fixture(scope="session")
def palm_model() -> Path:
    """MediaPipe's palm detector, from the pinned mediapipe wheel: `eval hands`'s peer."""
    return _fetched("palm-detection-full")


def copy_project(dest: Path) -> Path:
    """The project's tracked and untracked-but-not-ignored files (no data/, no demo media) in a new
    git repository at ``dest``."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=PROJECT,
                           capture_output=True, text=True, check=True).stdout.split()
    for name in files:
        src = PROJECT / name
        if src.is_file() and not name.startswith(("data/", "demo/media")):
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    subprocess.run(["git", "init", "-q"], cwd=dest, check=True)
    return dest


def tool_environment() -> dict[str, str]:
    """This environment with its executables (dance3d, dvc) first on the PATH, for subprocesses."""
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}


def dvc(root: Path, *args: str) -> subprocess.CompletedProcess:
    """``dvc ARGS`` in ``root`` with this environment's executables on the PATH."""
    return subprocess.run([str(Path(sys.executable).parent / "dvc"), *args], cwd=root, env=tool_environment(),
                          capture_output=True, text=True)


@pytest.fixture(scope="session")
def built_demo(tmp_path_factory: pytest.TempPathFactory, media_dir: Path, models_dir: Path,
               mocap_dir: Path) -> Path:
    """The demo project after one `dvc repro`, built once per session and never changed: tests that
    change it work on ``demo_copy``. The asset fixtures vouch for DANCE3D_MODELS, DANCE3D_MOCAP and
    DANCE3D_MEDIA (local copies of the demo's public clips), which `dvc repro` inherits."""
    root = copy_project(tmp_path_factory.mktemp("demo") / "dance3d")
    # The demo's lifter: the shipped one (training it is tested in tests/motion/test_lifting.py).
    set_params(root, "train", steps=10)  # that it trains: tests/corpus measures the loss
    set_params(root, "propose_segments", sample_fps=2.0)  # its own tests measure it at the default
    done = dvc(root, "repro")
    if done.returncode != 0:
        pytest.fail("dvc repro on the demo failed:\n" + done.stderr[-3000:])
    return root


def demo_copy(built: Path, dest: Path) -> Path:
    """A copy of the built demo (data, DVC lock and git repository included) to change freely."""
    shutil.copytree(built, dest, symlinks=True)
    return dest
