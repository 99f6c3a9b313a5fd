"""Fixtures of the 2D tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.pose.pose2d import Pose2dOptions


@pytest.fixture(scope="session")
def default_models(models_dir: Path):
    from pipeline.core.params import load_params, stage_params
    from pipeline.pose.models.loading import load_pose_models, worker_files
    from tests.conftest import PROJECT

    params = stage_params(load_params(PROJECT / "params.yaml"), "pose2d")
    files = worker_files(PROJECT, params)  # found through DANCE3D_MODELS, as models_dir was
    return load_pose_models(files), Pose2dOptions.from_params(params)
