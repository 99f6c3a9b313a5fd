"""Headline metrics and the reports beside them.

A stage's figures are written twice (``write_metrics``): the whole breakdown (per source, per foot,
per protocol, loudness per segment, ...) to ``reports/<name>.json``, and the few figures that say
whether a run is good to ``metrics/<name>.json``, flat and named to read alone
(``lifter_p_mpjpe_mm``, ``corpus_minutes``), for ``dvc metrics show`` and ``dvc metrics diff``.
Which figure of a report is a headline is said once, here (``HEADLINES``); ``dance3d status`` prints
the same figures.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pipeline.core.paths import METRICS, REPORTS


def _at(*path: str) -> Callable[[dict], Any]:
    def get(report: dict) -> Any:
        value: Any = report
        for key in path:
            if not isinstance(value, dict) or key not in value:
                return None
            value = value[key]
        return value
    return get


def _windows(report: dict) -> int | None:
    train, val = report.get("windows_train"), report.get("windows_val")
    return None if train is None or val is None else train + val


# Per metrics file: headline name -> how it is read from the report. DVC prints one column per
# name, so they are few and short: the table stays narrower than a terminal (about 220 characters).
# Stages without a line here (smooth, audio) write their report only.
HEADLINES: dict[str, dict[str, Callable[[dict], Any]]] = {
    "clean": {"clean_minutes": _at("clip_minutes")},
    "lifter": {"lifter_mpjpe_mm": _at("val_mpjpe_mm"), "lifter_p_mpjpe_mm": _at("val_p_mpjpe_mm")},
    "contact": {"contact_f1": _at("contact_f1")},
    "corpus": {"corpus_videos": _at("videos"), "corpus_minutes": _at("segment_minutes"),
               "corpus_windows": _windows, "beat_f1": _at("beat_alignment", "matched_beat_f1"),
               "beat_f1_shuffled": _at("beat_alignment", "shuffled_beat_f1"),
               "skate_m_s": _at("grounding", "skate_after_m_s"), "failed_share": _at("failures", "failed_share")},
    "train": {"train_loss": _at("loss_last")},
}


def headline(name: str, report: dict) -> dict:
    """The headline figures of a report (those it has)."""
    values = {key: read(report) for key, read in HEADLINES.get(name, {}).items()}
    return {key: value for key, value in values.items() if value is not None}


def write_metrics(root: Path, name: str, report: dict) -> None:
    """``reports/<name>.json`` (the whole report) and, for a stage with headline figures,
    ``metrics/<name>.json``."""
    from pipeline.core.storage import write_json

    write_json(Path(root) / REPORTS / f"{name}.json", report)
    if name in HEADLINES:
        write_json(Path(root) / METRICS / f"{name}.json", headline(name, report))


def read_report(root: Path, name: str) -> dict | None:
    path = Path(root) / REPORTS / f"{name}.json"
    return json.loads(path.read_text()) if path.is_file() else None


def headline_figures(root: Path) -> dict[str, Any]:
    """Every headline figure a project has written, in ``HEADLINES``' order."""
    figures: dict[str, Any] = {}
    for name in HEADLINES:
        path = Path(root) / METRICS / f"{name}.json"
        if path.is_file():
            try:
                figures.update(json.loads(path.read_text()))
            except ValueError:
                continue
    return figures
