"""The verdict on a fit: J-test at 5 % and the share of levels inside the model's 95 % band.

Truth: seeded simulations of GM + WN. The true structure keeps about 95 % of the levels in its
band and passes the J-test in most runs; white noise alone, fitted to the same data, is
rejected and misfits exactly where the GM's correlation shows (tau near and beyond Tc = 2 s).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import stochmod
from stochmod.fit.selection import RankingRow
from stochmod.fit.verdict import model_band, verdict

FREQ = 100.0
TRUTH = {"processes": [{"family": "GM", "params": {"beta": 0.5, "sigma2": 1e-6}},
                       {"family": "WN", "params": {"sigma2": 1e-4}}]}


def test_the_band_is_the_chi_square_interval_of_the_model_wv() -> None:
    x = stochmod.model_from_spec(TRUTH, FREQ).simulate(2**14, rng=1)
    fit = stochmod.gmwm(x, "GM+WN", FREQ)
    low, high = model_band(fit)
    nu = fit.model.wv(fit.levels)
    eta = 2 * nu**2 / np.diag(fit.null_wv_covariance)
    np.testing.assert_allclose(low, nu * eta / stats.chi2.ppf(0.975, eta), rtol=1e-10)
    np.testing.assert_allclose(high, nu * eta / stats.chi2.ppf(0.025, eta), rtol=1e-10)


@pytest.mark.slow
def test_the_true_structure_stays_in_its_band_and_a_wrong_one_misfits() -> None:
    truth = stochmod.model_from_spec(TRUTH, FREQ)
    inside, accepted = [], []
    for seed in range(12):
        x = truth.simulate(2**15, rng=seed)
        v = verdict(stochmod.gmwm(x, "GM+WN", FREQ))
        inside.append(v.inside)
        accepted.append(v.accepted)
    assert 0.88 <= np.mean(inside) <= 1.0
    assert np.mean(accepted) >= 0.75
    wrong = verdict(stochmod.gmwm(x, "WN", FREQ))
    assert not wrong.accepted and wrong.pvalue < 1e-6
    assert wrong.inside < 0.7 and min(wrong.misfit_tau) <= 2.0 <= max(wrong.misfit_tau)
    assert "rejected by the J-test at 5 %" in wrong.summary()


def test_every_candidate_rejected_is_said() -> None:
    x = stochmod.model_from_spec(TRUTH, FREQ).simulate(2**14, rng=3)
    fit = stochmod.gmwm(x, "WN", FREQ)
    rows = [RankingRow("WN", 1, 1.0, 0.0, 1.0, 1e-9, True),
            RankingRow("GM", 2, 1.0, 0.0, 1.0, 1e-3, True)]
    v = verdict(fit, candidates=rows)
    assert v.every_candidate_rejected and "best model of the lattice" in v.summary()
    rows[1] = RankingRow("GM", 2, 1.0, 0.0, 1.0, 0.3, True)
    assert verdict(fit, candidates=rows).every_candidate_rejected is False
    assert verdict(fit).to_dict()["every_candidate_rejected"] is None


def test_calibrate_prints_and_records_the_verdict(tmp_path, capsys) -> None:
    import json

    from stochmod.cli import main

    x = stochmod.model_from_spec(TRUTH, FREQ).simulate(2**14, rng=4)
    path = tmp_path / "gyro.npz"
    np.savez(path, gyro_x=x, freq=FREQ)
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--assume-si", "--candidates", "WN", "--no-plots",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    expected = verdict(stochmod.gmwm(x, "WN", FREQ))
    assert expected.summary() in printed
    column = json.loads((out / "calibration.json").read_text())["columns"]["gyro_x"]
    assert column["verdict"]["accepted"] is False
    assert column["verdict"]["misfit_levels"] == list(expected.misfit_levels)
    assert column["verdict"]["every_candidate_rejected"] is True  # WN was the only candidate
