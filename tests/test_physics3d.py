"""Three dimensions in the physics layer: the thrust (R, T, N), the Cartesian equations,
the turning-plane decomposition, and the conversions between the polar state in its plane
and the Cartesian state."""

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from esail_opt.physics import rotation
from esail_opt.physics.constants import accel_from_mm_s2, time_from_years
from esail_opt.physics.dynamics import rhs_cartesian, rhs_turning
from esail_opt.physics.elements import (cartesian_from_polar3d, inclination_and_node,
                                        polar3d_from_cartesian, polar_from_classical)
from esail_opt.physics.thrust import (BEST_FIT, EXACT, canonical_attitude, radial_transverse,
                                      radial_transverse_normal)
from test_plane_turn import sail_acceleration

angles = st.floats(-math.pi / 2, math.pi / 2)
clocks = st.floats(-math.pi, math.pi)


@settings(max_examples=60, deadline=None)
@given(alpha=angles, delta=clocks, r=st.floats(0.3, 5.0), vr=st.floats(-0.5, 0.5),
       vt=st.floats(0.2, 1.5), tilt=st.floats(-1.0, 1.0))
def test_cartesian_thrust_is_huo_geometry(alpha, delta, r, vr, vt, tilt):
    """rhs_cartesian's thrust with (R, T, N)(alpha, delta) is a = (a_c/2)(r_E/r)
    [r_hat + (r_hat . n) n], evaluated directly from the sail's normal."""
    quat = rotation.from_rotation_vector([tilt, 0.3 * tilt, -0.5])
    y = np.array(cartesian_from_polar3d([r, 0.7, vr, vt], quat)).ravel()
    ac = 0.2
    R, T, N = radial_transverse_normal(alpha, delta, EXACT)
    got = np.array(rhs_cartesian(y, ac, R, T, N)).ravel()[3:]
    gravity = -y[:3] / r**3
    want = sail_acceleration(y[:3], y[3:], ac, alpha, delta)
    assert np.abs(got - gravity - want).max() < 1e-14


@pytest.mark.parametrize("coefficients", [EXACT, BEST_FIT])
def test_thrust_in_the_plane_is_eqs_3_4(coefficients):
    """At delta = 0 (R, T, N) is (R, T, 0) of Eqs. 3-4 to the bit; any clock turns the
    in-plane transverse part about r_hat, keeping R and |(T, N)|."""
    b1, b2 = coefficients
    for alpha in np.linspace(-math.pi / 2, math.pi / 2, 13):
        R, T, N = (float(v) for v in radial_transverse_normal(alpha, 0.0, coefficients))
        R2, T2 = (float(v) for v in radial_transverse(alpha, coefficients))
        assert (R, T, N) == (R2, T2, 0.0)
        assert abs(R - (b1 + b2 * math.cos(2 * alpha))) < 1e-16
        for delta in (0.4, -2.0, math.pi / 2):
            R3, T3, N3 = (float(v) for v in radial_transverse_normal(alpha, delta, coefficients))
            assert R3 == R
            assert abs(math.hypot(T3, N3) - abs(T)) < 1e-16
            assert abs(N3 - b2 * math.sin(2 * alpha) * math.sin(delta)) < 1e-16



@settings(max_examples=80, deadline=None)
@given(alpha=angles, delta=st.floats(-4 * math.pi, 4 * math.pi))
def test_canonical_attitude_is_the_same_sail(alpha, delta):
    """The canonical name of an attitude has its clock in (-90, 90] deg and gives the
    same acceleration, computed from the sail's normal (Huo's geometry), as the NLP's."""
    a2, d2 = canonical_attitude(alpha, delta)
    assert -math.pi / 2 < d2 <= math.pi / 2 + 1e-15
    assert abs(a2) == abs(alpha)
    pos, vel = np.array([0.8, 0.3, 0.1]), np.array([-0.2, 1.0, 0.05])
    want = sail_acceleration(pos, vel, 1.0, alpha, delta)
    got = sail_acceleration(pos, vel, 1.0, a2, d2)
    assert np.abs(got - want).max() < 1e-14


def test_canonical_attitude_keeps_a_planar_braking_pitch():
    """A planar-like attitude keeps its name: delta = 0 with a negative pitch, and the
    clock of 180 deg is renamed to delta = 0 with the pitch's sign changed."""
    assert canonical_attitude(-0.3, 0.0) == (-0.3, 0.0)
    a, d = canonical_attitude(0.3, math.pi)
    assert a == -0.3 and abs(d) < 1e-15


def _integrator(name, ode, state, params, tol):
    opts = {"abstol": tol, "reltol": tol, "max_num_steps": 1_000_000,
            "linear_multistep_method": "adams"}
    return ca.integrator(name, "cvodes", {"x": state, "p": params, "ode": ode}, 0, 1, opts)


def _flights(tol=3e-16):
    """CVODES over a span s (a parameter, as time = s tau) on the Cartesian equations
    and on Eqs. 1-2 plus the turning plane's quaternion."""
    ac, R, T, N, span = (ca.SX.sym(n) for n in ("ac", "R", "T", "N", "span"))
    p = ca.vertcat(ac, R, T, N, span)
    y = ca.SX.sym("y", 6)
    cart = _integrator("cart", rhs_cartesian(y, ac, R, T, N) * span, y, p, tol)
    z = ca.SX.sym("z", 8)
    turn = _integrator("turn", rhs_turning(z[:4], z[4:], ac, R, T, N) * span, z, p, tol)
    return cart, turn


def _grid():
    """alpha, delta, a_c (mm/s^2) and e0, less the schedules whose angular momentum
    (h0 + a_c T t, exactly; e.g. T < 0 at 1 mm/s^2) would fall below 0.5 within 5 years:
    they spiral into the Sun."""
    span = time_from_years(5.0)
    cases = []
    for a in (35.0, -60.0, 80.0):
        for d in (25.0, -100.0, 155.0):
            _, T, _ = radial_transverse_normal(math.radians(a), math.radians(d))
            for ac in (0.1, 1.0):
                if 1.0 + accel_from_mm_s2(ac) * float(T) * span > 0.5:
                    cases += [(math.radians(a), math.radians(d), ac, e0) for e0 in (0.0, 0.2)]
    return cases


GRID = _grid()


def test_decomposition_agrees_with_cartesian_over_five_years():
    """Cartesian CVODES and (Eqs. 1-2 + turning plane) CVODES agree to 1e-10 (au, au/TU,
    relative to r and v) over 5 years, on a grid of alpha, delta, a_c and e0."""
    cart, turn = _flights()
    span = time_from_years(5.0)
    start = np.array(rotation.from_rotation_vector([0.04, -0.02, 0.3])).ravel()
    worst = 0.0
    for alpha, delta, ac_mm, e0 in GRID:
        R, T, N = (float(v) for v in radial_transverse_normal(alpha, delta))
        p = [accel_from_mm_s2(ac_mm), R, T, N, span]
        x0 = np.array(polar_from_classical(1.0, e0, 0.5, 1.0)).ravel()
        y0 = np.array(cartesian_from_polar3d(x0, start)).ravel()
        y1 = np.array(cart(x0=y0, p=p)["xf"]).ravel()
        z1 = np.array(turn(x0=np.r_[x0, start], p=p)["xf"]).ravel()
        quat = z1[4:] / np.linalg.norm(z1[4:])
        y2 = np.array(cartesian_from_polar3d(z1[:4], quat)).ravel()
        r, v = np.linalg.norm(y1[:3]), np.linalg.norm(y1[3:])
        miss = max(np.abs(y2[:3] - y1[:3]).max() / r, np.abs(y2[3:] - y1[3:]).max() / v)
        tilt = inclination_and_node(quat)[0]
        assert float(tilt) > 0.01  # the plane did turn
        worst = max(worst, miss)
    assert worst < 1e-10


@settings(max_examples=60, deadline=None)
@given(pos=st.tuples(*[st.floats(-3, 3)] * 3), vel=st.tuples(*[st.floats(-1.5, 1.5)] * 3))
def test_cartesian_round_trip(pos, vel):
    """Cartesian -> (polar, plane) -> Cartesian is the identity, for any state whose
    angular momentum is not tiny or exactly retrograde; the plane's normal is h_hat."""
    y = np.r_[pos, vel]
    h = np.cross(y[:3], y[3:])
    r = np.linalg.norm(y[:3])
    speed = np.linalg.norm(y[3:])
    if r < 0.1 or speed < 0.1 or np.linalg.norm(h) < 0.05 * r * speed:
        return
    if h[2] < -0.99 * np.linalg.norm(h):
        return
    x, quat = polar3d_from_cartesian(y)
    back = np.array(cartesian_from_polar3d(x, quat)).ravel()
    assert np.abs(back - y).max() < 1e-13 * max(1.0, np.abs(y).max())
    normal = np.array(rotation.matrix(quat))[:, 2]
    assert np.abs(normal - h / np.linalg.norm(h)).max() < 1e-13
    assert abs(float(np.linalg.norm(np.array(quat))) - 1) < 1e-15


def test_planar_state_is_the_identity_plane():
    """A state in the fixed x-y plane, moving prograde, has the identity plane and its
    longitude as theta: the planar model's convention."""
    x = np.array([1.3, 2.1, 0.1, 0.8])
    y = np.array(cartesian_from_polar3d(x, rotation.IDENTITY)).ravel()
    assert abs(y[2]) == 0 and abs(y[5]) == 0
    back, quat = polar3d_from_cartesian(y)
    assert np.abs(np.array(back).ravel() - x).max() < 1e-15
    assert np.abs(np.array(quat).ravel() - rotation.IDENTITY).max() < 1e-15


@settings(max_examples=60, deadline=None)
@given(r=st.floats(0.2, 5.0), theta=st.floats(-10, 10), vr=st.floats(-0.5, 0.5),
       vt=st.floats(0.2, 2.0), turn=st.tuples(*[st.floats(-1.2, 1.2)] * 3))
def test_polar_plane_round_trip(r, theta, vr, vt, turn):
    """(polar, plane) -> Cartesian -> (polar, plane') keeps r, v_r, v_theta and h_hat;
    plane' differs from plane only by a turn about h_hat, matched by the shift of theta,
    so both give the same Cartesian state."""
    quat = rotation.from_rotation_vector(list(turn))
    y = np.array(cartesian_from_polar3d([r, theta, vr, vt], quat)).ravel()
    back, quat2 = polar3d_from_cartesian(y)
    back = np.array(back).ravel()
    assert np.abs(back[[0, 2, 3]] - [r, vr, vt]).max() < 1e-13 * max(1, r, 1 / r)
    relative = np.array(rotation.matrix(quat)).T @ np.array(rotation.matrix(quat2))
    spin = math.atan2(relative[1, 0], relative[0, 0])
    assert np.abs(relative[:, 2] - [0, 0, 1]).max() < 1e-13
    shift = (theta - back[1] - spin + math.pi) % (2 * math.pi) - math.pi
    assert abs(shift) < 1e-12


def test_inclination_and_node_of_a_plane():
    """The plane reached by turning the fixed frame by i about the x axis and then by
    Omega about z has inclination i and node Omega (rotation composed by scipy)."""
    for inc, node in ((0.3, 1.1), (1.0, -2.5), (2.0, 0.2)):
        quat_xyzw = Rotation.from_euler("ZX", [node, inc]).as_quat()
        quat = np.r_[quat_xyzw[3], quat_xyzw[:3]]
        i, n = (float(v) for v in inclination_and_node(quat))
        assert abs(i - inc) < 1e-14 and abs(n - node) < 1e-14
