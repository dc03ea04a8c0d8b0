"""Record-length advice (stochmod.fit.plan, ``stochmod plan``) against Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.fit.plan import interval_half_widths, record_length

FREQ = 100.0
GM_WN = "GM(beta=0.5, sigma2=1e-4) + WN(sigma2=1e-3)"
Z = 1.959963984540054


@pytest.mark.parametrize("n", [2**14, 2**15, 2**16])
def test_predicted_widths_match_the_simulated_spread_of_gmwm_estimates(n) -> None:
    """The planner's half-widths are those of the GMWM estimates' spread (log scale) over 100
    seeded records of n samples, to 20 %."""
    model = stochmod.model_from_spec(GM_WN, FREQ)
    predicted = np.log1p(interval_half_widths(model, n)) / Z
    logs = np.log([stochmod.gmwm(model.simulate(n, rng=7000 + r), "GM+WN", FREQ).model.vector()
                   for r in range(100)])
    simulated = logs.std(axis=0, ddof=1)
    np.testing.assert_allclose(predicted, simulated, rtol=0.2)


@pytest.mark.parametrize("n", [2**15, 2**16, 2**17])
def test_predicted_widths_match_the_model_weighted_spread_of_a_random_walk(n) -> None:
    """WN(1e-4) + RW(1e-9) at 100 Hz: only the deepest levels see the RW. Fitted with the
    weighting the plan assumes (``weighting="model"``), the spread of the log estimates over 200
    seeded records is the planned one to 20 % for both parameters."""
    model = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-9)", FREQ)
    predicted = np.log1p(interval_half_widths(model, n)) / Z
    logs = np.log([stochmod.gmwm(model.simulate(n, rng=5000 + r), "WN+RW", FREQ,
                                 weighting="model").model.vector() for r in range(200)])
    np.testing.assert_allclose(logs.std(axis=0, ddof=1), predicted, rtol=0.2)


def test_the_planned_record_is_the_shortest_that_reaches_the_precision() -> None:
    model = stochmod.model_from_spec(GM_WN, FREQ)
    plan = record_length(model, precision=0.15, current=2**16)
    assert plan.names == ("GM.beta", "GM.sigma2", "WN.sigma2")
    for k, n in enumerate(plan.samples):
        assert interval_half_widths(model, n)[k] <= 0.15
        assert interval_half_widths(model, int(n * 0.98))[k] > 0.15
    np.testing.assert_allclose(plan.hours, plan.samples / FREQ / 3600.0)
    np.testing.assert_array_equal(plan.current_widths, interval_half_widths(model, 2**16))
    assert "record needed" in plan.summary() and "GM.beta" in plan.summary()


def test_white_noise_widths_shrink_as_one_over_root_n() -> None:
    """WN only: the estimate's standard error falls as N^-1/2 (each level's M_j ~ N)."""
    model = stochmod.model_from_spec("WN(sigma2=2e-5)", FREQ)
    se = [math.log1p(interval_half_widths(model, n)[0]) for n in (2**20, 2**22)]
    assert se[0] / se[1] == pytest.approx(2.0, rel=0.02)


def test_bad_plans_are_refused() -> None:
    model = stochmod.model_from_spec(GM_WN, FREQ)
    with pytest.raises(InputError, match="precision"):
        record_length(model, precision=0.0)
    with pytest.raises(InputError, match="no parameter"):
        record_length(model, parameters=["RW.sigma2"])
    with pytest.raises(InputError, match="sampling frequency"):
        record_length(stochmod.model_from_spec("WN(sigma2=1e-4)"))
    assert np.all(np.isinf(interval_half_widths(model, 12)))  # fewer levels than parameters


def test_plan_command_reads_a_calibration(tmp_path, capsys) -> None:
    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-9)", FREQ)
    rec = stochmod.io.Recording(truth.simulate(2**14, rng=2)[:, None], ("gyro_x",), FREQ,
                                units=("rad/s",))
    cal = stochmod.calibrate(rec, candidates=["WN", "WN+RW"])
    path = cal.write(tmp_path / "calibration.json")
    assert main(["plan", "--calibration", str(path), "--precision", "20"]) == 0
    out = capsys.readouterr().out
    assert "gyro_x: WN+RW" in out and "RW.sigma2" in out and "at 2.73 min" in out
    assert "fitted with the diagonal weighting" in out  # the plan is for the model weighting
    again = stochmod.calibrate(rec, candidates=["WN", "WN+RW"], final_weighting="model")
    assert main(["plan", "--calibration", str(again.write(tmp_path / "model.json"))]) == 0
    assert "fitted with the" not in capsys.readouterr().out
    assert main(["plan", "--model", "WN(sigma2=1e-4)"]) == 2  # no --freq
    assert "--model needs --freq" in capsys.readouterr().err
