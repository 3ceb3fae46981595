"""A fixed-step Runge-Kutta segment of Eqs. 1-2, expanded into one SX graph, with the
signature of ``segment_methods.closed_form_segment`` so the same multiple-shooting NLP
takes it: for the exact polish (its truncation error removed by defect correction
against CVODES, far cheaper than differentiating CVODES) and as the precision
benchmark's generic baseline.
"""

import functools

import casadi as ca

from esail_opt.physics.dynamics import (rhs, rhs_cartesian, rhs_cartesian_in_theta,
                                        rhs_in_theta, rhs_turning, swept_angle_rate)
from esail_opt.physics.thrust import EXACT, radial_transverse, radial_transverse_normal


@functools.lru_cache(maxsize=None)
def rk4_segment(steps, coefficients=EXACT, length_in="theta"):
    """One constant-pitch segment of Eqs. 1-2 by ``steps`` (>= 1) equal classic RK4 steps,
    global error like steps^-4: ``(x0[5], ac, alpha, length) -> (x1[5], q3[0])``, SX and
    expanded, x = [r, theta, v_r, v_theta, t] canonical, ``ac`` times the throttle,
    ``alpha`` in rad, ``length`` an angle (rad) or, with ``length_in="time"``, a duration
    (TU).  ``coefficients`` are (b1, b2) of Eqs. 3-4.  An integrator of the exact
    equations has no validity margin: q3 is empty, and ``transcription.transcribe`` adds
    no q3 rows for it.
    """
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps = {steps!r} is not a whole number >= 1")
    if length_in not in ("theta", "time"):
        raise ValueError(f"length_in must be 'theta' or 'time', not {length_in!r}")
    steps = int(steps)
    x = ca.SX.sym("x", 5)
    ac, alpha, h = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("h")
    R, T = radial_transverse(alpha, coefficients)

    def f(y):
        # The right-hand side depends on neither t nor theta, only on r, v_r, v_theta.
        if length_in == "theta":
            return rhs_in_theta(y[:4], ac, R, T)
        return ca.vertcat(rhs(y[:4], ac, R, T), 1)

    step = ca.Function("rk4_step", [x, ac, alpha, h], [_classic_step(f, x, h)])

    x0 = ca.SX.sym("x0", 5)
    ac, alpha, length = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("length")
    x1 = x0
    for _ in range(steps):
        x1 = step(x1, ac, alpha, length / steps)
    # expand(): one flat SX graph, which the NLP maps as it maps the closed form's.
    return ca.Function("segment_rk4", [x0, ac, alpha, length], [x1, ca.SX(0, 1)],
                       ["x0", "ac", "alpha", "length"], ["x1", "q3"]).expand()


def _classic_step(f, x, h):
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@functools.lru_cache(maxsize=None)
def rk4_segment3d(steps, coefficients=EXACT, length_in="theta"):
    """One segment of constant pitch and clock on the Cartesian equations by ``steps``
    equal classic RK4 steps: ``(y0[7], ac, alpha, delta, length) -> (y1[7], q3[0])``, SX
    and expanded, y = [x, y, z, vx, vy, vz, t] canonical, ``length`` the angle the
    Sun-sail line sweeps (rad) or a duration (TU), as :func:`rk4_segment`'s.
    """
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps = {steps!r} is not a whole number >= 1")
    if length_in not in ("theta", "time"):
        raise ValueError(f"length_in must be 'theta' or 'time', not {length_in!r}")
    step = rk4_step3d(coefficients, length_in)
    return _stepped3d("segment_rk4_3d", step, 7, steps, ("y0", "y1"), "length")


@functools.lru_cache(maxsize=None)
def rk4_step3d(coefficients=EXACT, length_in="theta", swept=False):
    """One classic RK4 step of :func:`rk4_segment3d`'s equations: ``(y, ac, alpha,
    delta, h) -> y``, SX, with y and ``length_in`` as there.  With ``swept`` (in time
    only) y has an eighth row, the angle swept (``dynamics.swept_angle_rate``),
    integrated with the motion: the 3-D polish names its nodes' plane by it."""
    if swept and length_in != "time":
        raise ValueError("swept = True counts the angle of a segment in time only")
    y = ca.SX.sym("y", 8 if swept else 7)
    ac, alpha, delta, h = (ca.SX.sym(n) for n in ("ac", "alpha", "delta", "h"))
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)

    def f(z):
        if length_in == "theta":
            return rhs_cartesian_in_theta(z[:6], ac, R, T, N)
        rate = [swept_angle_rate(z[:6])] if swept else []
        return ca.vertcat(rhs_cartesian(z[:6], ac, R, T, N), 1, *rate)

    return ca.Function("rk4_step3d" + ("_swept" if swept else ""), [y, ac, alpha, delta, h],
                       [_classic_step(f, y, h)], {"cse": True})


@functools.lru_cache(maxsize=None)
def rk4_segment_turning(steps, coefficients=EXACT):
    """One segment of constant pitch and clock on the turning-plane equations
    (``dynamics.rhs_turning``) in theta by ``steps`` equal classic RK4 steps:
    ``(x0[9], ac, alpha, delta, dtheta) -> (x1[9], q3[0])``, SX and expanded,
    x = [r, theta, v_r, v_theta, t, qw, qx, qy, qz] as ``closed_form_segment3d`` takes it.
    The quaternion's norm drifts by the method's error, as any component does.
    """
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps = {steps!r} is not a whole number >= 1")
    x = ca.SX.sym("x", 9)
    ac, alpha, delta, h = (ca.SX.sym(n) for n in ("ac", "alpha", "delta", "h"))
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)

    def f(z):
        dt_dtheta = z[0] / z[3]
        return ca.vertcat(rhs_in_theta(z[:4], ac, R, T),
                          rhs_turning(z[:4], z[5:], ac, R, T, N)[4:] * dt_dtheta)

    step = ca.Function("rk4_step_turning", [x, ac, alpha, delta, h], [_classic_step(f, x, h)])
    return _stepped3d("segment_rk4_turning", step, 9, steps, ("x0", "x1"), "dtheta")


def _stepped3d(name, step, rows, steps, ends, length_name):
    """A segment of ``steps`` equal calls of the 3-D RK4 ``step``: ``(start, ac, alpha,
    delta, length) -> (end, q3[0])``, SX and expanded."""
    y0 = ca.SX.sym(ends[0], rows)
    ac, alpha, delta, length = (ca.SX.sym(n) for n in ("ac", "alpha", "delta", length_name))
    y1 = y0
    for _ in range(int(steps)):
        y1 = step(y1, ac, alpha, delta, length / int(steps))
    return ca.Function(name, [y0, ac, alpha, delta, length], [y1, ca.SX(0, 1)],
                       [ends[0], "ac", "alpha", "delta", length_name],
                       [ends[1], "q3"]).expand()
