"""One interface for running a function over work items: inline, threads, processes or Ray.

Each item's outcome comes back as an ``Outcome`` (value or error), so one bad item
never stops the others. Per-worker state (e.g. ONNX sessions) is built once per worker
by ``initializer``, not once per item; ``with_state`` hands the object a ``setup``
function built to the worker function with every item.
"""

from __future__ import annotations

import concurrent.futures as cf
import functools
import logging
import multiprocessing as mp
import os
import signal
import time
import traceback
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator, Sequence

from tqdm import tqdm

from pipeline.core import numba_cache

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Outcome:
    item: Any
    value: Any = None
    error_class: str = ""
    error_message: str = ""

    @property
    def ok(self) -> bool:
        return not self.error_class


_WORKER: dict[str, Any] = {}  # this worker process's state, built once by ``setup``


def _build_state(setup: Callable[..., Any], args: tuple) -> None:
    _WORKER["state"] = setup(*args)


def _call_with_state(fn: Callable[[Any, Any], Any], item: Any) -> Any:
    return fn(_WORKER["state"], item)


def with_state(fn: Callable[[Any, Any], Any], setup: Callable[..., Any], args: tuple = ()) -> tuple:
    """(function, initializer, initargs) for ``run_items`` such that each worker builds
    ``setup(*args)`` once and every item is processed as ``fn(state, item)``."""
    return functools.partial(_call_with_state, fn), _build_state, (setup, tuple(args))


def _label(item: Any) -> str:
    return str(getattr(item, "item_id", item))


def _call(fn: Callable[[Any], Any], item: Any) -> Outcome:
    try:
        return Outcome(item, fn(item))
    except Exception as exc:  # isolate the item; the stage decides what a failure costs
        message = str(exc) or traceback.format_exception_only(type(exc), exc)[-1].strip()
        return Outcome(item, error_class=type(exc).__name__, error_message=message)


def _run_ray(fn, items, workers, initializer, initargs, options: dict, gpu: bool) -> Iterator[Outcome]:
    """Items as tasks on Ray actors: each actor builds its per-worker state (e.g. an ONNX
    session) once and then takes items; at most two items per actor are in flight."""
    import ray

    if not ray.is_initialized():
        address = options.get("address") or None
        ray.init(address=address, num_cpus=None if address else int(options.get("num_cpus") or 0) or None,
                 include_dashboard=False, log_to_driver=False, configure_logging=False)
    gpus = 1 if gpu and ray.cluster_resources().get("GPU", 0) > 0 else 0

    @ray.remote(num_cpus=1, num_gpus=gpus)
    class Worker:
        def __init__(self) -> None:
            if initializer is not None:
                initializer(*initargs)

        def run(self, item):
            return _call(fn, item)

    n_actors = max(1, min(workers, len(items)))
    actors = [Worker.remote() for _ in range(n_actors)]
    load = [0] * n_actors
    pending: dict = {}
    queue = list(items)
    try:
        while queue or pending:
            while queue and len(pending) < 2 * n_actors:  # bounded in-flight work
                a = load.index(min(load))
                load[a] += 1
                item = queue.pop(0)
                pending[actors[a].run.remote(item)] = (item, a)
            done, _ = ray.wait(list(pending), num_returns=1)
            item, a = pending.pop(done[0])
            load[a] -= 1
            try:
                yield ray.get(done[0])
            except ray.exceptions.RayActorError:
                yield Outcome(item, error_class="WorkerCrashed",
                              error_message="the Ray worker died (a crash in native code or out of memory)")
    finally:
        for actor in actors:
            ray.kill(actor)


def crash_message(exitcode: int | None) -> str:
    """Why a worker process died, from its exit code, in words a user can act on."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        why = {"SIGKILL": "killed, usually by the out-of-memory killer",
               "SIGSEGV": "a crash in native code", "SIGABRT": "aborted by native code",
               "SIGBUS": "a crash in native code"}.get(name, "killed")
        return f"the worker process died from {name} (signal {-exitcode}: {why})"
    return f"the worker process exited with code {exitcode} before returning a result"


def _isolated_child(conn, fn: Callable[[Any], Any], item: Any, initializer, initargs: tuple) -> None:
    if initializer is not None:
        initializer(*initargs)
    conn.send(_call(fn, item))
    conn.close()


def _isolated(fn: Callable[[Any], Any], item: Any, initializer, initargs: tuple) -> Outcome:
    """Run one item alone in a new process with an empty numba cache, so neither a neighbour
    nor a corrupted compilation cache can fail it; a crash here is the item's own."""
    ctx = mp.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    process = ctx.Process(target=_isolated_child, args=(send, fn, item, initializer, initargs), daemon=True)
    previous = os.environ.get(numba_cache.ENV_FRESH)
    os.environ[numba_cache.ENV_FRESH] = "1"  # inherited by the child at start
    try:
        process.start()
    finally:
        if previous is None:
            os.environ.pop(numba_cache.ENV_FRESH, None)
        else:
            os.environ[numba_cache.ENV_FRESH] = previous
    send.close()
    try:
        outcome = receive.recv()
    except EOFError:  # the child died without answering
        outcome = None
    process.join()
    if outcome is not None:
        return outcome
    return Outcome(item, error_class="WorkerCrashed",
                   error_message=crash_message(process.exitcode) + ", also when run alone in a fresh process")


def run_items(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    workers: int = 1,
    kind: str = "process",
    initializer: Callable[..., None] | None = None,
    initargs: Iterable[Any] = (),
    desc: str = "",
    unit: str = "item",
    ray_options: dict | None = None,
    gpu: bool = False,
    inline_seconds: float = 0.0,
) -> Iterator[Outcome]:
    """Yield one Outcome per item, in completion order, with a progress bar.

    ``kind`` is "process" (CPU-bound work), "thread" (I/O-bound work such as downloads)
    or "ray" (a Ray cluster, ``ray_options``: address, num_cpus); ``workers <= 1`` runs
    inline in this process (not for "ray"). With ``inline_seconds`` (kind "process"), items
    run inline until that much time has passed, and only what is left then goes to the
    workers: spawning them costs more than a few items of a light stage take.
    """
    if not items:  # nothing to do: no worker state (models) built, no pool started
        return
    bar = tqdm(total=len(items), desc=desc, unit=unit, leave=True)
    try:
        if kind == "ray":
            for outcome in _run_ray(fn, items, workers, initializer, tuple(initargs), ray_options or {}, gpu):
                bar.update()
                yield outcome
            return
        if workers <= 1 or len(items) <= 1:
            budget = float("inf")  # no pool at all
        else:
            budget = inline_seconds if kind == "process" else 0.0
        if budget > 0:
            started = time.perf_counter()
            if initializer is not None:
                initializer(*initargs)
            done = 0
            while done < len(items) and time.perf_counter() - started < budget:
                outcome = _call(fn, items[done])
                done += 1
                bar.update()
                yield outcome
            items = items[done:]
            if not items:
                return
        if kind == "thread":
            pool: cf.Executor = cf.ThreadPoolExecutor(workers, initializer=initializer, initargs=tuple(initargs))
        elif kind == "process":
            # spawn: no inherited ONNX/torch thread pools or locks from the parent.
            pool = cf.ProcessPoolExecutor(
                workers, mp_context=mp.get_context("spawn"), initializer=initializer, initargs=tuple(initargs)
            )
        else:
            raise ValueError(f"unknown executor kind {kind!r} (process or thread)")
        crashed = []
        with pool:
            futures = {pool.submit(_call, fn, item): item for item in items}
            try:
                for future in cf.as_completed(futures):
                    try:
                        outcome = future.result()
                    except cf.process.BrokenProcessPool:
                        crashed.append(futures[future])  # this one, or a neighbour, killed the worker
                        continue
                    bar.update()
                    yield outcome
            finally:
                for future in futures:
                    future.cancel()
        if crashed:
            log.warning("a worker process died; retrying %d unfinished item(s) one at a time in fresh processes",
                        len(crashed))
        for item in crashed:  # alone in a fresh process each: only the real culprit fails
            outcome = _isolated(fn, item, initializer, tuple(initargs))
            if outcome.ok:
                log.warning("%s: finished when retried alone", _label(item))
            bar.update()
            yield outcome
    finally:
        bar.close()
