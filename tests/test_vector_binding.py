"""The GMWM binding from parameter vectors (stochmod.fit.vector_binding, the VectorisedWV
protocol, geometric.haar_wv_positive_rows): the same digits as the Process path, which it
replaces inside the optimizer only for speed."""

from __future__ import annotations

import numpy as np
import pytest

import stochmod
from stochmod.core import geometric
from stochmod.core.errors import DomainError, InputError
from stochmod.core.geometric import haar_wv_positive, haar_wv_positive_rows
from stochmod.core.vectorised_wv import VectorisedWV, declares_wv_rows, wv_kernel, wv_rows_domains
from stochmod.fit.engine import Problem
from stochmod.fit.vector_binding import VectorBinding

FREQ = 100.0


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


@pytest.fixture(params=["compiled", "numpy"])
def gm_path(request, monkeypatch) -> str:
    """Each path of haar_wv_positive_rows: the compiled recursion (numba) and the numpy one."""
    if request.param == "compiled" and not geometric._JIT:
        pytest.skip("numba is not available")
    monkeypatch.setattr(geometric, "_JIT", request.param == "compiled")
    return request.param


def test_compiled_and_numpy_gm_paths_agree(monkeypatch) -> None:
    """The compiled closed form and the numpy fallback: the same recursion, libm's and
    numpy's exp/expm1/sinh/tanh (a few ulps apart)."""
    if not geometric._JIT:
        pytest.skip("numba is not available")
    rng = np.random.default_rng(5)
    u = np.concatenate([10.0 ** rng.uniform(-12, 0, 60), rng.uniform(1, 6.9, 10)])
    m = 2.0 ** np.arange(30)
    w, dw = haar_wv_positive_rows(u, m)
    monkeypatch.setattr(geometric, "_JIT", False)
    w0, dw0 = haar_wv_positive_rows(u, m)
    np.testing.assert_allclose(w, w0, rtol=1e-14, atol=0)
    # dW/du = 1/(2m) + ... - W coth(u/2) crosses zero at W's maximum over u: on the scale
    # of its largest term
    terms = 0.5 / m + w / np.tanh(0.5 * u)[:, None]
    assert np.all(np.abs(dw - dw0) <= 1e-14 * terms)


def test_haar_wv_positive_rows_is_the_one_u_function_bit_for_bit(gm_path: str) -> None:
    rng = np.random.default_rng(11)
    m = 2.0 ** np.arange(22)
    # slow processes (series at most levels), fast ones, and z < 1e-3 (the polynomial path)
    u = np.concatenate([10.0 ** rng.uniform(-12, 0, 40), rng.uniform(1, 6.9, 10), [7.0, 12.0, 700.0]])
    rng.shuffle(u)
    w, dw = haar_wv_positive_rows(u, m)
    for k, uk in enumerate(u):
        w1, dw1 = haar_wv_positive(float(uk), m)
        assert np.array_equal(_bits(w[k]), _bits(w1)) and np.array_equal(_bits(dw[k]), _bits(dw1))


@pytest.mark.parametrize("u", [0.0, -1.0, np.inf, np.nan])
def test_haar_wv_positive_rows_refuses_a_non_positive_u(u: float) -> None:
    with pytest.raises(InputError, match="u must be positive"):
        haar_wv_positive_rows(np.array([0.1, u]), 2.0 ** np.arange(5))


@pytest.mark.parametrize("family", ["GM", "WN", "RW", "QN", "RR"])
def test_haar_wv_rows_is_each_rows_process_bit_for_bit(family: str) -> None:
    proto = stochmod.model_from_spec(family, FREQ).processes[0]
    rng = np.random.default_rng(3)
    values = 10.0 ** rng.uniform(-9, 2.5, (7, proto.n_params))
    for levels in (1, 6, 21):
        wv, jac = proto.haar_wv_rows(values, levels, FREQ)
        assert wv.shape == (values.shape[0], levels) and jac.shape == (values.shape[0], levels, proto.n_params)
        for k, row in enumerate(values):
            p = proto.from_vector(row)
            assert np.array_equal(_bits(wv[k]), _bits(p.wv(levels, FREQ)))
            assert np.array_equal(_bits(jac[k]), _bits(p.wv_jacobian(levels, FREQ)))


def test_only_plain_built_in_families_have_a_vector_form() -> None:
    reg = {p.family: type(p) for p in stochmod.model_from_spec("GM+WN+RW+QN+RR+AR(1)", FREQ).processes}
    assert all(wv_rows_domains(reg[f]) is not None for f in ("GM", "WN", "RW", "QN", "RR"))
    # AR declares no vectorised form (and its construction checks stationarity)
    assert not issubclass(reg["AR"], VectorisedWV) and wv_rows_domains(reg["AR"]) is None
    assert VectorBinding.of(stochmod.model_from_spec("2*GM+AR(1)", FREQ), 10) is None
    assert wv_rows_domains(stochmod.model_from_spec("GM", FREQ).processes[0]) is None  # a class


@pytest.mark.parametrize("family", ["GM", "WN", "RR"])
@pytest.mark.parametrize("changed", ["wv", "wv_jacobian"])
def test_a_subclass_that_changes_its_wv_does_not_use_its_parents_rows(family: str, changed: str) -> None:
    """The protocol's rule: rows (and a kernel) are in force only in the class that defines
    haar_wv_rows and below, up to a subclass that changes wv or wv_jacobian; such a subclass
    is evaluated through Process objects, and is back on the vector path with rows of its
    own."""
    parent = type(stochmod.model_from_spec(family, FREQ).processes[0])

    def doubled(self, *args, **kwargs):
        return 2.0 * getattr(parent, changed)(self, *args, **kwargs)

    Changed = type("Changed", (parent,), {changed: doubled})
    assert issubclass(Changed, VectorisedWV)  # it still inherits the declaration ...
    assert not declares_wv_rows(Changed)  # ... but the parent's rows are not in force
    assert wv_rows_domains(Changed) is None and wv_kernel(Changed) is None
    wn = stochmod.model_from_spec("WN(sigma2=1.0)", FREQ).processes[0]
    assert VectorBinding.of(stochmod.Model((Changed.example(FREQ), wn), FREQ), 8) is None

    def rows(self, values, levels, freq):
        wv, jac = parent.haar_wv_rows(self, values, levels, freq)
        return (2.0 * wv, jac) if changed == "wv" else (wv, 2.0 * jac)

    Own = type("Own", (Changed,), {"haar_wv_rows": rows})
    assert declares_wv_rows(Own) and wv_rows_domains(Own) == wv_rows_domains(parent)
    assert wv_kernel(Own) is None  # the parent's kernel is not below the rows in force


class _ProcessPath(Problem):
    """The Process-object binding (overriding phi makes Problem skip the vector binding)."""

    def phi(self, x: np.ndarray) -> np.ndarray:
        return super().phi(x)


@pytest.mark.parametrize("spec", ["GM(beta=5.0, sigma2=1e-6) + GM(beta=0.01, sigma2=4e-6) + WN(sigma2=1e-4)",
                                  "QN(Q2=1e-7) + WN(sigma2=3e-6) + RW(sigma2=1e-12) + RR(omega=1e-8)",
                                  "GM(beta=0.5) + WN(sigma2=3e-6) + RW(sigma2=1e-10)"])
def test_problem_with_the_vector_binding_is_the_process_path_bit_for_bit(spec: str) -> None:
    truth = stochmod.model_from_spec(spec, FREQ)
    filled = truth.start(np.ones(18)) if truth.is_free else truth
    nu = stochmod.model_from_spec(spec.replace("GM(beta=0.5)", "GM(beta=0.5, sigma2=2e-6)"), FREQ).wv(18)
    nu = nu * (1.0 + 0.05 * np.sin(np.arange(18)))
    omega = np.diag(1.0 / nu**2)
    mask = truth.free_mask() if truth.is_free else np.ones(truth.n_params, dtype=bool)
    fast = Problem(filled, nu, omega, mask)
    slow = _ProcessPath(filled, nu, omega, mask)
    assert fast._vector is not None and slow._vector is None
    rng = np.random.default_rng(2)
    x0 = filled.to_unconstrained()[mask]
    points = x0 + rng.normal(0.0, 3.0, size=(30, x0.size))
    points[3, 0] = 800.0  # exp overflows: outside the domain, inf by both paths
    for x in points[:8]:
        with np.errstate(over="ignore"):
            usable = np.isfinite(slow.safe_objective(x))
        if usable:
            assert np.array_equal(_bits(fast.phi(x)), _bits(slow.phi(x)))
            assert np.array_equal(_bits(fast.dphi(x)), _bits(slow.dphi(x)))
            assert np.array_equal(_bits(fast.flat_jacobian(x)), _bits(slow.flat_jacobian(x)))
    with np.errstate(over="ignore"):
        expected = np.array([slow.safe_objective(x) for x in points])
        got = fast.safe_objectives(points)
        assert np.isinf(got[3]) and np.array_equal(_bits(got), _bits(expected))
        with pytest.raises(DomainError):
            fast.phi(points[3])


def test_select_takes_the_wv_here_and_its_v_is_data_covariance_bit_for_bit() -> None:
    from concurrent.futures import ThreadPoolExecutor

    from stochmod.empirical.wavelet_variance import wvar
    from stochmod.fit.selection import select
    from stochmod.fit.weighting import data_covariance

    truth = stochmod.model_from_spec("GM(beta=10.0, sigma2=1.0) + WN(sigma2=1.0)", FREQ)
    x = truth.simulate(3000, rng=4)
    with ThreadPoolExecutor(2) as pool:
        for levels in (None, 6):
            res = select(x, FREQ, candidates=["WN", "GM+WN"], executor=pool, levels=levels)
            emp = wvar(x, FREQ, levels=levels)
            V = data_covariance(x, emp, emp.wv.size)
            assert np.array_equal(_bits(res.wv_covariance), _bits(V))


def test_one_point_is_the_rows_path_bit_for_bit() -> None:
    """VectorBinding.point (the optimizer's one point) against values + evaluate of that row,
    and None where values() finds the row outside its domains."""
    model = stochmod.model_from_spec("GM(beta=5.0, sigma2=1e-6) + GM(beta=0.01, sigma2=4e-6) + WN(sigma2=1e-4) "
                                     "+ QN(Q2=1e-7) + RW(sigma2=1e-12) + RR(omega=1e-8)", FREQ)
    binding = VectorBinding.of(model, 17)
    rng = np.random.default_rng(4)
    theta = model.to_unconstrained() + rng.normal(0.0, 2.0, size=(12, model.n_params))
    theta[5, 2] = 800.0  # exp overflows: outside the domain
    with np.errstate(over="ignore"):
        values, valid = binding.values(theta)
    assert not valid[5] and valid.sum() == 11
    wv, jac = binding.evaluate(values[valid])
    rows = iter(range(int(valid.sum())))
    for t, ok in zip(theta, valid):
        with np.errstate(over="ignore"):
            found = binding.point(t)
        if not ok:
            assert found is None
            continue
        k = next(rows)
        assert np.array_equal(_bits(found[0]), _bits(wv[k])) and np.array_equal(_bits(found[1]), _bits(jac[k]))


def test_compiled_kernels_give_the_rows_digits() -> None:
    """A model whose every family declares VectorisedWV.haar_wv_kernel (GM, and WN, RW, QN
    through ScaledFamily) is evaluated by the kernels, one call per component in model order:
    bit for bit the rows path, including a GM whose e^-u < 1e-3 (its kernel declines and the
    point goes through the rows)."""
    model = stochmod.model_from_spec("GM(beta=5.0, sigma2=1e-6) + WN(sigma2=1e-4) + RW(sigma2=1e-12) "
                                     "+ GM(beta=0.01, sigma2=4e-6) + QN(Q2=1e-7) "
                                     "+ GM(beta=0.3, sigma2=1e-5)", FREQ)
    binding = VectorBinding.of(model, 19)
    if not geometric._JIT:
        assert binding._kernels is None  # without numba: the rows path only
        return
    assert binding._kernels is not None
    rows = VectorBinding.of(model, 19)
    rows._kernels = None
    rng = np.random.default_rng(1)
    theta = model.to_unconstrained() + rng.normal(0.0, 2.0, size=(400, model.n_params))
    theta[7, 0] = np.log(2000.0 * FREQ)  # u = 2000: the polynomial path
    used = 0
    for t in theta:
        with np.errstate(all="ignore"):
            got, expected = binding.point(t), rows.point(t)
        assert (got is None) == (expected is None)
        if got is not None:
            used += 1
            assert np.array_equal(_bits(got[0]), _bits(expected[0]))
            assert np.array_equal(_bits(got[1]), _bits(expected[1]))
    assert used > 300
    # a model with a family without a kernel (RR) keeps the rows path
    assert VectorBinding.of(stochmod.model_from_spec("GM + WN + RW + RR", FREQ), 19)._kernels is None


@pytest.mark.parametrize("family", ["GM", "WN", "RW", "QN"])
def test_a_subclass_that_changes_the_rows_does_not_inherit_the_kernel(family: str) -> None:
    cls = type(stochmod.model_from_spec(family, FREQ).processes[0])

    class Rows(cls):
        def haar_wv_rows(self, values, levels, freq):
            return super().haar_wv_rows(values, levels, freq)

    if cls.haar_wv_kernel is None:
        pytest.skip("numba is not available")
    assert wv_kernel(cls) is cls.haar_wv_kernel and wv_kernel(Rows) is None
    assert wv_rows_domains(Rows) is not None  # its own rows are in force


def test_the_polynomial_rows_are_the_complex_paths_digits() -> None:
    """haar_wv_positive_rows' rows with z = e^-u < 1e-3 (real arithmetic) against
    haar_wv_geometric and its derivative (complex arithmetic, zero imaginary parts), bit for
    bit, from the threshold to z underflowing to 0."""
    rng = np.random.default_rng(0)
    u = np.concatenate([rng.uniform(6.9078, 12.0, 300), 10.0 ** rng.uniform(1, 3, 300),
                        [6.90776, 700.0, 745.0, 746.0, 1e5, 1e300]])
    for levels in (1, 19, 30):
        m = 2.0 ** np.arange(levels)
        w, dw = haar_wv_positive_rows(u, m)
        assert np.array_equal(_bits(w), _bits(geometric.haar_wv_geometric(-u[:, None], m)))
        assert np.array_equal(_bits(dw), _bits(-geometric.haar_wv_geometric_dlog(-u[:, None], m)))
