"""attrs field helpers shared by the result classes."""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

__all__ = ["array_field"]


def array_field(**kwargs: Any) -> Any:
    """An attrs field holding an ndarray, compared with :func:`numpy.array_equal`."""
    return attrs.field(eq=attrs.cmp_using(eq=np.array_equal), **kwargs)
