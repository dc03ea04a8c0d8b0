"""Robust GMWM, selection and CLI (issue 13) on simulations with additive outliers."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import stochmod
from stochmod.cli import main as cli_main
from stochmod.core.errors import InputError
from stochmod.fit.gmwm import gmwm
from stochmod.fit.selection import select

GMWN = ("GM(beta=2.0, sigma2=1e-6) + WN(sigma2=3e-6)", 100.0)
WNRW = ("WN(sigma2=1.0) + RW(sigma2=1e-4)", 1.0)


def contaminate(x: np.ndarray, rng: np.random.Generator, share: float = 0.005,
                size: float = 20.0, bursts: int = 0, burst_len: int = 32) -> np.ndarray:
    """Additive outliers: `share` of isolated spikes of +-`size` times the signal's level-1
    standard deviation, and `bursts` offsets of +-size/3 over `burst_len` samples."""
    sd = np.std(np.diff(x)) / np.sqrt(2.0)
    out = x.copy()
    idx = rng.choice(x.size, int(share * x.size), replace=False)
    out[idx] += rng.choice([-1.0, 1.0], idx.size) * size * sd
    for start in rng.choice(x.size - burst_len, bursts, replace=False):
        out[start : start + burst_len] += rng.choice([-1.0, 1.0]) * size / 3 * sd
    return out


def test_robust_gmwm_follows_the_truth_where_classical_follows_spikes():
    spec, freq = GMWN
    truth = stochmod.model_from_spec(spec, freq)
    x = contaminate(truth.simulate(2**14, rng=3), np.random.default_rng(4), share=0.002)
    rob = gmwm(x, "GM+WN", freq, robust=True)
    cla = gmwm(x, "GM+WN", freq)
    wn = truth.param_names.index("WN.sigma2")
    # the spikes are white: the classical fit puts them into the WN (0.2 % of 20^2 sd^2 = 0.8x)
    assert cla.model.vector()[wn] > 1.5 * truth.vector()[wn]
    # the robust one is off by its sampling error plus the M-scale's bias where outliers are
    # rejected (about -2 eps delta / B for a share eps rejected: docs/robust.md)
    assert rob.model.vector()[wn] == pytest.approx(truth.vector()[wn], rel=0.1)
    assert rob.empirical.robust and "robust WV: biweight" in rob.summary()
    assert "Contamination" in rob.summary()
    # inference uses the robust estimator's covariance: its standard errors are those of the
    # classical fit on the clean record inflated by at most 1/sqrt(eff) (and a little noise)
    ref = gmwm(truth.simulate(2**14, rng=3), "GM+WN", freq).std_errors
    assert np.all(rob.std_errors > 0.8 * ref) and np.all(rob.std_errors < 1.5 * ref / np.sqrt(0.6))


def _mc(spec: str, freq: float, reps: int, n: int, **contamination) -> dict[str, np.ndarray]:
    truth = stochmod.model_from_spec(spec, freq)
    out: dict[str, list] = {"clean": [], "classical": [], "robust": []}
    for r in range(reps):
        x = truth.simulate(n, rng=np.random.default_rng([91, r]))
        xc = contaminate(x, np.random.default_rng([92, r]), **contamination)
        free = truth.freed()
        out["clean"].append(gmwm(x, free, freq).model.vector())
        out["classical"].append(gmwm(xc, free, freq).model.vector())
        out["robust"].append(gmwm(xc, free, freq, robust=True).model.vector())
    return {k: np.array(v) for k, v in out.items()}


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    (GMWN, 2**13, {"share": 0.002}),               # 0.2 % isolated spikes
    (WNRW, 2**14, {"share": 0.002, "bursts": 4}),  # 0.2 % spikes and four 32-sample bursts
])
def test_robust_gmwm_recovery_monte_carlo(case):
    """Small Monte Carlo (5 records): the tolerance is the classical estimator's own
    RMSE on the clean records (its sampling error). The robust fit on the contaminated
    records stays within twice it (the efficiency loss, 1/sqrt(0.6) = 1.3, and MC noise)
    plus 10 % of the value (the M-scale's bias at the middle levels, where a spike touches
    2^j eps of the coefficients by a few sd: docs/robust.md); the classical fit on the same
    records misses the WN by far."""
    (spec, freq), n, contamination = case
    truth = stochmod.model_from_spec(spec, freq).vector()
    mc = _mc(spec, freq, reps=5, n=n, **contamination)
    rmse = {k: np.sqrt(np.mean((v - truth) ** 2, axis=0)) for k, v in mc.items()}
    assert np.all(rmse["robust"] <= 2.0 * rmse["clean"] + 0.1 * truth), rmse
    # the WN variance is what isolated spikes inflate: the classical misses it by far
    wn = stochmod.model_from_spec(spec, freq).param_names.index("WN.sigma2")
    assert rmse["classical"][wn] > 5.0 * rmse["robust"][wn], rmse
    assert rmse["classical"][wn] > 4.0 * rmse["clean"][wn] + 0.05 * truth[wn], rmse


@pytest.mark.slow
def test_robust_selection_picks_the_true_structure():
    """WN + RW with 0.2 % spikes and four bursts: the classical selection explains the bursts'
    hump with a spurious GM, the robust one selects WN + RW."""
    spec, freq = WNRW
    truth = stochmod.model_from_spec(spec, freq)
    x = contaminate(truth.simulate(2**14, rng=0), np.random.default_rng(100), share=0.002,
                    bursts=4)
    candidates = ["WN+RW", "GM+WN+RW", "GM+WN", "2*GM+WN"]
    with ThreadPoolExecutor(1) as pool:
        cla = select(x, freq, candidates=candidates, executor=pool)
        rob = select(x, freq, candidates=candidates, executor=pool, robust=True)
    assert cla.best.model.name != "WN+RW"
    assert "GM" in cla.best.model.name
    assert rob.best.model.name == "WN+RW"
    assert rob.empirical.robust and rob.empirical.contamination.share[0] > 0.002
    assert "Contamination" in rob.summary()


GMWN_SLOW = ("GM(beta=0.2, sigma2=2e-5) + WN(sigma2=1e-3)", 100.0)


def spikes_and_bursts(x: np.ndarray, rng: np.random.Generator, share: float = 5e-4,
                      size: float = 25.0, bursts: int = 3, burst_len: int = 50,
                      burst_size: float = 8.0, kind: str = "noise"
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Isolated spikes (`share` of the samples, +-`size` level-1 sd) and `bursts` patches of
    `burst_len` samples: white noise of `burst_size` sd (``kind="noise"``) or an offset of
    +-`burst_size` sd (``kind="offset"``); the contaminated signal and the spikes' indices."""
    sd = np.std(np.diff(x)) / np.sqrt(2.0)
    out = x.copy()
    idx = rng.choice(x.size, int(share * x.size), replace=False)
    out[idx] += rng.choice([-1.0, 1.0], idx.size) * size * sd
    for start in rng.choice(x.size - burst_len, bursts, replace=False):
        shape = rng.standard_normal(burst_len) if kind == "noise" else rng.choice([-1.0, 1.0])
        out[start : start + burst_len] += burst_size * sd * shape
    return out, idx


@pytest.mark.parametrize("kind", ["noise", "offset"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_robust_gmwm_beats_classical_on_spikes_and_bursts(seed, kind):
    """GM(0.2, 2e-5) + WN(1e-3), 5e5 samples at 100 Hz (83 min), 0.05 % isolated spikes of
    25 sd and three 50-sample bursts of 8 sd. At levels 6-10 each spike touches 3-50 % of
    the coefficients by 3-0.8 sd: without the screening of isolated outliers the robust WV
    rose there by 10-17 % and beta came out 30-55 % high. The tolerance on beta is about
    twice its sampling sd (8 % for the classical fit on clean records of this length)."""
    spec, freq = GMWN_SLOW
    truth = stochmod.model_from_spec(spec, freq)
    tv = truth.vector()
    x, _ = spikes_and_bursts(truth.simulate(500_000, rng=seed),
                             np.random.default_rng([17, seed]), kind=kind)
    rob = gmwm(x, "GM+WN", freq, robust=True).model.vector()
    cla = gmwm(x, "GM+WN", freq).model.vector()
    err_rob, err_cla = np.abs(rob / tv - 1), np.abs(cla / tv - 1)
    beta, wn = truth.param_names.index("GM.beta"), truth.param_names.index("WN.sigma2")
    assert err_rob[beta] < 0.15, rob
    assert err_rob[wn] < 0.02, rob  # its sampling sd is 0.2 %
    # the spikes are white: the classical fit puts them into the WN (0.05 % of 25^2 = +31 %)
    assert err_cla[wn] > 0.25, cla
    assert err_rob.max() < err_cla.max(), (rob, cla)


def test_screening_removes_the_spikes_from_every_level():
    """Same scenario, one record: the spikes are replaced (the diagnostic lists them) and
    the robust WV of the contaminated record is the robust WV of the clean one within 2 % at
    levels 1-10 (their sampling sd: 0.3-6 %); without the screening it is 2 % low at level 5,
    where the spikes are rejected, and 10-17 % high at levels 7-9, where they pass."""
    spec, freq = GMWN_SLOW
    clean = stochmod.model_from_spec(spec, freq).simulate(500_000, rng=5)
    x, spikes = spikes_and_bursts(clean, np.random.default_rng(6))
    ref = stochmod.wvar(clean, freq, robust=True)
    assert ref.contamination.replaced_time.size == 0  # nothing to screen in a clean record
    rob = stochmod.wvar(x, freq, robust=True)
    replaced = np.round(rob.contamination.replaced_time * freq).astype(int)
    assert np.isin(spikes, replaced).mean() > 0.99
    assert replaced.size < 1.3 * spikes.size  # and few others (samples of the noise bursts)
    assert np.all(np.abs(rob.wv[:10] / ref.wv[:10] - 1) < 0.02)
    # level 1 of the diagnostic is the record as given: two coefficients per spike
    assert rob.contamination.share[0] > 1.9 * spikes.size / x.size
    assert "Isolated outliers replaced" in rob.summary()
    from stochmod.empirical.robust_wv import robust_wvar

    raw = robust_wvar(x, freq, screen=False)
    assert raw.contamination.replaced_time.size == 0
    assert raw.wv[4] < 0.99 * ref.wv[4] and np.all(raw.wv[6:9] > 1.05 * ref.wv[6:9])


def test_robust_weighting_uses_the_robust_variances():
    spec, freq = GMWN
    x = stochmod.model_from_spec(spec, freq).simulate(2**12, rng=1)
    fit = gmwm(x, "GM+WN", freq, robust=True, efficiency=0.5)
    emp = fit.empirical
    eta = np.maximum(emp.n_coef / 2.0**emp.levels, 1.0)
    # chi2 intervals: kappa = 1/eff, so the diagonal weights are eff eta / (2 nu^2)
    assert np.allclose(np.diag(fit.omega), 0.5 * eta / (2 * emp.wv**2), rtol=1e-12)
    opt = gmwm(x, "GM+WN", freq, robust=True, efficiency=0.5, weighting="optimal")
    V = opt.wv_covariance
    assert np.allclose(np.linalg.inv(opt.omega), V, rtol=1e-8, atol=1e-12 * np.abs(V).max())
    # V is scaled by kappa = 2 from eq. 17 on the clipped coefficients
    from stochmod.empirical.wv_covariance import wv_covariance

    raw = wv_covariance(x, emp.wv.size, clip=emp.tuning * np.sqrt(emp.wv))
    assert V[0, 0] == pytest.approx(2.0 * raw[0, 0], rel=1e-10)


def test_robust_gmwm_bad_input():
    spec, freq = GMWN
    x = stochmod.model_from_spec(spec, freq).simulate(2**10, rng=1)
    with pytest.raises(InputError, match="efficiency"):
        gmwm(x, "GM+WN", freq, robust=True, efficiency=0.0)
    with pytest.raises(InputError, match="robust"):
        gmwm(stochmod.wvar(x, freq), "GM+WN", robust=True)
    with pytest.raises(InputError, match="efficiency"):
        select(x, freq, candidates=["WN"], robust=True, efficiency=1.5)


def test_cli_calibrate_and_wv_robust(tmp_path, capsys):
    spec, freq = GMWN
    x = contaminate(stochmod.model_from_spec(spec, freq).simulate(2**13, rng=5),
                    np.random.default_rng(6), share=0.003)
    path = tmp_path / "gyro.npy"
    np.save(path, x[:, None])
    out = tmp_path / "out"
    code = cli_main(["calibrate", str(path), "--freq", str(freq), "--candidates", "GM+WN",
                     "WN", "--robust", "--efficiency", "0.6", "--no-plots", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "Contamination" in text
    report = json.loads((out / "calibration.json").read_text())
    (col,) = report["columns"].values()
    assert col["robust"]["efficiency"] == 0.6 and col["name"] == "GM+WN"
    share = col["robust"]["contamination"]["share"]
    assert share[0] > 0.003
    wn = [p for p in col["parameters"] if p["name"] == "WN.sigma2"][0]
    assert wn["value"] == pytest.approx(3e-6, rel=0.1)
    assert cli_main(["wv", str(path), "--freq", str(freq), "--robust", "--levels", "5"]) == 0
    assert "Robust wavelet variance (biweight" in capsys.readouterr().out
    assert cli_main(["fit", str(path), "--freq", str(freq), "--model", "GM+WN", "--robust",
                     "--efficiency", "0.7"]) == 0
    assert "robust WV: biweight, efficiency 0.7" in capsys.readouterr().out
    assert cli_main(["fit", str(path), "--freq", str(freq), "--model", "GM+WN", "--robust",
                     "--json"]) == 0
    (fit,) = json.loads(capsys.readouterr().out)["columns"].values()
    assert fit["robust"]["contamination"]["share"][0] > 0.003
    assert cli_main(["fit", str(path), "--freq", str(freq), "--model", "GM+WN", "--robust",
                     "--efficiency", "2"]) == 2
    assert "efficiency" in capsys.readouterr().err
