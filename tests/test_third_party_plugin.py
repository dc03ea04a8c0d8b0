"""The example third-party plugin (docs/examples/third_party_plugin, family MA1) works with no
change to the core, registered at run time.

Truth: the closed form of the MA(1) Haar wavelet variance derived below from block sums of the
innovations (independent of the core's kernel-weighted autocovariance sum that MA1 relies
on); the MA(1) autocovariance through the state-space block (H Phi^k P0 H'); seeded Monte
Carlo means within their standard error; the conformance kit.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.core.errors import DomainError, InputError, SpecError
from stochmod.fit.weighting_plugins import get_weighting, weighting_names
from stochmod.empirical.wavelet_variance import wvar
from stochmod.testing import check_family, check_weighting

FREQ = 100.0
PLUGIN_DIR = Path(__file__).resolve().parents[1] / "docs" / "examples" / "third_party_plugin"


def _installed() -> bool:
    entry_points = importlib.metadata.entry_points(group="stochmod")
    return any(ep.value == "stochmod_ma1" for ep in entry_points)


@contextmanager
def _registered() -> Iterator[ModuleType]:
    """Import stochmod_ma1 from its folder and register it; undo both on exit."""
    sys.path.insert(0, str(PLUGIN_DIR))
    module = importlib.import_module("stochmod_ma1")
    ours = "MA1" not in stochmod.process_names()  # else already installed via its entry point
    if ours:
        stochmod.register_plugin(module)
    try:
        yield module
    finally:
        if ours:
            stochmod.unregister_plugin(module)
        sys.path.remove(str(PLUGIN_DIR))


@pytest.fixture(scope="module")
def ma1() -> Iterator[ModuleType]:
    with _registered() as module:
        yield module


def exact_ma1_wv(theta: float, sigma2: float, levels: int) -> np.ndarray:
    """Haar WV of X_t = e_t + theta e_{t-1}, derived from the innovations.

    The level-j coefficient is (A - B) / (2m), A and B the sums of X over two adjacent blocks
    of m samples. In innovations: A - B = theta e_0 + (1 + theta)(e_1 + ... + e_{m-1})
    + (1 - theta) e_m - (1 + theta)(e_{m+1} + ... + e_{2m-1}) - e_{2m}, so
    var = sigma2 [theta^2 + 2 (m - 1)(1 + theta)^2 + (1 - theta)^2 + 1]
        = sigma2 [2 m (1 + theta^2) + (4 m - 6) theta], divided by 4 m^2.
    """
    m = 2.0 ** np.arange(levels)
    return sigma2 * (2 * m * (1 + theta**2) + (4 * m - 6) * theta) / (4 * m * m)


def test_registration_is_undone(ma1: ModuleType) -> None:
    assert stochmod.get_process("MA1") is ma1.MA1
    assert ma1.MA1.wv is stochmod.Process.wv  # no analytic WV: the core's fallback is used
    if not _installed():
        stochmod.unregister_plugin(ma1)
        try:
            assert "MA1" not in stochmod.process_names()
            assert "relative" not in weighting_names()
        finally:
            stochmod.register_plugin(ma1)
    assert "MA1" in stochmod.process_names()


def test_spec_string_and_dict_round_trip(ma1: ModuleType) -> None:
    free = stochmod.model_from_spec("MA1+WN", FREQ)
    assert free.name == "MA1+WN" and free.param_names == ("MA1.theta", "MA1.sigma2", "WN.sigma2")
    model = free.with_vector([-0.3, 2.0, 0.5])
    spec = json.loads(json.dumps(model.to_spec()))
    assert spec == {"processes": [{"family": "MA1", "params": {"theta": -0.3, "sigma2": 2.0}},
                                  {"family": "WN", "params": {"sigma2": 0.5}}], "freq": FREQ}
    assert stochmod.model_from_spec(spec) == model
    assert stochmod.model_from_spec("MA1(theta=-0.3, sigma2=2.0) + WN(sigma2=0.5)", FREQ) == model


@settings(max_examples=60, deadline=None)
@given(theta=st.floats(-1, 1, exclude_min=True, exclude_max=True),
       sigma2=st.floats(-8, 8).map(lambda e: 10.0**e),
       wn=st.floats(-8, 8).map(lambda e: 10.0**e),
       levels=st.integers(1, 18))
def test_composer_wv_equals_the_closed_form(ma1: ModuleType, theta: float, sigma2: float, wn: float,
                                            levels: int) -> None:
    model = stochmod.model_from_spec({"processes": [
        {"family": "MA1", "params": {"theta": theta, "sigma2": sigma2}},
        {"family": "WN", "params": {"sigma2": wn}}]}, FREQ)
    exact = exact_ma1_wv(theta, sigma2, levels) + wn / 2.0 ** np.arange(1, levels + 1)
    # the closed form itself cancels near theta = -1 (it is a difference of O(sigma2) terms)
    np.testing.assert_allclose(model.wv(levels), exact, rtol=1e-12, atol=1e-15 * (sigma2 + wn))


def test_simulation_matches_the_theoretical_wv(ma1: ModuleType) -> None:
    model = stochmod.model_from_spec("MA1(theta=0.6, sigma2=2.0) + WN(sigma2=0.3)", FREQ)
    reps, n, levels = 40, 2**12, 7
    est = np.array([wvar(model.simulate(n, g), FREQ, levels=levels).wv
                    for g in np.random.default_rng(8).spawn(reps)])
    mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(mean - model.wv(levels)) < 4.5 * se)
    np.testing.assert_array_equal(model.simulate(50, 3),
                                  model.simulate(50, np.random.default_rng(3)))


def test_augment_carries_the_ma1_autocovariance(ma1: ModuleType) -> None:
    theta, sigma2, wn = 0.4, 2.0, 0.5
    model = stochmod.model_from_spec(f"MA1(theta={theta}, sigma2={sigma2}) + WN(sigma2={wn})", FREQ)
    aug = model.augment()
    assert aug.state_names == ("MA1.e", "MA1.e_prev")
    assert aug.white_var == wn
    acvf = [aug.H @ np.linalg.matrix_power(aug.Phi, k) @ aug.P0 @ aug.H for k in range(3)]
    np.testing.assert_allclose(acvf, [sigma2 * (1 + theta**2), sigma2 * theta, 0.0], rtol=1e-15)
    three = model.augment(3 / FREQ)  # the shift is nilpotent: after 2 steps both states are new
    np.testing.assert_array_equal(three.Phi, np.zeros((2, 2)))
    np.testing.assert_allclose(three.Q, sigma2 * np.eye(2), rtol=1e-15)
    with pytest.raises(InputError, match="whole multiple"):
        model.augment(1.5 / FREQ)


def test_start_recovers_the_parameters_from_an_exact_wv(ma1: ModuleType) -> None:
    for theta in (-0.8, -0.2, 0.0, 0.45, 0.9):
        guess = ma1.MA1().start(exact_ma1_wv(theta, 3.0, 6), FREQ)
        assert guess.theta == pytest.approx(theta, abs=1e-12)
        assert guess.sigma2 == pytest.approx(3.0, rel=1e-12)


def test_physical_view(ma1: ModuleType) -> None:
    phys = ma1.MA1(theta=0.5, sigma2=4.0).physical(FREQ)
    assert phys["sigma"].value == 2.0
    # low-frequency PSD sigma2 (1 + theta)^2 / freq equals the white density N^2
    low = ma1.MA1(theta=0.5, sigma2=4.0).psd(np.array([0.0]), FREQ)[0]
    assert phys["N"].value ** 2 == pytest.approx(low, rel=1e-14)


def test_conformance_kit_passes(ma1: ModuleType) -> None:
    report = check_family(ma1.MA1, freq=FREQ, rng=20240611)
    report.raise_if_failed()
    # MA(1) is built from no classical reading and keeps the base class's vectorised rows:
    # only the ieee952 and wv_rows checks do not apply
    assert report.passed == tuple(c for c in report.ran if c not in ("ieee952", "wv_rows"))
    assert set(report.skipped) == {"ieee952", "wv_rows"}
    assert report.figures["wv_fallbacks"]["autocovariance_rel_error"] == 0.0
    assert report.figures["wv_jacobian"]["analytic"] is False


def test_bad_input_raises(ma1: ModuleType) -> None:
    for theta in (1.0, -1.0, 1.5, math.nan):
        with pytest.raises(DomainError, match="theta"):
            ma1.MA1(theta=theta, sigma2=1.0)
    with pytest.raises(SpecError, match="free"):
        ma1.MA1(theta=0.5).autocovariance([0], FREQ)
    with pytest.raises(InputError, match="rng"):
        ma1.MA1.example(FREQ).simulate(10, FREQ, None)
    with pytest.raises(InputError, match="levels 1 and 2"):
        ma1.MA1().start(np.array([1.0]), FREQ)


def test_the_relative_weighting_gives_the_closed_form_white_noise_estimate(ma1: ModuleType) -> None:
    assert get_weighting("relative") is ma1.RELATIVE
    x = np.random.default_rng(4).normal(0.0, 3.0, 2**13)
    emp = wvar(x, FREQ)
    fit = stochmod.gmwm(x, "WN", FREQ, weighting="relative")
    assert fit.weighting == "relative"
    np.testing.assert_allclose(fit.omega, np.diag(emp.wv**-2.0), rtol=1e-15)
    # eq. 20 with Omega = diag(nu^-2) is sum_j (1 - s2 a_j)^2 with a_j = 2^-j / nu_j
    a = 2.0**-emp.levels / emp.wv
    assert fit.model.vector()[0] == pytest.approx(a.sum() / (a * a).sum(), rel=1e-8)
    assert fit.objective == pytest.approx(np.sum((1 - fit.model_wv() / emp.wv) ** 2), rel=1e-10)


def test_the_relative_weighting_passes_the_conformance_kit(ma1: ModuleType) -> None:
    figures = check_weighting(ma1.RELATIVE, "MA1(theta=0.4, sigma2=2.0) + RW(sigma2=1e-4)", FREQ, rng=3)
    assert figures["registered"] and figures["scale_rel_error"] < 1e-12


def test_third_party_reader_is_dispatched_and_conforms(ma1: ModuleType, tmp_path: Path) -> None:
    from stochmod.io.recording import read_recording
    from stochmod.plugin.registry import readers
    from stochmod.testing import check_reader

    rng = np.random.default_rng(9)
    t, x = np.arange(30) / 50.0, rng.normal(size=(30, 2))
    lines = [json.dumps({"units": {"gx": "deg/s"}})]
    lines += [json.dumps({"t": float(ti), "gx": float(a), "az": float(b)}) for ti, (a, b) in zip(t, x)]
    path = tmp_path / "imu.jsonl"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.data, x)  # json round-trips float64 exactly (repr)
    assert rec.columns == ("gx", "az") and rec.units == ("deg/s", None)
    assert rec.freq == pytest.approx(50.0, rel=1e-9)
    np.testing.assert_allclose(rec.to_si().data[:, 0], x[:, 0] * math.pi / 180.0, rtol=1e-15)
    assert check_reader(readers()["jsonl"], path, expected=x)["has_time"]
    with pytest.raises(InputError, match=r"line 3 has keys \['gx', 't'\]"):
        bad = tmp_path / "bad.jsonl"
        bad.write_text(lines[1] + "\n" + lines[2] + "\n" + json.dumps({"t": 1.0, "gx": 0.0}) + "\n")
        read_recording(bad)
