"""Timing helper shared by the benchmark scripts (run them as ``python bench/bench_x.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["best_of"]


def best_of(fn: Callable[[], object], repeat: int = 3) -> float:
    """Smallest wall-clock time in seconds of `repeat` calls of `fn` (the least disturbed run)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)
