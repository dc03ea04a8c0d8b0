"""Loosely-coupled INS/GNSS error-state extended Kalman filter with feedback (closed loop).

The filter follows Gonzalez et al. (2015), Algorithms 1-2 and eqs. 20-24, with the sensor-error
part generalised as in Quinchia et al. (2013), Section 7 and Appendix (eqs. 21-33): the 9
navigation error states (position ``dr`` NED m, velocity ``dv`` NED m/s, attitude ``psi`` rad,
all "estimate minus truth", ``C_nb_hat = (I - [psi x]) C_nb``) are followed by sensor-error
states assembled on demand from one stochmod model per axis (:func:`stochmod.augment_axes`):
random walks or Gauss-Markov biases give the 15-state filter, AR(p) the 27-state one, bias + GM
Gonzalez's 21-state UMM; any registered family works because only its state-space block is used.
Optional turn-on biases (random constants, ``gyro_bias_sd``/``accel_bias_sd``) add 6 states
(Gonzalez's ``b_g``, ``b_f``, eq. 20f, 24).

Continuous error model (the psi-angle model of Gonzalez eq. 20k with Titterton & Weston's
sub-matrices):

- ``d(dr)/dt = dv``
- ``d(dv)/dt = [f_n x] psi - (2 w_ie + w_en) x dv + dg(dr) - C_nb H_a ds + C_nb w_a``
- ``d(psi)/dt = -w_in x psi + C_nb H_g ds - C_nb w_g``
- ``d(ds)/dt = F_s ds + G_s dW`` (the models' continuous form)

with ``dg = (-g/R dr_N, -g/R dr_E, 2g/R dr_D)``. The white parts of the models become the
navigation process noise with PSD ``N^2 = white_var / freq``; so does a decoupled scalar
process decorrelated within a tenth of an IMU sample (``SUB_SAMPLE_POLE``), with its stationary
variance per sample, because that is what it is at the IMU rate. Covariance propagation happens at
the filter step ``dt_filter`` (and at measurement epochs), not at every IMU sample, with the
transition frozen over the step and discretised exactly (Van Loan) when every sensor block has a
continuous form. For discrete-only blocks (AR) the sensor block is composed exactly from its
one-sample transition, the navigation block is exact (Van Loan), and the coupling uses the
trapezoid ``dt/2 (Phi_nn F_ns + F_ns Phi_ss)``.

The covariance step is linearised at its middle: F varies along the trajectory (attitude in
turns, velocity, specific force), and the exact transition over a step is the time-ordered
exponential of F; ``expm(F(t_mid) dt)`` is its first Magnus term, with a local error O(dt^3)
(the midpoint rule; Iserles & Norsett 1999, "On the solution of linear
differential equations in Lie groups", and Hairer, Lubich & Wanner, "Geometric Numerical
Integration", IV.7), against O(dt^2) at the end point; the state at the middle is the mean of
the two ends (:func:`midpoint_pva`), second-order accurate. pyins linearises there too;
Gonzalez's Alg. 1 (lines 1-2) takes F (eq. 20k) at the update epoch and ``Phi = I + F dt``,
first order in both.

Measurements are applied at their own time stamps (the estimate is interpolated between the two
IMU epochs around the stamp, and the measurement matrix refers the error to the stamp,
``H (I - (t_k - t_m) F)``, Gonzalez eqs. 20h-20i at ``t_m``; the measurements of one IMU
interval, such as a fix's position and velocity, are updated in sequence, each predicted from
the state the ones before it corrected at both ends of the interval), gated by a chi-square
test on the normalised innovation, and fed back into the mechanisation (Gonzalez Alg. 2 lines
27-30, eq. 26), after which the error state is zero again.

Gating and recovery (``gate``, ``recover_after``): an update whose normalised innovation
squared ``NIS = y' S^-1 y``, ``S = H P H' + R`` (Gonzalez Alg. 1 line 4), exceeds the
``gate`` quantile of the chi-square distribution with ``dim y`` degrees of freedom is rejected
(Bar-Shalom, Li & Kirubarajan 2001, Section 5.4, for the NIS test). A filter whose covariance
has become too small for its true error (a sensor error far outside its model, such as a
turn-on gyro bias of thousands of deg/h against a 300 deg/h prior) rejects every later fix and
drifts without bound. So after ``recover_after`` consecutive rejections of one kind, the next
update of that kind that fails the gate is applied after scaling the whole error covariance
by ``lam >= 1`` chosen so that its NIS equals its chi-square mean, ``y' (lam H P H' + R)^-1 y =
dim y`` (:func:`matching_factor`): the fading-memory step (Sorenson & Sacks 1971) with the
covariance-matching scale. A common scale keeps every correlation, so the fix corrects the
states it depends on (attitude and sensor errors through their correlation with position);
if the cause persists, the next run of rejections scales again, until the sensor-error
sigmas cover it. Each recovery is kept (:class:`Recovery`, ``NavResult.recoveries``) and its
NIS row is flagged 2 (accepted 1, rejected 0). On an emulated drive with 5000 deg/h gyro
biases and a 300 deg/h prior the filter recovers twice and reaches the accuracy of the same
drive without the biases (tests/nav/test_gating.py); without the recovery it rejects 97 % of
the fixes and drifts by 85 km. The price: a run of more than ``recover_after`` bad fixes
(multipath) is taken after the inflation; the inflated covariance then lets the good fixes
that follow pull the solution back.

Smoothing (``run(..., smooth=True)``): the forward pass also stores, per filter epoch, the
smoother gain and the fed-back estimate, and ``NavResult.smoothed`` is the fixed-interval
Rauch-Tung-Striebel solution over the record (:mod:`stochmod.nav.smoother`).

Error model (``error_model``): how the estimate is fed back and where the covariance is held
across the feedback (the reset). Write ``e`` for the error before a feedback, ``e_hat`` for the
applied estimate and ``e+ = g(e, e_hat)`` for the error after it; the reset is ``P <- G P G'``
with ``G = dg/de`` at ``e = e_hat`` (Groves 2013, Chapter 14 on the closed-loop correction of
the INS; Sola 2017, "Quaternion kinematics for the error-state Kalman filter", Section 7.2).

- ``"psi"`` (default): ``v <- v_hat - dv_hat``, position and sensor states likewise, and
  ``C_nb <- Exp(psi_hat) C_nb_hat``; ``G = I`` (the first-order reset).
- ``"modified-phi"``: Scherzinger & Reid's modified phi-angle model, the one pyins uses: the
  velocity error ``dv' = v_hat - Exp(psi)' v`` (``dv - v_hat x psi`` to first order; the
  specific force moves out of F into that definition). Its F is the psi model's carried into
  ``dv'`` (the two propagate the same covariance to 5e-6 of the correlation scale at the same
  linearisation point, docs/navigation_real_drive.md), so the propagation is done in the psi
  form. Its feedback is the exact injection of its own error, ``v <- Exp(psi_hat) (v_hat -
  dv'_hat)`` (pyins' ``correct_pva``), and its reset holds the covariance in ``(dv', psi)``
  while ``v_hat`` moves by the applied change ``Delta v``: in stochmod's states ``G = I +
  [Delta v x]`` in the velocity-attitude block. That is the first-order reset of this model, as
  pyins has it (its exact Jacobian in ``(dv', psi)`` would be ``Exp(psi_hat)`` on ``dv'`` and
  ``J_l(psi_hat)`` on ``psi``). On the n380 drive this decides how much
  heading information the filter takes at rest, and with it the tilt / accelerometer-bias split
  (docs/navigation_real_drive.md).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import EstimationError, InputError, SpecError
from stochmod.core.fields import array_field
from stochmod.core.jit import compiled
from stochmod.core.model import Model, augment_axes
from stochmod.core.statespace import ContinuousBlock, compose_steps
from stochmod.core.tables import format_table
from stochmod.core.units import signal_unit
from stochmod.nav import earth, frames
from stochmod.nav.alignment import InitialState, align_from_gnss
from stochmod.nav.emulate import AXES, Trajectory
from stochmod.nav.measurements import (
    GnssPosition,
    GnssVelocity,
    MagneticHeading,
    Measurement,
    Snapshot,
    ZeroVelocity,
)
from stochmod.nav.records import GnssData, TrajectoryArrays, check_time
from stochmod.nav.smoother import (
    SmootherStore,
    correct_rows,
    interpolate_errors,
    node_ranges,
)
from stochmod.nav.strapdown import Mechanisation, check_imu, imu_increments, mech_step

_A, _E2, _OM = earth.A, earth.E2, earth.OMEGA_IE
_G0, _G1, _G2 = earth.GRAVITY_G0, earth.GRAVITY_G1, earth.GRAVITY_G2

__all__ = [
    "ERROR_MODELS",
    "NAV_STATES",
    "Alignment",
    "Health",
    "LooselyCoupledFilter",
    "NavResult",
    "RandomWalkEquivalent",
    "Recovery",
    "error_dynamics",
    "matching_factor",
    "midpoint_pva",
]

NAV_STATES = ("dr_n", "dr_e", "dr_d", "dv_n", "dv_e", "dv_d", "psi_x", "psi_y", "psi_z")

#: The error models of :class:`LooselyCoupledFilter` (module notes): how the estimate is fed back
#: and where the covariance is held across the feedback.
ERROR_MODELS = ("psi", "modified-phi")


@attrs.frozen
class RandomWalkEquivalent:
    """A correlated sensor-error component whose correlation time exceeds the record the model
    was fitted on, augmented as the random walk it is equivalent to over that record
    (:mod:`stochmod.fit.equivalence`).

    Attributes
    ----------
    state : str
        Filter state (``axis.label.state``).
    tc : float
        Fitted correlation time, s.
    q : float
        Random-walk intensity ``2 sigma^2 / Tc`` (the component's driving noise; signal unit
        squared per second).
    record : float
        Record length T, s; the state starts with variance ``q T`` (:attr:`p0`).
    """

    state: str
    tc: float
    q: float
    record: float

    @property
    def p0(self) -> float:
        """Initial variance ``q T``: the spread the walk reaches over the record."""
        return self.q * self.record

    @property
    def stationary_sd(self) -> float:
        """The fitted stationary sigma, ``sqrt(q Tc / 2)`` (not identified by the record)."""
        return math.sqrt(self.q * self.tc / 2.0)

    def describe(self) -> str:
        """One line for reports."""
        return (f"{self.state}: correlation time {self.tc:.3g} s beyond the {self.record:g} s "
                f"record, augmented as a random walk q = 2 sigma^2/Tc = {self.q:.3g} per s with "
                f"initial sd sqrt(q T) = {math.sqrt(self.p0):.3g} (not the stationary sigma "
                f"{self.stationary_sd:.3g})")


@attrs.frozen
class Recovery:
    """One recovery from a run of rejected updates (module notes, "Gating and recovery").

    Attributes
    ----------
    time : float
        Time stamp of the update that was applied after the inflation, s.
    kind : str
        Measurement kind (``gnss_position``, ``gnss_velocity``, ...).
    nis : float
        Its normalised innovation squared before the inflation.
    dof : int
        Its dimension (the chi-square degrees of freedom).
    factor : float
        The factor ``lam`` >= 1 the error covariance was multiplied by.
    """

    time: float
    kind: str
    nis: float
    dof: int
    factor: float

    def describe(self) -> str:
        """One line for reports."""
        return (f"t = {self.time:.3f} s {self.kind}: NIS {self.nis:.3g} (dof {self.dof}), "
                f"covariance x {self.factor:.3g} (sd x {math.sqrt(self.factor):.3g})")


def matching_factor(y: np.ndarray, A: np.ndarray, R: np.ndarray, target: float) -> float:
    """The covariance-matching inflation of a rejected innovation.

    The smallest ``lam >= 1`` with ``y' (lam A + R)^-1 y <= target``, for the innovation `y`
    (m,), its predicted part ``A = H P H'`` and its noise `R` (m, m): with the whole error
    covariance scaled by ``lam`` the innovation's NIS equals `target` (the chi-square mean, its
    dimension), the moment condition ``E[y' S^-1 y] = m`` of the NIS test (Bar-Shalom, Li &
    Kirubarajan 2001, Section 5.4) solved for a common scale of ``P`` as in fading-memory
    filtering (Sorenson & Sacks 1971). With ``R = L L'`` and ``L^-1 A L^-T = U diag(a) U'`` the
    NIS is ``sum z_i^2 / (lam a_i + 1)``, ``z = U' L^-1 y``: decreasing in ``lam``, solved by
    bisection on ``log lam``. Returns 1 when the NIS is already at or below `target`; at most
    1e12 (an innovation outside the predicted part's range).
    """
    Li = np.linalg.inv(np.linalg.cholesky(R))
    a, U = np.linalg.eigh(Li @ A @ Li.T)
    a = np.clip(a, 0.0, None)
    z2 = (U.T @ (Li @ y)) ** 2

    def nis(lam: float) -> float:
        return float((z2 / (lam * a + 1.0)).sum())

    if nis(1.0) <= target:
        return 1.0
    lo, hi = 0.0, 12.0 * math.log(10.0)
    if nis(math.exp(hi)) > target:
        return math.exp(hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if nis(math.exp(mid)) > target else (lo, mid)
    return math.exp(hi)


#: Below this speed (m/s) the start state counts as static (:class:`Alignment`).
STATIC_SPEED = 0.5


@attrs.frozen
class Alignment:
    """Where and how the filter started.

    Attributes
    ----------
    time : float
        Time of the initial state, s.
    first_time : float
        First IMU time stamp, s.
    lat, lon : float
        deg.
    height : float
        m.
    speed : float
        Speed of the initial state, m/s.
    source : {"given", "gnss"}
        ``"given"``: the caller's ``init``; ``"gnss"``: aligned in motion from GNSS
        (:func:`~stochmod.nav.alignment.align_from_gnss`, heading from the course).
    sd : tuple of float
        Initial 1-sigma: position N/E/D (m), velocity (m/s), roll/pitch/heading (deg), 9 values.
    """

    time: float
    first_time: float
    lat: float
    lon: float
    height: float
    speed: float
    source: str
    sd: tuple = ()

    @property
    def static(self) -> bool:
        """Whether the start was at rest (speed below :data:`STATIC_SPEED`)."""
        return self.speed < STATIC_SPEED

    def describe(self) -> str:
        """One line for reports."""
        how = ("given initial state" if self.source == "given"
               else "in-motion alignment from GNSS (heading from the course)")
        sd = np.asarray(self.sd, dtype=float)
        sig = "" if sd.size != 9 else (
            f"; initial 1-sigma {sd[0]:.3g} m, {sd[3]:.3g} m/s, level {sd[6]:.3g}/{sd[7]:.3g} "
            f"deg, heading {sd[8]:.3g} deg")
        return (f"alignment: t = {self.time:.3f} s ({self.time - self.first_time:.3f} s after "
                f"the first IMU sample) at {self.lat:.7f}, {self.lon:.7f} deg, "
                f"{self.height:.2f} m; {'static' if self.static else 'in motion'} (speed "
                f"{self.speed:.2f} m/s), {how}{sig}")


#: The health rule (:meth:`NavResult.health`): a kind with more than this share of its updates
#: rejected makes the solution untrusted.
MAX_REJECTED_SHARE = 0.2
#: Window of the windowed NIS, s.
NIS_WINDOW = 60.0
#: Windows that start less than this long (s) after the alignment are not judged (convergence).
NIS_SETTLE = 60.0
#: Two-sided probability of a window's chi-square band.
NIS_BAND = 0.99
#: A window is far out of its band when its mean NIS is more than this factor above the band's
#: upper end (the filter is overconfident: its sigmas and its gate cannot be relied on). A mean
#: below the band (noise sigmas pessimistic, common with receiver-reported sigmas) is reported,
#: not judged.
NIS_FAR = 3.0


@attrs.frozen
class Health:
    """Whether a filter's solution can be trusted, and why (:meth:`NavResult.health`).

    Attributes
    ----------
    trusted : bool
        False when any kind has more than ``max_rejected`` of its updates rejected, or any
        window after the settling time has its mean NIS far above its chi-square band.
    reasons : tuple of str
        One line per failed condition.
    shares : dict of str to float
        Rejected share of the updates, per kind.
    recoveries : dict of str to int
        Recoveries per kind.
    windows : dict of str to ndarray
        Per kind, rows ``(start s, end s, n updates, mean NIS, band low, band high, judged,
        far)`` (:meth:`NavResult.nis_windows`).
    alignment : Alignment or None
    rule : str
        The rule, in words.
    """

    trusted: bool
    reasons: tuple
    shares: dict
    recoveries: dict
    windows: dict = attrs.field(eq=False)
    alignment: Alignment | None
    rule: str

    def describe(self) -> str:
        """The health section of a report: alignment, rejections, recoveries, windowed NIS,
        verdict."""
        lines = ["Filter health"]
        if self.alignment is not None:
            lines.append(self.alignment.describe())
        for kind, share in self.shares.items():
            lines.append(f"{kind}: {share:.1%} of the updates rejected, "
                         f"{self.recoveries.get(kind, 0)} recoveries")
        rows = [[kind, f"{w[0]:.1f}", f"{w[1]:.1f}", int(w[2]), float(w[3]),
                 f"[{w[4]:.3g}, {w[5]:.3g}]",
                 "FAR ABOVE" if w[7] else ("settling" if not w[6] else
                                           "below" if w[3] < w[4] else
                                           "above" if w[3] > w[5] else "in band")]
                for kind, arr in self.windows.items() for w in arr]
        if rows:
            lines.append(format_table(["measurement", "from s", "to s", "n", "mean NIS",
                                       f"{NIS_BAND:.0%} band", ""], rows,
                                      title="NIS per window (times from the first IMU sample)"))
        lines.append(f"rule: {self.rule}")
        if self.trusted:
            lines.append("verdict: the solution passes the health rule")
        else:
            lines += ["verdict: UNTRUSTED SOLUTION"] + [f"  - {r}" for r in self.reasons]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready form."""
        al = None if self.alignment is None else {
            **attrs.asdict(self.alignment), "static": self.alignment.static,
            "sd": list(self.alignment.sd)}
        keys = ("start", "end", "n", "mean_nis", "band_low", "band_high", "judged", "far_out")
        return {"trusted": self.trusted, "reasons": list(self.reasons), "rule": self.rule,
                "rejected_share": dict(self.shares), "recoveries": dict(self.recoveries),
                "alignment": al,
                "nis_windows": {k: [dict(zip(keys, (float(v) for v in w))) for w in arr]
                                for k, arr in self.windows.items()}}


@attrs.frozen
class NavResult(TrajectoryArrays):
    """Output of :meth:`LooselyCoupledFilter.run`.

    Navigation arrays are at the IMU time stamps from the start time on; their 1-sigma holds the
    value of the latest filter epoch. Per-epoch arrays (``epoch_*``) are at the filter epochs.

    Attributes
    ----------
    time, lat, lon, height, vel_ned, rph
        Trajectory (s, deg, deg, m, m/s (n, 3), deg (n, 3)).
    sd_position, sd_velocity, sd_rph : ndarray (n, 3)
        1-sigma of N/E/D position (m), velocity (m/s), and attitude error about N/E/D (deg).
    epoch_time : ndarray (k,)
        Filter epochs, s.
    state_names : tuple of str
        All filter states (9 navigation + sensor states).
    epoch_sd : ndarray (k, n_states)
        1-sigma of every state at each epoch (after any update).
    sensor_states : ndarray (k, n_sensor)
        Estimated sensor-error states (the fed-back nominal values).
    sensor_errors : ndarray (k, 6)
        Estimated error per axis (``gyro_x ... accel_z``; rad/s, m/s^2) without white noise.
    innovations : dict of str to ndarray
        Per measurement kind, rows ``(time, y...)``.
    nis : dict of str to ndarray
        Per measurement kind, rows ``(time, NIS, dof, accepted)``.
    rejected : dict of str to int
        Updates rejected by the innovation gate, per kind.
    recoveries : tuple of Recovery
        Each recovery from a run of rejected updates (module notes, "Gating and recovery").
    alignment : Alignment
        Where and how the filter started.
    smoothed : NavResult or None
        With ``run(..., smooth=True)``: the fixed-interval smoothed solution, the same fields
        at the same times (its ``epoch_sd``, ``sensor_states``, ``nees`` smoothed; its
        innovations, NIS and rejections the forward pass's).
    nees : ndarray (k,) or None
        NEES of the 9 navigation states against the truth at each epoch (``truth`` given).
    random_walks : tuple of RandomWalkEquivalent
        Correlated components whose correlation time exceeds the filter's ``record``, augmented
        as the random walks they are equivalent to over it (empty without ``record``).
    """

    sd_position: np.ndarray = array_field()
    sd_velocity: np.ndarray = array_field()
    sd_rph: np.ndarray = array_field()
    epoch_time: np.ndarray = array_field()
    state_names: tuple[str, ...] = ()
    epoch_sd: np.ndarray = array_field(factory=lambda: np.zeros((0, 0)))
    sensor_states: np.ndarray = array_field(factory=lambda: np.zeros((0, 0)))
    sensor_errors: np.ndarray = array_field(factory=lambda: np.zeros((0, 6)))
    innovations: dict = attrs.field(factory=dict, eq=False)
    nis: dict = attrs.field(factory=dict, eq=False)
    rejected: dict = attrs.field(factory=dict)
    nees: np.ndarray | None = attrs.field(default=None, eq=False)
    gate: float | None = None
    random_walks: tuple = ()
    recoveries: tuple = ()
    recover_after: int | None = None
    alignment: Alignment | None = None
    smoothed: NavResult | None = attrs.field(default=None, eq=False, repr=False)

    @property
    def lever_arm(self) -> np.ndarray | None:
        """Estimated IMU-to-antenna lever arm (k, 3; body x/y/z, m) at the filter epochs, or None
        when the filter did not estimate it (``lever_arm_sd`` = 0)."""
        names = self.state_names[len(NAV_STATES):]
        if "lever_arm.x" not in names:
            return None
        i = names.index("lever_arm.x")
        return self.sensor_states[:, i:i + 3]

    @property
    def mean_nees(self) -> float | None:
        """Average NEES over the epochs (9 for an honest filter), or None without truth."""
        return None if self.nees is None else float(np.mean(self.nees))

    def nis_windows(self, window: float = NIS_WINDOW, settle: float = NIS_SETTLE,
                    band: float = NIS_BAND, far: float = NIS_FAR) -> dict[str, np.ndarray]:
        """The NIS of every update (rejected ones too) over consecutive windows, per kind.

        For ``n`` updates of dimension ``m`` in a window the sum of the NIS is chi-square with
        ``n m`` degrees of freedom when the filter is consistent (Bar-Shalom, Li & Kirubarajan
        2001, Section 5.4), so the window's mean NIS lies in ``chi2.ppf((1 -+ band) / 2, n m) /
        n`` with probability `band`.

        Parameters
        ----------
        window : float
            Window length, s, from the alignment time on.
        settle : float
            Windows starting earlier than this (s) after the alignment are not judged.
        band : float
            Two-sided probability of the band.
        far : float
            A judged window whose mean NIS exceeds `far` times the band's upper end is far out
            (overconfident); a mean below the band (pessimistic) is not.

        Returns
        -------
        dict of str to ndarray (k, 8)
            Rows ``(start, end, n, mean NIS, band low, band high, judged, far)``; start and
            end in s from the first IMU sample.
        """
        from scipy.stats import chi2

        t0 = float(self.time[0]) if self.time.size else 0.0
        first = t0 if self.alignment is None else self.alignment.first_time
        out = {}
        for kind, arr in self.nis.items():
            rows = []
            if arr.size:
                idx = np.floor((arr[:, 0] - t0) / window).astype(int)
                for k in np.unique(idx):
                    sel = arr[idx == k]
                    n, m = sel.shape[0], int(sel[0, 2])
                    lo, hi = chi2.ppf([(1 - band) / 2, (1 + band) / 2], n * m) / n
                    mean = float(sel[:, 1].mean())
                    start = t0 + k * window
                    judged = start - t0 >= settle
                    bad = judged and mean > far * hi
                    rows.append((start - first, start + window - first, n, mean, lo, hi,
                                 float(judged), float(bad)))
            out[kind] = np.array(rows).reshape(-1, 8)
        return out

    def health(self, max_rejected: float = MAX_REJECTED_SHARE, **windows: float) -> Health:
        """The health rule: the solution cannot be trusted when a measurement kind has more
        than `max_rejected` of its updates rejected by the gate, or when any window after the
        settling time has its mean NIS far above its chi-square band (:meth:`nis_windows`,
        whose keywords `windows` takes). A mean NIS far above its band says the covariance is
        too small for the errors (an overconfident filter, whose sigmas and gate decisions are
        wrong); a share of rejections that large says the gate has been throwing away the
        information the solution needs."""
        opts = {"window": NIS_WINDOW, "settle": NIS_SETTLE, "band": NIS_BAND, "far": NIS_FAR,
                **windows}
        win = self.nis_windows(**opts)
        shares = {k: self.rejected.get(k, 0) / max(a.shape[0], 1) for k, a in self.nis.items()}
        recov = {k: sum(r.kind == k for r in self.recoveries) for k in self.nis}
        reasons = [f"{k}: {v:.1%} of the updates rejected (more than {max_rejected:.0%})"
                   for k, v in shares.items() if v > max_rejected]
        for k, arr in win.items():
            bad = arr[arr[:, 7] > 0]
            if bad.size:
                reasons.append(f"{k}: mean NIS far above its {opts['band']:.0%} chi-square band "
                               f"in {bad.shape[0]} of {int(arr[:, 6].sum())} windows after "
                               f"convergence (first at {bad[0, 0]:.1f}-{bad[0, 1]:.1f} s: "
                               f"{bad[0, 3]:.3g}, band [{bad[0, 4]:.3g}, {bad[0, 5]:.3g}])")
        rule = (f"untrusted when a measurement kind has more than {max_rejected:.0%} of its "
                f"updates rejected, or the mean NIS of a {opts['window']:g} s window starting "
                f"{opts['settle']:g} s or more after the alignment is above {opts['far']:g} x "
                f"the upper end of its {opts['band']:.0%} chi-square band")
        return Health(not reasons, tuple(reasons), shares, recov, win, self.alignment, rule)

    def summary(self) -> str:
        """Counts of updates, average NIS per kind, rejections, NEES and final sigmas."""
        rows = []
        for kind, arr in self.nis.items():
            acc = arr[:, 3] > 0 if arr.size else np.zeros(0, bool)
            dof = int(arr[0, 2]) if arr.size else 0
            n_rec = sum(r.kind == kind for r in self.recoveries)
            rows.append([kind, int(acc.sum()), self.rejected.get(kind, 0),
                         f"{self.rejected.get(kind, 0) / max(arr.shape[0], 1):.1%}", n_rec,
                         float(arr[acc, 1].mean()) if acc.any() else float("nan"), dof])
        gate = "off" if self.gate is None else (f"{self.gate:g}, recovery after "
                                                f"{self.recover_after} rejections"
                                                if self.recover_after is not None else
                                                f"{self.gate:g}, no recovery")
        lines = [format_table(["measurement", "used", "rejected", "share", "recoveries",
                               "mean NIS", "dof"], rows,
                              title=f"Loosely-coupled filter: {len(self.state_names)} states, "
                                    f"{self.time.size} IMU epochs, {self.epoch_time.size} filter "
                                    f"epochs, gate {gate}")]
        lines += [f"recovery {r.describe()}" for r in self.recoveries[:20]]
        if len(self.recoveries) > 20:
            lines.append(f"... and {len(self.recoveries) - 20} more recoveries")
        lines += [r.describe() for r in self.random_walks]
        lines.append(self.health().describe())
        if self.nees is not None:
            from scipy.stats import chi2

            lo, hi = chi2.ppf([0.025, 0.975], 9)
            lines.append(f"mean NEES (9 nav states) {self.mean_nees:.3g}; single-epoch 95% band "
                         f"[{lo:.3g}, {hi:.3g}], {np.mean((self.nees > lo) & (self.nees < hi)):.0%}"
                         " of epochs inside")
        sd = self.epoch_sd[-1] if self.epoch_sd.size else np.full(len(self.state_names), np.nan)
        lines.append(format_table(["state", "final 1-sigma"], list(zip(self.state_names, sd)),
                                  title="Final standard deviations (m, m/s, rad, sensor units)"))
        return "\n".join(lines)


def _axis_models(gyro: object, accel: object) -> dict[str, Model]:
    out: dict[str, Model] = {}
    for prefix, m in (("gyro", gyro), ("accel", accel)):
        if isinstance(m, Model):
            seq = [m, m, m]
        elif isinstance(m, Mapping):
            try:
                seq = [m[a] for a in "xyz"]
            except KeyError as exc:
                raise SpecError(f"{prefix} models need keys 'x', 'y', 'z': missing {exc}") from None
        elif isinstance(m, Sequence) and len(m) == 3:
            seq = list(m)
        else:
            raise SpecError(f"{prefix}_models must be a Model, three Models or a mapping x/y/z, "
                            f"got {m!r}")
        for a, mod in zip("xyz", seq):
            if not isinstance(mod, Model):
                raise SpecError(f"{prefix}_{a} model must be a stochmod Model, got {mod!r}")
            if mod.freq is None:
                raise SpecError(f"{prefix}_{a} model is not bound to a sampling frequency: "
                                "use model.bind(freq)")
            out[f"{prefix}_{a}"] = mod
    return out


class _Sensors:
    """Sensor-error states: the stacked per-axis augmentation plus optional turn-on biases."""

    def __init__(self, models: dict[str, Model], dt: float, gyro_bias_sd: float,
                 accel_bias_sd: float, lever_arm_sd: Sequence[float] = (0.0, 0.0, 0.0),
                 record: float | None = None) -> None:
        try:
            aug = augment_axes(models, dt)
        except InputError:
            # a discrete-only family (AR) re-samples at whole multiples of its sample period:
            # snap the base step to the nearest multiple (IMU clocks drift by ppm)
            f = min(m.freq for m in models.values())
            dt = max(1, round(dt * f)) / f
            try:
                aug = augment_axes(models, dt)
            except InputError as exc:
                raise InputError(f"the sensor models cannot be discretised at the IMU step: {exc}"
                                 ) from None
        blk = aug.block
        order = [aug.axes.index(a) for a in AXES]
        H = aug.H[order]
        names = list(aug.state_names)
        Phi, Q, P0 = blk.Phi, blk.Q, blk.P0
        cont = blk.continuous if blk.n_states else ContinuousBlock(np.zeros((0, 0)),
                                                                   np.zeros((0, 0)),
                                                                   np.zeros((0, 0)))
        F = None if cont is None else cont.F
        GQG = None if cont is None else cont.G @ cont.Qc @ cont.G.T
        white_var = aug.white_var[order].astype(float)
        self.random_walks: tuple[RandomWalkEquivalent, ...] = ()
        if record is not None:
            F, Phi, Q, P0, self.random_walks = _as_random_walks(
                models, names, record, dt, F, GQG, Phi, Q, P0)
        fast = np.zeros(0, int) if F is None else _sub_sample_states(F, GQG, dt)
        if fast.size:
            # a process decorrelated within one sample is, for the samples (and the fit that
            # produced it), white noise of its stationary variance per sample; integrated in
            # continuous time it would give the angle/velocity random walk 2 sigma^2 Tc instead
            # of sigma^2 h (too little noise for Tc << h): it joins the white feed-through
            white_var = white_var + (H[:, fast] ** 2 * (np.diag(GQG)[fast] / (-2.0 * np.diag(F)[
                fast]))).sum(axis=1)
            keep = np.setdiff1d(np.arange(F.shape[0]), fast)
            sel = np.ix_(keep, keep)
            names = [names[i] for i in keep]
            H, Phi, Q, P0, F, GQG = H[:, keep], Phi[sel], Q[sel], P0[sel], F[sel], GQG[sel]
        extra = [(i, sd) for i, sd in enumerate([gyro_bias_sd] * 3 + [accel_bias_sd] * 3)
                 if sd]
        if extra:
            k = len(extra)
            names += [f"{AXES[i]}.bias" for i, _ in extra]
            Phi = _bdiag(Phi, np.eye(k))
            Q = _bdiag(Q, np.zeros((k, k)))
            P0 = _bdiag(P0, np.diag([sd**2 for _, sd in extra]))
            Hx = np.zeros((6, k))
            for j, (i, _) in enumerate(extra):
                Hx[i, j] = 1.0
            H = np.hstack([H, Hx])
            if F is not None:
                F, GQG = _bdiag(F, np.zeros((k, k))), _bdiag(GQG, np.zeros((k, k)))
        self.lever = None
        if any(lever_arm_sd):
            # the antenna lever arm as three random constants (no effect on the IMU: zero H)
            self.lever = slice(len(names), len(names) + 3)
            names += [f"lever_arm.{a}" for a in "xyz"]
            Phi = _bdiag(Phi, np.eye(3))
            Q = _bdiag(Q, np.zeros((3, 3)))
            P0 = _bdiag(P0, np.diag(np.square(lever_arm_sd)))
            H = np.hstack([H, np.zeros((6, 3))])
            if F is not None:
                F, GQG = _bdiag(F, np.zeros((3, 3))), _bdiag(GQG, np.zeros((3, 3)))
        self.names = tuple(names)
        self.n = len(names)
        self.H = H                      # (6, n): rows gyro_x..accel_z
        self.Phi1, self.Q1, self.P0 = Phi, Q, P0
        self.F, self.GQG = F, GQG       # continuous form or None
        self.dt = dt
        freqs = np.array([models[a].freq for a in AXES])
        self.psd = white_var / freqs  # two-sided PSD N^2 of the white parts
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def steps(self, m: int) -> tuple[np.ndarray, np.ndarray]:
        """Exact transition and noise over `m` base steps."""
        if m not in self._cache:
            self._cache[m] = compose_steps(self.Phi1, self.Q1, m)
        return self._cache[m]


def _as_random_walks(models: dict[str, Model], names: list[str], record: float, dt: float,
                     F: np.ndarray | None, GQG: np.ndarray | None, Phi: np.ndarray,
                     Q: np.ndarray, P0: np.ndarray) -> tuple:
    """Components beyond `record` (s) as the random walks they are over it: their one state gets
    ``F = 0``, ``Phi = 1``, ``Q = q dt`` and ``P0 = q record`` with ``q = 2 sigma^2 / Tc`` (the
    state's continuous driving noise; from a discrete-only block, its one-step ``Q / dt``).
    Returns ``(F, Phi, Q, P0, walks)`` (copies when changed)."""
    from stochmod.fit.equivalence import beyond_record  # only with a record: keeps fit out

    walks, kept = [], []
    for axis, model in models.items():
        for k, tc in beyond_record(model, signal_unit(axis), record):
            label = model.labels[k]
            states = [i for i, n in enumerate(names) if n.startswith(f"{axis}.{label}.")]
            (walks if len(states) == 1 else kept).append((axis, label, tc, states))
    if kept:
        warnings.warn("correlation time beyond the record, but not a one-state component, so "
                      "kept as fitted: " + ", ".join(f"{a}.{lab} (Tc {tc:.3g} s)"
                                                     for a, lab, tc, _ in kept), stacklevel=4)
    if not walks:
        return F, Phi, Q, P0, ()
    F = None if F is None else F.copy()
    Phi, Q, P0 = Phi.copy(), Q.copy(), P0.copy()
    out = []
    for axis, label, tc, (i,) in walks:
        q = float(GQG[i, i]) if F is not None else float(Q[i, i]) / dt
        if F is not None:
            F[i, i] = 0.0
        Phi[i, i], Q[i, i], P0[i, i] = 1.0, q * dt, q * record
        out.append(RandomWalkEquivalent(names[i], tc, q, float(record)))
    warnings.warn("; ".join(r.describe() for r in out), stacklevel=4)
    return F, Phi, Q, P0, tuple(out)


#: A decoupled scalar state whose pole exceeds this many times the IMU rate (correlation time
#: below a tenth of the sample period; successive samples correlate by < 5e-5) is white noise.
SUB_SAMPLE_POLE = 10.0


def _sub_sample_states(F: np.ndarray, GQG: np.ndarray, dt: float) -> np.ndarray:
    """Indices of decoupled scalar Gauss-Markov-like states (``dx = -beta x dt + dw``, no other
    state in their row or column of F and GQG) with ``beta dt >= SUB_SAMPLE_POLE``."""
    d = np.diag(F)
    off_f = np.abs(F - np.diag(d))
    off_q = np.abs(GQG - np.diag(np.diag(GQG)))
    alone = (off_f.sum(0) + off_f.sum(1) + off_q.sum(0) + off_q.sum(1)) == 0
    return np.flatnonzero(alone & (-d * dt >= SUB_SAMPLE_POLE))


@compiled(fastmath=frozenset())
def _fill_error_dynamics(F: np.ndarray, lat: float, hgt: float, v: Sequence[float],
                         f_n: Sequence[float]) -> None:
    """Write the navigation block of the psi-angle model's F (module notes) into ``F[:9, :9]``
    at latitude `lat` (rad), height `hgt` (m), NED velocity `v` (m/s) and specific force `f_n`
    (NED, m/s^2), both tuples; ``F[0:3, 3:6]`` (the identity) is left as it is."""
    vn, ve = v[0], v[1]
    sl, cl = math.sin(lat), math.cos(lat)
    w = 1.0 - _E2 * sl * sl
    re = _A / math.sqrt(w)
    rn = re * (1.0 - _E2) / w
    d = 1.0 + hgt / math.sqrt(rn * re)
    g = _G0 * (1.0 + _G1 * sl * sl - _G2 * 4.0 * sl * sl * cl * cl) / (d * d)  # eq. 16
    r0 = math.sqrt(rn * re) + hgt
    om = _OM
    wen0, wen1, wen2 = ve / (re + hgt), -vn / (rn + hgt), -ve * sl / cl / (re + hgt)  # eq. 10
    win0, win1, win2 = om * cl + wen0, wen1, -om * sl + wen2  # eq. 9 + 10
    F[3:6, 0:3] = 0.0
    F[3, 0], F[4, 1], F[5, 2] = -g / r0, -g / r0, 2 * g / r0
    # -[cor x], [f_n x], -[w_in x] with cor = w_in + w_ie
    _skew_into(F, 3, 3, -(win0 + om * cl), -win1, -(win2 - om * sl))
    _skew_into(F, 3, 6, f_n[0], f_n[1], f_n[2])
    _skew_into(F, 6, 6, -win0, -win1, -win2)


@compiled(fastmath=frozenset())
def _skew_into(F: np.ndarray, r: int, c: int, x: float, y: float, z: float) -> None:
    """``F[r:r+3, c:c+3] = [(x, y, z) x]``."""
    F[r, c], F[r, c + 1], F[r, c + 2] = 0.0, -z, y
    F[r + 1, c], F[r + 1, c + 1], F[r + 1, c + 2] = z, 0.0, -x
    F[r + 2, c], F[r + 2, c + 1], F[r + 2, c + 2] = -y, x, 0.0


@compiled(fastmath=frozenset())
def _fill_noise_coupling(F: np.ndarray, W: np.ndarray, C: np.ndarray, psd: np.ndarray,
                         H: np.ndarray) -> None:
    """The attitude-dependent blocks of a covariance step: the white noise of the sensors in
    NED, ``W[3:6, 3:6] = C diag(psd_a) C'`` and ``W[6:9, 6:9] = C diag(psd_g) C'``, and the
    coupling of the sensor states, ``F[3:6, 9:] = -C H_a``, ``F[6:9, 9:] = C H_g``."""
    ns = H.shape[1]
    for i in range(3):
        for j in range(3):
            wa, wg = 0.0, 0.0
            for k in range(3):
                wa += C[i, k] * psd[3 + k] * C[j, k]
                wg += C[i, k] * psd[k] * C[j, k]
            W[3 + i, 3 + j], W[6 + i, 6 + j] = wa, wg
        for j in range(ns):
            fa, fg = 0.0, 0.0
            for k in range(3):
                fa += C[i, k] * H[3 + k, j]
                fg += C[i, k] * H[k, j]
            F[3 + i, 9 + j], F[6 + i, 9 + j] = -fa, fg


@compiled(fastmath=frozenset())
def _linearise(F: np.ndarray, W: np.ndarray, start: np.ndarray, x: np.ndarray, f0: float,
               f1: float, f2: float, psd: np.ndarray, H: np.ndarray) -> None:
    """F and W of a covariance step at its middle: :func:`midpoint_pva` of `start` (``lat, h,
    v, q``) and the mechanisation's state vector `x`, then :func:`_fill_error_dynamics` with
    the mean specific force ``(f0, f1, f2)`` and :func:`_fill_noise_coupling`."""
    dot = 0.0
    for i in range(4):
        dot += start[5 + i] * x[6 + i]
    sign = 1.0 if dot >= 0.0 else -1.0
    q0, q1 = start[5] + sign * x[6], start[6] + sign * x[7]
    q2, q3 = start[7] + sign * x[8], start[8] + sign * x[9]
    nrm = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0, q1, q2, q3 = q0 * nrm, q1 * nrm, q2 * nrm, q3 * nrm
    v = (0.5 * (start[2] + x[3]), 0.5 * (start[3] + x[4]), 0.5 * (start[4] + x[5]))
    _fill_error_dynamics(F, 0.5 * (start[0] + x[0]), 0.5 * (start[1] + x[2]), v, (f0, f1, f2))
    C = np.empty((3, 3))  # Gonzalez eq. 14, as frames.quat_to_dcm
    C[0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    C[0, 1], C[0, 2] = 2.0 * (q1 * q2 - q0 * q3), 2.0 * (q1 * q3 + q0 * q2)
    C[1, 0], C[1, 2] = 2.0 * (q1 * q2 + q0 * q3), 2.0 * (q2 * q3 - q0 * q1)
    C[1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    C[2, 0], C[2, 1] = 2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1)
    C[2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    _fill_noise_coupling(F, W, C, psd, H)


@compiled(fastmath=frozenset())
def _left_sparse(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    """``out = A @ B`` summed over the nonzero entries of `A` only (the covariance step's
    matrices are mostly zeros: the F of the 21-state filter has 60 of 441)."""
    for i in range(A.shape[0]):
        out[i, :] = 0.0
        for k in range(A.shape[1]):
            a = A[i, k]
            if a != 0.0:
                for j in range(B.shape[1]):
                    out[i, j] += a * B[k, j]


@compiled(fastmath=frozenset())
def _scaled_series(F: np.ndarray, W: np.ndarray, dt: float, Phi: np.ndarray,
                   Q: np.ndarray) -> bool:
    """:func:`stochmod.core.statespace.discretise` (its sub-step, series and squarings, term
    for term) into `Phi` and `Q`, its products over the nonzero entries of their left
    factor; False when `F` or `W` holds a non-finite value."""
    n = F.shape[0]
    norm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(F[i, j])
        norm = max(norm, col)
    norm *= dt
    if not (math.isfinite(norm) and np.isfinite(W).all()):
        return False
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    h = math.ldexp(dt, -s)
    a = 2.0 * math.ldexp(norm, -s)
    K, bound = 1, a / 2.0
    while bound > 1e-17:
        K += 1
        bound *= a / (K + 1)
    A = F * h
    X = np.empty((n, 2 * n))  # [A^k | U_(k-1)], both halves with the coefficient 1 / k!
    X[:, :n] = A
    X[:, n:] = W * h
    acc = X.copy()
    Y = np.empty((n, 2 * n))
    c = 1.0
    for k in range(2, K + 1):
        _left_sparse(A, X, Y)
        X, Y = Y, X
        for i in range(n):
            for j in range(i, n):
                u = X[i, n + j] + X[j, n + i]
                X[i, n + j] = u
                X[j, n + i] = u
        c /= k
        acc += X * c
    E = acc[:, :n].copy()  # Phi - I
    Qs = acc[:, n:].copy()
    EQ, EQE, EE = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    for _ in range(s):
        _left_sparse(E, Qs, EQ)
        _left_sparse(E, EQ.T, EQE)  # E (E Q)' = (E Q E')'
        _left_sparse(E, E, EE)
        Qs = 2.0 * Qs + EQ + EQ.T + EQE.T
        E = 2.0 * E + EE
    Phi[:, :] = E
    for i in range(n):
        Phi[i, i] += 1.0
    Q[:, :] = 0.5 * (Qs + Qs.T)
    return True


def discretise(F: np.ndarray, W: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The covariance step's ``Phi = expm(F dt)`` and ``Q = int_0^dt expm(F s) W expm(F s)'
    ds``: :func:`stochmod.core.statespace.discretise` compiled for the sparse F of the
    filter (equal to it to rounding)."""
    n = F.shape[0]
    Phi, Q = np.empty((n, n)), np.empty((n, n))
    if not _scaled_series(F, W, float(dt), Phi, Q):
        raise InputError(_NON_FINITE)
    return Phi, Q


_NON_FINITE = ("the continuous model to discretise holds a non-finite value (a model parameter "
               "is infinite or NaN)")
#: The filter's own :func:`discretise` (a caller may replace the module's name by a wrapper:
#: the covariance step then calls that instead of its compiled whole).
_OWN_DISCRETISE = discretise


@compiled(fastmath=frozenset())
def _covariance_step(F: np.ndarray, W: np.ndarray, start: np.ndarray, x: np.ndarray, f0: float,
                     f1: float, f2: float, psd: np.ndarray, H: np.ndarray, dt: float,
                     P: np.ndarray, Phi: np.ndarray, Q: np.ndarray) -> tuple:
    """One covariance step in one call: :func:`_linearise`, :func:`discretise` into `Phi` and
    `Q`, and :func:`_predict` from `P`. Returns ``(predicted P, False when F or W holds a
    non-finite value)``."""
    _linearise(F, W, start, x, f0, f1, f2, psd, H)
    if not _scaled_series(F, W, dt, Phi, Q):
        return P, False
    return _predict(Phi, P, Q), True


@compiled(fastmath=frozenset())
def _predict(Phi: np.ndarray, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``Phi P Phi' + Q``, symmetrised (Gonzalez Alg. 1 lines 7-8)."""
    T = np.empty(P.shape)
    U = np.empty(P.shape)
    _left_sparse(Phi, P, T)
    _left_sparse(Phi, T.T, U)  # U' = T Phi'
    out = U.T + Q
    return 0.5 * (out + out.T)


def error_dynamics(lat: float, height: float, vel_ned: ArrayLike, C_nb: ArrayLike,
                   f_n: ArrayLike) -> np.ndarray:
    """The filter's continuous error dynamics ``F`` (15 x 15) at one navigation state: the 9
    navigation error states (``dr, dv, psi``; module notes, Gonzalez 2015 eq. 20) followed by
    constant gyro and accelerometer errors along the body axes (rad/s, m/s^2), which enter as
    ``d(psi)/dt += C_nb b_g`` and ``d(dv)/dt -= C_nb b_a``.

    Parameters
    ----------
    lat : float
        Latitude, rad.
    height : float
        Ellipsoidal height, m.
    vel_ned : array_like (3,)
        NED velocity, m/s.
    C_nb : array_like (3, 3)
        Body-to-NED rotation.
    f_n : array_like (3,)
        Specific force in NED, m/s^2.

    Returns
    -------
    ndarray (15, 15)
        ``F`` such that ``de/dt = F e`` (the white-noise inputs aside).
    """
    F = np.zeros((15, 15))
    F[0:3, 3:6] = np.eye(3)
    _fill_error_dynamics(F, float(lat), float(height), tuple(np.asarray(vel_ned, float).tolist()),
                         tuple(np.asarray(f_n, float).tolist()))
    C = np.asarray(C_nb, dtype=float)
    F[3:6, 12:15] = -C
    F[6:9, 9:12] = C
    return F


def midpoint_pva(start: tuple, end: tuple) -> tuple:
    """The navigation state in the middle of a covariance step, from the states at its ends.

    The filter linearises the covariance step there: the midpoint rule for a time-varying
    ``F`` over the step, whose local error is third order in the step against the end point's
    second order (module notes).

    Parameters
    ----------
    start, end : tuple
        ``(lat rad, height m, (vn, ve, vd) m/s, (q0, q1, q2, q3))`` at the step's two ends
        (scalar-first unit quaternion of ``C_nb``).

    Returns
    -------
    tuple
        The same fields: their mean, with the quaternion normalised (the mean of two unit
        quaternions of the same hemisphere lies on the geodesic between them); second-order
        accurate for the state at the middle time.
    """
    lat0, h0, v0, q0 = start
    lat1, h1, v1, q1 = end
    sign = 1.0 if sum(a * b for a, b in zip(q0, q1)) >= 0.0 else -1.0
    q = [a + sign * b for a, b in zip(q0, q1)]
    nrm = 1.0 / math.sqrt(sum(a * a for a in q))
    return (0.5 * (lat0 + lat1), 0.5 * (h0 + h1),
            tuple(0.5 * (a + b) for a, b in zip(v0, v1)), tuple(a * nrm for a in q))


def _bdiag(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n, k = a.shape[0], b.shape[0]
    out = np.zeros((n + k, n + k))
    out[:n, :n], out[n:, n:] = a, b
    return out


@compiled(fastmath=frozenset())  # no flag: the plain loop's bits
def _advance(x: np.ndarray, t: np.ndarray, h: np.ndarray, dth: np.ndarray, dv: np.ndarray,
             con: np.ndarray, scu: np.ndarray, corr: np.ndarray, k: int, t_event: float,
             dtf: float, last: int, rows: np.ndarray, prev: np.ndarray) -> tuple:
    """The mechanisation from IMU interval `k` on to the end of the covariance step: after the
    interval that reaches `t_event` (within 1 ns), after `dtf` seconds or at the `last`
    interval, whichever comes first. The increments are corrected by the nominal sensor errors
    `corr` (gyro x/y/z, accel x/y/z, per second); ``rows[k + 1]`` takes the state after
    interval ``k``, `prev` position and velocity before the last one. Returns ``(k of the last
    interval, seconds advanced, whether t_event was reached)``."""
    cg0, cg1, cg2, ca0, ca1, ca2 = corr[0], corr[1], corr[2], corr[3], corr[4], corr[5]
    elapsed = 0.0
    while True:
        hk = h[k]
        due = t_event <= t[k + 1] + 1e-9
        if due:
            prev[:] = x[:6]
        mech_step(x, hk, dth[k, 0] - cg0 * hk, dth[k, 1] - cg1 * hk, dth[k, 2] - cg2 * hk,
                  dv[k, 0] - ca0 * hk, dv[k, 1] - ca1 * hk, dv[k, 2] - ca2 * hk, con[k, 0],
                  con[k, 1], con[k, 2], scu[k, 0], scu[k, 1], scu[k, 2], math.nan)
        elapsed += hk
        rows[k + 1] = x[:10]
        if due or elapsed >= dtf - 1e-9 or k == last:
            return k, elapsed, due
        k += 1


class LooselyCoupledFilter:
    """Closed-loop error-state EKF for INS/GNSS (and magnetometer, zero-velocity) integration.

    Parameters
    ----------
    gyro_models, accel_models : Model, three Models, or mapping ``x/y/z -> Model``
        Per-axis stochastic error models bound to their sampling frequency (rad/s, m/s^2).
    dt_filter : float
        Covariance propagation step, s (measurements add epochs at their time stamps).
    lever_arm : array_like (3,)
        IMU to GNSS antenna in the body frame, m.
    gyro_bias_sd, accel_bias_sd : float
        Turn-on bias 1-sigma (rad/s, m/s^2): adds a random-constant state per axis; 0 for none.
    gate : float or None
        Probability of the chi-square innovation gate (e.g. 0.9999); None: no gating.
    recover_after : int or None
        Consecutive rejections of one measurement kind after which the next update of that
        kind that fails the gate is applied after inflating the error covariance (module notes,
        "Gating and recovery"; default 5). None: no recovery (a run of rejections can last to
        the end of the record).
    gnss_sd : float or (3,)
        Default N, E, D position 1-sigma (m) when the GNSS record has none.
    gnss_vel_sd : float or (3,)
        Default velocity 1-sigma (m/s).
    lever_arm_sd : float or (3,)
        1-sigma (m, body x/y/z) of the prior `lever_arm`: nonzero adds the lever arm as three
        constant states estimated from the GNSS updates (``NavResult.lever_arm``); 0: the lever
        arm is taken as exact. An antenna offset that the filter ignores is read as attitude and
        accelerometer-bias errors at every turn (see docs/navigation.md, "Real drive").
    record : float, optional
        Length (s) of the record the models were fitted on. A correlated component whose
        correlation time exceeds it (:func:`stochmod.fit.equivalence.equivalent_term`) is
        augmented as the random walk it is equivalent to over the record, ``q = 2 sigma^2 /
        Tc``, with initial variance ``q * record`` instead of its unidentified stationary
        ``sigma^2``; a warning and ``NavResult.random_walks`` report each one. None (default):
        the models are taken as they are.
    error_model : {"psi", "modified-phi"}
        The error formulation, which decides how an estimate is fed back and where the
        covariance is held across the feedback (module notes). ``"psi"`` (default): the
        psi-angle model of Gonzalez (2015) and Titterton & Weston; the covariance of
        ``(dr, dv, psi)`` is held. ``"modified-phi"``: Scherzinger & Reid's modified phi-angle
        model, the one pyins uses; the covariance of ``(dr, dv - v_hat x psi, psi)`` is held and
        the velocity is corrected by ``v <- Exp(psi_hat) (v_hat - dv'_hat)``. Choose it to
        reproduce a pyins filter (on the n380 drive, docs/navigation_real_drive.md, its outage
        errors are within 0.3 % of pyins'). Both are honest (NEES in band) and neither is
        more accurate on emulated drives where the truth is known; they differ at second
        order, most when heading is weakly observable (long standstills).
    """

    def __init__(self, gyro_models: object, accel_models: object, *, dt_filter: float = 0.1,
                 lever_arm: ArrayLike = (0.0, 0.0, 0.0), gyro_bias_sd: float = 0.0,
                 accel_bias_sd: float = 0.0, gate: float | None = 0.9999,
                 gnss_sd: object = (3.0, 3.0, 5.0), gnss_vel_sd: object = 0.2,
                 lever_arm_sd: object = 0.0, record: float | None = None,
                 error_model: str = "psi", recover_after: int | None = 5) -> None:
        self.models = _axis_models(gyro_models, accel_models)
        if error_model not in ERROR_MODELS:
            raise InputError(f"error_model must be one of {ERROR_MODELS}, got {error_model!r}")
        self.error_model = error_model
        if record is not None and not (record > 0 and math.isfinite(record)):
            raise InputError(f"record must be a positive number of seconds, got {record!r}")
        self.record = None if record is None else float(record)
        if not (dt_filter > 0 and math.isfinite(dt_filter)):
            raise InputError(f"dt_filter must be a positive number of seconds, got {dt_filter!r}")
        self.dt_filter = float(dt_filter)
        self.lever_arm = np.asarray(lever_arm, dtype=float).reshape(-1)
        if self.lever_arm.shape != (3,) or not np.all(np.isfinite(self.lever_arm)):
            raise InputError(f"lever_arm must be three finite numbers, got {lever_arm!r}")
        for name, v in (("gyro_bias_sd", gyro_bias_sd), ("accel_bias_sd", accel_bias_sd)):
            if not (v >= 0 and math.isfinite(v)):
                raise InputError(f"{name} must be >= 0, got {v!r}")
        self.gyro_bias_sd, self.accel_bias_sd = float(gyro_bias_sd), float(accel_bias_sd)
        if gate is not None and not 0.0 < gate < 1.0:
            raise InputError(f"gate must be a probability in (0, 1) or None, got {gate!r}")
        self.gate = gate
        if recover_after is not None and not (isinstance(recover_after, (int, np.integer))
                                              and recover_after >= 1):
            raise InputError(f"recover_after must be a whole number >= 1 or None, got "
                             f"{recover_after!r}")
        self.recover_after = None if recover_after is None else int(recover_after)
        self.gnss_sd = np.broadcast_to(np.asarray(gnss_sd, dtype=float), (3,)).copy()
        self.gnss_vel_sd = np.broadcast_to(np.asarray(gnss_vel_sd, dtype=float), (3,)).copy()
        try:
            self.lever_arm_sd = np.broadcast_to(np.asarray(lever_arm_sd, dtype=float), (3,)).copy()
        except ValueError:
            raise InputError(f"lever_arm_sd must be one or three numbers, got {lever_arm_sd!r}"
                             ) from None
        if not np.all(np.isfinite(self.lever_arm_sd)) or np.any(self.lever_arm_sd < 0):
            raise InputError(f"lever_arm_sd must be >= 0 and finite, got {lever_arm_sd!r}")

    # ------------------------------------------------------------------ set-up
    def state_names(self, dt_imu: float) -> tuple[str, ...]:
        """All state names for IMU step `dt_imu`."""
        s = _Sensors(self.models, dt_imu, self.gyro_bias_sd, self.accel_bias_sd, self.lever_arm_sd,
                     self.record)
        return NAV_STATES + s.names

    def _events(self, gnss: GnssData | None, heading: object, zero_velocity: object,
                outages: Sequence[tuple[float, float]], t_first: float, t_start: float
                ) -> list[tuple[float, int, Measurement]]:
        ev: list[tuple[float, int, Measurement]] = []
        arm = self.lever_arm
        if gnss is not None:
            if not isinstance(gnss, GnssData):
                raise InputError(f"gnss must be a GnssData, got {type(gnss).__name__}")
            keep = np.ones(gnss.n, bool)
            for o in outages:
                start, dur = o
                if not dur > 0:
                    raise InputError(f"outage duration must be positive, got {o!r}")
                keep &= ~((gnss.time >= t_first + start) & (gnss.time < t_first + start + dur))
            g = gnss.select(keep)
            sd = g.sd if g.sd is not None else np.tile(self.gnss_sd, (g.n, 1))
            for i in range(g.n):
                ev.append((float(g.time[i]), 0, GnssPosition(float(g.lat[i]), float(g.lon[i]),
                                                             float(g.height[i]), sd[i], arm)))
                if g.vel_ned is not None:
                    sv = g.sd_vel[i] if g.sd_vel is not None else self.gnss_vel_sd
                    ev.append((float(g.time[i]), 1, GnssVelocity(g.vel_ned[i], sv, arm)))
        if heading is not None:
            t, hdg, sd = heading
            t = check_time(t, "heading time")
            hdg = np.asarray(hdg, dtype=float)
            if hdg.shape != t.shape:
                raise InputError("heading values must match their time stamps")
            ev += [(float(a), 2, MagneticHeading(float(b), float(sd))) for a, b in zip(t, hdg)]
        if zero_velocity is not None:
            t, sd = zero_velocity
            ev += [(float(a), 3, ZeroVelocity(float(sd))) for a in check_time(t, "zupt time")]
        ev = [e for e in ev if e[0] > t_start]
        ev.sort(key=lambda e: (e[0], e[1]))
        return ev

    # ------------------------------------------------------------------ run
    def run(self, imu_time: ArrayLike, gyro: ArrayLike, accel: ArrayLike, *, kind: str = "rate",
            gnss: GnssData | None = None, init: InitialState | None = None,
            outages: Sequence[tuple[float, float]] = (), truth: Trajectory | None = None,
            heading: tuple[ArrayLike, ArrayLike, float] | None = None,
            zero_velocity: tuple[ArrayLike, float] | None = None,
            init_sd: Sequence[float | None] | None = None, smooth: bool = False) -> NavResult:
        """Run the filter over an IMU record.

        Parameters
        ----------
        imu_time, gyro, accel, kind
            As :func:`stochmod.nav.strapdown`.
        gnss : GnssData, optional
            Position (and velocity when present) fixes.
        init : InitialState, optional
            Start state; None: in-motion alignment from GNSS (:func:`~stochmod.nav.alignment.
            align_from_gnss`).
        outages : sequence of (start, duration)
            Seconds from the first IMU time during which GNSS is withheld.
        truth : Trajectory, optional
            Reference for the NEES.
        heading : (time, heading_deg, sd_deg), optional
            Magnetic heading measurements (declination removed).
        zero_velocity : (time, sd), optional
            Time stamps of zero-velocity updates and their 1-sigma, m/s.
        init_sd : (position, velocity, level, heading), optional
            Initial 1-sigma replacing those of `init` or of the alignment: position N/E/D (m),
            velocity (m/s), roll and pitch (deg), heading (deg); None entries keep theirs.
        smooth : bool
            Also run the fixed-interval (Rauch-Tung-Striebel) smoother over the record
            (:mod:`stochmod.nav.smoother`): ``NavResult.smoothed`` is the smoothed solution.
        """
        t_all, g_all, a_all = check_imu(imu_time, gyro, accel)
        if init is None:
            if gnss is None:
                raise InputError("without init the filter aligns from GNSS: give gnss")
            init = align_from_gnss(t_all, g_all, a_all, gnss, kind=kind)
            source = "gnss"
        else:
            source = "given"
        if not isinstance(init, InitialState):
            raise InputError(f"init must be an InitialState, got {type(init).__name__}")
        if init_sd is not None:
            init = _with_sd(init, init_sd)
        t_start = t_all[0] if init.time is None else float(init.time)
        i0 = int(np.searchsorted(t_all, t_start - 1e-9))
        if i0 >= t_all.size - 1:
            raise InputError(f"init time {t_start} leaves fewer than two IMU samples")
        # keep one sample before the start for the increments' coning terms
        j0 = max(i0 - 1, 0)
        t, g, a = t_all[j0:], g_all[j0:], a_all[j0:]
        h, dth, dv, con, scu = imu_increments(t, g, a, kind)
        if i0 > j0:  # drop the interval that ends at the start epoch
            t, h, dth, dv, con, scu = t[1:], h[1:], dth[1:], dv[1:], con[1:], scu[1:]
        dt_imu = float(np.median(h))
        sens = _Sensors(self.models, dt_imu, self.gyro_bias_sd, self.accel_bias_sd,
                        self.lever_arm_sd, self.record)
        events = self._events(gnss, heading, zero_velocity, outages, float(t_all[0]), t[0])
        sd = np.sqrt(np.diag(init.covariance()))
        alignment = Alignment(float(t[0]), float(t_all[0]), float(init.lat), float(init.lon),
                              float(init.height), float(np.linalg.norm(init.vel_ned)), source,
                              tuple(np.r_[sd[:6], np.degrees(sd[6:])].tolist()))
        run = _Run(self, sens, init, t, h, dth, dv, con, scu, events, truth, smooth)
        res = run.execute()
        sm = None if res.smoothed is None else attrs.evolve(res.smoothed, alignment=alignment)
        return attrs.evolve(res, alignment=alignment, smoothed=sm)


def _with_sd(init: InitialState, init_sd: Sequence[float | None]) -> InitialState:
    """`init` with the 1-sigma of ``init_sd = (position m, velocity m/s, level deg, heading
    deg)`` where they are not None."""
    if len(init_sd) != 4:
        raise InputError(f"init_sd takes four values (position, velocity, level, heading), got "
                         f"{init_sd!r}")
    for v in init_sd:
        if v is not None and not (math.isfinite(v) and v > 0):
            raise InputError(f"initial sigmas must be positive and finite, got {init_sd!r}")
    pos, vel, lev, hdg = init_sd
    att = np.broadcast_to(np.asarray(init.sd_attitude, dtype=float), (3,)).copy()
    if lev is not None:
        att[:2] = lev
    if hdg is not None:
        att[2] = hdg
    return attrs.evolve(init, sd_position=init.sd_position if pos is None else float(pos),
                        sd_velocity=init.sd_velocity if vel is None else float(vel),
                        sd_attitude=tuple(att.tolist()))


class _Run:
    """One pass of the filter (keeps the loop state out of the public class)."""

    def __init__(self, flt: LooselyCoupledFilter, sens: _Sensors, init: InitialState,
                 t: np.ndarray, h: np.ndarray, dth: np.ndarray, dv: np.ndarray, con: np.ndarray,
                 scu: np.ndarray, events: list, truth: Trajectory | None,
                 smooth: bool = False) -> None:
        self.flt, self.sens = flt, sens
        self.t, self.h, self.dth, self.dv, self.con, self.scu = t, h, dth, dv, con, scu
        self.events, self.truth = events, truth
        self.n = 9 + sens.n
        self._eye = np.eye(self.n)
        self._F = np.zeros((self.n, self.n))
        self._F[0:3, 3:6] = np.eye(3)
        self._W = np.zeros((self.n, self.n))
        if sens.n and sens.F is not None:
            self._F[9:, 9:] = sens.F
            self._W[9:, 9:] = sens.GQG
        self.P = _bdiag(init.covariance(), sens.P0)
        self.s = np.zeros(sens.n)
        if sens.lever is not None:  # nominal value of the lever-arm states: the prior
            self.s[sens.lever] = flt.lever_arm
        self.mech = Mechanisation(init.nav_state())
        self.corr = np.zeros(6)
        self.thresholds = {}
        self.innov: dict[str, list] = {}
        self.nis: dict[str, list] = {}
        self.rejected: dict[str, int] = {}
        self.streak: dict[str, int] = {}
        self.recoveries: list[Recovery] = []
        self.store = None
        self.n_epochs = 0
        if smooth:  # one node per filter step and per measurement epoch, at most
            steps = math.ceil((t[-1] - t[0]) / flt.dt_filter) + len({e[0] for e in events}) + 2
            self.store = SmootherStore(self.n, min(steps, t.size + 1))

    # -------------------------------------------------------------- covariance propagation
    def _propagate(self, dt: float, m: int, f_n: tuple[float, float, float]) -> None:
        sens = self.sens
        lat, hgt, v, q = self._start
        F, W, n, ns = self._F, self._W, self.n, sens.n
        start = np.array((lat, hgt, *v, *q))
        exact = sens.F is not None or not ns  # Van Loan over the whole F
        if exact and discretise is _OWN_DISCRETISE:
            Phi, Q = np.empty((n, n)), np.empty((n, n))
            P, finite = _covariance_step(F, W, start, self.mech.x, f_n[0], f_n[1], f_n[2],
                                         sens.psd, sens.H, dt, self.P, Phi, Q)
            if not finite:
                raise InputError(_NON_FINITE)
        else:
            Phi, P = self._step_parts(start, dt, m, f_n)
        if self.store is not None:
            self.store.step(self.P, Phi, P, self.n_epochs)
        self.P = P
        if ns:  # nominal sensor errors follow their mean dynamics
            self.s = Phi[9:, 9:] @ self.s
            self.corr = sens.H @ self.s
        if not math.isfinite(float(self.P.sum())):
            raise EstimationError(f"filter covariance became non-finite at t = {self.t_now:.6g} s")

    def _step_parts(self, start: np.ndarray, dt: float, m: int, f_n: tuple) -> tuple:
        """The covariance step by its parts (a discrete-only sensor block, or a replaced
        :func:`discretise`): the transition and the predicted P."""
        sens = self.sens
        F, W, ns = self._F, self._W, sens.n
        _linearise(F, W, start, self.mech.x, f_n[0], f_n[1], f_n[2], sens.psd, sens.H)
        if sens.F is not None or not ns:
            Phi, Q = discretise(F, W, dt)
        else:
            Fnn = F[:9, :9]
            Fns = F[:9, 9:]
            Pnn, Qnn = discretise(Fnn, W[:9, :9], dt)
            Pss, Qss = sens.steps(m)
            Phi = _bdiag(Pnn, Pss)
            Phi[:9, 9:] = 0.5 * dt * (Pnn @ Fns + Fns @ Pss)
            Q = _bdiag(Qnn, Qss)
        return Phi, _predict(Phi, self.P, Q)

    # -------------------------------------------------------------- updates
    def _snapshot(self, tm: float, prev: tuple, w_nb: np.ndarray) -> Snapshot:
        mech = self.mech
        t1 = self.t_now
        t0 = self.t_prev
        lam = 1.0 if t1 <= t0 else min(max((tm - t0) / (t1 - t0), 0.0), 1.0)
        lat = prev[0] + lam * (mech.lat - prev[0])
        lon = prev[1] + lam * (mech.lon - prev[1])
        hgt = prev[2] + lam * (mech.h - prev[2])
        v = np.array(prev[3]) + lam * (np.array(mech.v) - np.array(prev[3]))
        C = frames.quat_to_dcm(mech.q)
        if tm < t1:
            # the attitude at the fix's time too: dC_nb/dt = C_nb [w_nb x] over the interval,
            # so C_nb(t_m) = C_nb(t_k) Exp(-(t_k - t_m) w_nb) (the lever-arm terms C l and
            # C (w x l) otherwise take the attitude up to one IMU step late)
            C = C @ frames.rotvec_to_dcm(-(t1 - max(tm, t0)) * w_nb)
        arm = None if self.sens.lever is None else self.s[self.sens.lever].copy()
        return Snapshot(lat, lon, hgt, v, C, w_nb, np.array(mech.w_in), arm)

    def _update(self, meas: Measurement, snap: Snapshot) -> None:
        y, Hn, R = meas.evaluate(snap)
        m = y.size
        H = np.zeros((m, self.n))
        H[:, :9] = Hn
        lag = self.t_now - self.t_meas
        navigation_only = True  # H reaches only the 9 navigation states
        if self.sens.lever is not None:
            lever = slice(9 + self.sens.lever.start, 9 + self.sens.lever.stop)
            H[:, lever] = meas.lever_arm_jacobian(snap)
            navigation_only = False
        J = meas.rate_jacobian(snap) if self.sens.n else None
        if J is not None:
            # the body rate is the gyro output less the estimated gyro error sens.H[:3] s, so
            # its error is -sens.H[:3] times the sensor states' error
            H[:, 9:] -= J @ self.sens.H[:3]
            navigation_only = False
        if lag > 0.0:
            # the fix measures the error at its own time t_m, e(t_m) = (I - lag F) e(t_k) to
            # first order in lag = t_k - t_m < one IMU step (F of the step just propagated)
            H -= lag * (H @ self._F)
            navigation_only = False
        if navigation_only:
            PHt = self.P[:, :9] @ Hn.T
            S = Hn @ PHt[:9] + R
        else:
            PHt = self.P @ H.T
            S = H @ PHt + R
        try:
            Si = np.linalg.inv(S)
        except np.linalg.LinAlgError:
            raise EstimationError(f"singular innovation covariance for {meas.kind} at "
                                  f"t = {self.t_now:.6g} s") from None
        nis = float(y @ Si @ y)
        kind = meas.kind
        gate = self.flt.gate
        flag = 1.0  # accepted
        if gate is not None:
            thr = self.thresholds.get(m)
            if thr is None:
                from scipy.stats import chi2

                thr = self.thresholds[m] = float(chi2.ppf(gate, m))
            streak = self.streak.get(kind, 0)
            if nis <= thr:
                self.streak[kind] = 0
            elif self.flt.recover_after is None or streak < self.flt.recover_after:
                self.streak[kind] = streak + 1
                flag = 0.0
            else:  # the recovery (module notes, "Gating and recovery")
                lam = matching_factor(y, S - R, R, float(m))
                self._inflate(lam)
                PHt, S = PHt * lam, (S - R) * lam + R
                Si = np.linalg.inv(S)
                self.streak[kind] = 0
                self.recoveries.append(Recovery(self.t_meas, kind, nis, m, lam))
                flag = 2.0
        self.innov.setdefault(kind, []).append((self.t_meas, *y))
        self.nis.setdefault(kind, []).append((self.t_meas, nis, m, flag))
        if not flag:
            self.rejected[kind] = self.rejected.get(kind, 0) + 1
            return
        K = PHt @ Si
        IKH = self._eye - K @ H
        P = IKH @ self.P @ IKH.T + K @ R @ K.T  # Joseph form (Alg. 1 lines 4-6, 8)
        self.P = 0.5 * (P + P.T)
        dx = K @ y  # Alg. 1 line 5
        self._feedback(dx)

    def _inflate(self, lam: float) -> None:
        """Scale the whole error covariance by `lam` >= 1 (the recovery)."""
        if self.store is not None:
            self.store.inflate(self.P, lam, self.n_epochs)
        self.P = self.P * lam

    def _feedback(self, dx: np.ndarray) -> None:
        """Correct the mechanisation and the nominal sensor errors (Alg. 2 lines 28-30)."""
        mech = self.mech
        if self.store is not None:
            self.store.correct(dx)
        sl = math.sin(mech.lat)
        w = 1.0 - earth.E2 * sl * sl
        re = earth.A / math.sqrt(w)
        rn = re * (1.0 - earth.E2) / w
        d = dx[:9].tolist()
        mech.lat -= d[0] / (rn + mech.h)
        mech.lon -= d[1] / ((re + mech.h) * math.cos(mech.lat))
        mech.h += d[2]
        model = self.flt.error_model
        vn, ve, vd = mech.v
        if model == "modified-phi":
            # the exact injection of the modified velocity error dv' = v_hat - R(psi)' v:
            # v <- R(psi_hat) (v_hat - dv'_hat), dv'_hat = dv_hat - v_hat x psi_hat
            # (pyins' InsErrorModel.correct_pva); then hold P in (dv', psi) across the change
            v = np.array(mech.v)
            rot = frames.rotvec_to_dcm(dx[6:9])
            new = rot @ (v - dx[3:6] + np.cross(v, dx[6:9]))
            mech.v = (float(new[0]), float(new[1]), float(new[2]))
            self._reset(slice(3, 6), slice(3, 9), np.hstack([self._eye[:3, :3],
                                                             frames.skew(new - v)]))
            if self.store is not None:
                self.store.reset(new - v)
        else:
            mech.v = (vn - d[3], ve - d[4], vd - d[5])
        # eq. 26 in multiplicative form: q <- q(psi) * q
        px, py, pz = d[6:9]
        a = math.sqrt(px * px + py * py + pz * pz)
        s = 0.5 if a < 1e-9 else math.sin(0.5 * a) / a
        c = math.cos(0.5 * a)
        r1, r2, r3 = s * px, s * py, s * pz
        q0, q1, q2, q3 = mech.q
        n0 = c * q0 - r1 * q1 - r2 * q2 - r3 * q3
        n1 = c * q1 + r1 * q0 + r2 * q3 - r3 * q2
        n2 = c * q2 - r1 * q3 + r2 * q0 + r3 * q1
        n3 = c * q3 + r1 * q2 - r2 * q1 + r3 * q0
        nrm = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
        mech.q = (n0 * nrm, n1 * nrm, n2 * nrm, n3 * nrm)
        if self.sens.n:
            self.s = self.s - dx[9:]
            self.corr = self.sens.H @ self.s

    def _reset(self, rows: slice, cols: slice, block: np.ndarray) -> None:
        """The reset of the error state's covariance across a feedback, ``P <- G P G'`` with
        ``G`` the identity except ``G[rows, cols] = block`` (`rows` inside `cols`): the
        Jacobian of the error after the feedback with respect to the error before it (module
        notes, ``error_model``)."""
        P = self.P.copy()
        P[rows] = block @ self.P[cols]
        P[:, rows] = P[:, cols] @ block.T
        self.P = 0.5 * (P + P.T)

    # -------------------------------------------------------------- loop
    def execute(self) -> NavResult:
        flt, sens, mech = self.flt, self.sens, self.mech
        t, h = self.t, self.h
        dth, dv = self.dth, self.dv
        tl = t.tolist()
        events = self.events
        ne, ie = len(events), 0
        dtf = flt.dt_filter
        dt_imu = sens.dt
        x = mech.x
        last = h.size - 1
        rows = np.empty((h.size + 1, 10))  # lat, lon, h, v, q after every IMU interval
        rows[0] = x[:10]
        prev = np.empty(6)
        epochs: list[tuple] = []
        epoch_rows: list[int] = []
        nav_P: list[np.ndarray] = []
        self.t_now = self.t_prev = tl[0]
        self._record(epochs, epoch_rows, nav_P, 0)
        x[21:24] = 0.0  # dv_n
        k = 0
        while k <= last:
            t_event = events[ie][0] if ie < ne else math.inf
            corr = self.corr  # the step's sensor-error correction (propagate replaces it)
            k, elapsed, due = _advance(x, t, h, dth, dv, self.con, self.scu, corr, k, t_event,
                                       dtf, last, rows, prev)
            tk = tl[k + 1]
            self.t_prev, self.t_now = tl[k], tk
            m = max(1, int(round(elapsed / dt_imu)))
            acc = x[21:24].tolist()
            self._propagate(elapsed, m, (acc[0] / elapsed, acc[1] / elapsed, acc[2] / elapsed))
            x[21:24] = 0.0
            if due:
                p = prev.tolist()
                batch = []
                while ie < ne and events[ie][0] <= tk + 1e-9:
                    batch.append(events[ie][::2])
                    ie += 1
                self._epoch_updates(batch, (p[0], p[1], p[2], (p[3], p[4], p[5])), dth[k],
                                    float(h[k]), corr)
                self._check_psd()
                rows[k + 1] = x[:10]  # the state after the feedback
            k += 1
            self._record(epochs, epoch_rows, nav_P, k)
        return self._result(rows, epochs, epoch_rows, nav_P)

    def _epoch_updates(self, batch: list[tuple[float, Measurement]], before: tuple,
                       dth: np.ndarray, hk: float, corr: np.ndarray) -> None:
        """The updates of the measurements `batch` (``(t_m, measurement)`` in order) that fall
        in the IMU interval just integrated, ``(t_k-1, t_k]`` of `hk` seconds with angle
        increment `dth` and gyro correction `corr`; `before` is the position and velocity at
        ``t_k-1`` (lat, lon rad, height m, NED velocity m/s).

        Each measurement is predicted from the state updated by the ones before it (sequential
        updates, Bar-Shalom, Li & Kirubarajan 2001, Section 3.4; Gonzalez Alg. 1-2 per
        measurement): the estimate at ``t_m`` is interpolated between ``t_k-1`` and ``t_k``, so
        after each feedback, which corrects the state at ``t_k``, the state at ``t_k-1`` takes
        the same correction (the same error estimate, to first order in the IMU step), and the
        body rate the corrected attitude and gyro bias. Without it a GNSS velocity following
        the position of the same fix would be predicted with only the share ``(t_m -
        t_k-1) / hk`` of the velocity correction that the position update just applied.
        """
        mech = self.mech
        w_nb = self._body_rate(dth, hk, corr)
        for n, (tm, meas) in enumerate(batch):
            self.t_meas = tm
            lat0, lon0, h0, (v0, v1, v2) = mech.lat, mech.lon, mech.h, mech.v
            self._update(meas, self._snapshot(tm, before, w_nb))
            if n + 1 < len(batch):
                vn, ve, vd = mech.v
                before = (before[0] + (mech.lat - lat0), before[1] + (mech.lon - lon0),
                          before[2] + (mech.h - h0),
                          (before[3][0] + (vn - v0), before[3][1] + (ve - v1),
                           before[3][2] + (vd - v2)))
                w_nb = self._body_rate(dth, hk)

    def _body_rate(self, dth: np.ndarray, hk: float, corr: np.ndarray | None = None
                   ) -> np.ndarray:
        """Body rate relative to the NED frame over the last IMU interval (rad/s, body axes):
        the angle increment `dth` (rad) over `hk` seconds less the gyro correction `corr`
        (default: the current one), less the NED frame's rate ``C_bn w_in``."""
        corr = self.corr if corr is None else corr
        g = (np.asarray(dth, dtype=float) - corr[:3] * hk) / hk
        return g - frames.quat_to_dcm(self.mech.q).T @ np.array(self.mech.w_in)

    def _record(self, epochs: list, epoch_rows: list, nav_P: list, row: int) -> None:
        mech = self.mech
        self._start = (mech.lat, mech.h, mech.v, mech.q)  # the next covariance step's start
        epochs.append((self.t_now, np.sqrt(np.maximum(self.P.diagonal(), 0.0)), self.s.copy(),
                       self.corr.copy()))
        epoch_rows.append(row)
        nav_P.append(self.P[:9, :9].copy())
        self.n_epochs = len(epochs)

    def _check_psd(self) -> None:
        """Raise EstimationError unless the covariance is finite and positive semi-definite
        (smallest eigenvalue above -1e-9 of the largest)."""
        if not np.all(np.isfinite(self.P)):
            raise EstimationError(f"filter covariance became non-finite at t = {self.t_now:.6g} s")
        ev = np.linalg.eigvalsh(self.P)
        if ev[0] < -1e-9 * max(ev[-1], 1e-300):
            raise EstimationError(f"filter covariance lost positive semi-definiteness at "
                                  f"t = {self.t_now:.6g} s (eigenvalues {ev[0]:.3g} .. {ev[-1]:.3g})")

    def _result(self, rows: list, epochs: list, epoch_rows: list, nav_P: list) -> NavResult:
        arr = rows
        et = np.array([e[0] for e in epochs])
        esd = np.array([e[1] for e in epochs])
        ess = np.array([e[2] for e in epochs]).reshape(len(epochs), -1)
        eer = np.array([e[3] for e in epochs])
        # hold each epoch's sigma until the next epoch
        idx = np.searchsorted(np.array(epoch_rows), np.arange(arr.shape[0]), side="right") - 1
        sd = esd[idx]
        nees = None
        if self.truth is not None:
            nees = _nees(self.truth, arr[epoch_rows], et, np.array(nav_P))
        pack = lambda d: {k: np.array(v) for k, v in d.items()}  # noqa: E731
        innov, nis = pack(self.innov), pack(self.nis)
        smoothed = None
        if self.store is not None:
            smoothed = self._smoothed(arr, epoch_rows, et, ess, innov, nis)
        return NavResult(
            self.t, np.degrees(arr[:, 0]), np.degrees(arr[:, 1]), arr[:, 2], arr[:, 3:6],
            frames.quat_to_rph(arr[:, 6:10]), sd[:, 0:3], sd[:, 3:6], np.degrees(sd[:, 6:9]),
            et, NAV_STATES + self.sens.names, esd, ess, eer, innov, nis,
            dict(self.rejected), nees, self.flt.gate, self.sens.random_walks,
            tuple(self.recoveries), self.flt.recover_after, smoothed=smoothed)

    def _smoothed(self, arr: np.ndarray, epoch_rows: list, et: np.ndarray, ess: np.ndarray,
                  innov: dict, nis: dict) -> NavResult:
        """The fixed-interval smoothed solution (:mod:`stochmod.nav.smoother`)."""
        store = self.store
        store.finish(self.P)
        s, u, sd_nodes, nav_cov = store.backward()
        rows_e = np.asarray(epoch_rows)
        first, last = node_ranges(store.epoch[:store.j + 1], et.size)
        err = interpolate_errors(self.t, rows_e, et, first, last, s, u)
        sm = correct_rows(arr, err, self.flt.error_model)
        esd = sd_nodes[last]
        ess_s = ess - s[last, 9:]
        eer = ess_s @ self.sens.H.T if self.sens.n else np.zeros((et.size, 6))
        idx = np.searchsorted(rows_e, np.arange(arr.shape[0]), side="right") - 1
        sd = esd[idx]
        nees = None
        if self.truth is not None:
            nees = _nees(self.truth, sm[rows_e], et, nav_cov[last])
        return NavResult(
            self.t, np.degrees(sm[:, 0]), np.degrees(sm[:, 1]), sm[:, 2], sm[:, 3:6],
            frames.quat_to_rph(sm[:, 6:10]), sd[:, 0:3], sd[:, 3:6], np.degrees(sd[:, 6:9]),
            et, NAV_STATES + self.sens.names, esd, ess_s, eer, innov, nis,
            dict(self.rejected), nees, self.flt.gate, self.sens.random_walks,
            tuple(self.recoveries), self.flt.recover_after)


def nav_errors(truth: Trajectory, rows: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Navigation errors (estimate minus truth) in the filter's error-state convention.

    `rows` holds ``(lat rad, lon rad, h, vn, ve, vd, q0..q3)`` per time; returns (k, 9):
    position NED m, velocity m/s, psi rad with ``C_hat = (I - [psi x]) C``.
    """
    tr = truth.at(times)
    lat_t = np.radians(tr.lat)
    rn, re = earth.principal_radii(lat_t)
    dr = np.stack([(rows[:, 0] - lat_t) * (rn + tr.height),
                   (rows[:, 1] - np.radians(tr.lon)) * (re + tr.height) * np.cos(lat_t),
                   -(rows[:, 2] - tr.height)], -1)
    dvel = rows[:, 3:6] - tr.vel_ned
    E = frames.quat_to_dcm(rows[:, 6:10]) @ np.swapaxes(frames.rph_to_dcm(tr.rph), -1, -2)
    psi = -frames.dcm_to_rotvec(E)
    return np.concatenate([dr, dvel, psi], -1)


def _nees(truth: Trajectory, rows: np.ndarray, times: np.ndarray, P: np.ndarray) -> np.ndarray:
    e = nav_errors(truth, rows, times)
    return np.einsum("ki,ki->k", e, np.linalg.solve(P, e[..., None])[..., 0])
