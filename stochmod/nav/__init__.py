"""Navigation: strapdown INS, loosely-coupled INS/GNSS/magnetometer filter built on stochmod's
sensor-error models, alignment and emulation.

Modules: :mod:`~stochmod.nav.earth` (WGS84), :mod:`~stochmod.nav.frames` (rotations),
:mod:`~stochmod.nav.records` (IMU and GNSS records), :mod:`~stochmod.nav.strapdown`
(mechanisation), :mod:`~stochmod.nav.emulate` (trajectories, ideal IMU, sensor errors, GNSS),
:mod:`~stochmod.nav.measurements` and :mod:`~stochmod.nav.filter` (error-state EKF),
:mod:`~stochmod.nav.alignment` (initialisation). See ``docs/navigation.md``.
"""

from __future__ import annotations

from stochmod.nav.emulate import (
    Segment,
    Trajectory,
    add_sensor_errors,
    gnss_measurements,
    ideal_imu,
    magnetometer_heading,
    trajectory_from_profile,
)
from stochmod.nav.alignment import InitialState, align_from_gnss, level, static_alignment
from stochmod.nav.filter import LooselyCoupledFilter, NavResult
from stochmod.nav.measurements import GnssPosition, GnssVelocity, MagneticHeading, ZeroVelocity
from stochmod.nav.records import GnssData, ImuData
from stochmod.nav.strapdown import Mechanisation, NavState, StrapdownResult, strapdown

__all__ = [
    "GnssData",
    "GnssPosition",
    "GnssVelocity",
    "InitialState",
    "LooselyCoupledFilter",
    "MagneticHeading",
    "NavResult",
    "ZeroVelocity",
    "align_from_gnss",
    "level",
    "static_alignment",
    "ImuData",
    "Mechanisation",
    "NavState",
    "Segment",
    "StrapdownResult",
    "Trajectory",
    "add_sensor_errors",
    "gnss_measurements",
    "ideal_imu",
    "magnetometer_heading",
    "strapdown",
    "trajectory_from_profile",
]
