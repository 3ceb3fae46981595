"""Constants, thrust model and element conversions against independent facts."""

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from esail_opt.physics import constants as units
from esail_opt.physics.elements import (
    ac_tilde, classical_from_polar, eccentricity_vector, polar_from_classical, polar_from_q,
    q_from_polar,
)
from esail_opt.physics.thrust import BEST_FIT, EXACT, cone_angle, radial_transverse


def test_ac_tilde_is_ac_over_5_93_mm_s2_at_1_au():
    """The paper (after Eq. 27): a~_c = a_c / (5.93 mm/s^2) at r0 = 1 au."""
    for ac in (0.01, 0.1, 1.0):
        assert ac_tilde(units.accel_from_mm_s2(ac), 1.0) == pytest.approx(ac / 5.93, rel=2e-4)
    # Eq. 7 scales with r0: twice as far, twice the dimensionless acceleration.
    assert ac_tilde(1.0, 2.0) == 2 * ac_tilde(1.0, 1.0)


def test_canonical_time_unit_is_58_13_days():
    assert units.TU_DAYS == pytest.approx(58.1324, abs=1e-4)
    assert units.time_to_days(units.time_from_years(1.0)) == pytest.approx(365.25, rel=1e-15)


@pytest.mark.parametrize("coefficients", [EXACT, BEST_FIT])
def test_thrust_components_eqs_3_4(coefficients):
    b1, b2 = coefficients
    assert np.allclose(radial_transverse(0.0, coefficients), (b1 + b2, 0.0))
    assert np.allclose(radial_transverse(math.pi / 4, coefficients), (b1, b2))
    assert np.allclose(radial_transverse(math.pi / 2, coefficients), (b1 - b2, 0.0), atol=1e-16)
    assert np.allclose(radial_transverse(-math.pi / 4, coefficients), (b1, -b2))


def test_exact_model_equivalent_forms():
    """R = (1 + cos^2 a)/2, T = sin a cos a / 2 for b1 = 3/4, b2 = 1/4 (THEORY.md §1.2)."""
    for a in np.linspace(-math.pi / 2, math.pi / 2, 19):
        R, T = radial_transverse(a)
        assert R == pytest.approx((1 + math.cos(a) ** 2) / 2, abs=1e-15)
        assert T == pytest.approx(math.sin(a) * math.cos(a) / 2, abs=1e-15)


def test_cone_angle_peak():
    """The cone angle peaks at arcsin(1/3) at alpha = arccos(1/sqrt 3), found numerically."""
    best = minimize_scalar(lambda a: -float(cone_angle(a)), bounds=(0, math.pi / 2),
                           method="bounded", options={"xatol": 1e-10})
    assert best.x == pytest.approx(math.acos(1 / math.sqrt(3)), abs=1e-6)
    assert -best.fun == pytest.approx(math.asin(1 / 3), abs=1e-12)
    assert float(cone_angle(math.pi / 4)) == pytest.approx(math.atan(1 / 3), abs=1e-15)


orbits = dict(
    a=st.floats(0.2, 30.0), e=st.floats(0.0, 0.95), omega=st.floats(-math.pi, math.pi),
    nu=st.floats(-math.pi, math.pi),
)


@settings(max_examples=200, deadline=None)
@given(**orbits)
def test_classical_round_trip(a, e, omega, nu):
    x = np.array(polar_from_classical(a, e, omega, nu)).ravel()
    a2, e2, omega2, h2, nu2 = (float(v) for v in classical_from_polar(x))
    assert a2 == pytest.approx(a, rel=1e-11)
    assert e2 == pytest.approx(e, abs=1e-12)
    assert h2 == pytest.approx(math.sqrt(a * (1 - e**2)), rel=1e-12)
    if e > 1e-6:  # the apse line is undefined on a circle
        assert math.remainder(omega2 - omega, 2 * math.pi) == pytest.approx(0, abs=1e-8)
    assert math.remainder(omega2 + nu2 - (omega + nu), 2 * math.pi) == pytest.approx(0, abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(**orbits, r0=st.floats(0.3, 5.0))
def test_q_round_trip_eqs_5_9_11(a, e, omega, nu, r0):
    x = np.array(polar_from_classical(a, e, omega, nu)).ravel()
    q = np.array(q_from_polar(x, r0)).ravel()
    # Eq. 5 with h in sqrt(mu r0): q3 = 1/h, |(q1, q2)| = e/h.
    h = x[0] * x[3] / math.sqrt(r0)
    assert q[2] == pytest.approx(1 / h, rel=1e-12)
    assert math.hypot(q[0], q[1]) == pytest.approx(e / h, rel=1e-9, abs=1e-12)
    back = np.array(polar_from_q(q, x[1], r0)).ravel()
    assert np.allclose(back, x, rtol=1e-11, atol=1e-13)


def test_eccentricity_vector_is_smooth_at_circular():
    x = ca.SX.sym("x", 4)
    jac = ca.Function("j", [x], [ca.jacobian(eccentricity_vector(x), x)])
    assert np.all(np.isfinite(np.array(jac([1.0, 0.3, 0.0, 1.0]))))


@pytest.mark.parametrize("x0, largest", [
    # (start, error of 0.3 rad at order 5 in units of r0: measured 2.9e-8, 1.1e-5, 2.6e-6)
    (np.array([1.0, 0.0, 0.0, 1.0]), 1e-7),    # the 1-au circle
    (np.array([0.4, 0.3, 0.3, 1.9]), 3e-5),    # e ~ 0.5, near perihelion
    (np.array([0.8, 1.0, -0.25, 1.2]), 1e-5),  # e ~ 0.3
])
def test_taylor_step_converges_to_eqs_1_2_at_its_order(x0, largest):
    """The series of ``dynamics.taylor_step`` against Eqs. 1-2 written out here and
    integrated by scipy's DOP853: its error falls like dt^(order + 1)."""
    from scipy.integrate import solve_ivp

    from esail_opt.physics.dynamics import taylor_step

    ac = units.accel_from_mm_s2(0.1)
    radial, transverse = 0.75 + 0.25 * math.cos(1.2), 0.25 * math.sin(1.2)

    def rhs(_t, y):
        r, _theta, vr, vt = y
        return [vr, vt / r, vt**2 / r - 1 / r**2 + ac * radial / r,
                -vr * vt / r + ac * transverse / r]

    def position_error(dt, order):
        truth = solve_ivp(rhs, [0.0, dt], x0, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
        step = np.array(taylor_step(x0, ac, radial, transverse, dt, order)).ravel()
        return math.hypot(step[0] * math.cos(step[1]) - truth[0] * math.cos(truth[1]),
                          step[0] * math.sin(step[1]) - truth[0] * math.sin(truth[1]))

    dt = 0.3 * x0[0] / x0[3]  # 0.3 rad of the local angular rate
    for order in (3, 5):
        # Halving the step divides the error by about 2^(order + 1) (measured 55-72
        # at order 5, 14-16 at order 3).
        assert position_error(dt, order) / position_error(dt / 2, order) > 0.7 * 2 ** (order + 1)
    assert position_error(dt, 5) < largest * x0[0]
