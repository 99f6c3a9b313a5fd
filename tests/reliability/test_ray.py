"""The Ray executor gives the same outputs, byte for byte, as the local one."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from tests.conftest import run_stages, set_params, write_sources


def digests(root: Path, folders: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for folder in folders:
        for path in sorted((root / folder).glob("*")):
            if path.is_file() and not path.name.startswith("_"):
                out[f"{folder}/{path.name}"] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def build(root: Path, media_dir: Path) -> None:
    write_sources(root, [("solo", media_dir / "videos/dance_solo_384x496_30fps.mp4"),
                         ("dance", media_dir / "videos/dance_single_music_musepose.mp4")])
    (root / "annotations/segments.csv").write_text("video_id,start,end\nsolo,0,2\nsolo,3,5\ndance,1,3\n")


@pytest.mark.slow
def test_ray_and_local_executors_write_identical_outputs(tmp_path: Path, media_dir: Path, models_dir: Path,
                                                         monkeypatch) -> None:
    import ray

    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    roots = {}
    for executor in ("local", "ray"):
        root = tmp_path / executor
        (root / "manifests").mkdir(parents=True)
        (root / "annotations").mkdir()
        (root / "params.yaml").write_text((Path(__file__).parents[2] / "params.yaml").read_text())
        build(root, media_dir)
        set_params(root, "common", executor=executor, workers=2, ray={"address": "", "num_cpus": 2})
        run_stages(root, "download", "trim", "pose2d", "track", "clean")
        roots[executor] = root
    ray.shutdown()
    folders = ("data/segments", "data/pose2d", "data/tracks", "data/clean")
    local, remote = digests(roots["local"], folders), digests(roots["ray"], folders)
    assert len(local) == 1 + 3 * 3  # the index + 3 segments x (pose2d, tracks, clean)
    assert local == remote
