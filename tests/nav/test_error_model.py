"""The filter's two error models (``error_model="psi"`` and pyins' ``"modified-phi"``): where the
covariance is held across a feedback, checked on the filter's own feedbacks, and the
modified-phi filter's honesty (NEES) on emulated data with a known error model."""

import numpy as np
import pytest
from scipy.stats import chi2

from stochmod.errors import InputError
from stochmod.nav import LooselyCoupledFilter
import stochmod.nav.filter as nf

# the emulated drive of the filter tests (its module-scoped fixtures, shared)
from .test_filter import ACCEL, GYRO, _emulate, _filter, clean_imu, truth  # noqa: F401


def _to_modified(P: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Covariance of ``(dr, dv - v x psi, psi, ...)`` from that of ``(dr, dv, psi, ...)``."""
    M = np.eye(P.shape[0])
    M[3:6, 6:9] = -nf._skew(v)
    return M @ P @ M.T


@pytest.mark.parametrize("error_model", nf.ERROR_MODELS)
def test_feedback_holds_the_covariance_of_its_own_states(truth, clean_imu, monkeypatch,
                                                         error_model):
    """Across every feedback of a 30 s run, "psi" keeps P of (dr, dv, psi) and "modified-phi"
    keeps P of (dr, dv - v_hat x psi, psi) while v_hat moves by the velocity correction; the
    velocity corrections are large enough that the two invariants exclude each other."""
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
    for P0, v0, P1, v1 in seen:
        scale = np.sqrt(np.outer(np.diag(P0), np.diag(P0)))
        if error_model == "psi":
            np.testing.assert_allclose(P1 / scale, P0 / scale, atol=1e-12)
        else:
            a, b = _to_modified(P0, v0), _to_modified(P1, v1)
            sa = np.sqrt(np.outer(np.diag(a), np.diag(a)))
            np.testing.assert_allclose(b / sa, a / sa, atol=1e-12)
    # the other invariant fails somewhere: the check above can tell the two models apart
    P0, v0, P1, v1 = max(seen, key=lambda s: np.abs(s[3] - s[1]).max())
    other = (P1, P0) if error_model == "modified-phi" else (_to_modified(P1, v1),
                                                            _to_modified(P0, v0))
    assert np.abs(other[0][3:6, 6:9] - other[1][3:6, 6:9]).max() > 1e-3 * np.sqrt(
        P0[3, 3] * P0[6, 6])


@pytest.mark.slow
def test_modified_phi_filter_is_honest_and_close_to_psi(truth, clean_imu):
    """Seeded emulations with the filter's own error model: the modified-phi filter's average
    NEES over runs inside the 95% band, and its trajectory within a fraction of a sigma of the
    psi filter's (the two differ at second order)."""
    runs = 3
    nees, gaps = [], []
    for seed in range(runs):
        imu, gnss, init, _ = _emulate(truth, clean_imu, seed)
        out = {m: _filter(error_model=m).run(imu.time, imu.gyro, imu.accel, kind="increment",
                                             gnss=gnss, init=init, truth=truth)
               for m in nf.ERROR_MODELS}
        mod, psi = out["modified-phi"], out["psi"]
        nees.append(mod.nees[mod.epoch_time > 10.0])
        north = (mod.lat - psi.lat) * np.pi / 180 * 6.37e6
        gaps.append(np.abs(north).max() / psi.sd_position[:, 0].mean())
    mean = np.mean([x.mean() for x in nees])
    lo, hi = chi2.ppf([0.025, 0.975], 9 * runs) / runs
    print(f"modified-phi mean NEES {mean:.3f} band [{lo:.3f}, {hi:.3f}], "
          f"largest north gap to psi {max(gaps):.3f} sigma")
    assert lo < mean < hi, (mean, lo, hi)
    assert 0.0 < max(gaps) < 0.5


def test_an_unknown_error_model_is_refused():
    with pytest.raises(InputError, match="error_model"):
        LooselyCoupledFilter(GYRO, ACCEL, error_model="phi")
