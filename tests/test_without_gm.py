"""The core names no family: with the GM plugin unregistered, selection and the classical
readings work with the families left, or fail with an error that says what is missing.

The signals are seeded simulations with known coefficients (white noise N, random walk K,
flicker B), so what is still built is checked against its truth.
"""

from __future__ import annotations

import concurrent.futures
import math

import numpy as np
import pytest

import stochmod as sm
from stochmod.empirical.acf import fit_gm_acf
from stochmod.empirical.psd import psd_reading
from stochmod.fit.classical import av_model
from stochmod.fit.classical import acf_model, allan_model, psd_reading_model
from stochmod.core.errors import SpecError, UnknownProcessError
from stochmod.fit.selection import candidate_lattice
from stochmod.fit.lattice import default_families, default_max_counts
from stochmod.plugin.registry import plugin_manager

FS = 100.0


@pytest.fixture
def without_gm():
    """Unregister the plugin that provides GM; register it again afterwards, whatever happens."""
    pm = plugin_manager()
    gm_cls = sm.get_process("GM")
    plugin = next(p for p in pm.get_plugins() if getattr(p, "GM", None) is gm_cls)
    name = pm.get_name(plugin)
    sm.unregister_plugin(plugin)
    try:
        yield
    finally:
        pm.register(plugin, name=name)
        assert sm.get_process("GM") is gm_cls


def _white_plus_walk(seed: int, n: int, n_coef: float, k_coef: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.standard_normal(n) * n_coef * math.sqrt(FS)
            + np.cumsum(rng.standard_normal(n)) * k_coef / math.sqrt(FS))


def _flicker(rng: np.random.Generator, n: int, b_coef: float) -> np.ndarray:
    """Two-sided PSD B^2 / (2 pi |f|) between 1/T and FS/2, by shaping white noise."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / FS)
    psd = np.zeros_like(f)
    psd[1:] = b_coef**2 / (2 * np.pi * f[1:])
    return np.fft.irfft(spec * np.sqrt(psd * FS), n)


def test_the_default_lattice_is_the_families_left(without_gm):
    assert "GM" not in sm.process_names()
    assert default_families() == ("WN", "RW", "QN", "RR")
    assert default_max_counts(default_families()) == {}
    assert len(candidate_lattice()) == 2**4 - 1
    with pytest.raises(UnknownProcessError, match="unknown process family 'GM'"):
        candidate_lattice(("GM", "WN"))


def test_select_works_with_the_families_left(without_gm):
    x = _white_plus_walk(7, 2**15, 1e-3, 1e-4)
    with concurrent.futures.ThreadPoolExecutor(2) as pool:  # workers see this registry
        res = sm.select(x, FS, executor=pool, progress=False)
    assert res.best.model.name == "WN+RW"
    wn, rw = res.best.model.processes
    assert wn.sigma2 == pytest.approx(1e-6 * FS, rel=0.05)  # N^2 fs
    assert rw.sigma2 == pytest.approx(1e-8 / FS, rel=0.5)  # K^2 / fs, a few slow levels
    with pytest.raises(UnknownProcessError, match="'GM'"):
        sm.select(x, FS, families=("GM", "WN"), executor=pool, progress=False)


def test_readings_give_coefficients_and_models_of_the_families_left(without_gm):
    x = _white_plus_walk(8, 400_000, 1e-3, 1e-3)
    reading = sm.allan_reading(x, FS)
    assert set(reading.coefficient_values()) == {"N", "K"}
    model = allan_model(reading)
    assert [p.family for p in model.processes] == ["WN", "RW"]
    assert model.processes[0].sigma2 == pytest.approx(reading.N.value**2 * FS, rel=1e-12)
    assert av_model(x, FS).model == model
    psd_model = psd_reading_model(psd_reading(x, FS))
    assert [p.family for p in psd_model.processes] == ["WN", "RW"]


def test_a_reading_that_needs_gm_names_what_is_missing(without_gm):
    rng = np.random.default_rng(9)
    n = 300_000
    x = rng.standard_normal(n) * 1e-3 * math.sqrt(FS) + _flicker(rng, n, 2e-3)
    reading = sm.allan_reading(x, FS)
    assert {"B", "Tc"} <= set(reading.coefficient_values())  # the reading itself still works
    with pytest.raises(SpecError, match=r"no registered process family is built from the "
                                        r"coefficients \('B', 'Tc'\)"):
        allan_model(reading)
    with pytest.raises(SpecError, match=r"\('B', 'Tc'\)"):
        av_model(x, FS)
    # the PSD's B still has a family when read as flicker above a corner (BI)
    psd = psd_reading(x, FS)
    assert psd.B.value == pytest.approx(2e-3, rel=0.1)
    bi = psd_reading_model(psd, bias="bi")
    assert [p.family for p in bi.processes] == ["WN", "BI"]
    assert bi.processes[1].B == psd.B.value and bi.processes[1].fc == psd.B.f_low
    with pytest.raises(SpecError, match=r"\('B', 'Tc'\)"):
        psd_reading_model(psd, bias_tc=10.0)
    fit = fit_gm_acf(x, FS)
    with pytest.raises(SpecError, match=r"\('rate', 'variance'\)"):
        acf_model(fit)
