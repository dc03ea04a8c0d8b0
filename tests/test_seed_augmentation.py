"""Kalman-filter augmentation of the seed papers' worked examples, built with stochmod.

Seeds (``/work/shared/seeds``; line numbers below are those of the files named):

- Q  = quinchia2013-mems-error-model-comparison.txt (equation numbers as printed there; the
  .web.txt copy of the Appendix, lines 363-428, has the same text without numbers), 3DM-GX3-25
  IMU at 100 Hz (line 650), filter step dt = 0.01 s (Q line 1505).
- G  = gonzalez2015-unified-ins-gps-model.txt, Table III and eqs. 20-24.

Truth: the papers' own equations written out here with the tables' numbers and their explicit
unit factors (3600, pi/180), never through stochmod.core.units; the exact discretisation
``exp(-dt/Tc)``, ``sigma^2 (1 - exp(-2 dt/Tc))``, ``K^2 dt`` as closed forms; composed steps by a
plain loop of ``x <- Phi x + w``. The papers' first-order forms (``I + F dt``) are compared
with stated bounds: ``0 <= exp(-x) - (1 - x) <= x^2/2`` and
``0 <= 2x - (1 - exp(-2x)) <= 2x^2`` for ``x = dt/Tc >= 0``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from fractions import Fraction
from types import MappingProxyType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import block_diag

import stochmod
from stochmod.core import units as U
from stochmod_gm import discrete as gm_discrete
from stochmod.core.errors import DomainError, InputError
from stochmod.core.model import AxesAugmentation, Model, augment_axes
from stochmod.core.statespace import compose_steps

FREQ = 100.0  # Q line 650: "The IMU was configured with a sampling frequency of 100 Hz"
DT = 0.01  # Q line 1505: "the sampling time of the INS i.e., 0.01 s"
N_NAV = 9  # Q lines 1480-1482: position, velocity and attitude errors (3 + 3 + 3)
XYZ = ("x", "y", "z")
DEG = math.pi / 180.0  # written out: the papers' deg -> rad


def _family(name: str) -> type:
    return stochmod.get_process(name)


# ================================================================ Quinchia et al. (2013)
# Table 4 (Q lines 945-949; .web.txt 604-606), accelerometers: N (m/s/sqrt(h)), B (m/s/h),
# K (m/s/h^(3/2)); Table 5 (Q line 974; .web.txt 615): Tc (s)
ACC = {
    "x": (0.045, 5.1581, 166.30, 4.56),
    "y": (0.045, 4.5507, 24.95, 7.26),
    "z": (0.047, 1.8336, 13.53, 20.74),
}
# Table 4 (Q lines 963-967; .web.txt 609-611), gyros: N (deg/sqrt(h)), B (deg/h), no K;
# Table 5 (Q line 974): Tc (s)
GYRO = {
    "x": (2.420, 44.533, 490.89),
    "y": (1.988, 38.810, 623.25),
    "z": (2.164, 31.717, 735.17),
}


def _acc_model(axis: str, with_rw: bool = True) -> Model:
    """Q eq. 19 (ase = WN(N) + 1st GM(B) + RW(K)), built with stochmod.core.units and eq. 29's 0.664."""
    n, b, k, tc = ACC[axis]
    WN, GM, RW = _family("WN"), _family("GM"), _family("RW")
    model = WN.from_density(U.to_si(n, "m/s/sqrt(h)", kind="N"), FREQ) + GM.from_bias_instability(
        U.to_si(b, "m/s/h", kind="B"), tc, factor=U.BI_FACTOR_IEEE
    )
    if with_rw:
        model = model + RW.from_rrw(U.to_si(k, "m/s/h^1.5", kind="K"), FREQ)
    return model.bind(FREQ)


def _gyro_model(axis: str) -> Model:
    """Q eq. 20 (gse = WN(N) + 1st GM(B))."""
    n, b, tc = GYRO[axis]
    WN, GM = _family("WN"), _family("GM")
    model = WN.from_density(U.to_si(n, "deg/sqrt(h)", kind="N"), FREQ) + GM.from_bias_instability(
        U.to_si(b, "deg/h", kind="B"), tc, factor=U.BI_FACTOR_IEEE
    )
    return model.bind(FREQ)


@functools.cache
def _av_models(with_rw: bool = True) -> Mapping[str, Model]:
    """The AV models of Table 8: 18 states with the accelerometers' RW(K), 15 states without."""
    models = {f"accel_{a}": _acc_model(a, with_rw) for a in XYZ}
    models.update({f"gyro_{a}": _gyro_model(a) for a in XYZ})
    return MappingProxyType(models)


# Eq. 23 (Q line 1536): delta x = [dr, dv, dpsi, db_a,bi, db_g,bi, db_a,k]
EQ23_ORDER = (
    [f"accel_{a}.GM.value" for a in XYZ]
    + [f"gyro_{a}.GM.value" for a in XYZ]
    + [f"accel_{a}.RW.value" for a in XYZ]
)


def _reorder(aug: AxesAugmentation, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi, Q, P0 of an augmentation with the states in the order `names` (a permutation)."""
    assert sorted(names) == sorted(aug.state_names)
    idx = [aug.state_names.index(n) for n in names]
    sel = np.ix_(idx, idx)
    return aug.Phi[sel], aug.Q[sel], aug.P0[sel]


def _tc_vector() -> np.ndarray:
    return np.array([ACC[a][3] for a in XYZ] + [GYRO[a][2] for a in XYZ])


def _sigma_gm_vector() -> np.ndarray:
    # eq. 29 (Q line 1673): sigma_GM = B * 0.664 / 3600 (m/s^2); the gyros' B also deg -> rad
    return np.array([ACC[a][1] * 0.664 / 3600 for a in XYZ]
                    + [GYRO[a][1] * 0.664 / 3600 * DEG for a in XYZ])


def _eq27_q_n() -> np.ndarray:
    # eq. 27 (Q line 1648): q_n = sigma_WN^2 / dt = N^2 / (3600 dt); gyros with deg -> rad
    return np.array([ACC[a][0] ** 2 / (3600 * DT) for a in XYZ]
                    + [(GYRO[a][0] * DEG) ** 2 / (3600 * DT) for a in XYZ])


def _k2_vector() -> np.ndarray:
    # eq. 30 (Q line 1681) divided by dt: K^2 / 3600^3 in (m/s^2)^2 / s, K in m/s/h^(3/2)
    return np.array([ACC[a][2] ** 2 / 3600**3 for a in XYZ])


def test_18_state_av_model_has_nine_augmented_states() -> None:
    aug = augment_axes(_av_models(), DT)
    assert aug.n_states == 9  # 3 accel GM + 3 gyro GM + 3 accel RW
    assert N_NAV + aug.n_states == 18  # Table 8 (Q line 1173), "18 States"
    assert set(aug.state_names) == set(EQ23_ORDER)
    assert aug.axes == tuple(f"accel_{a}" for a in XYZ) + tuple(f"gyro_{a}" for a in XYZ)
    # eq. 8 (Q lines 317-335): y_k = (1 1)(x1 x2)' + ...: each accelerometer reads its GM + RW,
    # each gyro its GM; no axis reads another's states
    expected_h = np.zeros((6, 9))
    for i, a in enumerate(XYZ):
        expected_h[i, [aug.state_names.index(f"accel_{a}.GM.value"),
                       aug.state_names.index(f"accel_{a}.RW.value")]] = 1.0
        expected_h[3 + i, aug.state_names.index(f"gyro_{a}.GM.value")] = 1.0
    np.testing.assert_array_equal(aug.H, expected_h)


def test_18_state_phi_exact_and_eq21_first_order() -> None:
    Phi, _, _ = _reorder(augment_axes(_av_models(), DT), EQ23_ORDER)
    x = DT / _tc_vector()  # beta dt, 2.19e-3 (Acc X) down to 1.36e-5 (Gyro Z)
    exact = np.concatenate([np.exp(-x), np.ones(3)])
    np.testing.assert_allclose(np.diag(Phi), exact, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(Phi - np.diag(np.diag(Phi)), 0.0)
    # eq. 21 (Q lines 1491-1503): A = blockdiag(I - diag(beta_a dt), I - diag(beta_g dt), I).
    eq21 = block_diag(np.eye(3) - np.diag(x[:3]), np.eye(3) - np.diag(x[3:]), np.eye(3))
    gap = np.diag(Phi) - np.diag(eq21)
    bound = np.concatenate([x**2 / 2, np.zeros(3)])  # 0 <= e^-x - (1 - x) <= x^2/2
    assert np.all(gap >= -1e-16) and np.all(gap <= bound + 1e-16)
    assert gap.max() < 2.41e-6  # Acc X: (0.01/4.56)^2 / 2 = 2.405e-6


def test_18_state_q_eqs_26_to_30() -> None:
    aug = augment_axes(_av_models(), DT)
    _, Q, P0 = _reorder(aug, EQ23_ORDER)
    tc, sigma_gm = _tc_vector(), _sigma_gm_vector()
    # eq. 28 (Q line 1664): q_bi = sigma_GM^2 (1 - e^{-2 dt/Tc}) (1 - e^-y as -expm1(-y): the
    # subtraction would lose ~4e-12 relative at the gyros' 2 dt/Tc = 2.7e-5)
    q_bi = sigma_gm**2 * -np.expm1(-2.0 * DT / tc)
    # eq. 30 (Q line 1681): q_k = K^2 dt / 3600^3
    q_k = _k2_vector() * DT
    np.testing.assert_allclose(np.diag(Q), np.concatenate([q_bi, q_k]), rtol=1e-13, atol=0)
    np.testing.assert_array_equal(Q - np.diag(np.diag(Q)), 0.0)
    # hand values for Acc X: 3.961173e-9 (GM) and 166.30^2 * 0.01 / 3600^3 = 5.927574e-9 (RW)
    assert Q[0, 0] == pytest.approx(3.961173e-9, rel=1e-6)
    assert Q[6, 6] == pytest.approx(5.927574e-9, rel=1e-6)
    q_n = _eq27_q_n()  # eq. 27: the white feed-through per sample
    np.testing.assert_allclose(aug.white_var, q_n, rtol=1e-13, atol=0)
    assert aug.white_var[0] == pytest.approx(5.625e-5, rel=1e-13)  # 0.045^2 / 36
    # eq. 26 (Q lines 1586-1616): Q = diag(q_a,n, q_g,n, q_a,bi, q_g,bi, q_a,k), 15 entries
    eq26 = np.concatenate([q_n, q_bi, q_k])
    np.testing.assert_allclose(np.concatenate([aug.white_var, np.diag(Q)]), eq26, rtol=1e-13)
    # initial covariance: the GMs start stationary (sigma_GM^2), the random walks at 0
    np.testing.assert_allclose(np.diag(P0), np.concatenate([sigma_gm**2, np.zeros(3)]), rtol=1e-13)


def test_18_state_continuous_form_eqs_1_4_5() -> None:
    aug = augment_axes(_av_models(), DT)
    sel = [aug.state_names.index(n) for n in EQ23_ORDER]
    block = aug.block
    assert block.F is not None  # every component is continuous (GM, RW; WN has no state)
    F, Qc = block.F[np.ix_(sel, sel)], block.Qc[np.ix_(sel, sel)]
    tc, sigma_gm = _tc_vector(), _sigma_gm_vector()
    # eq. 1 (Q line 211): xdot = -x/Tc + w; eq. 5 (line 259): xdot = w
    np.testing.assert_allclose(np.diag(F), np.concatenate([-1.0 / tc, np.zeros(3)]), rtol=1e-15)
    # eq. 4 (Q line 242): sigma_w^2 = 2 beta sigma_GM^2; RW: K^2 = q_k / dt (eq. 30 / dt)
    np.testing.assert_allclose(np.diag(Qc), np.concatenate([2 * sigma_gm**2 / tc, _k2_vector()]),
                               rtol=1e-13)
    np.testing.assert_array_equal(block.G, np.eye(9))  # eq. 24's identity rows for the 9 states


def test_15_state_av_model() -> None:
    # Table 8 (Q lines 1173-1189), "15 States": ase = gse = WN(N) + GM(B), 6 augmented states
    aug = augment_axes(_av_models(with_rw=False), DT)
    names = EQ23_ORDER[:6]
    Phi, Q, _ = _reorder(aug, names)
    assert N_NAV + aug.n_states == 15
    x = DT / _tc_vector()
    np.testing.assert_allclose(np.diag(Phi), np.exp(-x), rtol=1e-15)
    np.testing.assert_allclose(np.diag(Q), _sigma_gm_vector() ** 2 * -np.expm1(-2 * x), rtol=1e-13)
    np.testing.assert_array_equal(aug.H, np.eye(6))  # one GM per axis


# ---------------------------------------------------------------- AR models (Table 2)
# Table 2 (Q lines 747-784; .web.txt 573-589): Burg coefficients after de-noising,
# x(n) = -sum_k alpha_k x(n-k) + beta_0 w(n) (eq. 9, line 345); beta_0^2 in (m/s^2)^2, (rad/s)^2
AR1 = {  # (alpha_1, beta_0^2)
    "accel_x": ("-1", 2.129e-10), "accel_y": ("-1", 1.148e-9), "accel_z": ("-1", 1.014e-9),
    "gyro_x": ("-0.999", 1.014e-10), "gyro_y": ("-0.999", 7.04e-11), "gyro_z": ("-0.999", 8.066e-11),
}
AR3 = {  # ((alpha_1, alpha_2, alpha_3), beta_0^2)
    "accel_x": (("-2.582", "2.166", "-0.585"), 4.973e-13),
    "accel_y": (("-2.564", "2.136", "-0.572"), 8.399e-12),
    "accel_z": (("-2.564", "2.136", "-0.572"), 7.964e-12),
    "gyro_x": (("-2.564", "2.131", "-0.567"), 2.739e-13),
    "gyro_y": (("-2.565", "2.133", "-0.568"), 1.905e-13),
    "gyro_z": (("-2.562", "2.128", "-0.566"), 2.181e-13),
}
# The printed AR(3)s are not stationary (test below): the rounding to 3 decimals moved a root
# of the (always stable) Burg fit onto or over the unit circle. These 4-decimal coefficients
# round to the printed ones and are stationary: among the points of the 1e-4 grid within
# +-4e-4 of Table 2, those with the smallest largest root modulus (a search run once).
AR3_STATIONARY = {
    "accel_x": (-2.5816, 2.1664, -0.5847),
    "accel_y": (-2.5636, 2.1361, -0.5724),
    "accel_z": (-2.5636, 2.1361, -0.5724),
    "gyro_x": (-2.5636, 2.1311, -0.5674),
    "gyro_y": (-2.5646, 2.1331, -0.5684),
    "gyro_z": (-2.5616, 2.1281, -0.5664),
}
AXES = tuple(f"accel_{a}" for a in XYZ) + tuple(f"gyro_{a}" for a in XYZ)


def _wn(axis: str) -> object:
    """The WN(N) of Table 4 (eq. 35's q_a,n, q_g,n are 'the same ... as the 18 states AV')."""
    sensor, a = axis.split("_")
    if sensor == "accel":
        return _family("WN").from_density(U.to_si(ACC[a][0], "m/s/sqrt(h)", kind="N"), FREQ)
    return _family("WN").from_density(U.to_si(GYRO[a][0], "deg/sqrt(h)", kind="N"), FREQ)


def _ar3_models() -> dict[str, Model]:
    AR = _family("AR")
    return {
        axis: (_wn(axis) + AR(phi=[-c for c in AR3_STATIONARY[axis]], sigma2=AR3[axis][1])).bind(FREQ)
        for axis in AXES
    }


# Eq. 33 (Q line 1732): [dr, dv, dpsi, db_a,b1, db_a,b2, db_a,b3, db_g,b1, db_g,b2, db_g,b3], each
# b_i a triple over x, y, z; eq. 10 (lines 357-392): x3 is the newest value, x1 the oldest.
# stochmod's companion order is (value, lag1, lag2): the paper's (x1, x2, x3) = (lag2, lag1, value).
EQ33_ORDER = [
    f"{sensor}_{a}.AR.{state}"
    for sensor in ("accel", "gyro")
    for state in ("lag2", "lag1", "value")
    for a in XYZ
]


def _eq31(alpha: dict[str, tuple[float, float, float]]) -> np.ndarray:
    """Eq. 31 (Q lines 1694-1712) from coefficient triples, written out with numpy blocks."""
    Z, I = np.zeros((3, 3)), np.eye(3)

    def sensor(prefix: str) -> np.ndarray:
        a = np.array([alpha[f"{prefix}_{x}"] for x in XYZ])  # rows x, y, z; columns alpha_1..3
        return np.block([[Z, I, Z], [Z, Z, I],
                         [-np.diag(a[:, 2]), -np.diag(a[:, 1]), -np.diag(a[:, 0])]])

    return block_diag(sensor("accel"), sensor("gyro"))


@pytest.mark.parametrize("axis", AXES)
def test_table2_printed_ar3_are_not_stationary(axis: str) -> None:
    alpha = [Fraction(c) for c in AR3[axis][0]]
    # characteristic polynomial z^3 + a1 z^2 + a2 z + a3 (eq. 9): P(1) <= 0 and P(+inf) = +inf
    # put a real root in [1, inf): five sensors have P(1) = 0 exactly, Acc X P(1) = -0.001
    p1 = 1 + sum(alpha)
    assert p1 == (Fraction(-1, 1000) if axis == "accel_x" else 0)
    with pytest.raises(DomainError, match="not stationary"):
        _family("AR")(phi=[-float(c) for c in alpha], sigma2=AR3[axis][1])


@pytest.mark.parametrize("axis", AXES)
def test_stationary_ar3_coefficients_round_to_table2(axis: str) -> None:
    printed = np.array([float(c) for c in AR3[axis][0]])
    close = np.array(AR3_STATIONARY[axis])
    assert np.all(np.abs(close - printed) <= 4e-4 + 1e-12)
    np.testing.assert_array_equal(np.round(close, 3), printed)
    assert np.max(np.abs(np.roots(np.concatenate([[1.0], close])))) < 0.997


def test_27_state_ar3_model_eq31_and_eq35() -> None:
    aug = augment_axes(_ar3_models(), DT)
    assert aug.n_states == 18 and N_NAV + aug.n_states == 27  # Table 8, "27 States"
    Phi, Q, P0 = _reorder(aug, EQ33_ORDER)
    np.testing.assert_array_equal(Phi, _eq31(AR3_STATIONARY))  # exact: only copies and signs
    # eqs. 34-36 (Q lines 1743-1815): the AR noise enters the newest state x3 only, q = beta_0^2
    beta2 = np.array([AR3[f"{s}_{a}"][1] for s in ("accel", "gyro") for a in XYZ])
    expected_q = np.zeros((18, 18))
    for g, sl in enumerate((slice(6, 9), slice(15, 18))):
        expected_q[sl, sl] = np.diag(beta2[3 * g : 3 * g + 3])
    np.testing.assert_array_equal(Q, expected_q)
    # eq. 35 (Q lines 1772-1795): diag(q_a,n, q_g,n, q_a,b, q_g,b) with eq. 27's q_n
    q_n = _eq27_q_n()
    eq35 = np.concatenate([q_n, beta2])
    got = np.concatenate([aug.white_var, np.diag(Q)[[6, 7, 8, 15, 16, 17]]])
    np.testing.assert_allclose(got, eq35, rtol=1e-13, atol=0)
    # each axis reads its newest AR state (x3)
    for i, axis in enumerate(AXES):
        assert np.flatnonzero(aug.H[i]).tolist() == [aug.state_names.index(f"{axis}.AR.value")]
    # the stationary initial covariance solves P0 = Phi P0 Phi' + Q
    resid = Phi @ P0 @ Phi.T + Q - P0
    assert np.max(np.abs(resid)) <= 1e-8 * np.max(np.abs(P0))


def test_15_state_ar1_model() -> None:
    # Table 8 "15 States", AR row: 1st order AR per axis. Table 2's accelerometer alpha_1 = -1 is
    # the random walk (Q lines 460-461: "if p = 1 and alpha_1 = -1, it becomes a random walk (RW)"),
    # which stochmod's stationary AR refuses; the gyros' alpha_1 = -0.999 is a stationary AR(1).
    AR, RW = _family("AR"), _family("RW")
    with pytest.raises(DomainError, match="not stationary"):
        AR(phi=[1.0], sigma2=AR1["accel_x"][1])
    models = {}
    for axis in AXES:
        alpha1, beta2 = AR1[axis]
        proc = RW(sigma2=beta2) if alpha1 == "-1" else AR(phi=[-float(alpha1)], sigma2=beta2)
        models[axis] = Model((proc,), FREQ)
    aug = augment_axes(models, DT)
    assert N_NAV + aug.n_states == 15
    # x(n) = -alpha_1 x(n-1) + beta_0 w(n): Phi = -alpha_1, Q = beta_0^2 (per axis, in AXES order)
    np.testing.assert_allclose(np.diag(aug.Phi), [-float(AR1[a][0]) for a in AXES], rtol=1e-15)
    np.testing.assert_allclose(np.diag(aug.Q), [AR1[a][1] for a in AXES], rtol=1e-13)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_each_ar_order_adds_six_states(order: int) -> None:
    # Q lines 394-396: "if the order of the AR model increases by one, the variables in the state
    # vector of the Kalman filter will increase by six" (one AR per axis, six axes)
    roots = 0.5 ** np.arange(1, order + 1)  # a stationary AR(p): phi from prescribed roots
    phi = list(-np.poly(roots)[1:])
    AR = _family("AR")
    models = {axis: Model((AR(phi=phi, sigma2=1.0),), FREQ) for axis in AXES}
    assert augment_axes(models, DT).n_states == 6 * order


# ================================================================ Gonzalez et al. (2015)
# Table III (G lines 436-460): per IMU, per axis X, Y, Z:
# n_g (deg/s/sqrt(Hz)), n_f (m/s^2/sqrt(Hz)), sigma_gdb (deg/s), sigma_fdb (m/s^2), tau_g, tau_f (s)
TABLE3 = {
    "XBOW1": dict(n_g=(3.996e-2, 3.141e-2, 3.581e-2), n_f=(1.353e-3, 1.353e-3, 9.850e-4),
                  s_g=(3.427e-3, 2.028e-3, 2.153e-3), s_f=(1.787e-4, 1.843e-4, 2.149e-4),
                  tau_g=(250.7, 432.2, 395.2), tau_f=(196.9, 332.8, 79.6)),
    "XSENS1": dict(n_g=(8.230e-2, 7.802e-2, 8.948e-2), n_f=(1.493e-3, 1.589e-3, 1.793e-3),
                   s_g=(1.142e-2, 1.230e-2, 1.526e-2), s_f=(4.274e-4, 3.396e-4, 4.769e-4),
                   tau_g=(274.4, 463.9, 132.2), tau_f=(33.4, 124.3, 39.2)),
    "GLAD": dict(n_g=(1.418e-1, 1.364e-1, 1.338e-1), n_f=(4.094e-2, 4.104e-2, 4.231e-2),
                 s_g=(1.154e-2, 1.200e-2, 1.154e-2), s_f=(3.232e-3, 3.171e-3, 3.610e-3),
                 tau_g=(458.9, 289.7, 370.9), tau_f=(260.2, 382.8, 351.3)),
}
# The EKF steps between GPS epochs dt_G (Alg. 1, line 329); the paper prints no GPS rate, so the
# comparison runs at 1 Hz and 10 Hz epochs (and at the IMU step, 0.01 s).
DT_GPS = (1.0, 0.1, 0.01)
IMU_FREQ = 100.0  # not printed either; N^2 = white_var / freq does not depend on it (tested)


def _gonzalez_models(imu: str, freq: float = IMU_FREQ) -> dict[str, Model]:
    """Eq. 1 and 3: per axis WN(n) + GM(sigma_db, tau); order of eq. 20f: gyros, then accels."""
    t = TABLE3[imu]
    WN, GM = _family("WN"), _family("GM")
    models = {}
    for i, a in enumerate(XYZ):
        models[f"gyro_{a}"] = (
            WN.from_density(U.to_si(t["n_g"][i], "deg/s/sqrt(Hz)", kind="N"), freq)
            + GM.from_correlation_time(t["tau_g"][i], U.to_si(t["s_g"][i], "deg/s", kind="B"))
        ).bind(freq)
    for i, a in enumerate(XYZ):
        models[f"accel_{a}"] = (
            WN.from_density(U.to_si(t["n_f"][i], "m/s^2/sqrt(Hz)", kind="N"), freq)
            + GM.from_correlation_time(t["tau_f"][i], U.to_si(t["s_f"][i], "m/s^2", kind="B"))
        ).bind(freq)
    return models


def _gonzalez_columns(imu: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n^2 of eq. 21's first six entries, sigma_db, tau) in SI, written out from Table III."""
    t = TABLE3[imu]
    n2 = np.concatenate([(np.array(t["n_g"]) * DEG) ** 2, np.array(t["n_f"]) ** 2])
    sigma = np.concatenate([np.array(t["s_g"]) * DEG, np.array(t["s_f"])])
    tau = np.concatenate([t["tau_g"], t["tau_f"]])
    return n2, sigma, tau


@pytest.mark.parametrize("freq", [50.0, 100.0, 400.0])
@pytest.mark.parametrize("imu", sorted(TABLE3))
def test_gonzalez_eq21_q_with_the_correct_gm_psd(imu: str, freq: float) -> None:
    aug = augment_axes(_gonzalez_models(imu, freq), 1.0)
    assert aug.n_states == 6  # the dynamic biases db_g, db_f of eq. 20f (GM states)
    assert aug.state_names == tuple(f"{ax}.GM.value" for ax in AXES[3:] + AXES[:3])
    n2, sigma, tau = _gonzalez_columns(imu)
    # eq. 21 (G line 303): Q = diag(n_g^2, n_f^2, n_gdb^2, n_fdb^2), PSDs of the driving noises.
    # The white noise PSD is the per-sample variance / freq; the GM's is stochmod's Qc, the
    # correct 2 sigma^2 / tau -- eq. 22 (lines 307-309) prints sigma^2 * tau, a misprint.
    correct = np.concatenate([n2, 2 * sigma**2 / tau])
    got = np.concatenate([aug.white_var / freq, np.diag(aug.block.Qc)])
    np.testing.assert_allclose(got, correct, rtol=1e-13, atol=0)
    printed = gm_discrete.gm_driving_psd(sigma, tau, form="gonzalez2015")
    np.testing.assert_allclose(printed, sigma**2 * tau, rtol=1e-15)
    # the printed PSD is tau^2 / 2 times too large (3.1e4 ... 2.7e5 for these IMUs' gyros)
    np.testing.assert_allclose(printed / np.diag(aug.block.Qc), tau**2 / 2, rtol=1e-13)
    # eq. 20k (line 293): F has -1/tau on the dynamic-bias states; eq. 20l: G = I there;
    # eq. 24 (line 343): P(1) holds sigma_db^2 for them
    np.testing.assert_allclose(np.diag(aug.block.F), -1.0 / tau, rtol=1e-15)
    np.testing.assert_array_equal(aug.block.G, np.eye(6))
    np.testing.assert_allclose(np.diag(aug.P0), sigma**2, rtol=1e-13)


@pytest.mark.parametrize("dt_g", DT_GPS)
@pytest.mark.parametrize("imu", sorted(TABLE3))
def test_gonzalez_alg1_first_order_against_exact(imu: str, dt_g: float) -> None:
    aug = augment_axes(_gonzalez_models(imu), dt_g)
    _, sigma, tau = _gonzalez_columns(imu)
    x = dt_g / tau
    # exact: Phi = exp(-dt/tau), Q = sigma^2 (1 - exp(-2 dt/tau))
    np.testing.assert_allclose(np.diag(aug.Phi), np.exp(-x), rtol=1e-15)
    np.testing.assert_allclose(np.diag(aug.Q), sigma**2 * -np.expm1(-2 * x), rtol=1e-13)
    # Alg. 1 lines 2-3 (G lines 330-331): Phi = I + F dt, Q_k = G Q G' dt, with the correct PSD
    alg1_phi = 1.0 - x
    alg1_q = 2 * sigma**2 / tau * dt_g
    gap_phi = np.diag(aug.Phi) - alg1_phi
    assert np.all(gap_phi >= -1e-16) and np.all(gap_phi <= x**2 / 2 + 1e-16)
    gap_q = alg1_q - np.diag(aug.Q)  # 0 <= 2x - (1 - e^-2x) <= 2x^2, times sigma^2
    assert np.all(gap_q >= -1e-13 * alg1_q) and np.all(gap_q <= 2 * x**2 * sigma**2 * (1 + 1e-12))
    # with the printed PSD, Q_k is tau^2 / 2 times the exact value to first order in x:
    # ratio / (tau^2/2) = 2x / (1 - e^-2x) = 1 + x + x^2/3 - ..., in [1, 1 + x (1 + x)]
    printed_q = gm_discrete.gm_driving_psd(sigma, tau, form="gonzalez2015") * dt_g
    ratio = printed_q / np.diag(aug.Q) / (tau**2 / 2)
    assert np.all(ratio >= 1 - 1e-13) and np.all(ratio - 1 <= x * (1 + x))
    assert np.min(printed_q / np.diag(aug.Q)) > 500  # smallest: XSENS1 accel X, 33.4^2/2 = 557.8


# ================================================================ re-discretisation
def _loop(Phi: np.ndarray, Q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """k steps of x <- Phi x + w, w ~ N(0, Q), one at a time."""
    P, S = np.eye(Phi.shape[0]), np.zeros_like(Q)
    for _ in range(k):
        P, S = Phi @ P, Phi @ S @ Phi.T + Q
    return P, S


SYSTEMS = {
    "18AV": lambda: _av_models(),
    "15AV": lambda: _av_models(with_rw=False),
    "27AR": _ar3_models,
    "gonzalez_XSENS1": lambda: _gonzalez_models("XSENS1"),
}


@pytest.mark.parametrize("k", [2, 10])
@pytest.mark.parametrize("system", sorted(SYSTEMS))
def test_integer_multiples_equal_composed_steps(system: str, k: int) -> None:
    models = SYSTEMS[system]()
    one, many = augment_axes(models, DT), augment_axes(models, k * DT)
    assert many.state_names == one.state_names
    np.testing.assert_array_equal(many.H, one.H)
    np.testing.assert_array_equal(many.P0, one.P0)
    np.testing.assert_array_equal(many.white_var, one.white_var)  # per sample at the sensor rate
    for Phi, Q in (compose_steps(one.Phi, one.Q, k), _loop(one.Phi, one.Q, k)):
        np.testing.assert_allclose(many.Phi, Phi, rtol=1e-12, atol=1e-14)
        scale = np.sqrt(np.outer(np.diag(many.Q), np.diag(many.Q)))  # covariance-relative
        assert np.all(np.abs(many.Q - Q) <= 1e-11 * scale + 1e-300)


@settings(max_examples=25, deadline=None)
@given(ls=st.floats(-3, 2.5), lt=st.floats(-3, 2.5))
def test_continuous_system_at_non_integer_steps(ls: float, lt: float) -> None:
    s, t = 10.0**ls, 10.0**lt  # steps in seconds, not multiples of 1/freq
    models = _av_models()
    a, b, ab = (augment_axes(models, h) for h in (s, t, s + t))
    Phi, Q, _ = _reorder(ab, EQ23_ORDER)
    tc, sigma_gm = _tc_vector(), _sigma_gm_vector()
    k2 = _k2_vector()
    # closed forms at the step s + t
    h = s + t
    np.testing.assert_allclose(np.diag(Phi), np.concatenate([np.exp(-h / tc), np.ones(3)]),
                               rtol=1e-13)
    np.testing.assert_allclose(np.diag(Q), np.concatenate([sigma_gm**2 * -np.expm1(-2 * h / tc),
                                                           k2 * h]), rtol=1e-12)
    # semigroup: one step of s + t equals a step of s followed by a step of t
    np.testing.assert_allclose(ab.Phi, b.Phi @ a.Phi, rtol=1e-13, atol=0)
    np.testing.assert_allclose(np.diag(ab.Q), np.diag(b.Phi @ a.Q @ b.Phi.T + b.Q), rtol=1e-12)


@pytest.mark.parametrize("dt", [0.01, 0.37, 10.0])
def test_stationary_gm_states_keep_p0(dt: float) -> None:
    aug = augment_axes(_av_models(), dt)
    gm = [i for i, n in enumerate(aug.state_names) if ".GM." in n]
    sel = np.ix_(gm, gm)
    P0, Phi, Q = aug.P0[sel], aug.Phi[sel], aug.Q[sel]
    np.testing.assert_allclose(np.diag(Phi @ P0 @ Phi.T + Q), np.diag(P0), rtol=1e-13)


def test_discrete_ar_needs_whole_sample_steps() -> None:
    models = _ar3_models()
    with pytest.raises(InputError, match="whole multiple"):
        augment_axes(models, 2.5 * DT)
    with pytest.raises(InputError, match="dt"):
        augment_axes(_av_models(), -DT)
