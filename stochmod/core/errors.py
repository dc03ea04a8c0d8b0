"""Exception types raised by stochmod.

Every error the framework raises on bad input derives from :class:`StochmodError`
(itself a :class:`ValueError`), so callers can catch one type, and the message
always names the offending argument and what was expected of it.
"""

from __future__ import annotations

__all__ = [
    "StochmodError",
    "InputError",
    "DomainError",
    "SpecError",
    "UnknownProcessError",
    "EstimationError",
    "AccuracyWarning",
]


class StochmodError(ValueError):
    """Base class of every error stochmod raises on bad input or failed estimation."""


class InputError(StochmodError):
    """A signal or argument is malformed (empty, too short, NaN/inf, wrong shape, non-numeric)."""


class DomainError(StochmodError):
    """A parameter value lies outside its family's domain (e.g. a negative variance)."""


class SpecError(StochmodError):
    """A model specification (string or dict) is malformed."""


class UnknownProcessError(SpecError, KeyError):
    """No registered process family has the requested name."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0]) if self.args else ""


class EstimationError(StochmodError):
    """An estimator failed (optimizer did not converge, singular weighting, ...)."""


class AccuracyWarning(RuntimeWarning):
    """A result could not be computed to a useful accuracy in double precision (e.g. a
    derivative at parameters within ~1e-8 of a domain boundary); the message says which."""
