"""A generator run in a thread of its own, joined to its consumer by a small queue.

Decoding, detection and pose each release the GIL in their native code, so chaining them as
threaded generators keeps more than one core busy on one video with memory bounded by the
queues. An exception in a producer is re-raised in the consumer; setting ``stop`` ends the
producers when the consumer gives up early.
"""

from __future__ import annotations

import queue
import threading
from typing import Any, Iterator

_DONE = object()


class _Failed:
    def __init__(self, exc: BaseException) -> None:
        self.exc = exc


def _pump(source: Iterator[Any], out: queue.Queue, stop: threading.Event) -> None:
    try:
        for item in source:
            while not stop.is_set():
                try:
                    out.put(item, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if stop.is_set():
                return
        out.put(_DONE)
    except BaseException as exc:  # re-raised in the consumer thread
        out.put(_Failed(exc))


def _drain(q: queue.Queue) -> Iterator[Any]:
    while True:
        item = q.get()
        if item is _DONE:
            return
        if isinstance(item, _Failed):
            raise item.exc
        yield item


def threaded(source: Iterator[Any], size: int, stop: threading.Event) -> Iterator[Any]:
    """The items of ``source``, produced in a daemon thread at most ``size`` ahead of the consumer."""
    q: queue.Queue = queue.Queue(maxsize=size)
    thread = threading.Thread(target=_pump, args=(source, q, stop), daemon=True)
    thread.start()
    return _drain(q)
