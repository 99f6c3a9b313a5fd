"""The loop every per-item stage shares: skip what is up to date, run the rest through the
executor, record failures, drop outputs of items that no longer exist, check the ratio.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import functools
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from pipeline.core.deferred import make_payload, resolve
from pipeline.core.executor import run_items, with_state
from pipeline.core.failures import Failure, check_failure_ratio, now, read_failures, write_failures
from pipeline.core.storage import read_meta, remove_stale_temps

log = logging.getLogger(__name__)

# A light stage's items (well under a second each on a demo segment) run in the stage's own
# process until this many seconds have passed, and only the rest goes to worker processes:
# spawning two workers costs about 1.5 s on 2 cores, more than a few such items take.
LIGHT_INLINE_SECONDS = 2.0

# `dance3d retry`: when set, only these items are attempted; the others stay as they are.
_ONLY: contextvars.ContextVar[frozenset[str] | None] = contextvars.ContextVar("only_items", default=None)


@contextlib.contextmanager
def only_items(items: set[str]):
    token = _ONLY.set(frozenset(items))
    try:
        yield
    finally:
        _ONLY.reset(token)


@dataclass(frozen=True)
class WorkItem:
    item_id: str
    fingerprint: str          # of the inputs and params that make this item's output
    outputs: tuple[Path, ...]  # the first is a Parquet file carrying the fingerprint in its metadata
    payload: Any              # what the worker function needs (a frozen dataclass: the job), or a Deferred one
    where: str = ""           # where a user finds the item (file:line), prefixed to its failure message
    size: float = 0.0         # how much work it is (e.g. seconds of video): the largest start first


@dataclass
class StageReport:
    done: dict[str, Any] = field(default_factory=dict)   # item_id -> worker result (new work)
    skipped: list[str] = field(default_factory=list)     # up to date, not redone
    failures: list[Failure] = field(default_factory=list)


def is_up_to_date(item: WorkItem) -> bool:
    if not all(p.exists() for p in item.outputs):
        return False
    try:
        return read_meta(item.outputs[0]).get("fingerprint") == item.fingerprint
    except Exception:  # unreadable output: redo it
        return False


def run_item_stage(
    stage: str,
    items: list[WorkItem],
    fn: Callable[[Any], Any] | str,
    *,
    out_dirs: Iterable[Path],
    params: dict,
    kind: str = "process",
    setup: Callable[..., Any] | str | None = None,
    setup_args: tuple = (),
    unit: str = "segment",
    gpu: bool = False,
    up_to_date: Callable[[WorkItem], bool] = is_up_to_date,
    keep_files: frozenset[str] = frozenset(),
    finish: Callable[[StageReport], None] | None = None,
    light: bool = False,
) -> StageReport:
    """Run ``fn(payload)`` for every item that is not up to date; with ``setup``, each worker
    builds ``setup(*setup_args)`` once (e.g. an ONNX session) and runs ``fn(state, payload)``.
    ``up_to_date`` decides what is skipped (default: the first output's fingerprint);
    ``keep_files`` names stage files in ``out_dirs`` that are not item outputs (e.g. an index);
    ``finish(report)`` runs before the failure ratio is checked, so what was done is kept;
    ``light``: the first items run in this process (``LIGHT_INLINE_SECONDS``), not in workers.
    ``fn`` and ``setup`` may be named ``"module:attribute"``, and payloads and ``setup_args`` may be
    ``Deferred`` (pipeline/core/deferred.py): they are imported and made only if some item is to be done."""
    out_dirs = list(out_dirs)
    only = _ONLY.get()
    for folder in out_dirs:
        folder.mkdir(parents=True, exist_ok=True)
        remove_stale_temps(folder)
    if only is None:
        _remove_stale_outputs(out_dirs, {i.item_id for i in items}, keep_files)
    report = StageReport()
    todo = []
    kept_failures = [] if only is None else [f for f in read_failures(out_dirs[0]) if f.item not in only]
    for item in items:
        if (only is not None and item.item_id not in only) or up_to_date(item):
            report.skipped.append(item.item_id)
        else:
            todo.append(item)
    log.info("%s: %d items, %d up to date, %d to do", stage, len(items), len(report.skipped), len(todo))
    # Largest first: a long video started last would leave the other workers idle while it runs.
    todo.sort(key=lambda item: -item.size)
    if todo:
        fn, setup = resolve(fn), (resolve(setup) if setup is not None else None)
        setup_args = tuple(make_payload(arg) for arg in setup_args)
        todo = [dataclasses.replace(item, payload=make_payload(item.payload)) for item in todo]
    executor = str(params.get("executor", "local"))
    if executor not in ("local", "ray"):
        raise ValueError(f"{stage}: executor must be local or ray, not {executor!r}")
    work, initializer, initargs = functools.partial(_apply, fn), None, ()
    if setup is not None:
        work, initializer, initargs = with_state(functools.partial(_apply_with_state, fn), setup, setup_args)
    for outcome in run_items(work, todo, workers=int(params.get("workers", 1)),
                             kind="ray" if executor == "ray" else kind, initializer=initializer, initargs=initargs,
                             desc=stage, unit=unit, ray_options=params.get("ray") or {}, gpu=gpu,
                             inline_seconds=LIGHT_INLINE_SECONDS if light else 0.0):
        item: WorkItem = outcome.item
        if outcome.ok:
            report.done[item.item_id] = outcome.value
            continue
        message = f"{item.where}: {outcome.error_message}" if item.where else outcome.error_message
        if outcome.error_class == "WorkerCrashed":
            message += f"; after fixing the cause, re-run only the failed items with `dance3d retry {stage}`"
        report.failures.append(Failure(item.item_id, stage, outcome.error_class, message, now()))
        log.warning("%s: %s: %s: %s", stage, item.item_id, outcome.error_class, message)
    crashed = sorted(f.item for f in report.failures if f.error_class == "WorkerCrashed")
    if report.failures:
        log.warning("%s: %d of %d items failed%s; see %s/_failures.parquet, then `dance3d retry %s`", stage,
                    len(report.failures), len(todo), f" (worker crashed: {', '.join(crashed)})" if crashed else "",
                    out_dirs[0], stage)
    failures = kept_failures + report.failures
    if finish is not None:
        finish(report)
    write_failures(out_dirs[0], stage, failures, total=len(items))
    check_failure_ratio(stage, len(failures), len(items), float(params.get("max_failure_ratio", 0.2)))
    return report


def _apply(fn: Callable[[Any], Any], item: WorkItem) -> Any:
    return fn(item.payload)


def _apply_with_state(fn: Callable[[Any, Any], Any], state: Any, item: WorkItem) -> Any:
    return fn(state, item.payload)


def _remove_stale_outputs(out_dirs: list[Path], keep: set[str], keep_files: frozenset[str]) -> None:
    """Outputs of items that are gone upstream must not feed later stages."""
    for folder in out_dirs:
        for path in sorted(folder.iterdir()):
            if (path.is_file() and not path.name.startswith(("_", ".")) and path.stem not in keep
                    and path.name not in keep_files):
                log.info("removing %s: its item no longer exists upstream", path)
                path.unlink()
