"""threaded: a generator in a thread of its own, joined to its consumer by a small queue."""

from __future__ import annotations

import threading
import time

import pytest

from pipeline.core.threads import threaded


def test_items_arrive_in_order_and_the_producer_runs_in_another_thread() -> None:
    stop = threading.Event()
    seen = []

    def source():
        for i in range(50):
            seen.append(threading.current_thread())
            yield i

    assert list(threaded(source(), 2, stop)) == list(range(50))
    assert all(t is not threading.current_thread() for t in seen)


def test_a_producer_error_is_raised_in_the_consumer_after_the_items_before_it() -> None:
    def source():
        yield 1
        yield 2
        raise ValueError("bad frame 3")

    got = []
    with pytest.raises(ValueError, match="bad frame 3"):
        for item in threaded(source(), 4, threading.Event()):
            got.append(item)
    assert got == [1, 2]


def test_setting_stop_ends_a_producer_blocked_on_a_full_queue() -> None:
    stop = threading.Event()
    producer = []

    def endless():
        producer.append(threading.current_thread())
        while True:
            yield 0

    stream = threaded(endless(), 1, stop)
    assert next(stream) == 0
    time.sleep(0.3)  # the queue is full again and the producer waits to put the next item
    stop.set()  # the consumer gives up; nothing drains the queue any more
    producer[0].join(timeout=2.0)
    assert not producer[0].is_alive()
