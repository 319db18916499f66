"""Stream routing: bounded recorder queue, counted and reported overflow, live subscriptions."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.streams import BlockQueue, StreamRouter, StreamSpec


def test_overflow_is_counted_and_reported_not_silent() -> None:
    reports: list[int] = []
    router = StreamRouter(queue_blocks=2, on_overflow=lambda block, dropped: reports.append(dropped))
    router.start_recording(["cam"])
    for k in range(252):
        router.publish("cam", "x", [k, k + 0.5], np.zeros(2))
    stats = router.stats[("cam", "x")]
    assert stats.samples == 504 and stats.overflows == 250 and stats.dropped_samples == 500
    assert reports == [2, 202, 402]  # first overflow, then every 100th
    assert router.recorder_queue.qsize() == 2


def test_not_recording_means_no_queueing_but_live_views_still_fed() -> None:
    router = StreamRouter(queue_blocks=1)
    sub = router.subscribe([("cam", "x")], max_bytes=3 * 16)  # 3 blocks of one f8 time and one f8 value
    for k in range(5):
        router.publish("cam", "x", [k], [k * 10.0])
    assert router.recorder_queue.empty()
    assert sub.dropped == 2 and [b.times[0] for b in sub.drain()] == [2.0, 3.0, 4.0]
    assert sub.latest is not None and sub.latest.values[0] == 40.0


def test_subscription_get_waits_for_another_thread() -> None:
    router = StreamRouter()
    sub = router.subscribe([("tracker", "azimuth")])
    assert sub.get(timeout=0.01) is None
    threading.Timer(0.05, router.publish, args=("tracker", "azimuth", [1.0], [0.25])).start()
    block = sub.get(timeout=2.0)
    assert block is not None and block.values[0] == 0.25


@given(st.lists(st.integers(1, 50), min_size=1, max_size=60), st.integers(1, 16))
def test_block_queue_keeps_order_and_bound(sizes: list[int], limit: int) -> None:
    router = StreamRouter(queue_blocks=40)
    router.start_recording(["a"])
    for i, n in enumerate(sizes):
        router.publish("a", "s", np.full(n, float(i)), np.zeros(n))
    q: BlockQueue = router.recorder_queue
    taken = []
    while batch := q.take(limit, timeout=0.0):
        assert len(batch) <= limit
        taken += [int(b.times[0]) for b in batch]
    assert taken == list(range(min(len(sizes), 40)))


@pytest.mark.parametrize(("spec", "expected"), [
    (StreamSpec("x", "f8", (), rate=1000.0), 1000),            # one second per chunk at 1 kHz
    (StreamSpec("img", "u1", (344, 512), rate=100.0), 5),       # about 1 MiB
    (StreamSpec("slow", "f8", (), rate=None), 65536),           # capped
])
def test_chunk_size_rule(spec: StreamSpec, expected: int) -> None:
    assert spec.chunk_samples() == expected
