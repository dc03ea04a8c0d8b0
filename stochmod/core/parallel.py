"""Worker processes and BLAS threads that do not compete for the same cores.

stochmod's linear algebra is on matrices of the size of the number of wavelet levels (about
20): a multi-threaded BLAS never speeds it up, and while worker processes use every core its
threads spin against them (OpenBLAS busy-waits), which can make this process's share of a
selection several times slower. :func:`single_threaded_blas` limits BLAS to one thread in
this process while work runs beside it, and :func:`process_pool` starts workers that do the
same (threadpoolctl, which finds the BLAS library numpy and scipy loaded).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import gc
import importlib
from collections.abc import Iterator, Sequence

from threadpoolctl import threadpool_limits

__all__ = ["process_pool", "single_threaded_blas"]


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Limit the BLAS libraries of this process to one thread inside the block."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _start_worker(warm: Sequence[str] = ()) -> None:
    """Worker initializer: one BLAS thread for the life of the worker, and the modules `warm`
    imported."""
    threadpool_limits(limits=1, user_api="blas")
    for name in warm:
        try:
            importlib.import_module(name)
        except ImportError:  # an optional module: the task that needs it says so
            pass


class _FrozenHeapPool(concurrent.futures.ProcessPoolExecutor):
    """A process pool that holds this process's objects out of the cyclic garbage collector
    while it runs (:func:`gc.freeze` at creation, :func:`gc.unfreeze` at shutdown).

    A forked worker inherits every object of this process (the imported modules alone are
    some 10^5). Without the freeze each of its full collections walks them all, and touching
    their reference counts copies the pages they sit on; frozen, they are skipped, in this
    process too (where they still die by reference counting)."""

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        try:
            super().shutdown(wait=wait, cancel_futures=cancel_futures)
        finally:
            gc.unfreeze()


def process_pool(max_workers: int, warm: Sequence[str] = ()
                 ) -> concurrent.futures.ProcessPoolExecutor:
    """A pool of `max_workers` processes, each with one BLAS thread, whose forked workers do
    not collect the objects inherited from this process (:class:`_FrozenHeapPool`).

    `warm` names modules each worker imports as it starts, before its first task: for
    modules its later tasks need that this process has not imported (matplotlib for
    figures drawn after the fits), whose import then runs while this process still
    prepares the work instead of after it."""
    gc.freeze()
    return _FrozenHeapPool(
        max_workers=max_workers, initializer=functools.partial(_start_worker, tuple(warm)))
