"""The plane's turn over one closed-form arc (``physics.plane_turn``), against a flight of
the Cartesian equations written out here with scipy's DOP853 and against quadrature.

The reference frame at the arc's end comes from the Cartesian state alone: h_hat from
r x v, and the direction theta is measured from found by turning r_hat back by the
plane's angle theta_end = theta_start + (the angle r_hat swept), with no use of the
turning-plane decomposition that the closed form rests on.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad, solve_ivp
from scipy.spatial.transform import Rotation

from esail_opt.physics import rotation
from esail_opt.physics.closed_form import FirstOrderArc, arc_frame
from esail_opt.physics.elements import cartesian_from_polar3d, polar_from_classical
from esail_opt.physics.plane_turn import arc_turn, first_order_turn, turned_plane
from esail_opt.physics.thrust import radial_transverse_normal


def sail_acceleration(pos, vel, ac, alpha, delta):
    """Huo et al.'s a = (a_c/2)(r_E/r)[r_hat + (r_hat . n) n], n at pitch alpha from
    r_hat, turned by delta about r_hat toward h_hat (mu = 1, r_E = 1)."""
    r = np.linalg.norm(pos)
    r_hat = pos / r
    h_hat = np.cross(pos, vel)
    h_hat /= np.linalg.norm(h_hat)
    t_hat = np.cross(h_hat, r_hat)
    n = (math.cos(alpha) * r_hat
         + math.sin(alpha) * (math.cos(delta) * t_hat + math.sin(delta) * h_hat))
    return 0.5 * ac / r * (r_hat + np.dot(r_hat, n) * n)


def fly_cartesian_theta(y0, ac, alpha, delta, dtheta):
    """The Cartesian state after r_hat has swept ``dtheta``, by DOP853 at rtol 1e-13."""

    def rhs(_theta, y):
        pos, vel = y[:3], y[3:]
        r = np.linalg.norm(pos)
        dt = r**2 / np.linalg.norm(np.cross(pos, vel))
        acc = -pos / r**3 + sail_acceleration(pos, vel, ac, alpha, delta)
        return np.r_[vel, acc] * dt

    sol = solve_ivp(rhs, (0, dtheta), y0, method="DOP853", rtol=1e-13, atol=1e-15)
    return sol.y[:, -1]


def frame_of(y, theta):
    """[e1 e2 h_hat] of the plane of Cartesian state y, e1 at angle -theta from r_hat."""
    pos, vel = y[:3], y[3:]
    r_hat = pos / np.linalg.norm(pos)
    h_hat = np.cross(pos, vel)
    h_hat /= np.linalg.norm(h_hat)
    t_hat = np.cross(h_hat, r_hat)
    c, s = math.cos(theta), math.sin(theta)
    return np.column_stack([c * r_hat - s * t_hat, s * r_hat + c * t_hat, h_hat])


ALPHA, DELTA = 0.6, 0.7
START_PLANE = np.array(rotation.from_rotation_vector([0.05, -0.1, 0.2])).ravel()


def turn_errors(e0, actilde, dphi, theta0=0.4):
    """Angle (rad) between the closed-form plane frame and the flown one after one arc,
    at first and second order, and the flown turn's own angle."""
    x0 = np.array(polar_from_classical(1.0, e0, 0.3, theta0 - 0.3)).ravel()
    ac = actilde / x0[0]
    y0 = np.array(cartesian_from_polar3d(x0, START_PLANE)).ravel()
    flown = frame_of(fly_cartesian_theta(y0, ac, ALPHA, DELTA, dphi), theta0 + dphi)
    R, T, N = (float(v) for v in radial_transverse_normal(ALPHA, DELTA))
    arc = arc_frame(x0, ac, R, T)
    errors = []
    for order in (1, 2):
        quat = turned_plane(START_PLANE, theta0, arc_turn(arc, N, dphi, order, 4))
        mine = np.array(rotation.matrix(quat))
        errors.append(Rotation.from_matrix(flown.T @ mine).magnitude())
    start = np.array(rotation.matrix(START_PLANE))
    return errors, Rotation.from_matrix(start.T @ flown).magnitude()


@pytest.mark.parametrize("e0", [0.0, 0.3])
def test_turn_orders_against_the_cartesian_flight(e0):
    """Over one radian, first order errs like a~_c^2 and second order like a~_c^3, below
    it at every a~_c from 0.001 to 0.2."""
    grid = [0.001, 0.01, 0.05, 0.2]
    results = [turn_errors(e0, eps, 1.0) for eps in grid]
    first = np.array([r[0][0] for r in results])
    second = np.array([r[0][1] for r in results])
    turned = np.array([r[1] for r in results])
    # The turn is real, and first order misses a fraction of it of order a~_c.
    assert np.all(first < 0.2 * np.array(grid) * turned)
    assert np.all(second < first / 20)
    assert np.all(first < 0.05 * np.array(grid) ** 2)
    assert np.all(second < 2e-3 * np.array(grid) ** 3)
    # From a~_c = 0.001 to 0.01 the errors scale by the order's power of ten.
    assert 70 < first[1] / first[0] < 130
    assert 600 < second[1] / second[0] < 1500


def test_circular_turn_is_the_noted_form():
    """At e0 = 0, Phi = a~_c N (sin phi, 1 - cos phi, 0)."""
    eps, N = 0.03, 0.2
    for phi in (0.3, 2.0, 7.5):
        got = np.array(first_order_turn(FirstOrderArc([0, 0, 1], eps, 0.7, 0.1), N, phi))
        want = eps * N * np.array([math.sin(phi), 1 - math.cos(phi), 0])
        assert np.abs(got.ravel() - want).max() < 1e-15


@settings(max_examples=40, deadline=None)
@given(e0=st.sampled_from([0.0, 1e-12, 1e-7]) | st.floats(0.0, 0.9),
       omega=st.floats(-math.pi, math.pi), phi=st.floats(0.01, 13.0))
def test_first_order_turn_is_the_quadrature(e0, omega, phi):
    """Phi = a~_c N h0^2 int_0^phi (cos p, sin p) / w^2 dp for every e0, e0 = 0 included,
    over arcs of several revolutions."""
    ex, ey = e0 * math.cos(omega), e0 * math.sin(omega)
    q3 = 0.8
    arc = FirstOrderArc([ex * q3, ey * q3, q3], 1.0, 0.7, 0.1)
    got = np.array(first_order_turn(arc, 1.0, phi)).ravel()
    h0 = 1 / q3

    def w2(p):
        return (1 + ex * math.cos(p) + ey * math.sin(p)) ** 2

    opts = {"epsabs": 1e-13, "epsrel": 1e-12, "limit": 400}
    want = [h0**2 * quad(lambda p: math.cos(p) / w2(p), 0, phi, **opts)[0],
            h0**2 * quad(lambda p: math.sin(p) / w2(p), 0, phi, **opts)[0]]
    scale = max(1.0, abs(want[0]), abs(want[1]))
    assert abs(got[0] - want[0]) < 1e-11 * scale
    assert abs(got[1] - want[1]) < 1e-11 * scale
    assert got[2] == 0
