"""Shared emulation helper of the filter tests: an IMU record with per-axis model errors and
turn-on biases (random constants) drawn from one generator."""

import numpy as np

from stochmod.nav import ImuData, add_sensor_errors
from stochmod.nav.emulate import AXES


def imu_with_biases(clean: ImuData, gyro, accel, bias_sd: tuple[float, float],
                    rng: np.random.Generator) -> tuple[ImuData, np.ndarray]:
    """`clean` increments plus errors drawn from the `gyro`/`accel` models and turn-on biases
    of 1-sigma ``bias_sd = (gyro rad/s, accel m/s^2)``; returns the record and the six biases."""
    bias = np.r_[rng.normal(0, bias_sd[0], 3), rng.normal(0, bias_sd[1], 3)]
    noisy = add_sensor_errors(clean, {a: (gyro if a.startswith("gyro") else accel) for a in AXES},
                              rng)
    h = np.diff(clean.time)
    h = np.r_[h[:1], h][:, None]
    imu = ImuData(noisy.time, noisy.gyro + bias[:3] * h, noisy.accel + bias[3:] * h, "increment")
    return imu, bias
