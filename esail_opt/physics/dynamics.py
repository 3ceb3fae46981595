"""The full equations of motion, Eqs. 1-2, in canonical units, and in three dimensions
the Cartesian equations and the planar motion in a turning plane (THEORY.md §9)."""

import functools

import casadi as ca

from esail_opt.physics import rotation


def rhs(x, ac, R, T):
    """Time derivative of the polar state ``[r, theta, v_r, v_theta]`` (Eqs. 1-2).

    The propulsive acceleration is ``ac (r_E / r) (R, T)`` with r_E = 1 au and mu = 1.
    """
    r, vr, vt = x[0], x[2], x[3]
    thrust = ac / r
    return ca.vertcat(
        vr,
        vt / r,
        vt**2 / r - 1 / r**2 + thrust * R,
        -vr * vt / r + thrust * T,
    )


def rhs_in_theta(x, ac, R, T):
    """d[r, theta, v_r, v_theta, t]/dtheta: Eqs. 1-2 divided by theta' = v_theta / r (its
    theta entry is 1)."""
    dt_dtheta = x[0] / x[3]
    return ca.vertcat(rhs(x, ac, R, T) * dt_dtheta, dt_dtheta)


def angular_momentum(x0, ac, T, dt):
    """Angular momentum r v_theta after ``dt`` (TU) of constant pitch from polar state ``x0``:
    exactly r0 v_theta0 + ac T dt, since Eq. 2 is d(r v_theta)/dt = a_c r_E T (THEORY.md §2.4).
    """
    return x0[0] * x0[3] + ac * T * dt



@functools.lru_cache(maxsize=None)
def _taylor_function(order):
    y, h = ca.SX.sym("x", 4), ca.SX.sym("dt")
    ac, R, T = ca.SX.sym("ac"), ca.SX.sym("R"), ca.SX.sym("T")
    rate = rhs(y, ac, R, T)
    term, series, factorial = rate, y, 1.0
    for k in range(1, order + 1):
        factorial *= k
        series = series + term * h**k / factorial
        term = ca.jtimes(term, y, rate)
    return ca.Function("taylor_step", [y, ac, R, T, h], [series])


def taylor_step(x, ac, R, T, dt, order):
    """Polar state ``[r, theta, v_r, v_theta]`` after ``dt`` (TU) of constant pitch from
    ``x``, by the Taylor series of Eqs. 1-2 about ``x`` to ``order`` in ``dt``.

    The series' derivatives are formed on free symbols, so any argument may be a CasADi
    expression.  The truncation error falls like dt^(order + 1): for steps that are a
    small part of an orbit.
    """
    return _taylor_function(order)(x, ac, R, T, dt)


def _cross(a, b):
    return ca.vertcat(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                      a[0] * b[1] - a[1] * b[0])


def rhs_cartesian(y, ac, R, T, N):
    """Time derivative of the Cartesian state ``[x, y, z, vx, vy, vz]`` under the Sun's
    gravity and the thrust ``ac (r_E / r) (R r_hat + T t_hat + N h_hat)``, canonical units.

    The frame comes from the state alone (h_hat = r x v / |r x v|, t_hat = h_hat x r_hat):
    this is the reference the turning-plane decomposition (:func:`rhs_turning`) is
    checked against, so it uses none of it.
    """
    pos, vel = y[:3], y[3:6]
    r = ca.norm_2(pos)
    r_hat = pos / r
    h_vec = _cross(pos, vel)
    h_hat = h_vec / ca.norm_2(h_vec)
    t_hat = _cross(h_hat, r_hat)
    thrust = ac / r * (R * r_hat + T * t_hat + N * h_hat)
    return ca.vertcat(vel, -pos / r**3 + thrust)


def swept_angle_rate(y):
    """d(theta)/dt = |r x v| / r^2 of a Cartesian state: the rate at which the Sun-sail
    line sweeps angle, by which a Cartesian flight measures lengths in theta."""
    pos, vel = y[:3], y[3:6]
    return ca.norm_2(_cross(pos, vel)) / ca.sumsqr(pos)


def rhs_cartesian_in_theta(y, ac, R, T, N):
    """d[x, y, z, vx, vy, vz, t]/dtheta, theta the angle swept (:func:`swept_angle_rate`)."""
    dt_dtheta = 1 / swept_angle_rate(y)
    return ca.vertcat(rhs_cartesian(y, ac, R, T, N) * dt_dtheta, dt_dtheta)


def plane_rate(x, ac, N):
    """Angular velocity of the turning plane's frame, in that frame's own axes, per unit
    time: (r f_N / h) r_hat = (ac N / h)(cos theta, sin theta, 0), f_N = ac N / r,
    h = r v_theta (THEORY.md §9.2)."""
    rate = ac * N / (x[0] * x[3])
    return rate * ca.vertcat(ca.cos(x[1]), ca.sin(x[1]), 0)


def rhs_turning(x, quat, ac, R, T, N):
    """d[x, quat]/dt (8-vector): the motion in three dimensions as the planar motion
    (:func:`rhs`) in a plane whose unit quaternion (``physics.rotation``'s convention;
    x along theta = 0, z along h_hat) turns about r_hat at :func:`plane_rate`.
    """
    omega = plane_rate(x, ac, N)
    dq = 0.5 * rotation.multiply(quat, ca.vertcat(0, omega))
    return ca.vertcat(rhs(x, ac, R, T), dq)
