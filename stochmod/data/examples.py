"""Bundled example data: simulated static recordings of the XSens MTi-G IMU.

The error models are those Stebler et al. (2014) estimated by the GMWM on 4 h of static
XSens MTi-G data at 100 Hz (their Table II): gyroscope WN + 2 GM, accelerometer WN + 3 GM,
used here for all three axes of each sensor, each axis simulated independently from a fixed
seed. No data file is shipped: the recording is generated on demand.

Reading Table II
----------------
* ``sigma_WN`` is a white-noise density N (deg/s/sqrt(Hz), ug/sqrt(Hz)): the variance per
  sample is ``N^2 freq`` (:func:`stochmod.core.units.wn_variance`).
* ``beta_i`` is printed in Hz and taken as a rate in 1/s (the GM's inverse correlation time).
* ``sigma_GM,i`` is printed in density units (deg/s/sqrt(Hz), ug/sqrt(Hz)). We read it as the
  density q of the white noise driving ``dx/dt = -beta x + q w(t)``, so the stationary
  variance is ``q^2 / (2 beta)`` (the discrete innovation variance is then
  ``q^2 / (2 beta) (1 - e^{-2 beta / freq}) ~ q^2 / freq``, the same conversion as for
  ``sigma_WN``). The alternative reading, ``sigma_GM,i`` as the stationary standard deviation
  with a misprinted unit, gives much smaller GMs (e.g. 900 ug instead of 0.042 g stationary
  for the slowest accelerometer GM); :func:`xsens_mtig_models` takes ``reading="stationary"``
  to build that variant.
* Units: deg = pi/180 rad, ug = 1e-6 x 9.80665 m/s^2 (:mod:`stochmod.core.units`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.errors import InputError
from stochmod.io.recording import Recording
from stochmod.core.model import Model
from stochmod.plugin.spec import model_from_spec
from stochmod.core.process import as_generator
from stochmod.core.units import to_si, wn_variance

__all__ = ["XSENS_MTIG_TABLE2", "XSENS_COLUMNS", "XSENS_UNITS", "xsens_mtig_models", "xsens_mtig",
           "DEFAULT_EXAMPLE_N"]

#: Table II of Stebler et al. (2014): (sigma_WN, [(beta_i [1/s], sigma_GM,i), ...], unit).
XSENS_MTIG_TABLE2 = {
    "gyro": (0.032, [(0.024, 7.63e-4), (9.03e-4, 8.64e-4)], "deg/s/sqrt(Hz)"),
    "accel": (85.5, [(25.8, 143.0), (0.04, 103.0), (2.32e-4, 900.0)], "ug/sqrt(Hz)"),
}

#: Column names of the example recording (rad/s for gyro, m/s^2 for accel).
XSENS_COLUMNS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")

#: Unit of each column of the example recording.
XSENS_UNITS = {c: ("rad/s" if c.startswith("gyro") else "m/s^2") for c in XSENS_COLUMNS}

#: Default number of samples per column (2^19 = 87 min at 100 Hz): enough to resolve the
#: slowest GMs' correlation times while keeping ``stochmod calibrate`` near a minute on 2 cores.
DEFAULT_EXAMPLE_N = 2**19


def _sensor_model(sensor: str, freq: float, reading: str) -> Model:
    n_wn, gms, unit = XSENS_MTIG_TABLE2[sensor]
    procs = [{"family": "GM", "params": {"beta": beta, "sigma2": _gm_sigma2(beta, s, unit, reading)}}
             for beta, s in gms]
    procs.append({"family": "WN", "params": {"sigma2": wn_variance(to_si(n_wn, unit, kind="N"), freq)}})
    return model_from_spec({"processes": procs}, freq)


def _gm_sigma2(beta: float, value: float, unit: str, reading: str) -> float:
    q = to_si(value, unit, kind="N")  # u/sqrt(Hz) in SI
    if reading == "driving":
        return q * q / (2.0 * beta)
    # "stationary": the number is a standard deviation in u (the /sqrt(Hz) taken as a misprint)
    return float(to_si(value, unit.replace("/sqrt(Hz)", ""))) ** 2


def xsens_mtig_models(freq: float = 100.0, *,
                      reading: Literal["driving", "stationary"] = "driving") -> dict[str, Model]:
    """The true models of the example, one per column, bound to `freq` Hz.

    Parameters
    ----------
    freq : float
        Sampling frequency, Hz (the paper's data: 100 Hz).
    reading : {"driving", "stationary"}
        How ``sigma_GM,i`` of Table II is read (see the module docstring).

    Returns
    -------
    dict of str to Model
        ``gyro_*``: GM + GM + WN in rad/s; ``accel_*``: GM + GM + GM + WN in m/s^2.
    """
    freq = check_freq(freq)
    if reading not in ("driving", "stationary"):
        raise InputError(f"reading must be 'driving' or 'stationary', got {reading!r}")
    models = {s: _sensor_model(s, freq, reading) for s in ("gyro", "accel")}
    return {c: models[c.split("_")[0]] for c in XSENS_COLUMNS}


def xsens_mtig(n: int = DEFAULT_EXAMPLE_N, seed: int = 2014, *, freq: float = 100.0,
               reading: Literal["driving", "stationary"] = "driving") -> Recording:
    """Simulated static recording of an XSens MTi-G (Stebler et al. 2014, Table II).

    Parameters
    ----------
    n : int
        Samples per column (default 2^19, 87 min at 100 Hz; the paper had 2,057,424).
    seed : int
        Seed; each column draws from its own child generator, so columns are independent
        and the recording reproduces exactly.
    freq : float
        Sampling frequency, Hz.
    reading : {"driving", "stationary"}
        Interpretation of Table II's ``sigma_GM,i`` (see the module docstring).

    Returns
    -------
    Recording
        ``data`` of shape (n, 6): ``gyro_x/y/z`` in rad/s and ``accel_x/y/z`` in m/s^2,
        ``freq`` set; error signals, each column less its mean, as a static recording is
        modelled once its bias is removed. The slowest accelerometer GM (0.042 g stationary,
        Tc 72 min) is otherwise a bias of that size over a short record, which the magnitude
        checks of :func:`stochmod.calibrate` would read as gravity in g; the wavelet variance
        and the Allan variance do not see the mean.
    """
    n = check_positive_int(n, name="n", minimum=64)
    models = xsens_mtig_models(freq, reading=reading)
    children = as_generator(seed).spawn(len(XSENS_COLUMNS))
    data = np.column_stack([models[c].simulate(n, g) for c, g in zip(XSENS_COLUMNS, children)])
    data -= data.mean(axis=0)
    hours = n / freq / 3600.0
    return Recording(data=data, columns=XSENS_COLUMNS, freq=float(freq),
                     units=tuple(XSENS_UNITS[c] for c in XSENS_COLUMNS),
                     path=f"<bundled example: XSens MTi-G, Stebler et al. 2014 Table II, "
                          f"{n} samples = {hours:.2f} h at {freq:g} Hz, seed {seed}>")

