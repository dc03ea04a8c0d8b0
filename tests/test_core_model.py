"""Tests of stochmod.core.model: the algebra of composite models, parameter vectors and their
transforms, the spec language (strings and dicts, JSON round trip), the sums of theoretical
quantities, simulation, and the Kalman-filter augmentation.

Truth: closed forms written here (WN: sigma2 / 2^j; RW: the exact variance of the Haar
coefficient of a random walk, summed in rational arithmetic; GM: autocovariance
sigma2 exp(-beta |k| / freq) and Phi = exp(-beta dt); positive transform = log; stationary AR
transform = arctanh of the partial autocorrelations, phi_1 = r_1 (1 - r_2), phi_2 = r_2).
"""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest

import stochmod
from stochmod import Model, model_from_spec
from stochmod.core.errors import DomainError, InputError, SpecError, StochmodError, UnknownProcessError
from stochmod.core.model import as_model

FREQ = 100.0


def family(name: str) -> type:
    if name not in stochmod.process_names():
        pytest.skip(f"family {name} is not registered yet")
    return stochmod.get_process(name)


@pytest.fixture
def GM() -> type:  # noqa: N802
    return family("GM")


@pytest.fixture
def WN() -> type:  # noqa: N802
    return family("WN")


@pytest.fixture
def RW() -> type:  # noqa: N802
    return family("RW")


@pytest.fixture
def AR() -> type:  # noqa: N802
    return family("AR")


def rw_wv_exact(sigma2: float, level: int) -> float:
    """Var of the level-j Haar coefficient of a random walk with increment variance sigma2.

    W = sum_l h_l X_{t-l} with h_l = 1/2^j (l < m), -1/2^j (l >= m); since sum h = 0 the
    innovation e_{t-q} enters with weight c_q = sum_{l <= q} h_l, so Var W = sigma2 sum c_q^2.
    """
    m = 2 ** (level - 1)
    h = [Fraction(1, 2 * m)] * m + [Fraction(-1, 2 * m)] * m
    c, total = Fraction(0), Fraction(0)
    for hl in h:
        c += hl
        total += c * c
    return sigma2 * float(total)


# ------------------------------------------------------------------ algebra and naming
def test_sum_and_multiples(GM, WN) -> None:
    m = GM() + GM() + WN()
    assert isinstance(m, Model) and len(m.processes) == 3
    assert m.labels == ("GM1", "GM2", "WN")
    assert m.name == str(m) == "2*GM+WN"
    assert m.param_names == ("GM1.beta", "GM1.sigma2", "GM2.beta", "GM2.sigma2", "WN.sigma2")
    assert m.n_params == 5 and m.is_free
    two = 2 * GM()
    assert two.processes == (GM(), GM()) and two == GM() * 2
    assert (2 * (GM() + WN())).labels == ("GM1", "WN1", "GM2", "WN2")
    assert (WN() + (GM() + GM())).labels == ("WN", "GM1", "GM2")
    assert as_model(WN()) == Model((WN(),))


def test_bad_algebra(GM, WN) -> None:
    with pytest.raises(TypeError):
        GM() + 1  # noqa: B018
    with pytest.raises(TypeError):
        0 * GM()  # noqa: B018
    with pytest.raises(TypeError):
        GM() * 1.5  # noqa: B018
    with pytest.raises(SpecError, match="cannot add models bound to 100.0 Hz and 200.0 Hz"):
        (GM() + WN()).bind(100.0) + (WN() + WN()).bind(200.0)
    with pytest.raises(SpecError, match="at least one process"):
        Model(())
    with pytest.raises(SpecError, match="sum of Process instances"):
        Model((WN(), "GM"))
    with pytest.raises(InputError, match="freq"):
        (GM() + WN()).bind(-1.0)


def test_param_names_of_vector_parameters(AR, WN) -> None:
    m = model_from_spec("AR(2)+WN")
    assert m.param_names == ("AR.phi[0]", "AR.phi[1]", "AR.sigma2", "WN.sigma2")
    assert m.name == "AR(2)+WN"


def test_free_masks(GM, WN) -> None:
    m = model_from_spec("GM(beta=0.1)+WN")
    np.testing.assert_array_equal(m.free_mask(), [False, True, True])
    assert m.processes[0].free_names == ("sigma2",)
    full = m.bind(FREQ).start(_wv_of(0.1))
    assert not full.is_free
    assert full.processes[0].beta == 0.1  # a given value survives the starting values
    np.testing.assert_array_equal(full.freed().free_mask(), [True] * 3)


def _wv_of(beta: float) -> np.ndarray:
    """A plausible empirical WV: that of GM(beta, 1) + WN(1) at FREQ, levels 1..10."""
    GM, WN = stochmod.get_process("GM"), stochmod.get_process("WN")
    return (GM(beta=beta, sigma2=1.0) + WN(sigma2=1.0)).bind(FREQ).wv(10)


# ------------------------------------------------------------------ parameter vectors
def test_vector_round_trips_and_transforms(GM, WN, AR) -> None:
    m = model_from_spec("GM(beta=0.5, sigma2=2.0) + AR(2, phi=[0.3, 0.4], sigma2=0.1) + WN(sigma2=3.0)",
                        FREQ)
    vec = m.vector()
    np.testing.assert_array_equal(vec, [0.5, 2.0, 0.3, 0.4, 0.1, 3.0])
    assert m.with_vector(vec) == m
    other = m.with_vector(vec * [2, 1, 1, 1, 1, 1])
    assert other.processes[0].beta == 1.0 and other.freq == FREQ
    theta = m.to_unconstrained()
    # positive -> log; AR(2) -> arctanh of the PACF r: phi_2 = r_2, phi_1 = r_1 (1 - r_2)
    r2 = 0.4
    r1 = 0.3 / (1 - r2)
    np.testing.assert_allclose(theta, [np.log(0.5), np.log(2.0), np.arctanh(r1), np.arctanh(r2),
                                       np.log(0.1), np.log(3.0)], rtol=1e-14)
    back = m.from_unconstrained(theta)
    np.testing.assert_allclose(back.vector(), vec, rtol=1e-12)
    J = m.transform_jacobian(theta)
    assert J.shape == (6, 6)
    np.testing.assert_allclose(np.diag(J)[[0, 1, 4, 5]], [0.5, 2.0, 0.1, 3.0], rtol=1e-14)  # d e^t/dt
    assert not J[:2, 2:].any() and not J[2:4, [0, 1, 4, 5]].any()  # block-diagonal
    free = model_from_spec("GM+WN")
    with pytest.raises(SpecError, match="free"):
        free.vector()


def test_vector_errors(GM, WN) -> None:
    m = (GM(beta=0.5, sigma2=2.0) + WN(sigma2=1.0)).bind(FREQ)
    with pytest.raises(SpecError, match="has 3 parameters, got 2 values"):
        m.with_vector([1.0, 2.0])
    with pytest.raises(SpecError, match="has 3 parameters, got 4"):
        m.from_unconstrained(np.zeros(4))
    with pytest.raises(DomainError, match=r"GM\.beta = -1\.0 is outside its domain"):
        m.with_vector([-1.0, 2.0, 1.0])
    with pytest.raises(DomainError, match=r"WN\.sigma2"):
        m.with_vector([1.0, 2.0, np.nan])
    with pytest.raises(DomainError, match=r"GM\.sigma2"):
        GM(beta=1.0, sigma2=0.0)
    with pytest.raises(SpecError, match="has no parameter"):
        WN().with_values(beta=1.0)


# ------------------------------------------------------------------ specs
def test_spec_strings(GM, WN, AR, RW) -> None:
    assert model_from_spec("2*GM+WN") == GM() + GM() + WN()
    assert model_from_spec("  2 * GM + WN + RW ") == 2 * GM() + WN() + RW()
    ar2 = model_from_spec("AR(2)").processes[0]
    assert ar2 == AR(order=2) and ar2.n_params == 3
    assert model_from_spec("AR(order=3)").processes[0].order == 3
    m = model_from_spec("GM(beta=0.1)+WN", FREQ)
    assert m.processes == (GM(beta=0.1), WN()) and m.freq == FREQ
    m = model_from_spec("AR(2, phi=[0.5, -0.2], sigma2=1e-3)+GM(beta=1e-2, sigma2=4)")
    assert m.processes[0].phi == (0.5, -0.2) and m.processes[1].sigma2 == 4.0


def test_spec_dicts_and_json_round_trip(GM, WN, AR) -> None:
    spec = {"processes": [{"family": "GM", "params": {"beta": 0.02, "sigma2": 1e-6}},
                          {"family": "AR", "order": 2, "params": {"phi": [0.5, 0.1], "sigma2": 1.0}},
                          {"family": "WN"}],
            "freq": 100.0}
    m = model_from_spec(spec)
    assert m.freq == 100.0
    assert m.processes == (GM(beta=0.02, sigma2=1e-6), AR(order=2, phi=(0.5, 0.1), sigma2=1.0), WN())
    text = json.dumps(m.to_spec(), allow_nan=False)
    assert model_from_spec(json.loads(text)) == m
    assert json.loads(text) == spec | {"processes": [spec["processes"][0], spec["processes"][1],
                                                      {"family": "WN", "params": {}}]}
    assert model_from_spec(json.loads(text), 50.0).freq == 50.0  # the argument overrides
    assert model_from_spec(m) is m
    unbound = model_from_spec("GM(beta=0.1, sigma2=2)+WN(sigma2=1)")
    assert "freq" not in unbound.to_spec()
    assert model_from_spec(json.loads(json.dumps(unbound.to_spec()))) == unbound


@pytest.mark.parametrize(
    ("spec", "error", "message"),
    [
        ("", SpecError, "empty model spec"),
        ("   ", SpecError, "empty model spec"),
        ("GM+", SpecError, "cannot parse model term ''"),
        ("+GM", SpecError, "cannot parse model term ''"),
        ("2*", SpecError, r"cannot parse model term '2\*'"),
        ("GM(", SpecError, r"cannot parse model term 'GM\('"),
        ("GM(beta=abc)", SpecError, "cannot read 'abc'"),
        ("GM(1)", SpecError, r"GM takes 0 positional argument\(s\)"),
        ("GM(gamma=1)", SpecError, "bad arguments for GM"),
        ("0*GM", SpecError, "count must be at least 1"),
        ("GMX+WN", UnknownProcessError, "unknown process family 'GMX'"),
        ("GM(beta=-1)", DomainError, r"GM\.beta = -1 is outside"),
        ("AR(2, phi=[0.5, 1.2])", DomainError, r"AR\.phi"),
        ("AR(2, phi=[0.5])", StochmodError, r"phi"),
        ({"processes": []}, SpecError, "non-empty list under 'processes'"),
        ({"models": []}, SpecError, r"unknown key\(s\) \['models'\]"),
        ({"processes": [{"params": {}}]}, SpecError, r"processes\[0\] must be a dict with a 'family' key"),
        ({"processes": ["GM"]}, SpecError, r"processes\[0\] must be a dict"),
        ({"processes": [{"family": "GM", "params": [1, 2]}]}, SpecError, r"processes\[0\]\.params must be a dict"),
        ({"processes": [{"family": "GM", "order": 2}]}, SpecError, r"unknown key\(s\) \['order'\]"),
        ({"processes": [{"family": "GM", "params": {"beta": 0}}]}, DomainError, r"GM\.beta = 0"),
        ({"processes": [{"family": "Nope"}]}, UnknownProcessError, "registered families"),
        ({"processes": [{"family": "WN"}], "freq": 0}, InputError, "freq"),
        (42, SpecError, "a model spec is a string or a dict, got int"),
    ],
)
def test_spec_errors(GM, AR, spec, error, message) -> None:
    with pytest.raises(error, match=message):
        model_from_spec(spec)


# ------------------------------------------------------------------ theory of sums
def test_wv_of_a_sum_is_the_sum_of_closed_forms(WN, RW) -> None:
    m = (WN(sigma2=2.0) + RW(sigma2=1e-3) + WN(sigma2=0.5)).bind(FREQ)
    j = np.arange(1, 13)
    exact = 2.5 / 2.0**j + np.array([rw_wv_exact(1e-3, int(k)) for k in j])
    np.testing.assert_allclose(m.wv(12), exact, rtol=1e-12)
    rw_unit = np.array([rw_wv_exact(1.0, int(k)) for k in j])  # d wv / d sigma2_rw
    np.testing.assert_allclose(m.wv_jacobian(12)[:, 1], rw_unit, rtol=1e-9)
    np.testing.assert_allclose(m.wv_jacobian(12)[:, [0, 2]], np.column_stack([1 / 2.0**j] * 2), rtol=1e-12)


def test_psd_and_autocovariance_of_a_sum(GM, WN) -> None:
    beta, s_gm, s_wn = 3.0, 2.0, 0.5
    m = (GM(beta=beta, sigma2=s_gm) + WN(sigma2=s_wn)).bind(FREQ)
    lags = np.arange(0, 50)
    exact = s_gm * np.exp(-beta * lags / FREQ) + np.where(lags == 0, s_wn, 0.0)
    np.testing.assert_allclose(m.autocovariance(lags), exact, rtol=1e-12)
    # the sampled GM is an AR(1) with phi = exp(-beta/freq): S(f) = s (1-phi^2) / (freq |1 - phi e^{-iw}|^2)
    f = np.linspace(-FREQ / 2, FREQ / 2, 11)[1:]
    phi = np.exp(-beta / FREQ)
    ar1 = s_gm * (1 - phi**2) / (FREQ * np.abs(1 - phi * np.exp(-2j * np.pi * f / FREQ)) ** 2)
    np.testing.assert_allclose(m.psd(f), ar1 + s_wn / FREQ, rtol=1e-10)


def test_unbound_model_refuses_theory(WN) -> None:
    m = WN(sigma2=1.0) + WN(sigma2=2.0)
    for call in (lambda: m.wv(3), lambda: m.psd([1.0]), lambda: m.autocovariance([0]),
                 lambda: m.simulate(10, 0), lambda: m.augment(), lambda: m.wv_jacobian(3),
                 lambda: m.start(np.ones(3))):
        with pytest.raises(SpecError, match=r"not bound to a sampling frequency: use model\.bind"):
            call()


def test_free_model_refuses_theory(GM, WN) -> None:
    m = (GM(beta=1.0) + WN(sigma2=1.0)).bind(FREQ)
    with pytest.raises(SpecError, match=r"GM has free parameter\(s\) \['sigma2'\]"):
        m.wv(3)


# ------------------------------------------------------------------ simulation
def test_simulate_reproducible_and_independent_components(GM, WN) -> None:
    gm, wn = GM(beta=2.0, sigma2=1.0), WN(sigma2=0.25)
    m = (gm + wn).bind(FREQ)
    x = m.simulate(4096, 11)
    assert x.shape == (4096,) and x.dtype == np.float64
    np.testing.assert_array_equal(x, m.simulate(4096, np.random.default_rng(11)))
    assert not np.array_equal(x, m.simulate(4096, 12))
    # each component draws from its own child generator: the sum of the separate paths
    g1, g2 = np.random.default_rng(11).spawn(2)
    np.testing.assert_allclose(x, gm.simulate(4096, FREQ, g1) + wn.simulate(4096, FREQ, g2), rtol=0, atol=0)
    with pytest.raises(InputError, match="rng must be a numpy Generator or an integer seed"):
        m.simulate(10, None)
    with pytest.raises(InputError, match="n must be at least 1"):
        m.simulate(0, 1)


def test_simulated_variance_matches_the_model(GM, WN) -> None:
    """Seeded simulation: the sample variance of GM + WN is sigma2_gm + sigma2_wn within MC error."""
    m = (GM(beta=20.0, sigma2=1.0) + WN(sigma2=0.5)).bind(FREQ)
    v = np.array([np.var(m.simulate(20000, s)) for s in range(10)])
    assert abs(v.mean() - 1.5) < 4 * v.std(ddof=1) / np.sqrt(v.size)


# ------------------------------------------------------------------ augmentation
def test_augment_structure(GM, WN, RW) -> None:
    b1, b2, s_wn, s_rw = 1.0, 0.05, 0.3, 1e-4
    m = (GM(beta=b1, sigma2=2.0) + GM(beta=b2, sigma2=3.0) + WN(sigma2=s_wn) + RW(sigma2=s_rw)).bind(FREQ)
    for dt in (None, 0.1):
        aug = m.augment(dt)
        step = 1 / FREQ if dt is None else dt
        assert aug.dt == step
        gm_state = GM(beta=1.0, sigma2=1.0).state_names[0]
        rw_state = RW(sigma2=1.0).state_names[0]
        assert aug.state_names == (f"GM1.{gm_state}", f"GM2.{gm_state}", f"RW.{rw_state}")
        np.testing.assert_allclose(np.diag(aug.Phi), [np.exp(-b1 * step), np.exp(-b2 * step), 1.0], rtol=1e-13)
        np.testing.assert_allclose(np.diag(aug.Q), [2.0 * -np.expm1(-2 * b1 * step),
                                                    3.0 * -np.expm1(-2 * b2 * step),
                                                    s_rw * FREQ * step], rtol=1e-10)
        assert np.count_nonzero(aug.Phi - np.diag(np.diag(aug.Phi))) == 0
        np.testing.assert_array_equal(aug.H, [1.0, 1.0, 1.0])  # every block adds to the reading
        assert aug.white_var == s_wn
        np.testing.assert_allclose(np.diag(aug.P0)[:2], [2.0, 3.0])
    assert aug.F is not None and aug.F.shape == (3, 3)


def test_summary_lists_every_parameter(GM, WN) -> None:
    text = (GM(beta=0.5, sigma2=2.0) + WN()).bind(FREQ).summary()
    assert text.splitlines()[0] == "Model GM+WN at 100 Hz"
    for word in ("beta", "sigma2", "1/s", "free"):
        assert word in text


def test_with_processes_is_the_evolved_model_and_refuses_another_composition():
    m = model_from_spec("GM(beta=2.0, sigma2=1e-6) + WN(sigma2=1e-4)", 100.0)
    theta = m.to_unconstrained() + 0.25
    procs = tuple(p.from_unconstrained(t) for p, t in zip(m.processes, np.split(theta, [2])))
    direct = m.with_processes(procs)
    assert direct == Model(procs, freq=100.0) and hash(direct) == hash(Model(procs, freq=100.0))
    assert direct == m.from_unconstrained(theta) and repr(direct) == repr(Model(procs, freq=100.0))
    np.testing.assert_array_equal(direct.wv(10), Model(procs, freq=100.0).wv(10))
    with pytest.raises(SpecError, match="takes 2 Process"):
        m.with_processes(procs[:1])
    with pytest.raises(SpecError, match="takes 2 Process"):
        m.with_processes((procs[0], "WN"))


def test_simulate_is_the_sum_of_the_components_own_simulations():
    """Model.simulate adds the components' paths (child generators spawned in order) in
    component order, and refuses a component path of the wrong shape."""
    import attrs
    from stochmod_wn import WN

    m = model_from_spec("GM(beta=5.0, sigma2=1e-6) + RW(sigma2=1e-10) + WN(sigma2=1e-4)", 100.0)
    children = np.random.default_rng(11).spawn(3)
    parts = [p.simulate(5000, 100.0, g) for p, g in zip(m.processes, children)]
    np.testing.assert_array_equal(m.simulate(5000, 11), (parts[0] + parts[1]) + parts[2])

    @attrs.frozen
    class ShortWN(WN):
        def simulate(self, n, freq, rng):
            return super().simulate(n - 1, freq, rng)

    with pytest.raises(SpecError, match=r"WN.simulate returned shape \(99,\) for n = 100"):
        Model((ShortWN(sigma2=1.0), WN(sigma2=1.0)), freq=1.0).simulate(100, 0)
