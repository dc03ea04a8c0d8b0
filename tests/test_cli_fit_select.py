"""``stochmod fit``, ``stochmod select`` and ``stochmod processes``."""

from __future__ import annotations

import json

import numpy as np
import pytest

import stochmod
from stochmod.cli import main

FREQ = 100.0


@pytest.fixture(scope="module")
def two_columns(tmp_path_factory):
    """CSV with a header: a white noise (sigma2 = 4) and a GM + WN (beta = 2/s)."""
    wn = stochmod.model_from_spec("WN(sigma2=4.0)", FREQ).simulate(2**14, rng=1)
    gm = stochmod.model_from_spec("GM(beta=2.0, sigma2=1.0) + WN(sigma2=0.5)", FREQ).simulate(2**14, rng=2)
    path = tmp_path_factory.mktemp("cli") / "rec.csv"
    np.savetxt(path, np.column_stack([wn, gm]), delimiter=",", header="white,markov", comments="")
    return path


def run_json(args: list[str], capsys) -> dict:
    assert main(args) == 0
    return json.loads(capsys.readouterr().out)


def test_fit_json_recovers_the_truth_and_equals_the_api(two_columns, capsys):
    out = run_json(["fit", str(two_columns), "--freq", "100", "--column", "markov",
                    "--model", "GM+WN", "--json"], capsys)
    fit = out["columns"]["markov"]
    gm, wn = fit["model"]["processes"]
    assert gm["params"]["beta"] == pytest.approx(2.0, rel=0.5)
    assert gm["params"]["sigma2"] == pytest.approx(1.0, rel=0.3)
    assert wn["params"]["sigma2"] == pytest.approx(0.5, rel=0.1)
    x = np.loadtxt(two_columns, delimiter=",", skiprows=1)[:, 1]
    api = stochmod.gmwm(x, "GM+WN", FREQ)
    assert fit["objective"] == pytest.approx(api.objective, rel=1e-12)
    assert out["freq"] == FREQ


def test_fit_text_report_per_column(two_columns, capsys):
    assert main(["fit", str(two_columns), "--freq", "100", "--model", "WN"]) == 0
    text = capsys.readouterr().out
    assert "column white" in text and "column markov" in text and "GMWM fit of WN" in text


def test_fit_bad_model_is_a_one_line_error(two_columns, capsys):
    assert main(["fit", str(two_columns), "--freq", "100", "--model", "GM+FOO"]) == 2
    err = capsys.readouterr().err
    assert "FOO" in err and err.count("\n") == 1
    with pytest.raises(SystemExit):
        main(["fit", str(two_columns), "--freq", "100"])  # --model is required


def test_select_json_picks_each_columns_model(two_columns, capsys):
    out = run_json(["select", str(two_columns), "--freq", "100", "--candidates", "WN", "GM+WN",
                    "2*GM+WN", "--json"], capsys)
    cols = out["columns"]
    assert cols["white"]["selected"] == "WN"
    assert cols["markov"]["selected"] == "GM+WN"
    ranking = cols["markov"]["ranking"]
    assert {r["model"] for r in ranking} == {"WN", "GM+WN", "2*GM+WN"}
    for row in ranking:
        assert row["criterion"] == pytest.approx(row["objective"] + row["optimism"], rel=1e-12)
    assert ["GM+WN", "2*GM+WN"] in cols["markov"]["edges"]


def test_select_lattice_text(two_columns, capsys):
    assert main(["select", str(two_columns), "--freq", "100", "--column", "white", "--families",
                 "WN", "RW", "--weighting", "optimal", "--levels", "8"]) == 0
    text = capsys.readouterr().out
    assert "3 candidates" in text and "selected WN" in text and "optimal weighting" in text


def test_select_unknown_family_is_a_one_line_error(two_columns, capsys):
    assert main(["select", str(two_columns), "--freq", "100", "--families", "GM", "XYZ"]) == 2
    assert "XYZ" in capsys.readouterr().err


def test_select_max_count_option(two_columns, capsys):
    base = ["select", str(two_columns), "--freq", "100", "--column", "white", "--levels", "8"]
    out = run_json(base + ["--families", "WN", "RW", "--max-count", "RW=0", "--json"], capsys)
    assert [r["model"] for r in out["columns"]["white"]["ranking"]] == ["WN"]
    for bad in ("RW", "RW=x", "=2", "RW=-1"):
        assert main(base + ["--families", "WN", "RW", "--max-count", bad]) == 2
        assert "--max-count" in capsys.readouterr().err


def test_processes_lists_every_registered_family(capsys):
    out = run_json(["processes", "--json"], capsys)["processes"]
    assert [p["family"] for p in out] == stochmod.process_names()
    gm = next(p for p in out if p["family"] == "GM")
    assert [(q["name"], q["unit"], q["domain"]) for q in gm["parameters"]] == [
        ("beta", "1/s", "positive"), ("sigma2", "u^2", "positive")]
    assert {q["name"] for q in gm["physical"]} == {"Tc", "sigma"}
    assert main(["processes"]) == 0
    text = capsys.readouterr().out
    for name in stochmod.process_names():
        assert f"{name}: " in text
