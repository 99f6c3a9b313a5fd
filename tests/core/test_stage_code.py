"""What a stage's outputs are made from is what makes DVC and the stage redo them: every module a
stage can import, and every module it fingerprints (``code_fingerprint``, which redoes its items),
is a dependency of the stage in dvc.yaml (which re-runs it), and the modules a stage's files are
computed by are fingerprinted."""

from __future__ import annotations

import ast
import functools
import importlib
import importlib.util
from pathlib import Path

import pytest
import yaml

import pipeline.core.storage as storage
from tests.conftest import PROJECT
from tests.test_imports import import_graph, imported


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
             "pipeline.pose.pose2dfile"},  # the hand layout, the sure hands' presence
    "ground": {"pipeline.motion.smpl.hands", "pipeline.motion.smpl.retarget",  # SMPL and SMPL-H in the world files
               "pipeline.motion.mocap.skeleton", "pipeline.pose.pose2dfile"},  # the feet and hand tables, rotations
    "propose_segments": {"pipeline.ingest.shots", "pipeline.pose.pose2d", "pipeline.pose.boxes"},  # cuts, people
    "pose2d": {"pipeline.pose.keyframes", "pipeline.pose.boxes"},  # which frames are posed, who is who between
    "track": {"pipeline.pose.boxes", "pipeline.pose.pose2dfile"},  # IoU and OKS (COCO's sigmas)
    "clean": {"pipeline.pose.tracking", "pipeline.pose.pose2dfile"},  # the OKS of the identity proposals
    "trim": {"pipeline.ingest.segments"},  # how annotation rows become segments
    "audio": {"pipeline.ingest.segmentvideo"},  # where a segment's audio is read
}


@pytest.mark.parametrize("stage", sorted(COMPUTED_BY))
def test_a_stage_fingerprints_the_code_its_outputs_are_computed_by(stage: str, monkeypatch) -> None:
    assert COMPUTED_BY[stage] - set(fingerprinted(stage, monkeypatch)) == set()


# How a stage runs, logs, names and stores its work, not what it computes: a change there is caught by
# the tests, not redone in every project.
PLUMBING = {f"pipeline.core.{name}" for name in (
    "deferred", "errors", "executor", "failures", "ids", "itemstage", "malloc", "numba_cache", "params", "paths",
    "stage", "storage", "tables", "threads")}


GRAPH = functools.cache(import_graph)


def module_path(name: str) -> Path:
    path = PROJECT / f"{name.replace('.', '/')}.py"
    return path if path.is_file() else PROJECT / name.replace(".", "/") / "__init__.py"


def import_closure(stage_module: str) -> set[str]:
    """The pipeline modules a stage module can import: those it imports or names for later import
    (``Deferred("pipeline.x:f")``, ``code_fingerprint("pipeline.x")``: only stages name work so),
    then everything they import, at the top or inside functions (the house's import graph)."""
    graph = GRAPH()
    tree = ast.parse(module_path(stage_module).read_text())
    named = imported(tree, graph) | {node.value.partition(":")[0] for node in ast.walk(tree)
                                     if isinstance(node, ast.Constant) and isinstance(node.value, str)
                                     and node.value.startswith("pipeline.")}
    seen, todo = set(), [m for m in named if m in graph]
    while todo:
        if (module := todo.pop()) not in seen:
            seen.add(module)
            todo.extend(graph[module])
    return seen


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_every_module_a_stage_imports_is_a_dvc_dependency_of_the_stage(stage: str) -> None:
    """Else ``dvc repro`` after a change to that module leaves the stage's outputs as they were."""
    deps = [PROJECT / d for d in STAGES[stage].get("deps", [])]
    module = "stages." + STAGES[stage]["cmd"].split("stages.")[1].split()[0]
    closure = import_closure(module) - PLUMBING
    missing = sorted(module_path(m).relative_to(PROJECT).as_posix() for m in closure
                     if not any(module_path(m) == d or d in module_path(m).parents for d in deps))
    assert missing == [], f"add to {stage}'s deps in dvc.yaml: {missing}"
