"""params.yaml: every tunable number in one place, read per stage."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from pipeline.core.errors import InputError

COMMON_KEYS = ("workers", "executor", "max_failure_ratio", "ray")


# The package's own parameters: the project's params.yaml as it ships (a link to it in the source
# tree, a copy in a wheel), for commands given every input on the command line outside a project.
DEFAULT_PARAMS = Path(__file__).resolve().parents[1] / "default_params.yaml"


def project_or_default_params(root: str | Path) -> dict[str, Any]:
    """The project's params.yaml, or outside a project the package's defaults (``DEFAULT_PARAMS``):
    an eval or export given all its inputs by path works anywhere and measures as the project would."""
    path = Path(root) / "params.yaml"
    return load_params(path if path.exists() else DEFAULT_PARAMS)


def load_params(path: str | Path = "params.yaml") -> dict[str, Any]:
    path = Path(path)
    if not path.exists():
        raise InputError(path, "not found: run this in a dance3d project (the folder with dvc.yaml and "
                               "params.yaml), or give --root")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        raise InputError(path, f"invalid YAML: {exc}", None if line is None else line + 1) from None
    if not isinstance(data, dict):
        raise InputError(path, "top level must be a mapping of sections")
    return data


def stage_params(params: dict[str, Any], stage: str) -> dict[str, Any]:
    """A stage's section, with the shared ``common`` keys filled in where the stage has none."""
    common = params.get("common") or {}
    section = dict(params.get(stage) or {})
    for key in COMMON_KEYS:
        if key in common and key not in section:
            section[key] = common[key]
    return section


def with_profile(section: dict[str, Any], stage: str) -> dict[str, Any]:
    """A section whose ``profile`` names one of its ``profiles``: that profile's keys, then the
    section's own keys on top (a key set in the section wins). DVC tracks the whole section, so
    switching profile re-runs the stage."""
    profiles = section.get("profiles") or {}
    name = section.get("profile")
    if name is None:
        return {k: v for k, v in section.items() if k != "profiles"}
    if name not in profiles:
        raise InputError("params.yaml", f"{stage}.profile is {name!r}; the profiles are "
                                        f"{', '.join(sorted(profiles)) or 'none'}")
    return {**profiles[name], **{k: v for k, v in section.items() if k != "profiles"}}


def corpus_fps(params: dict[str, Any]) -> float:
    """The corpus frame rate (``common.fps``, 24 by default): motion and every audio feature share it."""
    fps = float((params.get("common") or {}).get("fps", 24))
    if not 1 <= fps <= 240:
        raise InputError("params.yaml", f"common.fps must be between 1 and 240, not {fps:g}")
    return fps
