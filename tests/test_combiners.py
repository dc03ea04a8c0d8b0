"""Redundant-sensor combiners (issue 11): the plugin point, the conformance kit, the first-party
combiners and the seed's experiments (Waegli et al. 2010, eqs. 1-4, 12-13, Table 4).

Truth: seeded simulations of sensors with known signal and known noise levels (errors are
measured against the simulated truth, never against the combiners' own estimates); the closed
forms ``sigma^2 / n`` (eq. 1) and ``(n - 1) / n`` (eq. 4); eq. 2 recomputed by a plain loop;
deliberately broken combiners that the kit must fail.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import stochmod
from stochmod import sdk
from stochmod.plugin.registry import get_combiner
from stochmod.redundant.combination import CombinationResult, as_sensor_array
from stochmod.core.errors import EstimationError, InputError, StochmodError
from stochmod.data.redundant import redundant_gyros
from stochmod.core.tables import format_table
from stochmod.testing import check_combiner

FIRST_PARTY = ("averaged-volatility", "garch", "inverse-variance", "mean")
FAST_GARCH = {"arma": (1, 0), "garch": (1, 1)}
PLUGIN_DIR = Path(__file__).resolve().parents[1] / "docs" / "examples" / "third_party_plugin"


def test_first_party_combiners_are_registered() -> None:
    assert set(FIRST_PARTY) <= set(stochmod.combiner_names())
    for name in FIRST_PARTY:
        comb = get_combiner(name)
        assert comb.name == name and comb.assumes and comb.description
        assert type(comb).__module__.startswith("stochmod_")  # a plugin, not the core
    with pytest.raises(InputError, match="unknown combiner 'nope'.*mean"):
        stochmod.combine(np.zeros((2, 10)), "nope")


@pytest.mark.parametrize("name", FIRST_PARTY)
def test_conformance_kit_passes(name: str) -> None:
    figures = check_combiner(name, rng=11, options=FAST_GARCH if name == "garch" else None)
    assert set(figures) == {"result", "equal_inputs", "permutation", "scale", "nan_refused"}


# ------------------------------------------------------------------ the kit fails broken ones
class _Broken:
    description = "broken on purpose"
    assumes = "nothing"

    def __init__(self, name: str, fault: str):
        self.name, self.fault = name, fault

    def combine(self, x: Any, **options: Any) -> CombinationResult:
        if self.fault != "nan":
            x = as_sensor_array(x)
        else:
            x = np.asarray(x, dtype=float)
        n = x.shape[0]
        w = np.full(x.shape, 1.0 / n)
        if self.fault == "sum":
            w = w * 1.01
        elif self.fault == "position":  # weights tied to the sensor's index, not its data
            w = np.broadcast_to((np.arange(n) + 1.0).reshape((n,) + (1,) * (x.ndim - 1)), x.shape)
            w = w / w.sum(axis=0)
        signal = np.sum(w * x, axis=0) + (0.1 if self.fault == "offset" else 0.0)
        if self.fault == "nan":
            signal = np.nan_to_num(np.nanmean(x, axis=0))
            w = np.full(x.shape, 1.0 / n)
        # a variance that scales as c^2 with the data, except in the "variance" fault
        var = np.full(signal.shape, np.mean(x * x) + (1.0 if self.fault == "variance" else 0.0))
        return CombinationResult(signal=signal, weights=w, variance=var, method=self.name,
                                 assumes=self.assumes)


@pytest.mark.parametrize(("fault", "failing"), [
    ("sum", "result"), ("position", "permutation"), ("offset", "equal_inputs"),
    ("nan", "nan_refused"), ("variance", "scale"),
])
def test_conformance_kit_fails_broken_combiners(fault: str, failing: str) -> None:
    with pytest.raises(AssertionError, match=rf"\[{failing}") as info:
        check_combiner(_Broken(f"broken-{fault}", fault))
    if fault == "position":  # weights tied to position are still scale-equivariant
        assert "[scale]" not in str(info.value)


def test_registry_refuses_bad_and_duplicate_combiners() -> None:
    class Dup:
        @sdk.hookimpl
        def stochmod_combiners(self) -> list[Any]:
            return [_Broken("mean", "sum")]

    class NotOne:
        @sdk.hookimpl
        def stochmod_combiners(self) -> list[Any]:
            return [object()]

    # register_plugin validates the combiners at once and leaves a refused plugin unregistered
    for plugin, match in ((Dup(), "two plugins register a combiner named 'mean'"),
                          (NotOne(), "not a combiner")):
        with pytest.raises(StochmodError, match=match):
            stochmod.register_plugin(plugin)
        assert get_combiner("mean").__module__ == "stochmod_mean"


def test_combine_checks_what_a_combiner_returns() -> None:
    class Plugin:
        @sdk.hookimpl
        def stochmod_combiners(self) -> list[Any]:
            return [_Broken("bad-sum", "sum")]

    plugin = Plugin()
    stochmod.register_plugin(plugin)
    try:
        with pytest.raises(EstimationError, match="sums differ from 1"):
            stochmod.combine(np.random.default_rng(0).standard_normal((3, 50)), "bad-sum")
    finally:
        stochmod.unregister_plugin(plugin)


def test_third_party_median_combiner() -> None:
    sys.path.insert(0, str(PLUGIN_DIR))
    try:
        import stochmod_ma1

        ours = "median" not in stochmod.combiner_names()
        if ours:
            stochmod.register_plugin(stochmod_ma1)
        try:
            check_combiner("median", rng=3)
            rng = np.random.default_rng(1)
            truth = np.sin(np.linspace(0, 20, 5000))
            x = truth + 0.1 * rng.standard_normal((5, 5000))
            x[2] += 50.0  # one faulty sensor: the median ignores it, the mean does not
            med = stochmod.combine(x, "median")
            assert np.std(med.signal - truth) < 0.1
            assert np.mean(np.abs(stochmod.combine(x, "mean").signal - truth)) > 9.0
            assert np.all(med.weights[2] == 0)
        finally:
            if ours:
                stochmod.unregister_plugin(stochmod_ma1)
    finally:
        sys.path.remove(str(PLUGIN_DIR))


# ------------------------------------------------------------------ first-party numbers
def test_mean_of_n_equal_sensors_cuts_noise_by_sqrt_n() -> None:
    rng = np.random.default_rng(2010)
    t = np.arange(200_000) / 100.0
    truth = 0.3 * np.sin(2 * np.pi * 0.2 * t)
    sigma = 0.0201  # rad/s, the seed's averaged MEMS gyro noise
    for n in (2, 4, 9):
        x = truth + sigma * rng.standard_normal((n, t.size))
        res = stochmod.combine(x, "mean")
        ratio = np.std(res.signal - truth) / np.std(x - truth)
        assert ratio == pytest.approx(1 / np.sqrt(n), rel=0.01)  # eq. 1: 50 % for n = 4
        # the estimated variance of the synthetic signal is sigma^2 / n
        assert res.variance[0] == pytest.approx(sigma**2 / n, rel=0.02)
        assert res.noise_reduction == pytest.approx(1 - 1 / np.sqrt(n), abs=1e-12)
        np.testing.assert_allclose(res.weights, 1 / n)


def _eq2_by_loop(x: np.ndarray, T: int) -> np.ndarray:
    """sigma_t^2 of eq. 2 (triads), the window truncated at the record's ends."""
    n, length, axes = x.shape
    r = x - x.mean(axis=0)
    out = np.empty(length)
    for t in range(length):
        lo, hi = max(t - T, 0), min(t + T + 1, length)
        m = hi - lo
        total = 0.0
        for j in range(axes):
            block = r[:, lo:hi, j]
            total += np.sum((block - block.mean()) ** 2)
        out[t] = total / ((m - 1) * n * axes)
    return out


def test_averaged_volatility_is_eq2() -> None:
    x = np.random.default_rng(4).standard_normal((4, 300, 3)) * np.linspace(1, 3, 300)[None, :, None]
    res = stochmod.combine(x, "averaged-volatility", half_window=7)
    sigma2 = _eq2_by_loop(x, 7)
    np.testing.assert_allclose(res.sensor_variance[0, :, 0], sigma2, rtol=1e-10)
    np.testing.assert_allclose(res.variance[:, 1], sigma2 / 4, rtol=1e-10)
    np.testing.assert_allclose(res.signal, x.mean(axis=0), rtol=1e-14)


def test_averaged_volatility_residual_bias_of_eq4() -> None:
    """Residuals from the mean under-estimate the error variance by (n - 1) / n (eq. 4)."""
    n, sigma = 4, 0.02
    x = sigma * np.random.default_rng(5).standard_normal((n, 100_000))
    plain = stochmod.combine(x, "averaged-volatility", half_window=500)
    fixed = stochmod.combine(x, "averaged-volatility", half_window=500, correct_residuals=True)
    assert np.mean(plain.sensor_variance) == pytest.approx(sigma**2 * (n - 1) / n, rel=0.01)
    assert np.mean(fixed.sensor_variance) == pytest.approx(sigma**2, rel=0.01)


def test_inverse_variance_three_cornered_hat_recovers_levels() -> None:
    sig = np.array([1.0, 2.0, 0.5, 1.5]) * 1e-3
    rng = np.random.default_rng(6)
    truth = np.cumsum(rng.standard_normal(200_000)) * 1e-4
    x = truth + sig[:, None] * rng.standard_normal((4, truth.size))
    res = stochmod.combine(x, "inverse-variance")
    np.testing.assert_allclose(res.sensor_variance, sig**2, rtol=0.03)
    optimal = (1 / sig**2) / np.sum(1 / sig**2)
    np.testing.assert_allclose(res.weights[:, 0], optimal, rtol=0.03)
    err = np.var(res.signal - truth)
    assert err == pytest.approx(1 / np.sum(1 / sig**2), rel=0.03)
    assert err < 0.8 * np.var(stochmod.combine(x, "mean").signal - truth)
    with pytest.raises(InputError, match="at least 3 sensors"):
        stochmod.combine(x[:2], "inverse-variance")


def test_inverse_variance_from_models_and_calibrations() -> None:
    freq = 100.0
    specs = [f"WN(sigma2={s})+RW(sigma2=1e-12)" for s in (1e-6, 4e-6, 1e-6)]
    x = np.random.default_rng(7).standard_normal((3, 1000)) * 1e-3
    res = stochmod.combine(x, "inverse-variance", models=[stochmod.model_from_spec(s, freq) for s in specs])
    np.testing.assert_allclose(res.weights[:, 0], [4 / 9, 1 / 9, 4 / 9], rtol=1e-12)
    np.testing.assert_allclose(res.variance, 1 / (1e6 + 2.5e5 + 1e6), rtol=1e-12)
    # tau = 0.04 s is level 3 at 100 Hz: the models' theoretical Haar WV there
    models = [stochmod.model_from_spec(s, freq) for s in specs]
    by_tau = stochmod.combine(x, "inverse-variance", models=models, tau=0.04)
    nu = np.array([m.wv(3)[-1] for m in models])
    np.testing.assert_allclose(by_tau.weights[:, 0], (1 / nu) / np.sum(1 / nu), rtol=1e-12)
    # calibration.json content as `stochmod calibrate` writes it (one per sensor)
    cals = [{"columns": {"gyro_x": {"model": stochmod.model_from_spec(s, freq).to_spec()}}}
            for s in specs]
    from_cal = stochmod.combine(x, "inverse-variance", calibrations=json.loads(json.dumps(cals)))
    np.testing.assert_allclose(from_cal.weights, res.weights, rtol=1e-12)
    with pytest.raises(InputError, match="no white-noise component"):
        stochmod.combine(x, "inverse-variance", models=["RW(sigma2=1e-12)"] * 3, freq=freq)
    with pytest.raises(InputError, match="2 model"):
        stochmod.combine(x, "inverse-variance", models=models[:2])


@pytest.mark.slow
def test_garch_weighting_keeps_the_error_flat_as_the_perturbation_grows() -> None:
    """The shape of Table 4: the weighted synthetic barely moves with a, the mean's error grows."""
    rows, std = [], {}
    for a in (0, 5, 10):
        x, truth = redundant_gyros(a)
        for name in FIRST_PARTY:
            res = stochmod.combine(x, name)
            err = res.signal - truth
            std[name, a] = float(np.std(err))
            rows.append([a, name, std[name, a], float(np.sqrt(np.mean(res.variance)))])
    print(format_table(["a", "combiner", "error std [rad/s]", "estimated std [rad/s]"], rows))
    growth = {name: std[name, 10] / std[name, 0] for name in FIRST_PARTY}
    assert growth["mean"] > 2.0  # seed: 0.0103 -> 0.0262 rad/s
    assert growth["garch"] < 1.6  # seed: 0.0088 -> 0.0112 rad/s
    assert growth["garch"] < 0.7 * growth["mean"]
    for a in (0, 5, 10):  # the noisier sensor is down-weighted even at a = 0
        assert std["garch", a] < 0.75 * std["mean", a]
    assert std["garch", 10] < 0.5 * std["mean", 10]
    # averaged volatility keeps the mean's signal (it cannot weight sensors: Section 6)
    assert std["averaged-volatility", 10] == pytest.approx(std["mean", 10], rel=1e-12)


def test_result_summary_and_bad_input() -> None:
    x, _ = redundant_gyros(5.0, length=3000)
    res = stochmod.combine(x, "garch", **FAST_GARCH)
    text = res.summary()
    assert "garch" in text and "GARCH(1,1)" in text and "ARMA(1,0)" in text and "sensor 3" in text
    assert len(res.sensors) == 4
    for bad, match in ((np.zeros((1, 100)), "at least 2"), (np.zeros((3, 10, 2)), "shape"),
                       (np.zeros(100), "shape")):
        with pytest.raises(InputError, match=match):
            stochmod.combine(bad, "mean")
    with pytest.raises(InputError, match="no options"):
        stochmod.combine(x, "mean", window=3)
    with pytest.raises(InputError, match="pair"):
        stochmod.combine(x, "garch", arma=3)


def test_garch_workers_give_the_serial_result() -> None:
    """The per-sensor fits in 2 processes (automatic orders, triads) equal the serial run."""
    x, _ = redundant_gyros(5.0, length=2000)
    triads = np.stack([redundant_gyros(a, length=2000, seed=20 + a)[0] for a in (0, 5, 10)], axis=-1)
    serial = stochmod.combine(triads, "garch")
    # some series grow past (1, 1): the pool's level-by-level growth is exercised
    assert any(sum(s.garch.order) > 2 for s in serial.sensors)
    parallel = stochmod.combine(triads, "garch", workers=2)
    for field in ("signal", "weights", "variance", "sensor_variance"):
        np.testing.assert_array_equal(getattr(parallel, field), getattr(serial, field))
    assert parallel.info == serial.info
    for a, b in zip(parallel.sensors, serial.sensors):
        assert (a.sensor, a.axis, a.arma.order, a.garch.order) == (b.sensor, b.axis, b.arma.order, b.garch.order)
        np.testing.assert_array_equal(a.garch.params, b.garch.params)
    fixed = [stochmod.combine(triads, "garch", workers=w, **FAST_GARCH) for w in (None, 2)]
    np.testing.assert_array_equal(fixed[0].signal, fixed[1].signal)
    with pytest.raises(InputError, match="workers"):
        stochmod.combine(x, "garch", workers=0, **FAST_GARCH)
