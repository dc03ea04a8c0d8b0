"""Conformance kits: checks that a plugin honours the contract of its plugin point.

Run :func:`check_family` on a process family, :func:`check_reader` on a log reader,
:func:`check_weighting` on a GMWM weighting and :func:`check_combiner` on a redundant-sensor
combiner; each raises :class:`AssertionError` naming the rule broken.
"""

from stochmod.testing.combiners import *  # noqa: F403
from stochmod.testing.combiners import __all__ as _combiners_all
from stochmod.testing.families import *  # noqa: F403
from stochmod.testing.families import __all__ as _families_all

__all__ = list(dict.fromkeys([*_families_all, *_combiners_all]))
