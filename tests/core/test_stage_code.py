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


def test_the_ground_stage_fingerprints_the_smplh_hands_its_world_files_carry(monkeypatch) -> None:
    assert {"pipeline.motion.smpl.hands", "pipeline.motion.smpl.retarget"} <= set(fingerprinted("ground", monkeypatch))


def test_the_lift_stage_fingerprints_what_its_motion_is_computed_by(monkeypatch) -> None:
    """The lifter's input normalisation and mirror tables, the root placement's one skeleton and the
    contact model's resampling: a change to any of them redoes the lifted files."""
    assert {"pipeline.motion.lifting.geometry", "pipeline.motion.mocap.skeleton", "pipeline.motion.world.bones",
            "pipeline.motion.resample"} <= set(fingerprinted("lift", monkeypatch))


def test_the_proposals_fingerprint_the_shot_cuts_and_the_people_finder_they_are_made_from(monkeypatch) -> None:
    assert {"pipeline.pose.propose", "pipeline.ingest.shots", "pipeline.pose.pose2d",
            "pipeline.pose.tracking"} <= set(fingerprinted("propose_segments", monkeypatch))
