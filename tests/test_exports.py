"""stochmod.output.exports: Kalibr / OpenVINS / pyins / stochmod-nav configurations from final models.

Every exported number is checked against an independent computation: N = sqrt(sigma2_WN / fs),
K = sqrt(sigma2_RW fs) from the canonical per-sample values (``model.to_spec()``); the model's
Allan variance at every averaging factor m against closed forms (a first-order GM through
``haar_wv_geometric`` and the AR(1) block-sum variance, white noise ``s2 / m``, random walk
``s2 (2 m^2 + 1) / (6 m)``, quantization ``3 Q2 / m^2``, AR(2) by the Haar sum over
statsmodels' autocovariance) and, at dyadic m, against twice the families' own wavelet
variance; the exported pair against the bound it states (at every m of the range) and
against a brute-force scan of the minimax ratio.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from statsmodels.tsa.arima_process import arma_acovf

import stochmod
from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.core.geometric import haar_wv_geometric
from stochmod.core.theory import haar_kernel
from stochmod.fit.gmwm import gmwm
from stochmod.io.calibration import Calibration
from stochmod.output.exports import (
    avar_bound,
    avar_grid,
    component_avar,
    default_horizon,
    envelope_avar,
    exports_from_calibration,
    header_lines,
    kalibr_yaml,
    noise_terms,
    openvins_yaml,
    pyins_parameters,
    stochmod_nav_config,
)

FS = 100.0
N = 2**15


def _wn_rw(n_density: float, k: float) -> stochmod.Model:
    return stochmod.model_from_spec(
        {"processes": [{"family": "WN", "params": {"sigma2": n_density**2 * FS}},
                       {"family": "RW", "params": {"sigma2": k**2 / FS}}]}, FS)


def _model(*procs: dict, freq: float = FS) -> stochmod.Model:
    return stochmod.model_from_spec({"processes": list(procs)}, freq)


def _gm(beta: float, sigma2: float) -> dict:
    return {"family": "GM", "params": {"beta": beta, "sigma2": sigma2}}


def _wn(sigma2: float) -> dict:
    return {"family": "WN", "params": {"sigma2": sigma2}}


def _rw(sigma2: float) -> dict:
    return {"family": "RW", "params": {"sigma2": sigma2}}


TRUTH = {"gyro_x": (3e-3, 4e-5), "accel_x": (2e-3, 5e-4)}  # (N, K) in SI


@pytest.fixture(scope="module")
def fits():
    return {col: gmwm(_wn_rw(*nk).simulate(N, rng=11 + i), "WN+RW", FS)
            for i, (col, nk) in enumerate(TRUTH.items())}


def _params(model, family):
    return next(p["params"] for p in model.to_spec()["processes"] if p["family"] == family)


# ---------------------------------------------------------------- the model's Allan variance
def _gm_avar_closed(beta: float, sigma2: float, freq: float, m: np.ndarray) -> np.ndarray:
    """AR(1) of variance sigma2, phi = exp(-beta/fs): the block-sum variance
    ``V(n) = sigma2 [n (1+phi)/(1-phi) - 2 phi (1-phi^n)/(1-phi)^2]`` and
    ``AVAR = (4 V(m) - V(2m)) / (2 m^2)``."""
    u = beta / freq
    phi, one = math.exp(-u), -math.expm1(-u)

    def V(n):
        return sigma2 * (n * (1 + phi) / one + 2 * phi * np.expm1(-n * u) / one**2)

    m = m.astype(float)
    return (4 * V(m) - V(2 * m)) / (2 * m * m)


def test_component_avar_against_closed_forms_at_every_m():
    m = np.arange(1, 3001)
    for beta, sigma2 in ((0.05, 4e-6), (300.0, 1e-4), (1e-4, 2e-8)):
        gm = _model(_gm(beta, sigma2)).processes[0]
        ours = component_avar(gm, FS, m)
        assert ours == pytest.approx(_gm_avar_closed(beta, sigma2, FS, m), rel=1e-5)
        geometric = 2 * sigma2 * haar_wv_geometric(-beta / FS, m)  # AVAR = 2 Haar WV
        assert ours == pytest.approx(geometric, rel=1e-10)
    wn, rw, qn = _model(_wn(2.5e-5), _rw(3e-11), {"family": "QN", "params": {"Q2": 4e-7}}).processes
    mf = m.astype(float)
    assert component_avar(wn, FS, m) == pytest.approx(2.5e-5 / mf, rel=1e-12)
    assert component_avar(rw, FS, m, "rad/s") == pytest.approx(3e-11 * (2 * mf**2 + 1) / (6 * mf),
                                                               rel=1e-12)
    assert component_avar(qn, FS, m) == pytest.approx(3 * 4e-7 / mf**2, rel=1e-9)


def test_component_avar_is_twice_the_families_wavelet_variance_at_dyadic_m():
    model = _model(_gm(0.02, 1e-6), _wn(1e-4), _rw(1e-12), {"family": "QN", "params": {"Q2": 1e-7}},
                   {"family": "AR", "order": 2, "params": {"phi": [1.2, -0.6], "sigma2": 1e-4}})
    levels = 14
    m = 2 ** np.arange(levels)
    for proc in model.processes:
        assert component_avar(proc, FS, m) == pytest.approx(2 * proc.wv(levels, FS), rel=1e-8)


def test_ar2_avar_against_the_haar_sum_of_statsmodels_autocovariance():
    phi = (1.2, -0.6)  # complex roots: an oscillating autocovariance
    ar = _model({"family": "AR", "order": 2, "params": {"phi": list(phi), "sigma2": 1e-4}}).processes[0]
    acv = arma_acovf(np.r_[1, -np.array(phi)], np.array([1.0]), nobs=4000, sigma2=1e-4)
    m = np.array([1, 2, 3, 5, 7, 12, 100, 333, 1000, 1999])
    brute = [2 * (haar_kernel(k)[0] * acv[0] + 2 * haar_kernel(k)[1:] @ acv[1:2 * k]) for k in m]
    assert component_avar(ar, FS, m) == pytest.approx(brute, rel=1e-8)


def test_envelope_is_kalibrs_sampled_white_noise_plus_random_walk():
    n, k = 3e-3, 4e-5
    m = np.array([1, 2, 10, 1000])
    tau = m / FS
    assert envelope_avar(n, k, FS, m) == pytest.approx(n**2 / tau + k**2 * tau / 3
                                                       + k**2 / (6 * FS**2 * tau), rel=1e-14)
    wn, rw = _wn_rw(n, k).processes
    assert envelope_avar(n, k, FS, m) == pytest.approx(
        component_avar(wn, FS, m) + component_avar(rw, FS, m, "rad/s"), rel=1e-12)


def test_grid_is_dense_and_spans_the_range():
    m = avar_grid(FS, 600.0)
    assert m[0] == 1 and m[-1] == 60000 and np.all(np.diff(m) > 0)
    assert np.array_equal(m[:128], np.arange(1, 129))
    step = np.diff(np.log2(m))
    assert np.all(step <= 1 / 128 + 1.5 / m[:-1])  # 128 per octave, to whole samples
    assert default_horizon(5242.88, FS) == pytest.approx(524.288)
    assert default_horizon(4 * 3600.0, FS) == 600.0
    assert default_horizon(0.01, FS) == 2 / FS  # never one sample


# ---------------------------------------------------------------- the bound
def _every_m_ratio(model: stochmod.Model, axis, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    """E / AVAR at every integer m of [1, H fs], AVAR from the closed forms (GM: the
    package's ``haar_wv_geometric``, WN, RW)."""
    m = np.arange(1, round(horizon * FS) + 1)
    mf = m.astype(float)
    avar = np.zeros(m.size)
    for p in model.to_spec()["processes"]:
        q = p["params"]
        if p["family"] == "GM":
            avar += 2 * q["sigma2"] * haar_wv_geometric(-q["beta"] / FS, m)
        elif p["family"] == "WN":
            avar += q["sigma2"] / mf
        elif p["family"] == "RW":
            avar += q["sigma2"] * (2 * mf**2 + 1) / (6 * mf)
    env = envelope_avar(axis.noise_density, axis.random_walk, FS, m)
    return m, env / avar


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tc=st.floats(0.05, 5000.0), sigma=st.floats(1e-5, 1e-2), n=st.floats(1e-4, 1e-2),
       k=st.one_of(st.just(0.0), st.floats(1e-7, 1e-3)), horizon=st.floats(0.05, 30.0))
def test_bound_holds_at_every_tau_of_its_range_and_is_tight(tc, sigma, n, k, horizon):
    procs = [_gm(1 / tc, sigma**2), _wn(n**2 * FS)] + ([_rw(k**2 / FS)] if k else [])
    model = _model(*procs)
    axis = avar_bound(model, "gyro", horizon=horizon)
    m, ratio = _every_m_ratio(model, axis, horizon)
    assert axis.horizon == horizon and m[-1] == round(horizon * FS)
    assert ratio.min() >= 1 - 1e-10  # every averaging time of [1/fs, H], not only the grid
    assert ratio.min() <= 1 + 1e-6  # tight somewhere in the range
    assert axis.max_ratio == pytest.approx(ratio.max(), rel=1e-6)
    assert axis.noise_density >= n * (1 - 1e-12)  # never below the model's own
    assert axis.random_walk >= k * (1 - 1e-12)
    assert axis.model_noise_density == pytest.approx(n) and axis.model_random_walk == pytest.approx(k)


def test_bound_is_the_minimax_ratio_by_brute_force():
    """No pair (N >= N0, K >= K0) that bounds the model over the range has a smaller
    largest ratio: scan K, take for each the smallest N that bounds."""
    model = _model(_gm(1 / 40.0, 4e-8), _gm(1 / 1100.0, 1.2e-7), _wn(3.1e-5))
    H = 120.0
    axis = avar_bound(model, "gyro", horizon=H)
    m = np.arange(1, int(H * FS) + 1)
    avar = sum(component_avar(p, FS, m) for p in model.processes)
    w, r = FS / m, (2.0 * m**2 + 1) / (6 * m * FS)
    best = math.inf
    for k2 in np.linspace(0, 2 * axis.random_walk**2, 4001):
        n2 = max(3.1e-5 / FS, float(np.max((avar - k2 * r) / w)))
        best = min(best, float(np.max((n2 * w + k2 * r) / avar)))
    assert axis.max_ratio <= best * (1 + 1e-6)
    assert axis.max_ratio == pytest.approx(best, rel=1e-3)


@settings(max_examples=60, deadline=None)
@given(n2=st.floats(1e-12, 1e-6), k2=st.one_of(st.just(0.0), st.floats(1e-16, 1e-9)),
       terms=st.lists(st.tuples(st.floats(-2.0, 4.0), st.floats(-12.0, -6.0)), min_size=1,
                      max_size=3),
       horizon=st.sampled_from([0.5, 10.0, 120.0, 1000.0]))
def test_minimax_pair_is_the_linear_programs_optimum(n2, k2, terms, horizon):
    """The two-stage linear program of the rule, solved by scipy's HiGHS on the same grid:
    the same largest ratio, a bound at every grid point, and no larger normalised addition
    than HiGHS's pair in the rule's band of that ratio."""
    from scipy.optimize import linprog

    from stochmod.output import exports

    m = exports.avar_grid(FS, horizon)
    w, r = FS / m, (2.0 * m**2 + 1) / (6 * m * FS)
    tau = m / FS
    rest = np.zeros(m.size)
    for log_tc, log_s2 in terms:  # GM-shaped Allan variances (a continuous-time form)
        x = tau / 10**log_tc
        rest += 10**log_s2 * (2 * x - 3 + 4 * np.exp(-x) - np.exp(-2 * x)) / x**2
    rest = np.maximum(rest, 1e-30)
    a, b = exports._minimax(w, r, n2, k2, rest)
    total = n2 * w + k2 * r + rest
    ratio = ((n2 + a) * w + (k2 + b) * r) / total
    assert a >= 0 and b >= 0 and ratio.min() >= 1 - 1e-12

    sa, sb = total[0] / w[0], total[-1] / r[-1]
    wn, rn, base = sa * w / total, sb * r / total, (n2 * w + k2 * r) / total
    one = np.ones((m.size, 1))
    tight = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
    first = linprog([0, 0, 1], A_ub=np.block([[-wn[:, None], -rn[:, None], 0 * one],
                                               [wn[:, None], rn[:, None], -one]]),
                    b_ub=np.r_[base - 1, -base], bounds=[(0, None), (0, None), (1, None)],
                    method="highs", options=tight)
    t = first.x[2]  # HiGHS's optimum, its pair meeting E >= A to its tolerance only
    reached = base + first.x[0] * wn + first.x[1] * rn
    feasible = float(reached.max() / min(1.0, reached.min()))  # that pair scaled to E >= A
    assert t * (1 - 1e-9) <= ratio.max() <= feasible * (1 + 1e-6) * (1 + 1e-9)
    # HiGHS's tie-break over the rule's band, its edge lowered by more than HiGHS's slack
    # (t is at most the optimum): the band then lies inside ours, so that HiGHS's pair is
    # one ours competes with (the tie-break's optimum moves steeply with the band's edge)
    second = linprog([1, 1], A_ub=np.column_stack([np.r_[-wn, wn], np.r_[-rn, rn]]),
                     b_ub=np.r_[base - 1, t * (1 + 1e-6) * (1 - 1e-8) - base],
                     bounds=[(0, None), (0, None)], method="highs", options=tight)
    if second.status == 0:  # HiGHS's pair, raised in b until feasible, is no better
        short = max(0.0, 1.0 - float(np.min(base + second.x[0] * wn + second.x[1] * rn)))
        assert a / sa + b / sb <= second.fun + short / rn.min() + 1e-9 * (1 + second.fun)


@settings(max_examples=80, deadline=None)
@given(top=st.integers(1, 3000), gaps=st.lists(st.integers(1, 50), min_size=1, max_size=40))
def test_averaging_factors_with_their_doubles_are_the_sorted_union(top, gaps):
    from stochmod.output.exports import _with_doubles

    every = np.arange(1, top + 1, dtype=np.int64)  # the bound's dense grid: built directly
    sparse = np.cumsum(np.asarray(gaps, dtype=np.int64))  # any increasing grid: sorted
    for m in (every, sparse):
        got = _with_doubles(m)
        assert got.dtype == np.int64 and np.array_equal(got, np.union1d(m, 2 * m))


def test_pure_white_noise_and_random_walk_export_their_own_n_and_k():
    for n, k in ((3e-3, 4e-5), (2e-3, 5e-4), (1e-4, 0.0)):
        procs = [_wn(n**2 * FS)] + ([_rw(k**2 / FS)] if k else [])
        model = _model(*procs)
        axis = avar_bound(model, "accel", horizon=300.0)
        assert axis.noise_density == math.sqrt(_params(model, "WN")["sigma2"] / FS)
        assert axis.random_walk == (math.sqrt(_params(model, "RW")["sigma2"] * FS) if k else 0.0)
        assert axis.max_ratio == 1.0 and axis.noise_inflation == 1.0
        assert [how for _, how in axis.rules] == ["white", "random walk"][:len(procs)]


def test_quantization_is_bounded_by_white_noise_at_one_sample():
    """QN's AVAR 3 Q2 / m^2 is covered by white noise of N^2 = 3 Q2 / fs (= 3 Q^2 fs) from
    m = 1 on, and by no smaller white noise: the exported N^2 is N0^2 + 3 Q2 / fs, K is K0."""
    q2, n0, k0 = 4e-7, 1e-3, 2e-5
    model = _model(_wn(n0**2 * FS), _rw(k0**2 / FS), {"family": "QN", "params": {"Q2": q2}})
    axis = avar_bound(model, "gyro", horizon=60.0)
    assert axis.noise_density == pytest.approx(math.sqrt(n0**2 + 3 * q2 / FS), rel=1e-7)
    assert axis.random_walk == pytest.approx(k0, rel=1e-9)
    assert dict(axis.rules)["QN"] == "bounded" and axis.tight_tau == 1 / FS
    q = model.processes[2].physical(FS)["Q"].value  # Q in u*s
    assert axis.noise_density**2 == pytest.approx(n0**2 + 3 * q**2 * FS, rel=1e-7)


def test_a_longer_horizon_never_needs_less_and_default_is_not_one_sample():
    model = _model(_gm(1 / 1100.0, 1.2e-7), _wn(3.1e-5))
    short = avar_bound(model, "gyro", horizon=10.0)
    long = avar_bound(model, "gyro", horizon=600.0)
    assert long.max_ratio >= short.max_ratio
    default = avar_bound(model, "gyro", record_seconds=5242.88)
    assert default.horizon == pytest.approx(524.288) and "record/10" in default.horizon_source
    driving = math.sqrt(2 * 1.2e-7 / 1100.0)  # the GM's own driving noise: the old one-sample rule
    assert default.random_walk < driving


def test_kalibr_densities_from_the_model_and_within_the_fit_interval_of_the_truth(fits):
    axes = [noise_terms(fit, "gyro" if c.startswith("gyro") else "accel", column=c)
            for c, fit in fits.items()]
    doc = yaml.safe_load(kalibr_yaml(axes, rostopic="/imu"))
    assert doc["rostopic"] == "/imu" and doc["update_rate"] == FS
    for col, prefix in (("gyro_x", "gyroscope"), ("accel_x", "accelerometer")):
        model = fits[col].model
        n = math.sqrt(_params(model, "WN")["sigma2"] / FS)  # per-sample variance -> density
        k = math.sqrt(_params(model, "RW")["sigma2"] * FS)  # increment variance -> K
        assert doc[f"{prefix}_noise_density"] == pytest.approx(n, rel=1e-12)
        assert doc[f"{prefix}_random_walk"] == pytest.approx(k, rel=1e-12)
        axis = next(a for a in axes if a.column == col)
        n_true, k_true = TRUTH[col]
        assert axis.noise_interval[0] < n_true < axis.noise_interval[1]
        assert axis.walk_interval[0] < k_true < axis.walk_interval[1]


def test_openvins_has_kalibr_values_under_imu0(fits):
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    text = openvins_yaml(axes)
    assert text.startswith("%YAML:1.0")
    doc = yaml.safe_load(text.split("\n", 1)[1])["imu0"]
    kal = yaml.safe_load(kalibr_yaml(axes))
    for key in ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                "accelerometer_random_walk", "update_rate"):
        assert doc[key] == kal[key]
    assert np.array_equal(doc["T_i_b"], np.eye(4)) and doc["model"] == "kalibr"


def test_header_states_the_rule_the_range_and_the_inflation():
    gyro = _model(_gm(1 / 40.0, 4e-8), _wn(3.1e-5))
    accel = _model(_wn(7e-5), _rw(8e-7))
    axes = [avar_bound(gyro, "gyro", column="gyro_x", horizon=20.0),
            avar_bound(accel, "accel", column="accel_x", horizon=20.0)]
    text = kalibr_yaml(axes)
    header = [line for line in text.splitlines() if line.startswith("#")]
    assert header == ["# " + line for line in header_lines(axes)]
    joined = "\n".join(header)
    assert "N^2/tau + K^2 tau/3" in joined and "[0.01 s, H]" in joined and "H = 20 s (given)" in joined
    g = axes[0]
    assert g.noise_inflation > 1 and f"x{g.noise_inflation:.4g} the model's" in joined
    assert "(the model has no random walk)" in joined
    assert f"envelope/AVAR in [1, {g.max_ratio:.4g}]" in joined
    assert "accel_x: N" in joined and "envelope = model AVAR at every tau" in joined
    assert "gyroscope: the largest over its axes" in joined
    assert yaml.safe_load(openvins_yaml(axes).split("\n", 1)[1])  # comments stay comments
    assert pyins_parameters(axes)["header"] == header_lines(axes, per_sensor=False)


def test_ramp_is_refused_with_a_clear_error():
    model = stochmod.model_from_spec("WN(sigma2=1e-4) + RR(omega=1e-7)", FS)
    fit = gmwm(model.simulate(2**12, rng=1), "WN + RR(omega=1e-7)", FS)
    with pytest.raises(InputError, match="rate ramp"):
        noise_terms(fit, "gyro")
    with pytest.raises(InputError, match="horizon"):
        noise_terms(fit, "gyro", horizon=-1.0)
    with pytest.raises(InputError, match="horizon"):
        avar_bound(_wn_rw(1e-3, 1e-5), "gyro", horizon=0.5 / FS)


def test_pyins_and_stochmod_nav(fits):
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    p = pyins_parameters(axes)
    model = fits["gyro_x"].model
    k = math.sqrt(_params(model, "RW")["sigma2"] * FS)
    T = N / FS
    assert p["gyro"]["noise"] == pytest.approx(math.sqrt(_params(model, "WN")["sigma2"] / FS))
    assert p["gyro"]["bias_walk"] == pytest.approx(k)
    assert p["gyro"]["bias_sd"] == pytest.approx(k * math.sqrt(T))  # the walk over the record
    assert p["units"]["accel"]["bias_walk"] == "m/s^3/sqrt(Hz)"
    units = {"gyro_x": "rad/s", "accel_x": "m/s^2"}
    nav = stochmod_nav_config(fits, units)
    for col, fit in fits.items():
        rebuilt = stochmod.model_from_spec(nav["axes"][col]["model"], nav["freq"])
        assert np.array_equal(rebuilt.wv(10), fit.model.wv(10))
        assert nav["axes"][col]["unit"] == units[col]
    assert nav["axes"]["gyro_x"]["parameter_units"]["WN.sigma2"] == "(rad/s)^2"
    assert stochmod_nav_config({c: f.model for c, f in fits.items()}, units) == nav


def test_bias_sd_is_the_stationary_spread_plus_the_walk_over_the_record():
    model = _model(_gm(1 / 40.0, 4e-8), _wn(3.1e-5), {"family": "QN", "params": {"Q2": 1e-7}})
    axis = avar_bound(model, "gyro", horizon=60.0, record_seconds=3600.0)
    assert axis.bias_sd == pytest.approx(math.sqrt(4e-8 + axis.random_walk**2 * 3600.0))


def test_pyins_reads_the_exported_parameters_as_the_fitted_model(fits):
    """The peer's own model and simulator take the export's keywords (pyins 1.0.1,
    ``inertial_sensor.EstimationModel`` and ``Parameters``); errors pyins simulates from them
    have the fitted model's wavelet variance: a refit recovers the exported model."""
    pyins_sensor = pytest.importorskip("pyins.inertial_sensor")
    pd = pytest.importorskip("pandas")
    axes = [noise_terms(fit, c.split("_")[0], column=c) for c, fit in fits.items()]
    p = pyins_parameters(axes)
    keywords = {k: p["gyro"][k] for k in ("bias_sd", "noise", "bias_walk")}
    est = pyins_sensor.EstimationModel(**keywords)  # refuses a misnamed or misshaped keyword
    assert est.n_states == 3 and np.allclose(np.diag(est.P), keywords["bias_sd"] ** 2)
    assert np.allclose(est.q, keywords["bias_walk"]) and np.allclose(est.v, keywords["noise"])
    n = 2**17
    imu = pd.DataFrame(0.0, index=pd.Index(np.arange(n) / FS, name="time"),
                       columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
    simulated = pyins_sensor.apply_imu_parameters(
        imu, "rate", pyins_sensor.Parameters(noise=keywords["noise"],
                                             bias_walk=keywords["bias_walk"], rng=3),
        pyins_sensor.Parameters(rng=4))
    refit = gmwm(simulated["gyro_x"].to_numpy(), "WN+RW", FS)
    z = (refit.model.vector() - fits["gyro_x"].model.vector()) / refit.std_errors
    assert np.all(np.abs(z) < 4), z


ALL_FORMATS = ["kalibr", "openvins", "pyins", "stochmod-nav"]


def test_calibrate_export_writes_the_files_and_export_rewrites_them_from_the_json(tmp_path, capsys):
    gm = _model(_gm(1 / 10.0, (5e-3) ** 2), _wn((3e-3) ** 2 * FS))
    x = np.column_stack([gm.simulate(N, rng=20), _wn_rw(*TRUTH["accel_x"]).simulate(N, rng=21)])
    path = tmp_path / "imu.npz"
    np.savez(path, gyro_x=x[:, 0], accel_x=x[:, 1], freq=FS)
    out = tmp_path / "out"
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "WN+RW", "GM+WN",
                 "--no-plots", "--jobs", "1", "--out", str(out), "--export", *ALL_FORMATS]) == 0
    text = capsys.readouterr().out
    assert "kalibr_imu.yaml" in text and "deg/sqrt(h)" in text
    doc = yaml.safe_load((out / "kalibr_imu.yaml").read_text())
    report = json.loads((out / "calibration.json").read_text())
    cal = Calibration.read(out / "calibration.json")
    # the exports are the bound of the calibration's final models over the default horizon
    axes = {a.column: avar_bound(a.model, a.kind, column=a.column,
                                 record_seconds=cal.record_seconds) for a in cal.axes}
    assert axes["gyro_x"].horizon == pytest.approx(N / FS / 10)
    for col, prefix in (("gyro_x", "gyroscope"), ("accel_x", "accelerometer")):
        assert doc[f"{prefix}_noise_density"] == axes[col].noise_density
        assert doc[f"{prefix}_random_walk"] == axes[col].random_walk
    assert ("GM", "bounded") in axes["gyro_x"].rules and axes["gyro_x"].max_ratio > 1
    spec = report["columns"]["gyro_x"]["model"]
    wn = next(p for p in spec["processes"] if p["family"] == "WN")
    assert axes["gyro_x"].model_noise_density == pytest.approx(math.sqrt(wn["params"]["sigma2"] / FS))
    assert "H = 32.768 s (default min(600 s, record/10), record 327.68 s)" in (
        out / "kalibr_imu.yaml").read_text()
    assert report["units"]["signal"] == {"gyro_x": "rad/s", "accel_x": "m/s^2"}
    assert report["datasheet"]["gyro_x"]["summary"][0]["unit"] == "deg/sqrt(h)"
    assert json.loads((out / "stochmod_nav.json").read_text())["format"] == "stochmod-nav"
    # stochmod export on the calibration.json: the same files, byte for byte
    again = tmp_path / "again"
    assert main(["export", str(out / "calibration.json"), "--format", *ALL_FORMATS,
                 "--out", str(again)]) == 0
    assert "kalibr_imu.yaml" in capsys.readouterr().out
    for name in ("kalibr_imu.yaml", "kalibr_imu_chain.yaml", "pyins_imu.json", "stochmod_nav.json"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name
    # the library call and a stated horizon
    paths = exports_from_calibration(cal, ["kalibr"], tmp_path / "lib", horizon=30.0)
    assert "H = 30 s (given)" in paths[0].read_text()
    assert main(["export", str(out / "calibration.json"), "--format", "kalibr", "--out",
                 str(again), "--export-horizon", "30"]) == 0
    assert (again / "kalibr_imu.yaml").read_bytes() == paths[0].read_bytes()
    # one sensor only: Kalibr needs both
    np.savez(path, gyro_x=x[:, 0], freq=FS)
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN+RW", "--no-plots", "--out",
                 str(out), "--export", "kalibr"]) == 2
    assert "accel" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.json"), "--format", "kalibr"]) == 2
    assert "no such calibration file" in capsys.readouterr().err
