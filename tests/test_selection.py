"""Automatic model selection (stochmod.fit.selection) and the WVIC criterion (stochmod.fit.criteria).

Truths are seeded simulations of known models; the optimism is checked against its closed form
(Omega = V^-1 gives 2p) and against a Monte Carlo of out-of-sample minus in-sample objectives.
"""

from __future__ import annotations

import itertools
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import attrs
import numpy as np
import pytest

import stochmod
from stochmod.core.errors import InputError, SpecError, UnknownProcessError
from stochmod.fit.criteria import WVIC, criterion_names, get_criterion, identified, optimism
from stochmod.fit.gmwm import gmwm
from stochmod.fit.selection import SelectionResult, candidate_lattice, nested_graph, select
from stochmod.plugin.hookspecs import hookimpl
from stochmod.empirical.wavelet_variance import wvar

FREQ = 100.0
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
GM_COUNTS = ["GM+WN", "2*GM+WN", "3*GM+WN"]


def model(spec: str) -> stochmod.Model:
    return stochmod.model_from_spec(spec, FREQ)


# Truths with well separated time scales (each component dominates the WV over some octaves).
GM1 = model("GM(beta=1.0, sigma2=0.1) + WN(sigma2=1.0)")
GM2 = model("GM(beta=10.0, sigma2=1.0) + GM(beta=0.1, sigma2=0.2) + WN(sigma2=1.0)")
GM3 = model("GM(beta=20.0, sigma2=1.0) + GM(beta=1.0, sigma2=0.3) + GM(beta=0.02, sigma2=0.1)"
            " + WN(sigma2=1.0)")
QWR = model("QN(Q2=1.0) + WN(sigma2=1.0) + RW(sigma2=1e-5)")
QWR_CANDIDATES = ["WN", "QN+WN", "WN+RW", "QN+WN+RW", "GM+WN", "QN+WN+RW+RR"]


@pytest.fixture(scope="module")
def threads():
    with ThreadPoolExecutor(2) as pool:
        yield pool


# ---------------------------------------------------------------- selection picks the truth
def test_multi_axis_selects_each_columns_number_of_gm(threads):
    x = np.column_stack([m.simulate(2**16, rng=s) for m, s in ((GM1, 1), (GM2, 2), (GM3, 3))])
    results = select(x, FREQ, candidates=GM_COUNTS, executor=threads, names=["a", "b", "c"])
    assert isinstance(results, list) and len(results) == 3
    assert [r.column for r in results] == ["a", "b", "c"]
    assert [r.best.model.name for r in results] == GM_COUNTS
    # the selected fit estimates the truth's time scales (GM1: beta = 1/s, WN sigma2 = 1)
    gm, wn = results[0].best.model.processes
    assert gm.beta == pytest.approx(1.0, rel=0.5)
    assert wn.sigma2 == pytest.approx(1.0, rel=0.05)


def test_qn_wn_rw_selected_among_power_laws(threads):
    x = QWR.simulate(2**16, rng=4)
    res = select(x, FREQ, candidates=QWR_CANDIDATES, executor=threads)
    assert isinstance(res, SelectionResult)
    assert res.best.model.name == "QN+WN+RW"
    assert res.ranking[0].model == "QN+WN+RW"
    ranked = [r.model for r in res.ranking]
    assert len(ranked) == len(QWR_CANDIDATES) and sorted(ranked) == sorted(QWR_CANDIDATES)
    # every candidate that misses a true component fits worse than the truth
    for name in ("WN", "QN+WN", "WN+RW", "GM+WN"):
        assert res.fits[name].objective > res.fits["QN+WN+RW"].objective, name
    # criterion = objective + optimism, and the ranking is sorted by it (identified first)
    for row in res.ranking:
        assert row.criterion == pytest.approx(row.objective + row.optimism, rel=1e-12)
        assert row.optimism == pytest.approx(optimism(res.fits[row.model]), rel=1e-12)
    keys = [(not r.identified, r.criterion) for r in res.ranking]
    assert keys == sorted(keys)


# ---------------------------------------------------------------- nesting and the DAG
def test_child_objective_never_worse_than_parent(threads):
    x = GM2.simulate(2**14, rng=5)
    res = select(x, FREQ, families=("GM", "WN", "RW"), max_counts={"GM": 2}, executor=threads)
    assert res.graph.number_of_nodes() == 3 * 2 * 2 - 1
    assert res.graph.number_of_edges() > 0
    for parent, child in res.graph.edges:
        assert res.fits[child].objective <= res.fits[parent].objective * (1 + 1e-12), (parent, child)


def test_a_child_searches_each_distinct_start_once(monkeypatch):
    """A start met twice (a parent's fit that is also among the screened starts) is searched
    once; the child's fit is the one the repeated search would give (it cannot win again)."""
    import stochmod.fit.selection as selection

    starts: list[list[np.ndarray]] = []
    searched = selection._local_search

    def local_search(task, base, nu_hat, mask):
        starts.append([])
        return searched(task, base, nu_hat, mask)

    def refine(fun, jac, x0, *args, **kwargs):
        starts[-1].append(np.array(x0))
        return real_refine(fun, jac, x0, *args, **kwargs)

    real_refine = selection.refine
    monkeypatch.setattr(selection, "_local_search", local_search)
    monkeypatch.setattr(selection, "refine", refine)
    x = GM2.simulate(2**14, rng=5)
    with ThreadPoolExecutor(1) as one:  # one search at a time, in this process
        res = select(x, FREQ, families=("GM", "WN", "RW"), max_counts={"GM": 2}, executor=one)
    assert sum(len(s) for s in starts) > len(starts) > 0
    for searched_from in starts:
        for i, x0 in enumerate(searched_from):
            assert not any(np.array_equal(x0, y) for y in searched_from[:i])
    for parent, child in res.graph.edges:
        assert res.fits[child].objective <= res.fits[parent].objective * (1 + 1e-12)


def test_nesting_guarantee_with_structured_and_vector_families(threads):
    """AR(1) (vector phi) and BI families in the lattice; the padded process is shrunk through
    its declared scale role (AR sigma2: variance, BI B: amplitude)."""
    x = GM1.simulate(2**13, rng=16)
    res = select(x, FREQ, families=("AR(1)", "WN", "BI"), executor=threads)
    assert res.graph.number_of_nodes() == 7
    for parent, child in res.graph.edges:
        assert res.fits[child].objective <= res.fits[parent].objective * (1 + 1e-12), (parent, child)
    assert res.best.model.name == "AR(1)+WN"  # the GM + WN truth, sampled


def _brute_force_edges(max_counts: dict[str, int]) -> set[tuple[tuple[int, ...], tuple[int, ...]]]:
    fams = list(max_counts)
    nodes = [c for c in itertools.product(*(range(max_counts[f] + 1) for f in fams)) if any(c)]
    return {(a, b) for a in nodes for b in nodes
            if sum(b) == sum(a) + 1 and all(y >= x for x, y in zip(a, b))}


def test_lattice_and_nesting_graph_match_brute_force():
    counts = {"GM": 3, "WN": 1, "RW": 1, "QN": 1, "RR": 1}
    models = candidate_lattice(tuple(counts), {"GM": 3})
    assert len(models) == 4 * 2**4 - 1
    graph = nested_graph(models)

    def vector(name: str) -> tuple[int, ...]:
        fams = [p.family for p in graph.nodes[name]["model"].processes]
        return tuple(fams.count(f) for f in counts)

    edges = {(vector(a), vector(b)) for a, b in graph.edges}
    assert edges == _brute_force_edges(counts)
    assert graph.edges["GM+WN", "2*GM+WN"]["added"] == "GM"


# ---------------------------------------------------------------- executors and reproducibility
def _ranking(res: SelectionResult) -> list[tuple[str, float, float]]:
    return [(r.model, r.objective, r.criterion) for r in res.ranking]


def test_thread_and_process_pools_give_the_same_ranking(threads):
    x = QWR.simulate(2**13, rng=6)
    kwargs = {"candidates": QWR_CANDIDATES[:4], "rng": 3}
    a = select(x, FREQ, executor=threads, **kwargs)
    with ProcessPoolExecutor(2) as pool:
        b = select(x, FREQ, executor=pool, **kwargs)
    c = select(x, FREQ, **kwargs)  # the default executor
    assert _ranking(a) == _ranking(b) == _ranking(c)
    d = select(x, FREQ, executor=threads, **kwargs)  # reproducible
    assert _ranking(a) == _ranking(d)
    assert a.best.model.to_spec() == d.best.model.to_spec()


def test_default_executor_keeps_a_few_fits_in_this_process(threads, monkeypatch):
    """Up to 8 fits (candidates x columns) and no executor: the fits run on a thread of this
    process, with the same ranking as on a process pool; more fits start 2 worker processes."""
    import stochmod.fit.selection as selection_module

    x = QWR.simulate(2**13, rng=6)
    kwargs = {"candidates": QWR_CANDIDATES[:4], "rng": 3}
    with ProcessPoolExecutor(2) as pool:
        on_pool = select(x, FREQ, executor=pool, **kwargs)
    started: list[int] = []
    pool_of = selection_module.process_pool

    def counted(max_workers: int, *args, **options):
        started.append(max_workers)
        return pool_of(max_workers, *args, **options)

    monkeypatch.setattr(selection_module, "process_pool", counted)
    assert _ranking(select(x, FREQ, **kwargs)) == _ranking(on_pool) and started == []
    both = select(np.column_stack([x, x[::-1]]), FREQ, **kwargs)  # 8 fits: still here
    assert started == [] and _ranking(both[0]) == _ranking(on_pool)
    select(np.column_stack([x, x[::-1], x]), FREQ, **kwargs)  # 12 fits: a process pool
    assert started == [2]


def test_a_local_pool_forks_its_workers_before_v_starts_on_a_thread(monkeypatch):
    """V (eq. 17) runs on a thread of this process beside a local process pool. The pool's
    workers must exist before that thread starts: a worker forked while the thread held
    numba's compiler lock (loading eq. 17's compiled loops) would wait forever on its own
    first compiled call. (It did: test_cli_calibrate hung in a worker's GM closed form.)"""
    import stochmod.fit.selection as selection_module

    covariance = selection_module._covariance
    workers_at_start: list[int] = []
    pool = ProcessPoolExecutor(2)

    def watched(item):
        workers_at_start.append(len(pool._processes or {}))
        return covariance(item)

    monkeypatch.setattr(selection_module, "_covariance", watched)
    x = QWR.simulate(2**12, rng=8)
    with pool:
        select(x, FREQ, candidates=QWR_CANDIDATES[:2], executor=pool, rng=1)
    assert workers_at_start == [2]


def test_dask_distributed_executor_works_unchanged():
    # a dask.distributed client's executor on a local cluster of worker processes: the fits are
    # pickled to other processes and come back through dask futures; same ranking as the default
    from distributed import Client, LocalCluster

    x = QWR.simulate(2**13, rng=6)
    kwargs = {"candidates": QWR_CANDIDATES[:4], "rng": 3}
    with (LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                       dashboard_address=None) as cluster,
          Client(cluster) as client):
        on_dask = select(x, FREQ, executor=client.get_executor(), **kwargs)
    assert _ranking(on_dask) == _ranking(select(x, FREQ, **kwargs))


def test_column_result_independent_of_other_columns(threads):
    x = GM1.simulate(2**13, rng=7)
    y = QWR.simulate(2**13, rng=8)
    alone = select(x, FREQ, candidates=GM_COUNTS[:2], executor=threads)
    both = select(np.column_stack([y, x]), FREQ, candidates=GM_COUNTS[:2], executor=threads)
    assert _ranking(both[1]) == _ranking(alone)


# ---------------------------------------------------------------- the criterion
def test_wvic_is_registered_through_the_hook():
    assert "wvic" in criterion_names()
    assert get_criterion("wvic") is WVIC


@pytest.mark.parametrize("spec", ["WN", "GM+WN", "QN+WN+RW"])
def test_optimism_is_twice_the_number_of_parameters_when_omega_is_inverse_v(spec):
    truth = {"WN": model("WN(sigma2=2.0)"), "GM+WN": GM1, "QN+WN+RW": QWR}[spec]
    fit = gmwm(truth.simulate(2**12, rng=9), spec, FREQ)
    V = np.linalg.inv(fit.omega)
    p = int(fit.free_mask.sum())
    assert optimism(fit, covariance=V) == pytest.approx(2 * p, rel=1e-9)


def test_optimism_equals_monte_carlo_out_of_sample_excess():
    """For a model linear in its parameters (WN + RW + QN) and a fixed Omega, the expected
    out-of-sample minus in-sample objective is exactly 2 tr(Omega D B V): Monte Carlo check
    with Gaussian draws of the empirical WV around the truth."""
    truth = model("WN(sigma2=1.0) + QN(Q2=0.3) + RW(sigma2=0.01)")
    J = 6
    template = wvar(truth.simulate(2**10, rng=0), FREQ, levels=J)
    nu = truth.wv(J)
    sd = np.full(J, 0.03 * nu.min())  # equal noise at every level: P then removes about half
    corr = 0.5 ** np.abs(np.subtract.outer(np.arange(J), np.arange(J)))
    V = corr * np.outer(sd, sd)
    L = np.linalg.cholesky(V)
    gen = np.random.default_rng(10)
    excess, pens = [], []
    for _ in range(200):
        draw = attrs.evolve(template, wv=nu + L @ gen.standard_normal(J))
        fit = gmwm(draw, "WN+QN+RW", FREQ, weighting="identity", n_starts=0, n_random=0)
        fresh = nu + L @ gen.standard_normal(J)
        r = fresh - fit.model_wv()
        excess.append(r @ fit.omega @ r - fit.objective)
        pens.append(optimism(fit, covariance=V))
    excess = np.asarray(excess)
    se = excess.std(ddof=1) / np.sqrt(excess.size)
    assert np.ptp(pens) < 1e-6 * np.mean(pens)  # linear model: the same at every fit
    assert abs(excess.mean() - np.mean(pens)) < 4 * se
    assert abs(excess.mean() - 2 * np.trace(V)) > 4 * se  # the test can tell tr(PV) from tr(V)


def test_custom_criterion_plugin_changes_the_ranking(threads):
    class ObjectiveOnly:
        name = "objective_only"

        def __call__(self, fit):
            return float(fit.objective)

    class Plugin:
        @hookimpl
        def stochmod_criteria(self):
            return [ObjectiveOnly()]

    plugin = Plugin()
    stochmod.register_plugin(plugin)
    try:
        x = GM1.simulate(2**13, rng=11)
        res = select(x, FREQ, candidates=GM_COUNTS, criterion="objective_only", executor=threads)
        objectives = [r.objective for r in res.ranking if r.identified]
        assert objectives == sorted(objectives)
        assert all(r.optimism == 0.0 for r in res.ranking)
    finally:
        stochmod.unregister_plugin(plugin)
    assert "objective_only" not in criterion_names()


def test_unidentified_fit_is_flagged():
    """A GM whose correlation time ran to infinity only determines sigma2 * beta."""
    x = model("RW(sigma2=1e-4) + WN(sigma2=1.0)").simulate(2**12, rng=12)
    fit = gmwm(x, "GM+WN", FREQ)
    degenerate = attrs.evolve(fit, model=fit.model.with_vector([1e-14, 1e8, fit.model.vector()[-1]]))
    assert not identified(degenerate)
    assert identified(gmwm(GM1.simulate(2**14, rng=13), "GM+WN", FREQ))


# ---------------------------------------------------------------- results
def test_summary_and_to_dict(threads):
    res = select(QWR.simulate(2**12, rng=14), FREQ, candidates=QWR_CANDIDATES[:3], executor=threads)
    text = res.summary()
    assert res.best.model.name in text and "J-test" in text
    d = res.to_dict()
    assert d["selected"] == res.best.model.name
    assert [r["model"] for r in d["ranking"]] == [r.model for r in res.ranking]
    assert ["WN", "QN+WN"] in d["edges"]


def test_progress_bar_and_its_missing_extra(threads, capsys, monkeypatch):
    x = QWR.simulate(2**10, rng=15)
    select(x, FREQ, candidates=["WN", "QN+WN"], executor=threads, progress=True)
    assert "select" in capsys.readouterr().err
    # automatic mode draws nothing when stderr is not a terminal (here: captured)
    monkeypatch.setattr("stochmod.fit.selection._AUTO_PROGRESS", 0)
    select(x, FREQ, candidates=["WN", "QN+WN"], executor=threads)
    assert "select" not in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    with pytest.raises(ImportError, match=r"stochmod\[progress\]"):
        select(x, FREQ, candidates=["WN"], executor=threads, progress=True)
    assert select(x, FREQ, candidates=["WN"], executor=threads).best.model.name == "WN"


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"candidates": []}, InputError, "candidates is empty"),
        ({"candidates": ["GM+XX"]}, UnknownProcessError, "XX"),
        ({"families": ("GM", "NOPE")}, UnknownProcessError, "NOPE"),
        ({"families": ()}, InputError, "families is empty"),
        ({"max_counts": {"AR": 2}}, InputError, "max_counts"),
        ({"max_counts": {"GM": -1}}, InputError, "non-negative"),
        ({"candidates": ["GM+WN", "GM+WN"]}, InputError, "twice"),
        ({"criterion": "bic"}, InputError, "unknown selection criterion"),
        ({"weighting": "bootstrap"}, InputError, "weighting"),
        ({"executor": object()}, InputError, "executor"),
        ({"rng": -1}, InputError, "rng"),
        ({"candidates": ["3*GM+WN"], "levels": 4}, InputError, "free parameters"),
        ({"candidates": ["WN(sigma2=1.0)"]}, SpecError, "no free parameter"),
    ],
)
def test_bad_arguments_raise_clear_errors(kwargs, error, match, threads):
    kwargs.setdefault("executor", threads)
    x = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(error, match=match):
        select(x, FREQ, **kwargs)


@pytest.mark.parametrize(
    "x, match",
    [
        (np.ones(1000), "constant"),
        (np.r_[np.random.default_rng(0).standard_normal(999), np.nan], "non-finite"),
        (np.zeros((0, 2)), "empty"),
        (np.zeros((2, 2, 2)), "1-D or 2-D"),
    ],
)
def test_bad_signals_raise(x, match):
    with pytest.raises(InputError, match=match):
        select(x, FREQ, candidates=["WN"])


def test_freq_is_required():
    with pytest.raises(InputError, match="freq"):
        select(np.random.default_rng(0).standard_normal(100), candidates=["WN"])


# ---------------------------------------------------------------- real data (peer: R gmwm)
@pytest.mark.data
@pytest.mark.slow
def test_real_gyro_x_selection_runs_without_warnings(threads):
    path = DATA / "imudata" / "adis_16405_imu1.npz"
    if not path.exists():
        pytest.skip(f"real data not available at {path}")
    with np.load(path) as z:
        x = np.deg2rad(z["Gyro_X"].astype(float))
    x -= x.mean()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = select(x, FREQ, candidates=["GM+WN", "2*GM+WN", "3*GM+WN", "QN+WN+RW+RR"],
                     executor=threads)
    # Peer: R gmwm's rank_models on the same data (reference/adis_16405_imu1_gyroX_gmwm.json)
    # ranks 2AR1+WN, 3AR1+WN, (3AR1+WN+QN+RW+DR), AR1+WN, QN+WN+RW+DR; GM = AR1 at 100 Hz and
    # R's deterministic drift DR has the WV shape of our random ramp RR.
    assert [r.model for r in res.ranking] == ["2*GM+WN", "3*GM+WN", "GM+WN", "QN+WN+RW+RR"]
    for parent, child in res.graph.edges:
        assert res.fits[child].objective <= res.fits[parent].objective * (1 + 1e-12)


def test_a_component_of_negligible_amplitude_is_not_identified():
    from stochmod.fit.criteria import identified, negligible_components

    x = np.random.default_rng(7).normal(size=2**14)
    fit = stochmod.gmwm(x, "WN+QN(Q2=1e-30)", 100.0)
    assert negligible_components(fit) == ["QN"]
    assert not identified(fit)
    assert identified(stochmod.gmwm(x, "WN", 100.0))


def _loaded(name: str) -> bool:
    import sys

    return name in sys.modules


def test_process_pool_workers_import_the_warm_modules_as_they_start():
    """A worker imports the `warm` modules before its first task (a missing one is skipped:
    the task that needs it reports it); without `warm` it has only what it inherited."""
    import sys

    from stochmod.core.parallel import process_pool

    assert "tabnanny" not in sys.modules  # a standard module nothing here imports
    with process_pool(1, warm=("tabnanny", "no_such_module_for_the_test")) as pool:
        assert pool.submit(_loaded, "tabnanny").result()
    with process_pool(1) as pool:
        assert not pool.submit(_loaded, "tabnanny").result()


def _frozen() -> int:
    import gc

    return gc.get_freeze_count()


def test_process_pool_workers_do_not_collect_what_they_inherited():
    """While the pool runs, this process's objects sit in the collector's permanent generation,
    which a forked worker inherits (its collections skip them); shutdown releases them."""
    import gc
    import multiprocessing

    from stochmod.core.parallel import process_pool

    before = gc.get_freeze_count()
    with process_pool(1) as pool:
        assert gc.get_freeze_count() > before
        inherited = pool.submit(_frozen).result()
    assert gc.get_freeze_count() == 0
    if multiprocessing.get_start_method() == "fork":
        assert inherited > 0


def test_the_final_weighting_refits_the_selected_model_only(threads):
    """``final_weighting="model"``: the ranking is the diagonal one; the selected WN + RW is
    the fit ``gmwm(..., weighting="model")`` gives, its intervals from the fitted model's V as
    that weighting declares; with "identity" they keep the selection's V. A weighting that
    needs the signal is refused (the refit has the WV only)."""
    x = model("WN(sigma2=1e-4) + RW(sigma2=1e-9)").simulate(2**16, rng=5001)
    candidates = ["WN", "WN+RW", "GM+WN"]
    plain = select(x, FREQ, candidates=candidates, executor=threads)
    again = select(x, FREQ, candidates=candidates, executor=threads, final_weighting="model")
    assert again.ranking == plain.ranking and plain.final_weighting is None
    assert again.best.model.name == plain.best.model.name == "WN+RW"
    assert again.final_weighting == again.best.weighting == "model"
    direct = gmwm(x, "WN+RW", FREQ, weighting="model")
    np.testing.assert_allclose(again.best.model.vector(), direct.model.vector(), rtol=1e-6)
    assert not np.allclose(again.best.model.vector(), plain.best.model.vector(), rtol=1e-3, atol=0)
    np.testing.assert_array_equal(again.best.wv_covariance, again.best.model_based_covariance())
    np.testing.assert_allclose(again.best.std_errors, direct.std_errors, rtol=1e-5)
    # the selected fit is the pilot: Omega is the inverse model variance of eq. 17 at it
    V = stochmod.fit.weighting.model_covariance(plain.best.model, plain.empirical.n_coef,
                                                plain.empirical.wavelet)
    np.testing.assert_allclose(np.diag(again.best.omega), 1.0 / np.diag(V), rtol=1e-12)
    ols = select(x, FREQ, candidates=candidates, executor=threads, final_weighting="identity")
    np.testing.assert_array_equal(ols.best.wv_covariance, plain.wv_covariance)
    with pytest.raises(InputError, match="final_weighting 'optimal' needs the signal"):
        select(x, FREQ, candidates=["WN"], final_weighting="optimal", executor=threads)
    assert "fitted again with the model weighting" in again.summary()
    assert again.to_dict()["final_weighting"] == "model"
    with pytest.raises(InputError, match="unknown weighting 'nope'"):
        select(x, FREQ, candidates=["WN"], final_weighting="nope", executor=threads)
