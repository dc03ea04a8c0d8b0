"""Classical pipelines (stochmod.fit.classical.pipelines) on seeded simulations with known parameters.

Tolerances: ``|bias| + 4 sd`` of the estimate / truth over 100 seeded replications of the same
case, or the largest deviation seen in them if larger (``python studies/compare_methods.py
--monte-carlo 100``, table in docs/comparison.md); case A is also docs/allan.md's Monte Carlo
case. A bias of the method (the Allan N next to a floor, the matched GM's sigma) is part of the
tolerance, so an improvement never fails a test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import stochmod as sm
from stochmod.core.errors import EstimationError, InputError, SpecError
from stochmod.fit.classical import ar_model, pipelines
from stochmod.empirical.ar_fit import fit_ar
from stochmod.fit.classical.pipelines import (
    acf_gm_model,
    av_model,
    avwd_model,
    compare_models,
    denoised_ar_model,
    psd_model,
)

FS = 100.0
N_SAMPLES = 1_000_000

# Monte Carlo (100 replications, seeds 2000-2099, N = 1e6, 100 Hz): mean, sd, min, max of
# estimate / truth (studies/compare_methods.py --monte-carlo 100; docs/comparison.md).
MC_A = {
    "AV N": (1.0081, 0.0009, 1.0059, 1.0108), "AV K": (1.0178, 0.0567, 0.8076, 1.1511),
    "AV sigma_GM matched": (0.8754, 0.0105, 0.8463, 0.8979),
    "PSD N": (0.9701, 0.0244, 0.9340, 1.0049),
    "GMWM N": (1.0000, 0.0008, 0.9980, 1.0016), "GMWM Tc": (1.0072, 0.0375, 0.9093, 1.1237),
    "GMWM sigma": (1.0023, 0.0136, 0.9579, 1.0357), "GMWM K": (0.9917, 0.0406, 0.8833, 1.0895),
    "AVWD min ratio tau>=2 limit": (0.9913, 0.0004, 0.9903, 0.9922),
}
MC_B = {
    "AV N": (1.0377, 0.0025, 1.0313, 1.0412), "AV B": (0.9845, 0.0290, 0.9309, 1.0775),
    "AV K": (1.0692, 0.1080, 0.7247, 1.3205),
    "PSD N": (0.9981, 0.0028, 0.9949, 1.0222), "PSD B": (1.0480, 0.0154, 0.9953, 1.0781),
    "GMWM N": (1.0000, 0.0009, 0.9978, 1.0022), "GMWM B": (1.0003, 0.0085, 0.9808, 1.0207),
    "GMWM K": (1.0131, 0.0891, 0.7837, 1.2431),
    "AVWD min ratio tau>=2 limit": (0.9867, 0.0005, 0.9856, 0.9880),
}
MC_C = {"ACF LS Tc": (0.9977, 0.0189, 0.9499, 1.0483),
        "ACF LS sigma2": (0.9991, 0.0145, 0.9707, 1.0323)}


def within(value: float, key: str, table: dict[str, tuple[float, float, float, float]]) -> bool:
    """|value - 1| <= max(|bias| + 4 sd, the largest |estimate - 1| of the Monte Carlo)."""
    mean, sd, low, high = table[key]
    return abs(value - 1.0) <= max(abs(mean - 1.0) + 4.0 * sd, abs(low - 1.0), abs(high - 1.0))


def spec_a() -> str:
    """Case A: WN(N = 3e-4) + GM(sigma = 1e-3, Tc = 1 s) + RW(K = 3e-4), u = rad/s."""
    return f"WN(sigma2={(3e-4) ** 2 * FS!r})+GM(beta=1.0, sigma2=1e-6)+RW(sigma2={(3e-4) ** 2 / FS!r})"


def spec_b() -> str:
    """Case B: WN(N = 1e-3) + BI(B = 2e-3, fc = 1e-6 Hz) + RW(K = 5e-4)."""
    return f"WN(sigma2={(1e-3) ** 2 * FS!r})+BI(B=2e-3, fc=1e-6)+RW(sigma2={(5e-4) ** 2 / FS!r})"


def spec_c() -> str:
    """Case C: GM(sigma = 1e-3, Tc = 1 s) + WN(N = 1e-4) (white variance = GM variance)."""
    return f"GM(beta=1.0, sigma2=1e-6)+WN(sigma2={(1e-4) ** 2 * FS!r})"


@pytest.fixture(scope="module")
def case_a() -> dict:
    x = sm.model_from_spec(spec_a(), FS).simulate(N_SAMPLES, 1)
    out = {"x": x, "AV": av_model(x, FS), "AVWD": avwd_model(x, FS, f_limit=0.4),
           "PSD": psd_model(x, FS), "WD+AR(3)": denoised_ar_model(x, FS, 3),
           "Burg AR(3)": ar_model(fit_ar(x, FS, 3), FS), "GMWM": sm.gmwm(x, "WN+GM+RW", FS)}
    return out


@pytest.fixture(scope="module")
def case_b() -> dict:
    x = sm.model_from_spec(spec_b(), FS).simulate(N_SAMPLES, 1)
    return {"x": x, "AV": av_model(x, FS), "AVWD": avwd_model(x, FS, level=7),
            "PSD": psd_model(x, FS), "WD+AR(3)": denoised_ar_model(x, FS, 3),
            "Burg AR(3)": ar_model(fit_ar(x, FS, 3), FS), "GMWM": sm.gmwm(x, "WN+BI+RW", FS)}


def _physical(model: sm.Model) -> dict[str, float]:
    return {f"{label}.{k}": v.value for label, p in zip(model.labels, model.processes)
            for k, v in p.physical(model.freq).items()}


# ----------------------------------------------------------------------------- case A


def test_av_model_recovers_n_k_and_builds_18av(case_a):
    av = case_a["AV"]
    r = av.reading
    assert within(r.N.value / 3e-4, "AV N", MC_A)
    assert within(r.K.value / 3e-4, "AV K", MC_A)
    assert [p.family for p in av.model.processes] == ["WN", "GM", "RW"]
    phys = _physical(av.model)
    # the model carries the reading: N, K exactly; Quinchia's GM: beta = 1/Tc, sigma = 0.664 B
    assert phys["WN.N"] == pytest.approx(r.N.value, rel=1e-12)
    assert phys["RW.K"] == pytest.approx(r.K.value, rel=1e-12)
    assert phys["GM.Tc"] == pytest.approx(r.Tc, rel=1e-12)
    assert phys["GM.sigma"] == pytest.approx(math.sqrt(2 * math.log(2) / math.pi) * r.B.value,
                                             rel=1e-12)


def test_av_model_matched_gm_sigma_within_the_readings_spread(case_a):
    # The AV cannot identify a GM (Stebler 2014 Sec. II); the matched GM gives 0.875 sigma.
    matched = av_model(case_a["x"], FS, gm="matched")
    assert within(_physical(matched.model)["GM.sigma"] / 1e-3, "AV sigma_GM matched", MC_A)


def test_avwd_is_the_av_model_with_the_input_denoised(case_a):
    av, wd = case_a["AV"], case_a["AVWD"]
    assert wd.model == av.model  # Quinchia: the parameters of Sec. 5.5 (raw AV) are used
    assert wd.level == 7  # f_limit 0.4 Hz -> freq / 2^(k+1) <= 0.4 -> k = 7 (Table 7: 0.39 Hz)
    assert wd.band_limit == pytest.approx(100 / 2**8)
    assert wd.tau_limit == pytest.approx(2.56)
    assert np.array_equal(wd.denoised.denoising.signal,
                          sm.denoise(case_a["x"], "db4", level=7))
    tau, ratio, inside = wd.long_term_check()
    assert tau[0] == pytest.approx(2.56)
    # Fig. 17: above the limit the de-noised AV follows the raw one
    assert within(ratio[tau >= 2 * wd.tau_limit].min(), "AVWD min ratio tau>=2 limit", MC_A)
    assert inside[tau >= 4 * wd.tau_limit].all()
    assert "18AVWD" in wd.summary()


def test_psd_model_recovers_n_and_carries_the_reading(case_a):
    ps = case_a["PSD"]
    r = ps.reading
    assert within(r.N.value / 3e-4, "PSD N", MC_A)
    phys = _physical(ps.model)
    assert phys["WN.N"] == pytest.approx(r.N.value, rel=1e-12)
    assert [p.family for p in ps.model.processes] == (
        ["WN"] + ["GM"] * (r.B is not None) + ["RW"] * (r.K is not None))
    if r.K is not None:
        assert phys["RW.K"] == pytest.approx(r.K.value, rel=1e-12)


def test_gmwm_recovers_every_parameter_case_a(case_a):
    phys = _physical(case_a["GMWM"].model)
    assert within(phys["WN.N"] / 3e-4, "GMWM N", MC_A)
    assert within(phys["GM.Tc"] / 1.0, "GMWM Tc", MC_A)
    assert within(phys["GM.sigma"] / 1e-3, "GMWM sigma", MC_A)
    assert within(phys["RW.K"] / 3e-4, "GMWM K", MC_A)


def test_compare_models_gmwm_smallest_case_a(case_a):
    models = {k: v for k, v in case_a.items() if k != "x"}
    comp = compare_models(case_a["x"], FS, models)
    assert comp.best.name == "GMWM"
    assert comp["GMWM"].objective == pytest.approx(case_a["GMWM"].objective, rel=1e-10)
    assert comp.ranked()[0].name == "GMWM"
    assert comp.summary().splitlines()[3].split()[1] == "GMWM"
    # the objective is eq. 20 with Omega = diag(1 / (2 nu^2 / max(M_j / 2^j, 1)))
    emp = sm.wvar(case_a["x"], FS)
    av = case_a["AV"].model.wv(emp.wv.size)
    eta = np.maximum(emp.n_coef / 2.0**emp.levels, 1.0)
    expected = float(np.sum((emp.wv - av) ** 2 * eta / (2 * emp.wv**2)))
    assert comp["AV"].objective == pytest.approx(expected, rel=1e-12)


# ----------------------------------------------------------------------------- case B


def test_av_and_psd_on_bias_instability(case_b):
    r = case_b["AV"].reading
    assert within(r.N.value / 1e-3, "AV N", MC_B)
    assert within(r.B.value / 2e-3, "AV B", MC_B)
    assert within(r.K.value / 5e-4, "AV K", MC_B)
    ps = case_b["PSD"]
    assert within(ps.reading.N.value / 1e-3, "PSD N", MC_B)
    assert within(ps.reading.B.value / 2e-3, "PSD B", MC_B)
    # the PSD gives no correlation time: the GM of B takes the Allan reading's (Table 5)
    assert ps.bias_tc == r.Tc
    gm = next(p for p in ps.model.processes if p.family == "GM")
    assert 1.0 / gm.beta == pytest.approx(r.Tc, rel=1e-12)


def test_avwd_fig17_on_bias_instability(case_b):
    tau, ratio, inside = case_b["AVWD"].long_term_check()
    limit = case_b["AVWD"].tau_limit
    assert within(ratio[tau >= 2 * limit].min(), "AVWD min ratio tau>=2 limit", MC_B)
    assert inside[tau >= 4 * limit].all()


def test_gmwm_recovers_every_parameter_case_b(case_b):
    model = case_b["GMWM"].model
    procs = {p.family: p for p in model.processes}
    assert within(math.sqrt(procs["WN"].sigma2 / FS) / 1e-3, "GMWM N", MC_B)
    assert within(procs["BI"].B / 2e-3, "GMWM B", MC_B)
    assert within(math.sqrt(procs["RW"].sigma2 * FS) / 5e-4, "GMWM K", MC_B)


def test_compare_models_gmwm_smallest_case_b(case_b):
    comp = compare_models(case_b["x"], FS, {k: v for k, v in case_b.items() if k != "x"})
    assert comp.best.name == "GMWM"
    # what each classical model misses, level by level: WD+AR(3) has no white noise left
    assert comp["WD+AR(3)"].ratio[0] < 1e-3
    assert comp["WD+AR(3)"].outside[0]


# ----------------------------------------------------------------------------- case C


@pytest.fixture(scope="module")
def case_c() -> np.ndarray:
    return sm.model_from_spec(spec_c(), FS).simulate(N_SAMPLES, 1)


def test_acf_gm_model_least_squares_recovers_the_gm(case_c):
    ls = acf_gm_model(case_c, FS, use_ls=True)
    phys = _physical(ls.model)
    assert within(phys["GM.Tc"] / 1.0, "ACF LS Tc", MC_C)
    assert within(phys["GM.sigma"] ** 2 / 1e-6, "ACF LS sigma2", MC_C)
    assert ls.denoising is None
    # the 1/e reading takes the lag-0 variance, white noise included (Quinchia eq. 11)
    raw = acf_gm_model(case_c, FS)
    assert raw.model.processes[0].sigma2 == pytest.approx(np.var(case_c), rel=1e-9)


def test_denoised_ar_model_is_closer_than_raw_burg_but_describes_the_denoised_signal(case_c):
    wd = denoised_ar_model(case_c, FS, 1, level=3)
    raw = ar_model(fit_ar(case_c, FS, 1), FS)
    tc_wd = wd.model.processes[0].physical(FS)["Tc"].value
    tc_raw = raw.processes[0].physical(FS)["Tc"].value
    # Section 5.3's point: de-noising first reduces Burg's white-noise bias of Tc a lot ...
    assert abs(math.log(tc_wd)) < abs(math.log(tc_raw)) / 3
    # ... but over-corrects: the de-noised signal is smoother than the GM (Monte Carlo: 2.09
    # +- 0.03 of the truth; raw Burg: 0.0142)
    assert tc_wd > 1.0
    # ... and the AR(1) is the de-noised signal's: its variance is that signal's
    y = wd.denoising.signal
    assert wd.model.autocovariance(np.array([0]))[0] == pytest.approx(np.var(y), rel=0.01)
    assert wd.denoising.level == 3


# ----------------------------------------------------------------------------- errors


def test_avwd_needs_exactly_one_of_level_and_f_limit():
    x = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(InputError, match="level"):
        avwd_model(x, FS)
    with pytest.raises(InputError, match="level"):
        avwd_model(x, FS, level=3, f_limit=1.0)


def test_denoise_options_are_checked_and_passed_on():
    x = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(InputError, match="thresh"):
        acf_gm_model(x, FS, level=3, denoise={"thresh": 1.0})
    ar = denoised_ar_model(x, FS, 1, level=3, denoise={"wavelet": "sym8", "mode": "hard"})
    assert (ar.denoising.wavelet, ar.denoising.mode, ar.denoising.level) == ("sym8", "hard", 3)
    expected = sm.denoise(x, "sym8", level=3, mode="hard")
    assert np.array_equal(ar.denoising.signal, expected)
    assert ar.ar.phi == pytest.approx(fit_ar(expected, FS, 1).phi, rel=1e-12)


def test_av_model_raises_when_nothing_is_identified():
    x = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(EstimationError):
        av_model(x, FS, terms=("R",))


def test_psd_model_without_tc_raises(monkeypatch, case_b):
    class NoFlat:
        Tc = None

    monkeypatch.setattr(pipelines, "allan_reading", lambda *a, **k: NoFlat())
    with pytest.raises(EstimationError, match="bias_tc"):
        psd_model(case_b["x"], FS)
    assert psd_model(case_b["x"], FS, bias_tc=2.0).bias_tc == 2.0


def test_compare_models_bad_input():
    x = np.random.default_rng(1).standard_normal(2**14)
    wn = sm.model_from_spec("WN(sigma2=1.0)", FS)
    with pytest.raises(InputError, match="non-empty"):
        compare_models(x, FS, {})
    with pytest.raises(InputError, match="bound to 50"):
        compare_models(x, FS, {"wn": wn.bind(50.0)})
    with pytest.raises(SpecError, match="free parameters"):
        compare_models(x, FS, {"free": "WN+GM"})
    with pytest.raises(InputError, match="Model, a Process"):
        compare_models(x, FS, {"bad": 3.0})
    with pytest.raises(InputError, match="freq"):
        compare_models(x, None, {"wn": wn})
    with pytest.raises(InputError, match="levels"):
        compare_models(sm.wvar(x, FS, levels=5), FS, {"wn": wn}, levels=6)


def test_compare_models_on_a_wavelet_variance_and_unbound_specs():
    x = np.random.default_rng(2).standard_normal(2**15) * 2.0
    emp = sm.wvar(x, FS)
    models = {"spec": "WN(sigma2=4.0)", "process": sm.WN(sigma2=4.0),
              "dict": {"processes": [{"family": "WN", "params": {"sigma2": 4.0}}]}}
    from_signal = compare_models(x, FS, models)
    from_wv = compare_models(emp, None, models)
    assert from_signal.objectives == pytest.approx(from_wv.objectives, rel=1e-15)
    objective = from_signal["spec"].objective
    assert from_signal.objectives == pytest.approx(dict.fromkeys(models, objective), rel=1e-12)
    # white noise's Haar WV is sigma2 / 2^j: the ratios are the data's scatter around it
    nu = 4.0 / 2.0 ** emp.levels
    assert from_signal["spec"].ratio == pytest.approx(nu / emp.wv, rel=1e-12)
    table = from_signal.wv_table()
    assert len(table.splitlines()) == 3 + emp.wv.size
