"""Timing helper shared by the benchmark scripts (run them as ``python bench/bench_x.py``)."""

from __future__ import annotations

import time
import tracemalloc
from collections.abc import Callable

__all__ = ["best_of", "peak_ratio"]


def best_of(fn: Callable[[], object], repeat: int = 3,
            clock: Callable[[], float] = time.perf_counter) -> float:
    """Smallest time in seconds of `repeat` calls of `fn` (the least disturbed run), by
    `clock`: wall clock by default, ``time.process_time`` for CPU time (less sensitive to
    other jobs on a shared machine)."""
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return min(times)


def peak_ratio(fn: Callable[[], object], nbytes: int) -> float:
    """Peak memory traced (tracemalloc) during one call of `fn`, relative to `nbytes`."""
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / nbytes
