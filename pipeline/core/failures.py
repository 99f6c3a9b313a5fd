"""Failure accounting shared by every stage: ``_failures.parquet`` and the failure ratio."""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass
from pathlib import Path

import pyarrow as pa

from pipeline.core.errors import Dance3dError
from pipeline.core.paths import REPORTS
from pipeline.core.storage import read_rows, write_rows

FAILURES_FILE = "_failures.parquet"
FAILURES_SCHEMA = pa.schema([(name, pa.string()) for name in ("item", "stage", "error_class", "message", "time")])


@dataclass(frozen=True)
class Failure:
    item: str
    stage: str
    error_class: str
    message: str
    time: str = ""


class StageFailed(Dance3dError):
    """Too many items failed for the stage to count as done."""


def now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")


def write_failures(folder: Path, stage: str, failures: list[Failure], total: int | None = None) -> Path:
    """Write (or clear) the stage's failure table; always written so stale rows vanish.

    With ``total`` (the stage's item count) a summary also goes to
    ``reports/failures_<stage>.json`` of the project (``folder`` is ``<project>/data/<stage>``); the
    shard stage sums them (``failure_totals``) into the corpus's headline ``failed_share``.
    """
    rows = [asdict(f) for f in sorted(failures, key=lambda f: f.item)]
    path = Path(folder) / FAILURES_FILE
    write_rows(rows, FAILURES_SCHEMA, path, schema_version=1, extra={"stage": stage})
    if total is not None:
        from pipeline.core.storage import write_json

        by_class: dict[str, int] = {}
        for f in failures:
            by_class[f.error_class] = by_class.get(f.error_class, 0) + 1
        write_json(Path(folder).parent.parent / REPORTS / f"failures_{stage}.json",
                   {"items": total, "failed": len(failures),
                    "failed_share": round(len(failures) / total, 4) if total else 0.0, "by_error_class": by_class})
    return path


def read_failures(folder: Path) -> list[Failure]:
    path = Path(folder) / FAILURES_FILE
    return [Failure(**row) for row in read_rows(path)] if path.exists() else []


def check_failure_ratio(stage: str, failed: int, total: int, max_ratio: float) -> None:
    """Raise StageFailed when the failed share exceeds ``max_ratio``."""
    if total and failed / total > max_ratio:
        raise StageFailed(
            f"{stage}: {failed} of {total} items failed ({failed / total:.0%} > max_failure_ratio "
            f"{max_ratio:.0%}); see the stage's {FAILURES_FILE}"
        )


def failure_totals(root: Path) -> dict:
    """Every stage's failure report summed: items, failed, failed share, and the stages with failures."""
    import json

    items = failed = 0
    stages = {}
    for path in sorted((Path(root) / REPORTS).glob("failures_*.json")):
        report = json.loads(path.read_text())
        items += int(report.get("items", 0))
        failed += int(report.get("failed", 0))
        if report.get("failed"):
            stages[path.stem.removeprefix("failures_")] = report["failed"]
    return {"items": items, "failed": failed, "failed_share": round(failed / items, 4) if items else 0.0,
            "stages_with_failures": stages}
