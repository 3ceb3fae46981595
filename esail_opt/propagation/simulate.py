"""The reference: Eqs. 1-2 integrated by CVODES under a piecewise-constant attitude.

Every segment is one call of a CVODES integrator on a normalised interval
tau in [0, 1]; its length (a time, or an angle when theta is the independent
variable) is a parameter, so one compiled integrator serves every segment, and a
``mapaccum`` chains the segments into a single ``casadi.Function``.  The state
carried is ``[r, theta, v_r, v_theta, t]`` in canonical units.
"""

import contextlib
import functools
import os

import casadi as ca
import numpy as np

from esail_opt.errors import SignalsHeld
from esail_opt.physics.dynamics import rhs, rhs_in_theta
from esail_opt.physics.thrust import EXACT, radial_transverse

#: Tight enough that the reference is not the error being measured (THEORY.md §5.5).
TOLERANCE = 1e-12
#: The verifier's tolerances: it flies every schedule twice and reports the difference as
#: its own error.  Final positions of CVODES (Adams) against scipy's DOP853 at rtol 1e-13
#: on the polished Earth-Venus, Earth-Mars and 0.1 mm/s^2 Earth-Mars schedules: 5-13 m at
#: 1e-13, 0.2-1.0 m at 1e-14, 0.06-0.5 m at 1e-15 and 0.03-0.25 m at 3e-16, each run
#: taking 0.01-0.03 s; so 1e-12, where this module used to stop, cannot judge a 1 m bound.
VERIFY_TOLERANCE = 3e-16
CHECK_TOLERANCE = 1e-15
MAX_STEPS = {"time": 10_000_000, "theta": 200_000}


class SimulationError(RuntimeError):
    """CVODES could not finish: too many steps, typically an orbit that escapes."""


@contextlib.contextmanager
def quiet_stderr():
    """Hold back what CasADi prints to fd 2 when an integration fails: it dumps
    every nested Function's inputs, and the caller reports the failure itself."""
    saved = os.dup(2)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


@functools.lru_cache(maxsize=None)
def segment_integrator(samples, length_in="time", coefficients=EXACT, tol=TOLERANCE):
    """CVODES over one constant-attitude segment, sampled at tau = k / samples.

    Returns a Function ``(x0[5], ac, alpha, length) -> xs[5 x samples]``, where
    ``length`` is the segment's duration (TU) or angle (rad) and ``ac`` is the
    characteristic acceleration times the throttle, canonical units.
    """
    x = ca.SX.sym("x", 5)
    ac, alpha, length = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("length")
    R, T = radial_transverse(alpha, coefficients)
    if length_in == "time":
        ode = ca.vertcat(rhs(x[:4], ac, R, T), 1) * length
    elif length_in == "theta":
        ode = rhs_in_theta(x[:4], ac, R, T) * length
    else:
        raise ValueError(f"length_in must be 'time' or 'theta', not {length_in!r}")
    grid = [k / samples for k in range(1, samples + 1)]
    # In theta, an escaping orbit's angle tends to a finite limit and dt/dtheta to
    # infinity: fail fast there instead of grinding through the time domain's budget.
    # Adams, as the paper's reference: on these non-stiff orbits it is ~50x more
    # accurate than CVODES's default BDF at the same tolerance, and faster.
    opts = {"abstol": tol, "reltol": tol, "max_num_steps": MAX_STEPS[length_in],
            "linear_multistep_method": "adams",
            "disable_internal_warnings": True, "show_eval_warnings": False}
    dae = {"x": x, "p": ca.vertcat(ac, alpha, length), "ode": ode}
    integ = ca.integrator("segment", "cvodes", dae, 0, grid, opts)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, length = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("length")
    xs = integ(x0=x0, p=ca.vertcat(ac, alpha, length))["xf"]
    return ca.Function("segment", [x0, ac, alpha, length], [xs])


@functools.lru_cache(maxsize=None)
def schedule_function(segments, samples, length_in="time", coefficients=EXACT, tol=TOLERANCE):
    """All segments chained: ``(x0[5], ac[N], alpha[N], length[N]) -> xs[5 x N*samples]``."""
    seg = segment_integrator(samples, length_in, coefficients, tol)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, length = (ca.MX.sym(n, 1, segments) for n in ("ac", "alpha", "length"))
    xs_sym = ca.MX.sym("xs0", 5)
    a_s, al_s, l_s = ca.MX.sym("a"), ca.MX.sym("al"), ca.MX.sym("l")
    block = seg(xs_sym, a_s, al_s, l_s)
    stepper = ca.Function("stepper", [xs_sym, a_s, al_s, l_s], [block[:, -1], block])
    chained = stepper.mapaccum("chain", segments, [0], [0])
    _, blocks = chained(x0, ac, alpha, length)
    return ca.Function("schedule", [x0, ac, alpha, length], [blocks])


@functools.lru_cache(maxsize=None)
def _segments_function(segments, length_in, coefficients, tol):
    return segment_integrator(1, length_in, coefficients, tol).map(segments)


def fly_segments(starts, ac, alphas, lengths, length_in="time", coefficients=EXACT,
                 tol=TOLERANCE):
    """Every segment flown on Eqs. 1-2 from its own start, not chained.

    ``starts`` is [5 x N] (canonical, with t), ``ac`` per segment (times the throttle),
    ``alphas`` and ``lengths`` per segment.  Returns the ends [5 x N]; a defect
    correction compares them with a cheaper model's ends from the same starts.

    Raises
    ------
    SimulationError
        If CVODES cannot fly a segment (an escaping arc).
    """
    n = np.shape(starts)[1]
    fun = _segments_function(n, length_in, coefficients, tol)
    try:
        with SignalsHeld(), quiet_stderr():
            return np.array(fun(starts, np.reshape(ac, (1, -1)), np.reshape(alphas, (1, -1)),
                                np.reshape(lengths, (1, -1))))
    except RuntimeError as err:
        raise SimulationError(str(err).strip().splitlines()[-1]) from None


def simulate(x0, alphas, lengths, ac, throttles=None, samples=1, length_in="time",
             coefficients=EXACT, tol=TOLERANCE):
    """Fly Eqs. 1-2 from ``x0`` under a piecewise-constant pitch schedule.

    Parameters
    ----------
    x0 : array_like, shape (4,)
        Polar state [r, theta, v_r, v_theta], canonical units.
    alphas, lengths : array_like, shape (N,)
        Pitch (rad) and length of each segment: duration (TU) if ``length_in`` is
        ``"time"``, angle (rad) if ``"theta"``.
    ac : float
        Characteristic acceleration, canonical units.
    throttles : array_like, shape (N,), optional
        Factor on ac per segment, default 1.
    samples : int
        Output points per segment, equally spaced in its independent variable.
    tol : float
        CVODES's relative and absolute tolerance.

    Returns
    -------
    numpy.ndarray, shape (5, N * samples + 1)
        [r, theta, v_r, v_theta, t] at the start and at every sample.

    Raises
    ------
    SimulationError
        If CVODES stops short, e.g. in theta on an escaping orbit.
    """
    alphas = np.atleast_1d(np.asarray(alphas, float))
    lengths = np.atleast_1d(np.asarray(lengths, float))
    n = alphas.size
    kappa = np.ones(n) if throttles is None else np.asarray(throttles, float)
    fun = schedule_function(n, samples, length_in, coefficients, tol)
    start = np.r_[np.asarray(x0, float), 0.0]
    try:
        # Ctrl-C waits for the flight: raised inside it, it made CVODES fail instead.
        with SignalsHeld(), quiet_stderr():
            xs = np.array(fun(start, ac * kappa, alphas, lengths))
    except RuntimeError as err:
        raise SimulationError(str(err).strip().splitlines()[-1]) from None
    return np.column_stack([start, xs])
