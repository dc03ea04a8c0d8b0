"""The optional compiler of stochmod's hot loops (numba, the ``fast`` extra).

:func:`compiled` turns a plain Python function into numba's ``njit`` version (without the
GIL, cached on disk) when numba is importable, and returns the function unchanged otherwise:
a compiled kernel and its fallback are one source. :data:`AVAILABLE` says which runs.
Setting ``STOCHMOD_DISABLE_JIT=1`` before importing stochmod forces the plain functions.
"""

from __future__ import annotations

import os
from typing import Any

__all__ = ["AVAILABLE", "compiled"]

try:  # pragma: no cover - depends on the environment
    if os.environ.get("STOCHMOD_DISABLE_JIT", "") not in ("", "0"):
        raise ImportError("disabled by STOCHMOD_DISABLE_JIT")
    import numba
except ImportError:  # pragma: no cover - depends on the environment
    numba = None

#: Whether the compiled loops are available (numba importable and not disabled).
AVAILABLE = numba is not None


def compiled(fn: Any = None, *, fastmath: frozenset[str] = frozenset({"reassoc"})) -> Any:
    """`fn` compiled by numba (``njit``, ``nogil``, `fastmath` flags), lazily on its first
    call; `fn` itself without numba. Use as ``@compiled`` or ``@compiled(fastmath=...)``.

    The machine code is cached on disk when numba finds a writable cache directory, and
    compiled again in each process otherwise. ``reassoc`` (the default) lets LLVM keep several
    partial sums of a reduction in SIMD lanes, so sums may differ from the plain function's in
    their last bits; no flag that assumes finite values is used.
    """
    if fn is None:
        return lambda f: compiled(f, fastmath=fastmath)
    if numba is None:  # pragma: no cover - depends on the environment
        return fn
    flags = set(fastmath)
    try:
        return numba.njit(cache=True, nogil=True, fastmath=flags)(fn)
    except RuntimeError:  # pragma: no cover - no writable cache location (read-only install)
        return numba.njit(cache=False, nogil=True, fastmath=flags)(fn)
