"""Outage studies: the filter with the true error model beats a white-noise-only filter in every
outage and reports an honest covariance (NEES) where the white-noise filter does not; the
horizontal error against an independent chord-length computation; statistics and input errors."""

from __future__ import annotations

import numpy as np
import pytest

import stochmod
from stochmod.core.errors import InputError, SpecError
from stochmod.nav import earth
from stochmod.nav.emulate import AXES, Segment, Trajectory
from stochmod.nav.study import (
    OutageStudy,
    horizontal_error,
    max_outage_errors,
    outage_study,
    truth_over_record,
)

FS = 50.0
WN, GM = stochmod.WN, stochmod.GM
GYRO = (WN.from_density(3e-4, FS) + GM.from_correlation_time(60.0, 3e-4)).bind(FS)
ACCEL = (WN.from_density(2e-3, FS) + GM.from_correlation_time(60.0, 5e-3)).bind(FS)
TRUTH = {a: GYRO if a.startswith("gyro") else ACCEL for a in AXES}
WHITE = {a: stochmod.Model((m.processes[0],)).bind(FS) for a, m in TRUTH.items()}
PROFILE = [Segment(20, speed=15), Segment(15, turn=90), Segment(30, speed=20),
           Segment(20, turn=-120, speed=12), Segment(30), Segment(20, turn=60, speed=18),
           Segment(30, speed=22), Segment(15, turn=-90)]
OUTAGES = [(60.0, 30.0), (130.0, 30.0)]


@pytest.mark.slow
def test_true_model_beats_white_noise_and_is_honest() -> None:
    study = outage_study({"true": TRUTH, "white": WHITE}, TRUTH, runs=3, seed=1,
                         profile=PROFILE, rate=FS, outages=OUTAGES, gyro_bias_sd=1e-3,
                         accel_bias_sd=0.02)
    true_stats, white_stats = study.statistics("true"), study.statistics("white")
    assert np.all(true_stats[:, 0] < white_stats[:, 0])  # mean max error, every outage
    assert np.all(true_stats[:, 1] < white_stats[:, 1])  # median
    assert study.n_states == {"true": 21, "white": 15}
    # NEES of 9 states averaged over ~2000 epochs: the true model's filter near 9, the
    # white-noise filter (unmodelled Gauss-Markov drift) several times too confident
    assert 4.5 < np.mean(study.nees["true"]) < 18.0
    assert np.mean(study.nees["white"]) > 3 * np.mean(study.nees["true"])
    text = study.summary()
    assert "130+30 s" in text and "white" in text and "NEES" in text


def _line(t: np.ndarray, north: float, east: float) -> Trajectory:
    lat0, lon0, h = 46.5, 6.6, 400.0
    r_n, r_e = earth.principal_radii(np.radians(lat0))
    lat = lat0 + np.degrees(north * t / (r_n + h))
    lon = lon0 + np.degrees(east * t / ((r_e + h) * np.cos(np.radians(lat0))))
    z = np.zeros((t.size, 3))
    return Trajectory(t, lat, lon, np.full(t.size, h), z, z)


def test_horizontal_error_matches_ecef_chord() -> None:
    t = np.linspace(0.0, 10.0, 11)
    ref = _line(t, 3.0, -2.0)
    rng = np.random.default_rng(3)
    lat = ref.lat + rng.normal(0, 2e-4, t.size)  # ~20 m offsets
    lon = ref.lon + rng.normal(0, 2e-4, t.size)
    got = horizontal_error(ref, t, lat, lon)
    # independent: straight-line distance between the two ECEF points at the same height
    chord = np.linalg.norm(earth.lla_to_ecef(lat, lon, ref.height)
                           - earth.lla_to_ecef(ref.lat, ref.lon, ref.height), axis=-1)
    np.testing.assert_allclose(got, chord, rtol=1e-4)
    windows = [(0.0, 4.0), (5.0, 10.0)]
    np.testing.assert_allclose(max_outage_errors(ref, t, lat, lon, windows),
                               [got[t <= 4].max(), got[t >= 5].max()])
    with pytest.raises(InputError, match="no solution epochs"):
        max_outage_errors(ref, t, lat, lon, [(20.0, 30.0)])


def test_statistics_and_summary() -> None:
    e = np.array([[1.0, 10.0], [2.0, 30.0], [9.0, 20.0]])
    study = OutageStudy(("a",), ((5.0, 60.0), (100.0, 60.0)), {"a": e}, {"a": np.array([9.0])},
                        runs=3, seed=0)
    np.testing.assert_allclose(study.statistics("a")[:, 0], [4.0, 20.0])
    np.testing.assert_allclose(study.statistics("a")[:, 1], [2.0, 20.0])
    np.testing.assert_allclose(study.statistics("a")[:, 2], [8.3, 29.0])  # linear interpolation
    with pytest.raises(InputError, match="no filter 'b'"):
        study.statistics("b")
    assert "100+60 s" in study.summary()


def test_bad_input() -> None:
    with pytest.raises(SpecError, match="gyro_z"):
        outage_study({"x": {a: TRUTH[a] for a in AXES if a != "gyro_z"}}, TRUTH, runs=1)
    with pytest.raises(SpecError, match="accel_x"):
        outage_study({"x": TRUTH}, {a: TRUTH[a] for a in AXES if a != "accel_x"}, runs=1)
    with pytest.raises(InputError, match="runs"):
        outage_study({"x": TRUTH}, TRUTH, runs=0)
    with pytest.raises(InputError, match="at least one filter"):
        outage_study({}, TRUTH)
    with pytest.raises(InputError, match="inside the"):
        outage_study({"x": TRUTH}, TRUTH, runs=1, profile=PROFILE[:2], rate=FS,
                     outages=[(20.0, 60.0)])
    with pytest.raises(InputError, match="gyro_bias_sd"):
        outage_study({"x": TRUTH}, TRUTH, runs=1, profile=PROFILE[:2], rate=FS,
                     outages=[(1.0, 2.0)], gyro_bias_sd=-1.0)


def test_workers_give_the_serial_result() -> None:
    # each run draws from its own stream (seed, r): spreading the runs over processes changes
    # nothing, to the bit
    profile, outages = [Segment(15, speed=10), Segment(10, turn=60), Segment(15)], [(20.0, 10.0)]
    kw = {"runs": 3, "seed": 5, "profile": profile, "rate": FS, "outages": outages,
          "gyro_bias_sd": 1e-3, "accel_bias_sd": 0.02}
    filters = {"true": TRUTH, "white": WHITE}
    seen = []
    serial = outage_study(filters, TRUTH, **kw)
    parallel = outage_study(filters, TRUTH, workers=2, progress=lambda r, n: seen.append((r, n)),
                            **kw)
    for name in filters:
        np.testing.assert_array_equal(parallel.max_error[name], serial.max_error[name])
        np.testing.assert_array_equal(parallel.nees[name], serial.nees[name])
        np.testing.assert_array_equal(parallel.end_nees[name], serial.end_nees[name])
        np.testing.assert_array_equal(parallel.end_ratio[name], serial.end_ratio[name])
        np.testing.assert_array_equal(parallel.rejected[name], serial.rejected[name])
    assert serial.end_nees["true"].shape == (3, 1) and np.all(serial.end_ratio["true"] > 0)
    assert parallel.n_states == serial.n_states
    assert sorted(seen) == [(r, n) for r in range(3) for n in sorted(filters)]
    assert np.all(serial.max_error["true"] > 0)
    with pytest.raises(InputError, match="workers"):
        outage_study(filters, TRUTH, workers=0, **kw)


# A degenerate fit as the truth (docs/outages.md): a Gauss-Markov gyro component correlated far
# beyond the record it came from, with a stationary sigma the record does not identify.
RECORD = 600.0
BEYOND = (WN.from_density(3e-4, FS) + GM.from_correlation_time(1e9, 0.01)).bind(FS)
FITTED = {a: BEYOND if a.startswith("gyro") else ACCEL for a in AXES}


def test_truth_over_record_is_the_random_walk_of_the_filter_rule() -> None:
    models, start_sd = truth_over_record(FITTED, RECORD)
    q = 2 * 0.01**2 / 1e9  # GM driving intensity 2 sigma^2 / Tc
    np.testing.assert_allclose(start_sd, [np.sqrt(q * RECORD)] * 3 + [0.0] * 3, rtol=1e-12)
    for axis in AXES:
        if axis.startswith("accel"):  # Tc 60 s is resolved by the record: untouched
            assert models[axis] is FITTED[axis]
            continue
        white, walk = models[axis].processes
        assert white is BEYOND.processes[0]
        block = walk.block(1.0 / FS, FS)
        c = block.continuous
        np.testing.assert_allclose(c.F, [[0.0]])  # a random walk ...
        np.testing.assert_allclose(c.G @ c.Qc @ c.G.T, [[q]], rtol=1e-12)  # ... of intensity q
        np.testing.assert_allclose(block.P0, [[0.0]])  # started at 0; start_sd draws the offset
    with pytest.raises(InputError, match="truth_record"):
        outage_study({"fitted": FITTED}, FITTED, runs=1, profile=PROFILE, rate=FS,
                     outages=OUTAGES, truth_record=-1.0)


def test_a_fitted_truth_beyond_its_record_is_drawn_as_the_filter_sees_it() -> None:
    """The filter told the record takes the component as a random walk started with variance
    q T; drawn from the stationary sigma (0.01 rad/s) the truth is far outside that, and the
    filter's NEES explodes; drawn over the record (truth_record) it is honest."""
    nees = {}
    for name, truth_record in (("over record", RECORD), ("stationary", None)):
        with pytest.warns(UserWarning, match="random walk"):  # the filter's record rule
            study = outage_study({"fitted": FITTED}, FITTED, runs=1, seed=3, profile=PROFILE,
                                 rate=FS, outages=OUTAGES, record=RECORD,
                                 truth_record=truth_record)
        nees[name] = float(study.nees["fitted"][0])
    print(nees)
    assert 3.0 < nees["over record"] < 20.0, nees
    assert nees["stationary"] > 10 * nees["over record"], nees
