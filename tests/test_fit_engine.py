"""The public fitting engine (stochmod.fit.engine) and the results built from it
(stochmod.fit.results).

Truth: eq. 20 written out as a quadratic form; the sandwich of eqs. 22-23 by explicit
inverses, and its optimal-weighting identity (D' V^-1 D)^-1; a known order of GM components;
the fit of stochmod.gmwm on the same data.
"""

from __future__ import annotations

import concurrent.futures
import functools

import numpy as np
import pytest

import stochmod
import stochmod.fit.weighting  # used as stochmod.fit.weighting below
from stochmod.core.errors import EstimationError, SpecError
from stochmod.data.examples import xsens_mtig
from stochmod.fit.criteria import identified
from stochmod.fit import results as results_module
from stochmod.fit.engine import (
    BOUND,
    Problem,
    canonical,
    refine,
    resolve_model,
    sandwich,
    search,
    weighted_svd,
)
from stochmod.fit.indirect import IndirectGMWMResult
from stochmod.fit.results import GMWMResult
from stochmod.fit.weighting_plugins import WeightingInput, get_weighting

FREQ = 100.0
TRUTH = "GM(beta=2.0, sigma2=1.0) + WN(sigma2=0.5)"


@pytest.fixture(scope="module")
def signal() -> np.ndarray:
    return stochmod.model_from_spec(TRUTH, FREQ).simulate(2**13, rng=11)


def test_problem_is_eq_20(signal: np.ndarray) -> None:
    emp = stochmod.wvar(signal, FREQ)
    base = resolve_model("GM+WN", FREQ)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(emp.wv.size,) * 2)
    omega = A @ A.T + emp.wv.size * np.eye(emp.wv.size)  # a full SPD weighting
    problem = Problem(base.start(emp.wv), emp.wv, omega, base.free_mask())
    x = problem.theta_full[base.free_mask()] + 0.3
    r = emp.wv - problem.model(x).wv(emp.wv.size)
    assert problem.objective(x) == pytest.approx(r @ omega @ r, rel=1e-12)
    assert problem.safe_objective(np.full(x.size, np.nan)) == np.inf


def test_sandwich_against_explicit_inverses() -> None:
    rng = np.random.default_rng(1)
    D = rng.normal(size=(9, 3)) * [1.0, 1e-4, 1e3]  # badly scaled columns
    A, C = rng.normal(size=(9, 9)), rng.normal(size=(9, 9))
    W, V = A @ A.T + np.eye(9), C @ C.T + np.eye(9)
    B = np.linalg.inv(D.T @ W @ D) @ D.T @ W
    np.testing.assert_allclose(sandwich(D, W, V), B @ V @ B.T, rtol=1e-9)
    # optimal weighting: B V B' = (D' V^-1 D)^-1 (eq. 26)
    np.testing.assert_allclose(sandwich(D, np.linalg.inv(V), V),
                               np.linalg.inv(D.T @ np.linalg.solve(V, D)), rtol=1e-9)
    with pytest.raises(EstimationError, match="does not depend on some parameter"):
        sandwich(np.column_stack([D[:, 0], np.zeros(9)]), W, V)
    with pytest.raises(EstimationError, match="not identified"):
        sandwich(np.column_stack([D[:, 0], 2 * D[:, 0]]), W, V)


def test_weighted_svd_gives_the_fits_projection_at_any_column_scale() -> None:
    # the fit's projection D (D' W D)^-1 D' W does not depend on the columns' scales; from the
    # orthogonal factors, L^-1 U U' L, it stays exact when a column is of order 1e-150 (where
    # the normal equations leave the float range): compare with explicit inverses on the same
    # columns brought to order 1
    rng = np.random.default_rng(2)
    D1 = rng.normal(size=(9, 3))
    A = rng.normal(size=(9, 9))
    W = A @ A.T + np.eye(9)
    projection = D1 @ np.linalg.inv(D1.T @ W @ D1) @ D1.T @ W
    for scale in ([1.0, 1.0, 1.0], [1.0, 1e-4, 1e3], [1.0, 1e-150, 1e150], [1e-140, 1.0, 1.0]):
        L, U, s = weighted_svd(D1 * scale, W)
        np.testing.assert_allclose(L.T @ L, W, rtol=1e-12)
        assert np.allclose(L, np.triu(L)) and s.size == 3 and s[-1] > 1e-3 * s[0]
        np.testing.assert_allclose(U.T @ U, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(np.linalg.solve(L, U @ U.T @ L), projection, rtol=1e-9,
                                   atol=1e-12)
    # a column the WV does not see (its squares underflow: norm 0) is left out; collinear
    # columns leave a singular value at rounding level (not identified)
    assert weighted_svd(D1 * [1.0, 1e-312, 1.0], W)[2].size == 2
    s = weighted_svd(np.column_stack([D1[:, 0], -3 * D1[:, 0], D1[:, 1]]), W)[2]
    assert s.size == 3 and s[-1] < 1e-15 * s[0]


def test_jtest_of_a_fit_with_an_unidentified_parameter_is_none() -> None:
    # `stochmod calibrate --n 65536` stopped with "Eigenvalues did not converge" in the J-test
    # of the candidate 3*GM+RR on accel_x: its first GM's beta ran to 7e4 (correlation time
    # 1.4e-5 s, white noise at 100 Hz), where d wv / d beta is subnormal (1e-312); the unscaled
    # solve of the J-test's projection returned inf and NaN instead of failing. Now the
    # J-test, like the sandwich and the selection's ranking, reports it as not identified
    rec = xsens_mtig(n=2**16)
    start = ("GM(beta=70285.66674261213, sigma2=6.967380202173328e-05) + "
             "GM(beta=36.673130617480645, sigma2=4.166025011863311e-07) + "
             "GM(beta=0.012058965719611538, sigma2=0.0031713053440993975) + "
             "RR(omega=1.5958560890060052e-23)")
    fit = stochmod.gmwm(rec.column("accel_x"), "3*GM+RR", rec.freq, starts=[start])
    beta = fit.model.processes[0]
    assert beta.beta > 1e4 and np.linalg.norm(fit.jacobian[:, 0]) == 0.0
    assert fit.jtest is None
    with pytest.raises(EstimationError, match="does not depend on some parameter"):
        fit.std_errors  # noqa: B018
    assert not identified(fit)


def test_canonical_orders_repeated_components_fastest_first() -> None:
    model = stochmod.model_from_spec("GM(beta=0.5, sigma2=1.0) + WN(sigma2=1.0) + GM(beta=5.0, sigma2=2.0)"
                                     " + GM(beta=2.0, sigma2=3.0)", FREQ)
    ordered = canonical(model)
    assert [p.family for p in ordered.processes] == ["GM", "WN", "GM", "GM"]
    assert [p.vector()[0] for p in ordered.processes if p.family == "GM"] == [5.0, 2.0, 0.5]
    assert canonical(ordered) == ordered


def test_search_and_from_search_reproduce_gmwm(signal: np.ndarray) -> None:
    emp = stochmod.wvar(signal, FREQ)
    J = emp.wv.size
    base = resolve_model("GM+WN", FREQ)
    mask = base.free_mask()
    omega = get_weighting("diagonal").matrix(WeightingInput(emp, J)).omega
    found = search(base, emp.wv, omega, mask, 4, 64, (), 0)
    again = search(base, emp.wv, omega, mask, 4, 64, (), 0)
    assert found == again  # seeded
    fit = GMWMResult.from_search(found, empirical=emp, omega=omega, weighting="diagonal", levels=J,
                                 mask=mask, signal=signal)
    ref = stochmod.gmwm(signal, "GM+WN", FREQ)
    np.testing.assert_array_equal(fit.model.vector(), ref.model.vector())
    np.testing.assert_array_equal(fit.std_errors, ref.std_errors)
    assert fit.jtest == ref.jtest and fit.free_names == ("GM.beta", "GM.sigma2", "WN.sigma2")
    with pytest.raises(SpecError, match="does not match"):
        search(base, emp.wv, omega, mask, 0, 0, ["WN(sigma2=1.0)"], 0)


def test_refine_stays_within_the_bound() -> None:
    res = refine(lambda x: x - 1e6, lambda x: np.eye(x.size), np.array([1e4, 0.0]))
    np.testing.assert_allclose(res.x, [BOUND, BOUND])


def test_selection_carries_the_model_covariance_computed_in_the_worker(signal, monkeypatch) -> None:
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        sel = stochmod.select(signal, FREQ, candidates=["WN", "GM+WN"], executor=pool, progress=False)
    fit = sel.fits["GM+WN"]
    assert fit.null_covariance is not None and fit.covariance is sel.wv_covariance
    expected = stochmod.fit.weighting.model_covariance(fit.model, fit.empirical.n_coef, "haar")
    np.testing.assert_allclose(fit.null_covariance, expected, rtol=1e-12)
    jtest = fit.jtest
    plain = stochmod.gmwm(signal, "GM+WN", FREQ)
    assert plain.null_covariance is None and plain.jtest_form is not None

    def fail(*args, **kwargs):
        raise AssertionError("the model covariance was computed again")

    monkeypatch.setattr(results_module, "model_covariance", fail)
    fresh = fit.with_data_covariance(fit.covariance)  # a copy: fields kept
    assert fresh.null_covariance is fit.null_covariance and fresh.jtest == jtest
    # the worker's J-test and SVD travel with the fit; what reads the data's V is computed again
    assert fresh.jtest_form is fit.jtest_form and fresh.analytic_weighted_svd is fit.analytic_weighted_svd
    other = fit.with_data_covariance(2.0 * fit.covariance)
    assert other.asymptotic_jtest is fit.asymptotic_jtest
    np.testing.assert_allclose(other.std_errors, np.sqrt(2.0) * fit.std_errors, rtol=1e-10)
    # without the model's covariance given, nothing is carried
    assert "jtest_form" not in vars(plain.with_data_covariance(2.0 * fit.covariance))


def test_results_compose_and_never_override_cached_properties() -> None:
    base = {n for n, v in vars(GMWMResult).items() if isinstance(v, functools.cached_property)}
    assert {"wv_covariance", "null_wv_covariance", "jacobian", "cov_params", "jtest"} <= base
    overridden = base & set(vars(IndirectGMWMResult))
    assert not overridden, f"IndirectGMWMResult overrides cached properties {overridden}"


def test_model_covariance_evaluates_the_psd_once_at_nodes_shared_by_every_model() -> None:
    """The Haar model covariance evaluates the PSD once per call, at nodes that do not depend
    on the model (the gains live in the cached weights), and its value is the same quadratic
    form whatever was computed before: a PSD scaled by c gives c^2 times the covariance."""
    from stochmod.core.theory import wv_covariance_from_psd

    n_coef = 2**14 - 2 ** np.arange(1, 11) + 1
    seen: list[np.ndarray] = []

    def counted(model: stochmod.Model):
        def psd(f: np.ndarray) -> np.ndarray:
            seen.append(np.array(f))
            return model.psd(f)
        return psd

    a = stochmod.model_from_spec("GM(beta=3.0, sigma2=2.0) + WN(sigma2=0.5)", FREQ)
    b = stochmod.model_from_spec("GM(beta=0.3, sigma2=8.0) + WN(sigma2=2.0)", FREQ)
    cov_a = wv_covariance_from_psd(counted(a), n_coef, FREQ)
    cov_b = wv_covariance_from_psd(counted(b), n_coef, FREQ)
    assert len(seen) == 2
    np.testing.assert_array_equal(seen[0], seen[1])
    scaled = stochmod.model_from_spec("GM(beta=3.0, sigma2=6.0) + WN(sigma2=1.5)", FREQ)
    np.testing.assert_allclose(wv_covariance_from_psd(scaled.psd, n_coef, FREQ), 9.0 * cov_a,
                               rtol=1e-13)
    assert not np.allclose(cov_a, cov_b)


def test_search_does_no_worse_than_a_local_search_from_the_truth() -> None:
    """A replication of studies/mc_gmwm.py's GM+WN+RW case whose stage-1 results all shrink the
    random walk to nothing and differ only in how far (a plateau of eq. 20): the refinements
    start from points whose models' WVs differ, and one of them finds the interior optimum
    (RW sigma2 ~ 1.3e-13) that a local search from the true parameters finds. Choosing the
    refined points by their coordinates alone ended on the plateau, 2.5 % higher."""
    spec = "GM(beta=0.1, sigma2=1e-7) + WN(sigma2=3e-6) + RW(sigma2=1e-12)"
    truth = stochmod.model_from_spec(spec, FREQ)
    x = truth.simulate(2**18, np.random.default_rng(np.random.SeedSequence(20240917, spawn_key=(3, 2))))
    emp = stochmod.wvar(x, FREQ)
    omega = get_weighting("diagonal").matrix(WeightingInput(emp, emp.wv.size)).omega
    base = truth.freed()
    mask = base.free_mask()
    found = search(base, emp.wv, omega, mask, 4, 64, (), 0)
    problem = Problem(truth, emp.wv, omega, mask)
    local = refine(problem.residuals, problem.jacobian, truth.to_unconstrained()[mask])
    assert found.objective <= problem.objective(local.x) * (1 + 1e-9)
    assert found.model.processes[2].sigma2 == pytest.approx(problem.model(local.x).processes[2].sigma2, rel=1e-3)


def test_jtest_exists_exactly_for_the_identified_fits_of_a_lattice() -> None:
    # the J-test and the ranking's identification read the same weighted SVD: on the default
    # lattice for the bundled MTi-G's accel_y (2^16 samples), every fit without a negligible
    # component has a J-test if and only if it is identified (19 of 63 are not)
    from stochmod.fit.criteria import identified
    from stochmod.fit.results import negligible_components
    from stochmod.workflows.fleet import SerialExecutor

    rec = xsens_mtig(n=2**16)
    sel = stochmod.select(rec.column("accel_y"), rec.freq, executor=SerialExecutor(),
                          progress=False)
    plain = {name: fit for name, fit in sel.fits.items() if not negligible_components(fit)}
    not_identified = [name for name, fit in plain.items() if not identified(fit)]
    assert len(not_identified) >= 5
    for name, fit in plain.items():
        assert (fit.jtest is None) == (name in not_identified), name
        if fit.jtest is not None:
            assert 0.0 <= fit.jtest.pvalue <= 1.0 and fit.jtest.df >= 1


def test_jtest_statistic_is_eq_27_with_the_explicit_projection(signal: np.ndarray) -> None:
    # r' (P V P')^+ r on the levels the test keeps, with P = I - D (D' W D)^-1 D' W from
    # explicit inverses (a well-conditioned fit) and the pseudo-inverse at the J-test's rank
    # (its df: the eigenvalues of the correlation form above 1e-3 of the largest)
    from stochmod.fit.results import JTEST_MIN_EDF

    for weighting in ("diagonal", "optimal"):
        fit = stochmod.gmwm(signal, "GM+WN", FREQ, weighting=weighting)
        D, W, V = fit.jacobian, fit.omega, fit.null_wv_covariance
        J = fit.levels
        P = np.eye(J) - D @ np.linalg.inv(D.T @ W @ D) @ D.T @ W
        keep = fit.empirical.n_coef[:J] / 2.0 ** fit.empirical.levels[:J] >= JTEST_MIN_EDF
        r = (fit.empirical.wv[:J] - fit.model_wv())[keep]
        C = (P @ V @ P.T)[np.ix_(keep, keep)]
        sd = np.sqrt(np.diag(V)[keep])
        jt = fit.jtest
        evals = np.linalg.eigvalsh(C / np.outer(sd, sd))
        cut = 0.5 * (evals[-jt.df] + evals[-jt.df - 1])  # between the kept and the dropped
        stat = (r / sd) @ np.linalg.pinv(C / np.outer(sd, sd), rcond=cut / evals[-1],
                                         hermitian=True) @ (r / sd)
        assert jt.statistic == pytest.approx(stat, rel=1e-8)
