"""What a stage's outputs are made from is what makes DVC and the stage redo them: every module a
stage fingerprints (``code_fingerprint``, which redoes its items) is a dependency of the stage in
dvc.yaml (which re-runs it), and the modules a stage's files are computed by are fingerprinted."""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import pytest
import yaml

import pipeline.core.storage as storage
from tests.conftest import PROJECT


def fingerprinted(stage: str, monkeypatch) -> list[str]:
    """The module names a stage module hands to ``code_fingerprint`` when it is imported."""
    names: list[str] = []
    real = storage.code_fingerprint

    def record(*modules):
        names.extend(m if isinstance(m, str) else m.__name__ for m in modules)
        return real(*modules)

    monkeypatch.setattr(storage, "code_fingerprint", record)
    importlib.reload(importlib.import_module(f"stages.{stage}"))
    return names


STAGES = {name: spec for name, spec in yaml.safe_load((PROJECT / "dvc.yaml").read_text())["stages"].items()
          if spec["cmd"].startswith("python -m stages.")}


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_every_module_a_stage_fingerprints_is_a_dvc_dependency_of_the_stage(stage: str, monkeypatch) -> None:
    deps = [PROJECT / d for d in STAGES[stage].get("deps", [])]
    module = STAGES[stage]["cmd"].split("stages.")[1].split()[0]
    paths = {name: Path(importlib.util.find_spec(name).origin) for name in fingerprinted(module, monkeypatch)}
    assert [name for name, path in paths.items() if not any(path == d or d in path.parents for d in deps)] == []


# What each stage's outputs are computed by, beyond its own package module (found by reading the
# imports of its work; file contracts are versioned by their schemas instead).
COMPUTED_BY = {
    "lift": {"pipeline.motion.lifting.geometry",  # the lifter's input normalisation
             "pipeline.motion.mocap.skeleton",  # the mirror tables of the flip averaging
             "pipeline.motion.world.bones", "pipeline.motion.resample",  # the root's skeleton, the contact's clock
             "pipeline.pose.hands"},  # the hands' presence threshold
    "ground": {"pipeline.motion.smpl.hands", "pipeline.motion.smpl.retarget",  # SMPL and SMPL-H in the world files
               "pipeline.motion.mocap.skeleton", "pipeline.pose.hands"},  # the feet and hand tables, rotations
    "propose_segments": {"pipeline.ingest.shots", "pipeline.pose.pose2d", "pipeline.pose.tracking"},  # cuts, people
    "clean": {"pipeline.pose.tracking"},  # the OKS of the identity proposals
    "trim": {"pipeline.ingest.segments"},  # how annotation rows become segments
    "audio": {"pipeline.ingest.segmentvideo"},  # where a segment's audio is read
}


@pytest.mark.parametrize("stage", sorted(COMPUTED_BY))
def test_a_stage_fingerprints_the_code_its_outputs_are_computed_by(stage: str, monkeypatch) -> None:
    assert COMPUTED_BY[stage] - set(fingerprinted(stage, monkeypatch)) == set()
