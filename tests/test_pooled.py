"""One model from several recordings (replicates) and the predicted WV of a synthetic IMU.

Truth: seeded simulations from known models; the pooled WV of K replicates is the WV of all
their coefficients (closed form); intervals ~sqrt(K) narrower than one replicate's; the
homogeneity test's rejection on replicates of different models; the synthetic signal's
empirical WV against ``sum w_i^2 nu_i``; the real ADIS16405 replicates where the data exist.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import stochmod
from stochmod.redundant.combination import synthetic_wv
from stochmod.core.errors import InputError
from stochmod.io.recording import read_recording
from stochmod.empirical.pooled import pooled_wvar

FREQ = 100.0
TRUE = "GM(beta=0.5, sigma2=1e-6) + WN(sigma2=1e-4)"
DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "imudata"


def replicates(spec: str, k: int, n: int = 2**16, seed: int = 0) -> list[np.ndarray]:
    model = stochmod.model_from_spec(spec, FREQ)
    return [model.simulate(n, rng=seed + i) for i in range(k)]


def test_pooled_wv_is_the_wv_of_all_coefficients() -> None:
    xs = [np.random.default_rng(i).standard_normal(n) for i, n in enumerate((5000, 9000, 7000))]
    pooled = pooled_wvar(xs, FREQ, levels=6)
    each = [stochmod.wvar(x, FREQ, levels=6) for x in xs]
    total = sum(w.wv * w.n_coef for w in each) / sum(w.n_coef for w in each)
    np.testing.assert_allclose(pooled.wv.wv, total, rtol=1e-13)
    np.testing.assert_array_equal(pooled.wv.n_coef, sum(w.n_coef for w in each))
    assert pooled.wv.n == 21000
    # white noise: WV sigma2 / 2^j, the test does not reject replicates of one model
    np.testing.assert_allclose(pooled.wv.wv, 0.5 ** np.arange(1, 7), rtol=0.05)
    assert pooled.test.pvalue > 0.01
    assert "pooled WV" in pooled.summary()


def test_pooled_gmwm_recovers_the_model_with_sqrt_k_narrower_intervals() -> None:
    xs = replicates(TRUE, 4)
    one = stochmod.gmwm(xs[0], "GM+WN", FREQ)
    pool = stochmod.gmwm(xs, "GM+WN", FREQ)
    truth = stochmod.model_from_spec(TRUE, FREQ).vector()
    z = (pool.model.vector() - truth) / pool.std_errors
    assert np.all(np.abs(z) < 4), (pool.model, pool.std_errors)
    ratio = one.std_errors / pool.std_errors
    assert np.all((ratio > 2 / 1.35) & (ratio < 2 * 1.35)), ratio  # sqrt(4) = 2
    assert pool.pooled.test.pvalue > 0.01
    assert pool.empirical.n == 4 * 2**16


def test_replicates_of_different_models_are_rejected() -> None:
    a = replicates(TRUE, 2)
    b = replicates("GM(beta=0.5, sigma2=3e-6) + WN(sigma2=1e-4)", 2, seed=50)
    fit = stochmod.gmwm([*a, *b], "GM+WN", FREQ)
    assert fit.pooled.test.pvalue < 1e-4
    assert fit.pooled.test.dof == 3 * fit.pooled.test.levels.size
    # the p-value is chi2(dof)'s survival function (scipy.stats' public one, independently)
    from scipy import stats

    same = stochmod.gmwm(a, "GM+WN", FREQ).pooled.test
    for test in (fit.pooled.test, same):
        ref = stats.chi2.sf(test.statistic, test.dof)
        assert test.pvalue == pytest.approx(ref, rel=1e-12, abs=1e-300)


def test_select_accepts_replicates() -> None:
    xs = replicates(TRUE, 3, n=2**15)
    res = stochmod.select(xs, FREQ, candidates=["WN", "GM+WN", "2*GM+WN"], executor=None)
    assert res.best.model.name == "GM+WN"
    assert res.empirical.n == 3 * 2**15
    from stochmod.fit.replicates import pooled_wv

    assert all(f.pooled.test == pooled_wv(xs, FREQ).test for f in res.fits.values())


def test_synthetic_wv_predicted_from_members_models() -> None:
    specs = ["GM(beta=0.5, sigma2=1e-6) + WN(sigma2=1e-4)", "WN(sigma2=4e-4)",
             "RW(sigma2=1e-9) + WN(sigma2=1e-4)"]
    models = [stochmod.model_from_spec(s, FREQ) for s in specs]
    n, reps, J = 2**14, 30, 8
    w = np.array([4, 1, 4]) / 9  # inverse white-noise levels 1e-4, 4e-4, 1e-4
    est = []
    for r in range(reps):
        x = np.stack([m.simulate(n, rng=1000 * r + i) for i, m in enumerate(models)])
        res = stochmod.combine(x, "inverse-variance", models=models)  # static weights from WN levels
        np.testing.assert_allclose(res.weights[:, 0], w, rtol=1e-12)
        est.append(stochmod.wvar(res.signal, FREQ, levels=J).wv)
    est = np.array(est)
    predicted = synthetic_wv(models, w, J)
    se = est.std(axis=0, ddof=1) / np.sqrt(reps)
    assert np.all(np.abs(est.mean(axis=0) - predicted) < 4.5 * se + 1e-12)
    with pytest.raises(InputError, match="sum to 1"):
        synthetic_wv(models, [0.5, 0.5, 0.5], J)


def test_bad_replicates() -> None:
    with pytest.raises(InputError, match="at least two"):
        stochmod.gmwm([np.zeros(100) + np.arange(100.0)], "WN", FREQ)
    with pytest.raises(InputError, match="constant"):
        stochmod.gmwm([np.ones(1000), np.random.default_rng(0).standard_normal(1000)], "WN", FREQ)
    with pytest.raises(InputError, match="freq"):
        stochmod.gmwm(replicates("WN(sigma2=1.0)", 2, n=1000), "WN")


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data is absent")
def test_adis16405_replicates() -> None:
    """The two real ADIS16405 replicates (Gyro_X, deg/s -> rad/s, mean removed): pooled fit and test."""
    xs = []
    for k in (1, 2):
        rec = read_recording(DATA / f"adis_16405_imu{k}.npz", columns=["Gyro_X"])
        x = np.deg2rad(rec.column("Gyro_X"))[: 2**18]  # the first 43 min of each (test time)
        xs.append(x - x.mean())
    pool = stochmod.gmwm(xs, "2*GM+WN", rec.freq)
    one = stochmod.gmwm(xs[0], "2*GM+WN", rec.freq)
    test = pool.pooled.test
    assert test is not None and 0.0 <= test.pvalue <= 1.0 and test.dof == test.levels.size
    # pooling two replicates narrows the white-noise interval
    wn = [i for i, n in enumerate(pool.free_names) if n.startswith("WN")][0]
    assert pool.std_errors[wn] < one.std_errors[wn]


@pytest.mark.slow
def test_calibrate_pooled_cli(tmp_path: Path, capsys) -> None:
    from stochmod.cli import main

    xs = replicates(TRUE, 2, n=2**14, seed=30)
    files = []
    for k, x in enumerate(xs):
        files.append(str(tmp_path / f"rep{k}.npz"))
        np.savez(files[-1], gyro_x=x, freq=FREQ)
    out = tmp_path / "cal"
    argv = ["calibrate", "--assume-si", *files, "--pooled", "--candidates", "WN", "GM+WN", "--out", str(out), "--json"]
    assert main(argv) == 0
    report = __import__("json").loads(capsys.readouterr().out)
    assert report["replicates"]["n"] == [2**14, 2**14]
    test = report["replicates"]["equality_test"]["gyro_x"]
    ref = pooled_wvar(xs, FREQ).test  # raw eq. 17 covariances: close to the CLI's decoupled ones
    assert test["dof"] == ref.dof and test["pvalue"] > 0.01
    direct = stochmod.select(xs, FREQ, candidates=["WN", "GM+WN"])
    assert report["columns"]["gyro_x"]["name"] == direct.best.model.name == "GM+WN"
    assert main(["calibrate", "--assume-si", "--pooled", "--out", str(out)]) == 2  # no FILE: no replicates
    assert "--pooled needs two or more FILEs" in capsys.readouterr().err


def test_replicates_of_different_lengths_pool_on_the_levels_each_has() -> None:
    from stochmod.empirical.wv_covariance import wv_covariance

    xs = [np.random.default_rng(10 + i).standard_normal(n) for i, n in enumerate((5000, 300, 9000))]
    pooled = pooled_wvar(xs, FREQ)
    each = [stochmod.wvar(x, FREQ) for x in xs]  # 11, 7 and 12 levels
    assert [w.wv.size for w in each] == [11, 7, 12] and pooled.wv.wv.size == 12
    for j in range(12):  # the mean of every squared coefficient at level j+1, by hand
        having = [w for w in each if w.wv.size > j]
        total = sum(w.wv[j] * w.n_coef[j] for w in having) / sum(w.n_coef[j] for w in having)
        assert pooled.wv.wv[j] == pytest.approx(total, rel=1e-13)
        assert pooled.wv.n_coef[j] == sum(w.n_coef[j] for w in having)
    # level 12 comes from the longest replicate alone, level 1 from all three
    covs = [wv_covariance(x, w.wv.size) for x, w in zip(xs, each)]
    assert pooled.covariance[11, 11] == pytest.approx(covs[2][11, 11], rel=1e-12)
    share = np.array([w.n_coef[0] for w in each], dtype=float)
    share /= share.sum()
    assert pooled.covariance[0, 0] == pytest.approx(sum(s**2 * c[0, 0] for s, c in zip(share, covs)),
                                                    rel=1e-12)
    assert "-" in pooled.summary()
    with pytest.raises(InputError, match="longest replicate"):
        pooled_wvar(xs, FREQ, levels=13)


@pytest.mark.slow
def test_calibrate_split_gaps_pools_the_segments(tmp_path: Path, capsys) -> None:
    """A recording with a gap: calibrate --split-gaps fits one model to both segments' pooled WV
    (the same as select on the segments as replicates) and recovers the simulated truth."""
    from stochmod.cli import main

    model = stochmod.model_from_spec(TRUE, FREQ)
    x = model.simulate(2**15, rng=41)
    keep = np.r_[0:12000, 13000:2**15]  # 10 s missing from t = 120 s
    path = tmp_path / "gap.csv"
    np.savetxt(path, np.column_stack([keep / FREQ, x[keep]]), delimiter=",",
               header="time,gyro_x", comments="")
    out = tmp_path / "cal"
    argv = ["calibrate", "--assume-si", str(path), "--candidates", "WN", "GM+WN", "--out", str(out),
            "--no-plots", "--json"]
    assert main(argv) == 2
    assert "--split-gaps" in capsys.readouterr().err
    assert main([*argv, "--split-gaps"]) == 0
    captured = capsys.readouterr()
    assert "pooling the wavelet variances of 2" in captured.err
    report = __import__("json").loads(captured.out)
    assert report["n"] == keep.size
    assert report["segments"] == [{"start": 0.0, "n": 12000}, {"start": 130.0, "n": 2**15 - 13000}]
    direct = stochmod.select([x[:12000], x[13000:]], FREQ, candidates=["WN", "GM+WN"])
    column = report["columns"]["gyro_x"]
    assert column["name"] == direct.best.model.name == "GM+WN"
    got = np.array([p["value"] for p in column["parameters"]])
    np.testing.assert_allclose(got, direct.best.model.vector(), rtol=1e-6)
    z = (direct.best.model.vector() - model.vector()) / direct.best.std_errors
    assert np.all(np.abs(z) < 4), z


@pytest.mark.slow
def test_jtest_on_pooled_replicates_holds_its_level() -> None:
    """Size of the J-test on pooled fits of the true structure: 40 seeded replicate pairs.

    Under the null the p-values are uniform: the count below 0.05 is Binomial(40, 0.05) (mean 2;
    P(count >= 9) < 0.001) and a Kolmogorov-Smirnov test does not reject uniformity.
    studies/mc_pooled_jtest.py runs the larger study (100 pairs: 5 % and 0 % rejected at the 5 %
    and 1 % levels).
    """
    from scipy import stats

    model = stochmod.model_from_spec(TRUE, FREQ)
    pvalues = []
    for k in range(40):
        fit = stochmod.gmwm([model.simulate(2**14, rng=7 + 2 * k + i) for i in range(2)], "GM+WN", FREQ)
        pvalues.append(fit.jtest.pvalue)
    pvalues = np.array(pvalues)
    assert np.sum(pvalues < 0.05) <= 8, np.sort(pvalues)[:10]
    assert stats.kstest(pvalues, "uniform").pvalue > 0.001
