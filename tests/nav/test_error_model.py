"""The filter's two error models (``error_model="psi"`` and pyins' ``"modified-phi"``): where the
covariance is held across a feedback, checked on the filter's own feedbacks, and the
modified-phi filter's honesty (NEES) on emulated data with a known error model."""

import numpy as np
import pytest
from scipy.stats import chi2

from stochmod.core.errors import InputError
from stochmod.nav import LooselyCoupledFilter, frames
import stochmod.nav.filter as nf

# the emulated drive of the filter tests (its module-scoped fixtures, shared)
from .test_filter import ACCEL, GYRO, _emulate, _filter, clean_imu, truth  # noqa: F401


def _to_modified(P: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Covariance of ``(dr, dv - v x psi, psi, ...)`` from that of ``(dr, dv, psi, ...)``."""
    M = np.eye(P.shape[0])
    M[3:6, 6:9] = -frames.skew(v)
    return M @ P @ M.T


@pytest.mark.parametrize("error_model", nf.ERROR_MODELS)
def test_feedback_holds_the_covariance_of_its_own_states(truth, clean_imu, monkeypatch,
                                                         error_model):
    """Across every feedback of a 30 s run, "psi" keeps P of (dr, dv, psi) and "modified-phi"
    keeps P of (dr, dv - v_hat x psi, psi) while v_hat moves by the velocity correction; the
    corrections are large enough that the invariants exclude each other."""
    seen = []
    real = nf._Run._feedback

    def spy(self, dx):
        before = (self.P.copy(), np.array(self.mech.v))
        real(self, dx)
        seen.append((*before, self.P.copy(), np.array(self.mech.v)))

    monkeypatch.setattr(nf._Run, "_feedback", spy)
    imu, gnss, init, _ = _emulate(truth, clean_imu, 3)
    sel = truth.time <= 30.0
    _filter(error_model=error_model).run(imu.time[sel], imu.gyro[sel], imu.accel[sel],
                                         kind="increment", gnss=gnss, init=init)
    assert len(seen) >= 50  # position and velocity fixes at 1 Hz
    moved = max(np.abs(v1 - v0).max() for _, v0, _, v1 in seen)
    assert moved > 1e-3  # m/s: the reset terms are not negligible

    def kept(P0, v0, P1, v1, model):
        if model == "psi":
            a, b = P0, P1
        else:
            a, b = _to_modified(P0, v0), _to_modified(P1, v1)
        sa = np.sqrt(np.outer(np.diag(a), np.diag(a)))
        return np.abs(b / sa - a / sa).max()

    for P0, v0, P1, v1 in seen:
        assert kept(P0, v0, P1, v1, error_model) < 1e-12
    # the other invariants fail on the largest corrections: the check tells the models apart
    for other in set(nf.ERROR_MODELS) - {error_model}:
        assert max(kept(*s, other) for s in seen) > 1e-4, other


@pytest.mark.slow
def test_other_error_models_are_honest_and_close_to_psi(truth, clean_imu):
    """Seeded emulations with the filter's own error model: the modified-phi filter's average
    NEES over runs inside the 95% band, and its trajectory within a fraction of a sigma of the
    psi filter's (they differ at second order)."""
    runs = 3
    others = [m for m in nf.ERROR_MODELS if m != "psi"]
    nees, gaps = {m: [] for m in others}, {m: [] for m in others}
    for seed in range(runs):
        imu, gnss, init, _ = _emulate(truth, clean_imu, seed)
        out = {m: _filter(error_model=m).run(imu.time, imu.gyro, imu.accel, kind="increment",
                                             gnss=gnss, init=init, truth=truth)
               for m in nf.ERROR_MODELS}
        psi = out["psi"]
        for m in others:
            nees[m].append(out[m].nees[out[m].epoch_time > 10.0])
            north = (out[m].lat - psi.lat) * np.pi / 180 * 6.37e6
            gaps[m].append(np.abs(north).max() / psi.sd_position[:, 0].mean())
    lo, hi = chi2.ppf([0.025, 0.975], 9 * runs) / runs
    for m in others:
        mean = np.mean([x.mean() for x in nees[m]])
        print(f"{m} mean NEES {mean:.3f} band [{lo:.3f}, {hi:.3f}], "
              f"largest north gap to psi {max(gaps[m]):.3f} sigma")
        assert lo < mean < hi, (m, mean, lo, hi)
        assert 0.0 < max(gaps[m]) < 0.5, m


def test_an_unknown_error_model_is_refused():
    with pytest.raises(InputError, match="error_model"):
        LooselyCoupledFilter(GYRO, ACCEL, error_model="phi")


# ---------------------------------------------------------------- the feedback and its reset
_TRUTH = dict(lat=37.3, lon=-122.1, height=40.0, vel=np.array([12.0, -5.0, 0.3]),
              rph=np.array([3.0, -2.0, 40.0]))


def _run(error_model: str) -> nf._Run:
    """A filter loop (no data) whose mechanisation and feedback the tests drive directly."""
    flt = LooselyCoupledFilter(GYRO, ACCEL, error_model=error_model)
    init = nf.InitialState(_TRUTH["lat"], _TRUTH["lon"], _TRUTH["height"], _TRUTH["vel"],
                           _TRUTH["rph"])
    z = np.zeros((1, 3))
    return nf._Run(flt, nf._Sensors(flt.models, 0.01, 0.0, 0.0), init, np.array([0.0, 0.01]),
                   np.array([0.01]), z, z, z, z, [], None)


def _truth() -> "nf.Trajectory":
    t = np.array([0.0, 1.0])
    two = lambda x: np.tile(x, (2, 1))  # noqa: E731
    return nf.Trajectory(t, np.full(2, _TRUTH["lat"]), np.full(2, _TRUTH["lon"]),
                         np.full(2, _TRUTH["height"]), two(_TRUTH["vel"]), two(_TRUTH["rph"]))


def _nominal(run: nf._Run, e: np.ndarray, modified: bool) -> None:
    """Set the mechanisation to the truth perturbed by the exact error `e` (dr NED m, then dv or
    the modified dv' = v_hat - Exp(psi)' v, m/s, then psi rad with C_hat = Exp(-psi) C)."""
    from stochmod.nav import earth, frames

    lat = np.radians(_TRUTH["lat"])
    rn, re = (float(r) for r in earth.principal_radii(lat))
    h = _TRUTH["height"]
    m = run.mech
    m.lat = lat + e[0] / (rn + h)
    m.lon = np.radians(_TRUTH["lon"]) + e[1] / ((re + h) * np.cos(lat))
    m.h = h - e[2]
    R = frames.quat_to_dcm(frames.rotvec_to_quat(e[6:9]))
    v = e[3:6] + (R.T @ _TRUTH["vel"] if modified else _TRUTH["vel"])
    m.v = tuple(float(x) for x in v)
    m.q = tuple(frames.dcm_to_quat(R.T @ frames.rph_to_dcm(_TRUTH["rph"])))


E_HAT = np.array([4.0, -3.0, 2.0, 0.4, -0.3, 0.2, 0.02, -0.03, 0.08])


@pytest.mark.parametrize("error_model", nf.ERROR_MODELS)
def test_feedback_injects_the_estimate_of_its_own_error_exactly(error_model):
    """When the estimate equals the error (in the model's own definition, see the module
    notes), the corrected mechanisation is the truth: the feedback zeroes the error, to the
    ~1e-6 relative of the radii of curvature taken at the estimate. The modified-phi model
    needs the corrected velocity rotated by the attitude correction (pyins' correct_pva); the
    first-order ``v_hat - dv_hat`` misses it by ``psi x dv'`` (~1e-2 m/s here)."""
    run = _run(error_model)
    modified = error_model == "modified-phi"
    _nominal(run, E_HAT, modified)
    dx = np.r_[E_HAT, np.zeros(run.n - 9)]
    if modified:  # the filter's states hold dv = dv' + v_hat x psi (module notes)
        dx[3:6] = E_HAT[3:6] + np.cross(np.array(run.mech.v), E_HAT[6:9])
    run._feedback(dx)
    m = run.mech
    after = nf.nav_errors(_truth(), np.array([[m.lat, m.lon, m.h, *m.v, *m.q]]),
                          np.array([0.0]))[0]
    np.testing.assert_allclose(after[:3], 0.0, atol=1e-4)  # m
    np.testing.assert_allclose(after[3:6], 0.0, atol=1e-9)  # m/s
    np.testing.assert_allclose(after[6:9], 0.0, atol=1e-12)  # rad
