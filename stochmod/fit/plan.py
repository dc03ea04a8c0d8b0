"""How long to record: the GMWM interval of each parameter as a function of the record length.

For a model with values (a calibration's final model, or a model declared before any
recording), the large-sample covariance of the GMWM estimate on N samples is the sandwich of
eqs. 22-23 (Stebler et al. 2014),

``cov(theta_hat) = B V_N B^T``,  ``B = (D^T Omega D)^{-1} D^T Omega``,

with D the Jacobian of the model's Haar WV at the levels N samples give, V_N the covariance of
the empirical WV under the model (the Gaussian form of eq. 17 from the model's PSD:
:func:`stochmod.fit.weighting.model_covariance`, with ``M_j = N - 2^j + 1`` coefficients at
level j), and Omega ``diag(1 / V_jj)``: the weighting ``"model"``
(:class:`stochmod.fit.weighting_plugins.ModelWeighting`), whose weights do not depend on the
levels' own errors. A positive parameter's
interval is ``theta */ exp(z se / theta)`` (the delta method on the log scale, as
:meth:`stochmod.fit.results.GMWMResult.parameters`), so its relative half-width is
``exp(z se / theta) - 1``. :func:`record_length` finds, per parameter, the shortest record
whose half-width is at most the asked precision.

The widths are those of the asymptotic intervals of a fit with ``weighting="model"``. The
default diagonal weighting divides each level by its own squared WV; for a parameter that only
the deepest levels see (a random walk, a slow Gauss-Markov term) its estimates spread up to
twice as much (docs/record_length.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import attrs
import numpy as np
from scipy import special

from stochmod.core.errors import EstimationError, InputError
from stochmod.core.filters import default_levels, filter_width
from stochmod.core.model import Model
from stochmod.core.tables import format_table
from stochmod.fit.engine import sandwich
from stochmod.fit.weighting import model_covariance

__all__ = ["MAX_SAMPLES", "RecordPlan", "interval_half_widths", "record_length"]

#: Longest record :func:`record_length` considers, samples (about 2.7 years at 400 Hz).
MAX_SAMPLES = 2**35


def _checked(model: Model) -> Model:
    if not isinstance(model, Model):
        raise InputError(f"model must be a stochmod Model with values, got {model!r}")
    if model.freq is None:
        raise InputError("the model is not bound to a sampling frequency: model.bind(freq)")
    for proc in model.processes:
        proc.require_values()
    return model


def interval_half_widths(model: Model, n: int, *, level: float = 0.95) -> np.ndarray:
    """Relative half-widths ``exp(z se / theta) - 1`` of the GMWM intervals of every
    parameter of `model` (``model.vector()`` order) on a record of `n` samples.

    Parameters
    ----------
    model : Model
        With values, bound to its sampling frequency.
    n : int
        Record length, samples.
    level : float
        Confidence level of the intervals.

    Returns
    -------
    ndarray
        One per parameter (dimensionless; 0.1 is +-10 %); inf where the parameter is not
        identified on `n` samples (fewer levels than parameters, a singular Jacobian) or is
        not positive.
    """
    model = _checked(model)
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be in (0, 1), got {level!r}")
    n = int(n)
    theta = model.vector()
    if n < 8:
        return np.full(theta.size, math.inf)
    J = default_levels(n)
    if J < theta.size:
        return np.full(theta.size, math.inf)
    n_coef = np.array([n - filter_width(j) + 1 for j in range(1, J + 1)], dtype=np.int64)
    V = model_covariance(model, n_coef)
    D = model.wv_jacobian(J)
    try:
        cov = sandwich(D, np.diag(1.0 / np.diag(V)), V)
    except (np.linalg.LinAlgError, EstimationError):
        return np.full(theta.size, math.inf)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    z = float(special.ndtri(0.5 + level / 2.0))
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        width = np.expm1(z * se / theta)
    return np.where((theta > 0) & np.isfinite(width), width, math.inf)


@attrs.frozen
class RecordPlan:
    """The record each parameter of a model needs for a given precision.

    Attributes
    ----------
    names : tuple of str
        Parameter names (``label.param``, ``model.param_names``).
    values : ndarray
        Their values (canonical, per sample in the signal unit).
    samples : ndarray
        Shortest record (samples) whose interval half-width is at most :attr:`precision`; -1
        where none up to :data:`MAX_SAMPLES` is.
    freq : float
        Sampling frequency, Hz.
    precision : float
        The asked relative half-width (0.1: +-10 %).
    level : float
        Confidence level.
    current : int or None
        The record the model was fitted on, samples, when known.
    current_widths : ndarray or None
        The half-widths at :attr:`current`.
    """

    names: tuple[str, ...]
    values: np.ndarray
    samples: np.ndarray
    freq: float
    precision: float
    level: float
    current: int | None = None
    current_widths: np.ndarray | None = None

    @property
    def hours(self) -> np.ndarray:
        """:attr:`samples` in hours (inf where no record reaches the precision)."""
        return np.where(self.samples > 0, self.samples / self.freq / 3600.0, math.inf)

    @property
    def longest(self) -> float:
        """The record, h, that gives every parameter its precision."""
        return float(np.max(self.hours)) if self.hours.size else 0.0

    def summary(self) -> str:
        """One row per parameter: value, record needed, half-width at the current record."""
        pct = f"{100 * self.precision:g} %"
        rows = []
        for k, name in enumerate(self.names):
            need = "beyond " + _duration(MAX_SAMPLES / self.freq) if self.samples[k] < 0 else (
                _duration(self.samples[k] / self.freq))
            now = ("-" if self.current_widths is None else
                   f"+-{100 * self.current_widths[k]:.3g} %")
            rows.append([name, float(self.values[k]), need, now])
        title = (f"record needed for each parameter's {100 * self.level:g} % interval within "
                 f"+-{pct} (asymptotic GMWM intervals, weighting='model')")
        head = ["parameter", "value", "record needed",
                "now" if self.current is None else f"at {_duration(self.current / self.freq)}"]
        return format_table(head, rows, title=title) + (
            f"\n\nall parameters: {_duration(self.longest * 3600.0)}"
            if math.isfinite(self.longest) else "")


def _duration(seconds: float) -> str:
    if seconds >= 3600.0:
        return f"{seconds / 3600.0:.3g} h"
    if seconds >= 60.0:
        return f"{seconds / 60.0:.3g} min"
    return f"{seconds:.3g} s"


def _shortest(model: Model, k: int, precision: float, level: float) -> int:
    """Smallest n with half-width of parameter `k` at most `precision` (doubling, then
    bisection on the doubling's last octave; -1 beyond :data:`MAX_SAMPLES`)."""
    lo, hi = 8, 64
    while interval_half_widths(model, hi, level=level)[k] > precision:
        lo, hi = hi, 2 * hi
        if hi > MAX_SAMPLES:
            return -1
    while hi - lo > max(1, lo // 256):  # 0.4 % of the length
        mid = (lo + hi) // 2
        if interval_half_widths(model, mid, level=level)[k] > precision:
            lo = mid
        else:
            hi = mid
    return hi


def record_length(model: Model, *, precision: float = 0.1, level: float = 0.95,
                  current: int | None = None, parameters: Sequence[str] | None = None
                  ) -> RecordPlan:
    """How long to record so that each parameter's interval is within +-`precision`.

    Parameters
    ----------
    model : Model
        With values, bound to its sampling frequency (e.g. ``Calibration.models[column]``,
        or a declared model such as a datasheet's).
    precision : float
        Relative half-width wanted (0.1: +-10 %), in (0, 10].
    level : float
        Confidence level of the intervals.
    current : int, optional
        A record length, samples, at which to report the half-widths too.
    parameters : sequence of str, optional
        Names (``model.param_names``) to plan for; default all.

    Returns
    -------
    RecordPlan

    Examples
    --------
    >>> import stochmod
    >>> from stochmod.fit.plan import record_length
    >>> m = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-10)", 100.0)
    >>> plan = record_length(m, precision=0.1)
    >>> plan.hours.round(2).tolist()  # doctest: +SKIP
    [0.0, 2.1]
    """
    model = _checked(model)
    if not (isinstance(precision, (int, float)) and 0.0 < precision <= 10.0):
        raise InputError(f"precision must be a relative half-width in (0, 10], got {precision!r}")
    names = tuple(model.param_names)
    wanted = names if parameters is None else tuple(parameters)
    unknown = [p for p in wanted if p not in names]
    if unknown:
        raise InputError(f"no parameter(s) {unknown} in {model.name}; its parameters are "
                         f"{list(names)}")
    index = [names.index(p) for p in wanted]
    samples = np.array([_shortest(model, k, float(precision), level) for k in index],
                       dtype=np.int64)
    widths = None if current is None else interval_half_widths(model, current, level=level)[index]
    return RecordPlan(wanted, model.vector()[index], samples, float(model.freq),
                      float(precision), float(level), current, widths)
