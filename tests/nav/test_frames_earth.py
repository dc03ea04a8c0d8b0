"""Frames and Earth model against independent computations (scipy's Rotation, ellipse geometry
through ECEF, Somigliana's closed-form normal gravity, finite differences of the NED frame)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from stochmod.nav import earth, frames

angles = st.tuples(
    st.floats(-179.0, 179.0), st.floats(-89.0, 89.0), st.floats(-179.0, 179.0)
)
lats = st.floats(-89.5, 89.5)


@settings(max_examples=60, deadline=None)
@given(angles)
def test_rph_dcm_matches_scipy_and_round_trips(rph):
    C = frames.rph_to_dcm(rph)
    ref = Rotation.from_euler("ZYX", [rph[2], rph[1], rph[0]], degrees=True).as_matrix()
    np.testing.assert_allclose(C, ref, atol=1e-13)
    np.testing.assert_allclose(frames.dcm_to_rph(C), rph, atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(angles, angles)
def test_quaternion_algebra_matches_scipy(a, b):
    qa, qb = frames.rph_to_quat(a), frames.rph_to_quat(b)
    ra = Rotation.from_euler("ZYX", a[::-1], degrees=True)
    rb = Rotation.from_euler("ZYX", b[::-1], degrees=True)
    # scipy stores the scalar last
    np.testing.assert_allclose(np.abs(np.dot(qa, np.roll(ra.as_quat(), 1))), 1.0, atol=1e-12)
    np.testing.assert_allclose(frames.quat_to_dcm(frames.quat_multiply(qa, qb)),
                               (ra * rb).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(frames.quat_to_dcm(frames.quat_conjugate(qa)),
                               ra.inv().as_matrix(), atol=1e-12)
    np.testing.assert_allclose(frames.dcm_to_rotvec(frames.quat_to_dcm(qa)), ra.as_rotvec(),
                               atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.tuples(*[st.floats(-3.0, 3.0)] * 3))
def test_rotvec_quat_matches_scipy_and_skew_is_cross(v):
    v = np.array(v)
    np.testing.assert_allclose(frames.quat_to_dcm(frames.rotvec_to_quat(v)),
                               Rotation.from_rotvec(v).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(frames.quat_to_rotvec(frames.rotvec_to_quat(v)),
                               Rotation.from_rotvec(v).as_rotvec(), atol=1e-10)
    w = np.array([0.3, -1.2, 2.0])
    np.testing.assert_allclose(frames.skew(v) @ w, np.cross(v, w), atol=1e-14)


@settings(max_examples=80, deadline=None)
@given(st.tuples(*[st.floats(-3.0, 3.0)] * 3), st.sampled_from([1.0, 1e-3, 1e-6, 1e-9, 0.0]))
def test_rotvec_to_dcm_is_scipys_rotation_down_to_zero(v, scale):
    """Rodrigues' matrix against scipy's, over the angles the filter's per-fix rotations take
    (tiny ones, where the series near zero is used) and up to 5 rad."""
    v = np.array(v) * scale
    np.testing.assert_allclose(frames.rotvec_to_dcm(v), Rotation.from_rotvec(v).as_matrix(),
                               rtol=0, atol=1e-14)


def test_dcm_to_quat_near_half_turns():
    for rv in ([np.pi, 0, 0], [0, np.pi - 1e-9, 0], [0, 0, -np.pi], [2.0, 2.0, 1.0]):
        C = Rotation.from_rotvec(rv).as_matrix()
        np.testing.assert_allclose(frames.quat_to_dcm(frames.dcm_to_quat(C)), C, atol=1e-12)


def test_wgs84_constants_are_consistent():
    # Table I: b = a sqrt(1 - e^2)
    assert earth.B == pytest.approx(earth.A * np.sqrt(1 - earth.E2), abs=1e-4)


@settings(max_examples=40, deadline=None)
@given(lats, st.floats(-180.0, 180.0), st.floats(-500.0, 9000.0))
def test_ecef_round_trip_and_radii_from_geometry(lat, lon, h):
    xyz = earth.lla_to_ecef(lat, lon, h)
    la, lo, hh = earth.ecef_to_lla(xyz)
    assert la == pytest.approx(lat, abs=1e-10)
    assert hh == pytest.approx(h, abs=1e-6)
    if abs(lat) < 89.0:
        assert np.cos(np.radians(lo - lon)) == pytest.approx(1.0, abs=1e-15)
    # radii from the ellipse itself: R_E = distance to the polar axis / cos(lat) at h = 0, and
    # R_N = arc length per radian of latitude (central differences of the ECEF meridian)
    rn, re = earth.principal_radii(np.radians(lat))
    x0 = earth.lla_to_ecef(lat, 0.0, 0.0)
    assert re == pytest.approx(np.hypot(x0[0], x0[1]) / np.cos(np.radians(lat)), rel=1e-12)
    d = 1e-4
    arc = np.linalg.norm(earth.lla_to_ecef(lat + d, 0.0, 0.0) - earth.lla_to_ecef(lat - d, 0.0, 0.0))
    assert rn == pytest.approx(arc / np.radians(2 * d), rel=1e-7)


@settings(max_examples=40, deadline=None)
@given(lats)
def test_normal_gravity_close_to_somigliana(lat):
    # Somigliana's closed form with the WGS84 equatorial/polar gravity: Table II's series is its
    # truncation, good to a few 1e-6 m/s^2 at the surface
    ge, gp = 9.7803253359, 9.8321849378
    k = earth.B * gp / (earth.A * ge) - 1.0
    s2 = np.sin(np.radians(lat)) ** 2
    somigliana = ge * (1 + k * s2) / np.sqrt(1 - earth.E2 * s2)
    g = earth.gravity_ned(np.radians(lat), 0.0)
    assert g[0] == 0.0 and g[1] == 0.0
    assert g[2] == pytest.approx(somigliana, abs=2e-5)
    # free-air decrease close to 2 g / R per metre
    dg = earth.gravity_ned(np.radians(lat), 1000.0)[2] - g[2]
    assert dg == pytest.approx(-2 * g[2] * 1000.0 / 6371000.0, rel=0.01)


@settings(max_examples=30, deadline=None)
@given(lats, st.floats(-180.0, 180.0))
def test_earth_rate_is_the_polar_axis_seen_in_ned(lat, lon):
    w = earth.ecef_to_ned_dcm(lat, lon) @ np.array([0, 0, earth.OMEGA_IE])
    np.testing.assert_allclose(earth.earth_rate_ned(np.radians(lat)), w, atol=1e-18)


@settings(max_examples=30, deadline=None)
@given(st.floats(-80.0, 80.0), st.floats(-40.0, 40.0), st.floats(-40.0, 40.0),
       st.floats(0.0, 3000.0))
def test_transport_rate_is_the_turn_rate_of_the_ned_frame(lat, vn, ve, h):
    # move along (vn, ve) for +-dt and read the NED frame's rotation from C_ne: independent of
    # eq. 10's closed form
    dt = 0.5
    rn, re = earth.principal_radii(np.radians(lat))
    dlat = np.degrees(vn * dt / (rn + h))
    dlon = np.degrees(ve * dt / ((re + h) * np.cos(np.radians(lat))))
    c1 = earth.ecef_to_ned_dcm(lat - dlat, -dlon)
    c2 = earth.ecef_to_ned_dcm(lat + dlat, dlon)
    # C_n(t+dt) n(t-dt) = c2 c1^T = I - [w x] 2dt  (frame turning at w relative to the Earth)
    rot = frames.dcm_to_rotvec(c1 @ c2.T) / (2 * dt)
    w = earth.transport_rate_ned(np.radians(lat), h, [vn, ve, 0.0])
    np.testing.assert_allclose(rot, w, atol=1e-10 + 1e-6 * np.abs(w).max())


@settings(max_examples=30, deadline=None)
@given(lats, st.floats(-180.0, 180.0), st.floats(-100.0, 2000.0),
       st.tuples(*[st.floats(-5000.0, 5000.0)] * 3))
def test_local_ned_round_trip(lat, lon, h, ned):
    la, lo, hh = earth.ned_to_lla(np.array(ned), lat, lon, h)
    np.testing.assert_allclose(earth.lla_to_ned(la, lo, hh, lat, lon, h), ned, atol=1e-6)
    # a pure down offset is a height decrease at the origin
    la, lo, hh = earth.ned_to_lla(np.array([0.0, 0.0, 10.0]), lat, lon, h)
    assert hh == pytest.approx(h - 10.0, abs=1e-6)
