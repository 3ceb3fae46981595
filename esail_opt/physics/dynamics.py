"""The full equations of motion, Eqs. 1-2, in canonical units."""

import functools

import casadi as ca


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
    """Derivative of ``[r, theta, v_r, v_theta]`` and of time, with theta as the
    independent variable: Eqs. 1-2 divided by theta' = v_theta / r.

    Returns the 5-vector d[r, theta, v_r, v_theta, t]/dtheta; its theta entry is 1.
    """
    dt_dtheta = x[0] / x[3]
    return ca.vertcat(rhs(x, ac, R, T) * dt_dtheta, dt_dtheta)


def angular_momentum(x0, ac, T, dt):
    """Angular momentum r v_theta after ``dt`` (TU) of constant pitch from polar state ``x0``.

    Eq. 2 is d(r v_theta)/dt = a_c r_E T, so with the pitch (and throttle) fixed,
    h = r0 v_theta0 + ac T dt exactly (r_E = 1 au, canonical units; THEORY.md §2.4).
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

    The k-th term is (dt^k / k!) (f . grad)^(k-1) f, each derivative the Jacobian-vector
    product of the one before, formed on free symbols (so that they are derivatives of
    Eqs. 1-2, not of whatever expression ``x`` is) and then evaluated at ``x``; any
    argument may be a CasADi expression.  The truncation error falls like
    dt^(order + 1); it is meant for steps that are a small part of an orbit.
    """
    return _taylor_function(order)(x, ac, R, T, dt)
