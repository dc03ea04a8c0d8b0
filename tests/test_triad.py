"""stochmod.fit.triad: one model structure for the three axes of a sensor (summed criterion)."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import attrs
import numpy as np
import pytest

import stochmod
from stochmod.core.errors import InputError
from stochmod.fit.triad import equivalences, group_triads, triad_select

FS = 100.0
N = 2**15
CANDIDATES = ["WN", "GM+WN", "2*GM+WN", "WN+RW"]
# one structure (GM + WN), different parameters per axis (rad/s, 1/s)
AXES = {"gyro_x": (0.2, 4e-6, 1e-4), "gyro_y": (0.1, 2e-6, 2e-4), "gyro_z": (0.3, 6e-6, 1.5e-4)}


@pytest.fixture(scope="module")
def selections():
    x = np.column_stack([
        stochmod.model_from_spec({"processes": [
            {"family": "GM", "params": {"beta": b, "sigma2": s2}},
            {"family": "WN", "params": {"sigma2": w}}]}, FS).simulate(N, rng=40 + i)
        for i, (b, s2, w) in enumerate(AXES.values())])
    with ThreadPoolExecutor(1) as pool:
        return stochmod.select(x, FS, candidates=CANDIDATES, names=list(AXES), executor=pool)


def test_three_axes_from_one_structure_get_that_structure(selections):
    choice = triad_select(selections)
    assert choice.structure == "GM+WN" and choice.sensor == "gyro"
    assert choice.columns == tuple(AXES)
    # the summed criterion is the sum of the per-axis criteria, by candidate
    for name in CANDIDATES:
        by_axis = [next(r.criterion for r in s.ranking if r.model == name) for s in selections]
        assert choice.summed[name] == pytest.approx(math.fsum(by_axis), rel=1e-12)
    # parameters stay per axis: each axis keeps its own fit of the structure
    for sel in selections:
        fit = choice.fits[sel.column]
        assert fit is sel.fits["GM+WN"]
        beta = fit.model.to_spec()["processes"][0]["params"]["beta"]
        assert beta == pytest.approx(AXES[sel.column][0], rel=0.6)
    assert "summed" in choice.summary() and choice.to_dict()["structure"] == "GM+WN"


@pytest.fixture(scope="module")
def walk_selections():
    """WN + RW on a short record (41 s): a GM+WN fit's correlation time runs past the record."""
    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-8)", FS)
    x = np.column_stack([truth.simulate(2**12, rng=60 + i) for i in range(3)])
    with ThreadPoolExecutor(1) as pool:
        return stochmod.select(x, FS, candidates=["WN", "GM+WN", "WN+RW"],
                               names=["gyro_x", "gyro_y", "gyro_z"], executor=pool)


def test_a_majority_of_identified_axes_is_enough(selections):
    """GM+WN unidentified on one axis of three still wins on the summed criterion; on two of
    three it does not (WN, identified everywhere, does)."""
    def unidentified(sel):
        ranking = tuple(attrs.evolve(r, identified=False) if r.model == "GM+WN" else r
                        for r in sel.ranking)
        return attrs.evolve(sel, ranking=ranking)

    one = [unidentified(selections[0]), *selections[1:]]
    assert triad_select(one).structure == "GM+WN"
    two = [unidentified(s) for s in selections[:2]] + [selections[2]]
    choice = triad_select(two)
    assert choice.identified["GM+WN"] == 1 and choice.identified[choice.structure] >= 2


def test_gm_beyond_the_record_is_a_random_walk(walk_selections):
    record = 2**12 / FS
    n_walks = 0
    for sel in walk_selections:
        gm = sel.fits["GM+WN"]
        tc = 1.0 / gm.model.to_spec()["processes"][0]["params"]["beta"]
        found = equivalences(gm, sel.column, "rad/s")
        assert [(e.component, e.equivalent) for e in found] == (
            [("GM", "random walk")] if tc > record else [])
        n_walks += bool(found)
    assert n_walks >= 1
    # one axis alone prefers GM+WN (this seed), the triad's summed criterion picks WN+RW for all
    assert {s.best.model.name for s in walk_selections} == {"GM+WN", "WN+RW"}
    choice = triad_select(walk_selections)
    assert choice.structure == "WN+RW"


def test_simpler_equivalent_preferred_when_the_criterion_cannot_separate(walk_selections):
    """Make GM+WN (its GM beyond the record) win by 1e-9 on gyro_x: the random walk it is
    equivalent to (WN+RW) is within the penalty of one parameter, so it is preferred."""
    sel = walk_selections[0]
    rows = {r.model: r for r in sel.ranking}
    assert equivalences(sel.fits["GM+WN"], sel.column, "rad/s")  # Tc beyond the record
    rigged = attrs.evolve(rows["GM+WN"], criterion=rows["WN+RW"].criterion - 1e-9, identified=True)
    ranking = (rigged, *(r for r in sel.ranking if r.model != "GM+WN"))
    choice = triad_select([attrs.evolve(sel, ranking=ranking)])
    assert choice.replaced == "GM+WN" and choice.structure == "WN+RW"
    # a clear win (beyond one parameter's penalty, optimism / n_params) is kept
    penalty = rows["GM+WN"].optimism / rows["GM+WN"].n_params
    assert penalty > max(rows["GM+WN"].optimism - rows["WN+RW"].optimism, 0)
    clear = attrs.evolve(rigged, criterion=rows["WN+RW"].criterion - 1.01 * penalty)
    choice = triad_select([attrs.evolve(sel, ranking=(clear, *ranking[1:]))])
    assert choice.structure == "GM+WN" and choice.replaced is None
    assert "random walk" in choice.summary()


def test_bad_triads(selections):
    assert group_triads(["gyro_x", "accel_x", "gyro_y"],
                        {"gyro_x": "rad/s", "gyro_y": "rad/s", "accel_x": "m/s^2"}) == {
        "gyro": ["gyro_x", "gyro_y"], "accel": ["accel_x"]}
    with pytest.raises(InputError, match="mix"):
        triad_select(selections, {"gyro_x": "rad/s", "gyro_y": "m/s^2", "gyro_z": "rad/s"})
    with pytest.raises(InputError, match="at least one"):
        triad_select([])


def test_calibrate_triad_gives_every_axis_of_a_sensor_the_same_structure(walk_selections, tmp_path,
                                                                          capsys):
    import json

    from stochmod.cli import main

    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-8)", FS)
    cols = {f"gyro_{a}": truth.simulate(2**12, rng=60 + i) for i, a in enumerate("xyz")}
    path = tmp_path / "imu.npz"
    np.savez(path, freq=FS, **cols)
    out = tmp_path / "out"
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "GM+WN", "WN+RW", "--no-plots",
                 "--out", str(out), "--triad"]) == 0
    assert "structures chosen per triad: gyro_x, gyro_y, gyro_z: WN+RW" in capsys.readouterr().out
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "GM+WN", "WN+RW", "--no-plots",
                 "--out", str(out), "--triad", "--verbose"]) == 0
    assert "summed wvic" in capsys.readouterr().out  # the criteria with --verbose
    report = json.loads((out / "calibration.json").read_text())
    (triad,) = report["triads"]
    assert triad["structure"] == triad_select(walk_selections).structure == "WN+RW"
    assert {report["columns"][c]["name"] for c in cols} == {"WN+RW"}


def test_calibrate_triad_with_a_final_weighting_refits_the_common_structure(tmp_path, capsys):
    """``--triad --final-weighting model``: each axis of the chosen structure is fitted again
    with the model weighting, as ``gmwm(..., weighting="model")`` fits it."""
    import json

    from stochmod.cli import main

    truth = stochmod.model_from_spec("WN(sigma2=1e-4) + RW(sigma2=1e-8)", FS)
    cols = {f"gyro_{a}": truth.simulate(2**12, rng=60 + i) for i, a in enumerate("xyz")}
    path = tmp_path / "imu.npz"
    np.savez(path, freq=FS, **cols)
    out = tmp_path / "out"
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "GM+WN", "WN+RW",
                 "--no-plots", "--report", "--out", str(out), "--triad", "--final-weighting",
                 "model"]) == 0
    printed = capsys.readouterr().out
    again = "fitted again after the ranking (diagonal weighting) with the model weighting"
    assert printed.count(again) == 3
    page = (out / "report.html").read_text()
    assert page.count(f"model structure chosen per triad; {again}") == 3
    report = json.loads((out / "calibration.json").read_text())
    cal = stochmod.Calibration.read(out / "calibration.json")
    for c, x in cols.items():
        assert report["columns"][c]["final_weighting"] == "model"
        direct = stochmod.gmwm(x, "WN+RW", FS, weighting="model")
        np.testing.assert_allclose(cal.models[c].vector(), direct.model.vector(), rtol=1e-6)
