"""`dance3d models fetch` on the online path, with a local HTTP server standing in for the public hosts."""

from __future__ import annotations

import hashlib
import importlib.util
from pathlib import Path
from typing import Iterator

import pytest

from pipeline.cli import main
from pipeline.pose.models.fetch import MIRROR_ENV, ROUTES, FetchError, fetch_model, verify_outputs
from tests.conftest import Mirror


def _mirror_path(url: str) -> str:
    from urllib.parse import urlparse

    parsed = urlparse(url)
    return f"/{parsed.netloc}{parsed.path}"


@pytest.fixture
def mirror(monkeypatch) -> Iterator[callable]:
    servers = []

    def start(files: dict[str, bytes]) -> Mirror:
        servers.append(Mirror(files))
        monkeypatch.setenv(MIRROR_ENV, servers[-1].url)
        monkeypatch.delenv("DANCE3D_MODELS", raising=False)
        return servers[-1]

    yield start
    for server in servers:
        server.httpd.shutdown()


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_detector_is_fetched_checksum_and_output_verified(tmp_path: Path, models_dir: Path, mirror) -> None:
    route = ROUTES["rtmdet-nano-person"][0]
    server = mirror({_mirror_path(route.url): (models_dir / "rtmdet_nano_person_end2end.onnx").read_bytes()})
    assert main(["--root", str(tmp_path), "models", "fetch", "rtmdet-nano-person"]) == 0
    path = tmp_path / "models/rtmdet_nano_person_end2end.onnx"
    assert _sha(path) == route.sha256
    assert server.requests == [_mirror_path(route.url)]
    fetch_model("rtmdet-nano-person", tmp_path / "models")  # present and verified: nothing downloaded
    assert len(server.requests) == 1


def test_a_corrupt_download_is_refused_and_nothing_is_left(tmp_path: Path, mirror, capsys) -> None:
    route = ROUTES["rtmdet-nano-person"][0]
    mirror({_mirror_path(route.url): b"an error page, not a model"})
    assert main(["--root", str(tmp_path), "models", "fetch", "rtmdet-nano-person"]) == 2
    assert "checksum mismatch" in capsys.readouterr().err
    assert not list((tmp_path / "models").glob("*.onnx"))


def test_a_model_that_computes_something_else_fails_verification(tmp_path: Path, models_dir: Path) -> None:
    import numpy as np
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(models_dir / "rtmdet_nano_person_end2end.onnx"))
    weight = max(model.graph.initializer, key=lambda t: int(np.prod(t.dims)))  # the largest weight tensor
    weight.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(weight) * 0.5, weight.name))
    onnx.save(model, str(tmp_path / "changed.onnx"))
    verify_outputs("rtmdet-nano-person", models_dir / "rtmdet_nano_person_end2end.onnx")
    with pytest.raises(FetchError, match="outputs differ from the reference"):
        verify_outputs("rtmdet-nano-person", tmp_path / "changed.onnx")


@pytest.mark.slow
def test_movenet_is_converted_from_googles_tflite_in_an_environment_of_its_own(tmp_path: Path, models_dir: Path,
                                                                               mirror) -> None:
    route = ROUTES["movenet-lightning"][0]
    mirror({_mirror_path(route.url): (models_dir / "movenet_singlepose_lightning_int8_4.tflite").read_bytes()})
    path = fetch_model("movenet-lightning", tmp_path / "models")  # raises unless its outputs match the reference
    assert path.name == "movenet_singlepose_lightning_4_dequant.onnx"
    assert importlib.util.find_spec("tensorflow") is None and importlib.util.find_spec("tf2onnx") is None


@pytest.mark.slow
def test_blazepose_is_fetched_from_the_pinned_mediapipe_wheel_and_converted(tmp_path: Path, monkeypatch) -> None:
    # The real route: pip downloads the wheel from the package registry (sha256 checked), the
    # TFLite member is checked, tf2onnx converts it in a throw-away venv, outputs are verified.
    monkeypatch.delenv("DANCE3D_MODELS", raising=False)
    path = fetch_model("blazepose-full", tmp_path / "models", force=True)
    assert path == tmp_path / "models/blazepose_full.onnx"
    verify_outputs("blazepose-full", path)
    assert importlib.util.find_spec("tensorflow") is None and importlib.util.find_spec("mediapipe") is None


def test_a_wheel_with_the_wrong_checksum_is_refused(tmp_path: Path, monkeypatch) -> None:
    import dataclasses

    from pipeline.pose.models import fetch

    monkeypatch.setattr(fetch, "download_wheel", lambda requirement: b"PK\x05\x06" + b"\0" * 18)  # an empty zip
    route = dataclasses.replace(ROUTES["blazepose-full"][0])
    with pytest.raises(FetchError, match="checksum mismatch"):
        fetch.fetch_route(route, tmp_path / "blazepose_full.onnx")
    assert not (tmp_path / "blazepose_full.onnx").exists()


def test_tinypose_ships_in_the_package_with_its_licence_and_is_found_without_any_models_folder(
        tmp_path: Path, monkeypatch) -> None:
    from pipeline.core.storage import sha256_file
    from pipeline.pose.models.fetch import model_outputs, resolve_model
    from pipeline.pose.models.registry import SHIPPED, get_spec

    empty = tmp_path / "no_models"
    empty.mkdir()
    monkeypatch.setenv("DANCE3D_MODELS", str(empty))
    spec = get_spec("tinypose")
    path = resolve_model("tinypose", tmp_path, allow_download=False)
    assert path == SHIPPED / spec.file and sha256_file(path) == spec.sha256
    assert "Apache License" in (SHIPPED / "LICENSE.tinypose").read_text()
    assert spec.sha256 in (SHIPPED / "PROVENANCE.md").read_text()
    # models fetch takes it as present once its outputs on the test card match the reference's.
    assert fetch_model("tinypose", tmp_path / "models") == path
    assert len(model_outputs("tinypose", path)["keypoints"]) == 17
    # A copy in DANCE3D_MODELS comes first (a user may put another build there).
    (empty / spec.file).write_bytes(path.read_bytes())
    assert resolve_model("tinypose", tmp_path) == empty / spec.file


def test_a_wheel_route_is_logged_as_the_wheel_it_is_not_as_a_mirror_address(tmp_path: Path, monkeypatch,
                                                                              caplog) -> None:
    from pipeline.pose.models import fetch

    monkeypatch.setenv(MIRROR_ENV, "http://127.0.0.1:9")  # a mirror serves URLs; pip routes go to the registry
    monkeypatch.delenv("DANCE3D_MODELS", raising=False)
    monkeypatch.setattr(fetch, "fetch_route", lambda route, target: (_ for _ in ()).throw(FetchError("stop")))
    with caplog.at_level("INFO"), pytest.raises(FetchError):
        fetch_model("blazepose-full", tmp_path / "models", force=True)
    assert "fetching pip:mediapipe==0.10.21" in caplog.text and "127.0.0.1:9" not in caplog.text
