"""The compiler of stochmod's hot loops (numba).

:func:`compiled` turns a plain Python function into numba's ``njit`` version (without the
GIL, cached on disk): a compiled kernel and its plain-Python self are one source, the latter
as the kernel's ``py_func``. Setting ``STOCHMOD_DISABLE_JIT=1`` before importing stochmod
makes :func:`compiled` return the plain functions (for debugging); :data:`AVAILABLE` says
which run.
"""

from __future__ import annotations

import os
from typing import Any

__all__ = ["AVAILABLE", "compiled"]

if os.environ.get("STOCHMOD_DISABLE_JIT", "") not in ("", "0"):  # pragma: no cover
    numba = None
else:
    import numba

#: Whether the loops run compiled (False when ``STOCHMOD_DISABLE_JIT`` is set).
AVAILABLE = numba is not None


def compiled(fn: Any = None, *, fastmath: frozenset[str] = frozenset({"reassoc"})) -> Any:
    """`fn` compiled by numba (``njit``, ``nogil``, `fastmath` flags), lazily on its first
    call; `fn` itself when ``STOCHMOD_DISABLE_JIT`` is set. Use as ``@compiled`` or
    ``@compiled(fastmath=...)``.

    The machine code is cached on disk when numba finds a writable cache directory, and
    compiled again in each process otherwise. ``reassoc`` (the default) lets LLVM keep several
    partial sums of a reduction in SIMD lanes, so sums may differ from the plain function's in
    their last bits; no flag that assumes finite values is used.
    """
    if fn is None:
        return lambda f: compiled(f, fastmath=fastmath)
    if numba is None:  # pragma: no cover - STOCHMOD_DISABLE_JIT
        return fn
    flags = set(fastmath)
    try:
        return numba.njit(cache=True, nogil=True, fastmath=flags)(fn)
    except RuntimeError:  # pragma: no cover - no writable cache location (read-only install)
        return numba.njit(cache=False, nogil=True, fastmath=flags)(fn)
