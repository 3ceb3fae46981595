"""The first-order arc against independent references: quadrature of Eq. 13, the
paper's printed Eqs. 15-26, finite differences, and its own validity limit."""

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from esail_opt.physics.closed_form import arc_end, q_of_theta, theta_max_circular
from esail_opt.physics.elements import parking_q0, polar_from_q
from esail_opt.physics.thrust import radial_transverse

# One compiled q(theta) in the paper's frame (theta from the parking apse line).
_e0, _th0, _th, _act, _R, _T = (ca.SX.sym(n) for n in ("e0", "th0", "th", "act", "R", "T"))
Q_OF_THETA = ca.Function(
    "q", [_e0, _th0, _th, _act, _R, _T],
    [q_of_theta(parking_q0(_e0, _th0), _th0, _th, _act, _R, _T)],
)


def q_closed(e0, th0, th, act, R, T):
    return np.array(Q_OF_THETA(e0, th0, th, act, R, T)).ravel()


def b_matrix(th, e0, th0):
    """Eq. 14 as printed."""
    h0 = math.sqrt(1 + e0 * math.cos(th0))
    w = 1 + e0 * math.cos(th)
    k = (2 + e0 * math.cos(th)) / w
    return h0 / w * np.array(
        [[math.sin(th), math.cos(th) * k], [-math.cos(th), math.sin(th) * k], [0.0, -1 / w]]
    )


def q_quadrature(e0, th0, th, act, R, T):
    """q0 (Eq. 8) + a~_c * int B a~ (Eq. 13), by adaptive quadrature, split per half turn."""
    edges = np.append(np.arange(th0, th, math.pi), th)
    total = np.zeros(3)
    for i in range(3):
        def integrand(t, i=i):
            row = b_matrix(t, e0, th0)[i]
            return row[0] * R + row[1] * T
        for lo, hi in zip(edges[:-1], edges[1:]):
            total[i] += quad(integrand, lo, hi, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
    return np.array(parking_q0(e0, th0)).ravel() + act * total


eccentricities = st.one_of(
    st.sampled_from([0.0, 1e-14, 1e-8]), st.floats(0.0, 0.95, allow_nan=False)
)


@settings(max_examples=80, deadline=None)
@given(
    e0=eccentricities,
    th0=st.floats(-math.pi, math.pi),
    length=st.floats(0.0, 4 * math.pi),
    act=st.floats(0.0, 0.05),
    alpha=st.floats(-math.pi / 2, math.pi / 2),
)
def test_closed_form_matches_quadrature_of_eq13(e0, th0, length, act, alpha):
    R, T = radial_transverse(alpha)
    got = q_closed(e0, th0, th0 + length, act, R, T)
    ref = q_quadrature(e0, th0, th0 + length, act, R, T)
    assert np.all(np.abs(got - ref) <= 1e-10 * (1 + np.abs(ref)))


def paper_elliptic_d(e0, th0, th, act):
    """Eqs. 21-25 as printed, with E from Eq. 26 made continuous (THEORY.md §3.3, §6.2)."""
    h0 = math.sqrt(1 + e0 * math.cos(th0))
    beta = e0 / (1 + math.sqrt(1 - e0**2))

    def ecc_anomaly(t):
        return t - 2 * math.atan2(beta * math.sin(t), 1 + beta * math.cos(t))

    dE = ecc_anomaly(th) - ecc_anomaly(th0)
    w, w0 = 1 + e0 * math.cos(th), h0**2
    root = math.sqrt(1 - e0**2)

    def pole_free(t):  # 2 e0 tan(t/2) / ((1 - e0) tan^2(t/2) + 1 + e0), Eq. 25
        return e0 * math.sin(t) / (1 + e0 * math.cos(t))

    d11 = -act * h0 / e0 * math.log(w / w0)
    d12 = act * h0 * ((th - th0) / e0 - dE / (e0 * root**3)
                      + (math.sin(th) / w - math.sin(th0) / w0) / (1 - e0**2))
    d21 = -act * h0 / e0 * (th - th0 - dE / root)
    d22 = -act * h0 / e0 * (math.log(w / w0) - 1 / w + 1 / w0)
    d32 = -act * h0 / (1 - e0**2) * (dE / root - pole_free(th) + pole_free(th0))
    return np.array([[d11, d12], [d21, d22], [0.0, d32]])


@pytest.mark.parametrize("e0", [0.05, 0.206, 0.5, 0.9])
@pytest.mark.parametrize("length", [0.7, 3.0, 9.0])
def test_closed_form_is_the_papers_elliptic_solution(e0, length):
    th0, act, alpha = 0.4, 0.02, math.radians(30)
    R, T = radial_transverse(alpha)
    printed = np.array(parking_q0(e0, th0)).ravel() + paper_elliptic_d(e0, th0, th0 + length, act) @ [R, T]
    assert np.allclose(q_closed(e0, th0, th0 + length, act, R, T), printed, rtol=0, atol=1e-12)


@pytest.mark.parametrize("theta", [0.3, 2.0, 7.5, 25.0])
def test_circular_case_is_eq15_and_eqs17_to_19(theta):
    act, alpha = 0.017, math.radians(45)
    R, T = radial_transverse(alpha)
    c, s = math.cos(theta), math.sin(theta)
    eq15 = np.array([0, 0, 1]) + act * np.array(
        [[1 - c, 2 * s], [-s, 2 * (1 - c)], [0, -theta]]) @ [R, T]
    q = q_closed(0.0, 0.0, theta, act, R, T)
    assert np.allclose(q, eq15, rtol=0, atol=1e-14)

    state = np.array(polar_from_q(q, theta, 1.0)).ravel()
    r17 = 1 / ((1 - T * act * theta) * (1 + R * act * (c - 1) + T * act * (2 * s - theta)))
    vr18 = act * (2 * T * (1 - c) + R * s)
    vt19 = 1 - 2 * R * act * math.sin(theta / 2) ** 2 + T * act * (2 * s - theta)
    assert np.allclose(state[[0, 2, 3]], [r17, vr18, vt19], rtol=1e-13, atol=0)


def test_theta_max_is_where_q3_vanishes():
    act, alpha = 0.1 / 5.930, math.radians(45)
    R, T = radial_transverse(alpha)
    limit = theta_max_circular(act, T)
    assert limit == pytest.approx(1 / (0.25 * act), rel=1e-14)
    assert q_closed(0.0, 0.0, limit, act, R, T)[2] == pytest.approx(0.0, abs=1e-12)
    assert q_closed(0.0, 0.0, 0.999 * limit, act, R, T)[2] > 0


# The arc map with every input symbolic, for its derivatives.
_x, _len, _ac, _alpha = ca.SX.sym("x", 4), ca.SX.sym("L"), ca.SX.sym("ac"), ca.SX.sym("alpha")
_inputs = ca.vertcat(_x, _len, _ac, _alpha)
_out = ca.vertcat(*arc_end(_x, _len, _ac, *radial_transverse(_alpha))[:2])
ARC = ca.Function("arc", [_inputs], [_out])
JAC = ca.Function("arc_jacobian", [_inputs], [ca.jacobian(_out, _inputs)])
# Second derivatives of every output at once, contracted with fixed weights.
_weights = ca.DM([1.0, 0.3, -0.7, 1.3, 0.9])
HESS = ca.Function("arc_hessian", [_inputs], [ca.hessian(ca.dot(_weights, _out), _inputs)[0]])


def state_with_e(e, omega=0.7, r=1.0):
    """A polar state at theta = 0 on an orbit of eccentricity e with apse at omega."""
    p = r * (1 + e * math.cos(-omega))
    return [r, 0.0, e * math.sin(-omega) / math.sqrt(p), math.sqrt(p) / r]


def point(e):
    return np.r_[state_with_e(e), 2.5, 0.02, 0.6]


@pytest.mark.parametrize("e", [0.0, 1e-12])
def test_derivatives_finite_at_circular(e):
    assert np.all(np.isfinite(np.array(JAC(point(e)))))
    assert np.all(np.isfinite(np.array(HESS(point(e)))))


def central_difference(fun, x, step):
    cols = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = step
        cols.append((np.array(fun(x + dx)) - np.array(fun(x - dx))).ravel() / (2 * step))
    return np.column_stack(cols)


@pytest.mark.parametrize("e", [0.05, 0.3, 0.8])
def test_jacobian_and_hessian_match_finite_differences(e):
    x = point(e)
    jac = np.array(JAC(x))
    assert np.allclose(jac, central_difference(ARC, x, 1e-6), rtol=1e-6, atol=1e-7)
    grad = lambda y: _weights.T @ JAC(y)  # noqa: E731
    assert np.allclose(np.array(HESS(x)), central_difference(grad, x, 1e-6), rtol=1e-5, atol=1e-6)


def test_derivatives_continuous_through_circular():
    """At e = 0 the derivatives equal their limits from e > 0 (no 1/e0 loss)."""
    jac0, hess0 = np.array(JAC(point(0.0))), np.array(HESS(point(0.0)))
    jac_near, hess_near = np.array(JAC(point(1e-9))), np.array(HESS(point(1e-9)))
    assert np.allclose(jac0, jac_near, rtol=0, atol=1e-7)
    assert np.allclose(hess0, hess_near, rtol=0, atol=1e-6)
    grad = lambda y: _weights.T @ JAC(y)  # noqa: E731
    assert np.allclose(hess0, central_difference(grad, point(0.0), 1e-6), rtol=1e-5, atol=1e-6)
