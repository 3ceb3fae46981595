"""The rectified closed-form propagator: first-order arcs restarted segment by segment.

At each rectification point the paper's arc is restarted from the current
osculating orbit: new r0, new a~_c, and a new reference direction, here the
current radius (``esail_opt.physics.closed_form.arc_frame``), which is defined
for every orbit, circular ones included.  The pitch and the throttle may change
there.  A segment's length is an angle, or a duration whose end is found on the
closed form's own clock by Newton's method.

The chain is one ``casadi.Function``: an SX arc, wrapped (for durations) in a
Newton rootfinder, accumulated over the segments with ``mapaccum``.  Its state is
``[r, theta, v_r, v_theta, t]``, canonical units, as in :mod:`.simulate`.
"""

import functools

import casadi as ca
import numpy as np

from esail_opt.physics.closed_form import arc_frame, arc_state
from esail_opt.physics.thrust import EXACT, radial_transverse

#: Gauss-Legendre points per sample interval for the time of flight.
NODES = 8


@functools.lru_cache(maxsize=None)
def panel_function(coefficients=EXACT, nodes=NODES):
    """One closed-form arc between two of its angles: ``(x0[5], ac, alpha, phi_a, phi_b)
    -> (state at phi_b [4], time from phi_a to phi_b, q3 at phi_b)``, an SX Function."""
    x0 = ca.SX.sym("x0", 5)
    ac, alpha = ca.SX.sym("ac"), ca.SX.sym("alpha")
    phi_a, phi_b = ca.SX.sym("phi_a"), ca.SX.sym("phi_b")
    R, T = radial_transverse(alpha, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    dt = x0[0] ** 1.5 * arc.time(phi_a, phi_b, nodes)
    return ca.Function(
        "panel", [x0, ac, alpha, phi_a, phi_b],
        [arc_state(x0[:4], arc, phi_b), dt, arc.q(phi_b)[2]],
    )


@functools.lru_cache(maxsize=None)
def arc_function(samples, coefficients=EXACT, nodes=NODES):
    """One closed-form arc sampled at phi_k = dtheta k / samples, k = 1..samples.

    Returns a Function ``(x0[5], ac, alpha, dtheta) -> (xs[5 x samples], q3)``
    where ``ac`` already includes any throttle, the time row of ``xs`` continues from
    x0's, and ``q3`` is the validity margin at the arc's end (positive is valid).
    The sample intervals double as the panels of the time quadrature.  The samples
    are a ``map`` of one panel Function, so building it costs the same for any count;
    ``expand()`` it where one flat SX expression is wanted.
    """
    panel = panel_function(coefficients, nodes).map(samples)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, dtheta = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("dtheta")
    fractions = ca.DM(np.arange(samples + 1) / samples).T
    phis = dtheta * fractions
    states, dts, q3s = panel(x0, ac, alpha, phis[:, :-1], phis[:, 1:])
    times = x0[4] + ca.cumsum(dts, 1)
    return ca.Function(
        "arc", [x0, ac, alpha, dtheta], [ca.vertcat(states, times), q3s[-1]],
        ["x0", "ac", "alpha", "dtheta"], ["xs", "q3"],
    )


#: Newton steps on the closed form's clock; from the starting-rate guess the error
#: after four is below 1e-13 rad on the paper's scenarios (tests check the residual).
NEWTON_STEPS = 5


@functools.lru_cache(maxsize=None)
def timed_arc_function(samples, coefficients=EXACT, nodes=NODES):
    """As :func:`arc_function`, but the last input is a duration (TU).

    The arc angle is the root of t(dtheta) = duration on the closed form's clock:
    a fixed number of Newton steps from the angle swept at the starting angular
    rate, unrolled in SX so that the whole arc stays one flat expression.
    dt/dtheta = r0^{3/2} / (q3 s^2) is exact on the closed form.  A third output
    is the clock's remaining residual (TU).
    """
    x0 = ca.SX.sym("x0", 5)
    ac, alpha, duration = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("duration")
    R, T = radial_transverse(alpha, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    time_unit = x0[0] ** 1.5

    def clock(phi):
        return time_unit * sum(
            arc.time(phi * (k - 1) / samples, phi * k / samples, nodes)
            for k in range(1, samples + 1)
        )

    def rate(phi):
        q = arc.q(phi)
        s = q[0] * ca.cos(phi) + q[1] * ca.sin(phi) + q[2]
        return time_unit / (q[2] * s**2)

    angle = duration * x0[3] / x0[0]
    for _ in range(NEWTON_STEPS):
        angle = angle - (clock(angle) - duration) / rate(angle)
    xs, q3 = arc_function(samples, coefficients, nodes).expand()(x0, ac, alpha, angle)
    return ca.Function(
        "timed_arc", [x0, ac, alpha, duration], [xs, q3, xs[4, -1] - x0[4] - duration],
        ["x0", "ac", "alpha", "duration"], ["xs", "q3", "residual"],
    ).expand()


@functools.lru_cache(maxsize=None)
def rectified_function(segments, samples=1, length_in="theta", coefficients=EXACT,
                       nodes=NODES):
    """The whole schedule as one Function.

    ``(x0[5], ac[1 x N], alpha[1 x N], length[1 x N]) -> (xs[5 x N*samples], q3[1 x N])``
    with ``ac`` per segment (characteristic acceleration times throttle).
    """
    if length_in == "theta":
        arc = arc_function(samples, coefficients, nodes)
    elif length_in == "time":
        arc = timed_arc_function(samples, coefficients, nodes)
    else:
        raise ValueError(f"length_in must be 'theta' or 'time', not {length_in!r}")
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, length = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("length")
    xs, q3 = arc(x0, ac, alpha, length)[:2]
    step = ca.Function("step", [x0, ac, alpha, length], [xs[:, -1], xs, q3])
    chain = step.mapaccum("chain", segments, [0], [0])
    x0 = ca.MX.sym("x0", 5)
    acs, alphas, lengths = (ca.MX.sym(n, 1, segments) for n in ("ac", "alpha", "length"))
    _, blocks, q3s = chain(x0, acs, alphas, lengths)
    return ca.Function(
        "rectified", [x0, acs, alphas, lengths], [blocks, q3s],
        ["x0", "ac", "alpha", "length"], ["xs", "q3"],
    )


def propagate(x0, alphas, lengths, ac, throttles=None, samples=1, length_in="theta",
              coefficients=EXACT):
    """Rectified closed-form propagation of a piecewise-constant pitch schedule.

    Parameters
    ----------
    x0 : array_like, shape (4,)
        Polar state [r, theta, v_r, v_theta], canonical units.
    alphas, lengths : array_like, shape (N,)
        Pitch (rad) and length of each segment: an angle (rad) if ``length_in`` is
        ``"theta"``, a duration (TU) if ``"time"``.
    ac : float
        Characteristic acceleration, canonical units.
    throttles : array_like, shape (N,), optional
        Factor on ac per segment (0 is a coast), default 1.
    samples : int
        Points per segment, equally spaced in theta; they also set the time
        quadrature's panels.

    Returns
    -------
    xs : numpy.ndarray, shape (5, N * samples + 1)
        [r, theta, v_r, v_theta, t] at the start and at every sample; the
        rectification points are every ``samples``-th column.
    q3 : numpy.ndarray, shape (N,)
        Validity margin at each segment's end; non-positive means the
        first-order arc went past theta_max.
    """
    alphas = np.atleast_1d(np.asarray(alphas, float))
    lengths = np.atleast_1d(np.asarray(lengths, float))
    n = alphas.size
    kappa = np.ones(n) if throttles is None else np.asarray(throttles, float)
    fun = rectified_function(n, samples, length_in, coefficients)
    start = np.r_[np.asarray(x0, float), 0.0]
    xs, q3 = fun(start, ac * kappa, alphas, lengths)
    return np.column_stack([start, np.array(xs)]), np.array(q3).ravel()
