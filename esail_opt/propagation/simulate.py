"""The reference: Eqs. 1-2 integrated by CVODES under a piecewise-constant attitude.

Every segment is one call of a CVODES integrator on a normalised interval
tau in [0, 1]; its length (a time, or an angle when theta is the independent
variable) is a parameter, so one compiled integrator serves every segment, and a
``mapaccum`` chains the segments into a single ``casadi.Function``.  The state
carried is ``[r, theta, v_r, v_theta, t]`` in canonical units; in three dimensions a
flight takes and returns Cartesian states, whichever form it integrates
(:data:`FORMS_3D`).
"""

import contextlib
import functools
import os

import casadi as ca
import numpy as np

from esail_opt.runtime.signals import SignalsHeld
from esail_opt.physics.dynamics import (rhs, rhs_cartesian, rhs_in_theta, rhs_turning,
                                        swept_angle_rate)
from esail_opt.physics.elements import cartesian_from_polar3d, polar3d_from_cartesian
from esail_opt.physics.thrust import EXACT, radial_transverse, radial_transverse_normal

#: Tight enough that the reference is not the error being measured (THEORY.md §5.5).
TOLERANCE = 1e-12
#: The verifier's tolerances: it flies every schedule twice and reports the difference as
#: its own error.  Final positions of CVODES (Adams) against scipy's DOP853 at rtol 1e-13
#: on the polished Earth-Venus, Earth-Mars and 0.1 mm/s^2 Earth-Mars schedules: 5-13 m at
#: 1e-13, 0.2-1.0 m at 1e-14, 0.06-0.5 m at 1e-15 and 0.03-0.25 m at 3e-16; so 1e-12,
#: where this module used to stop, cannot judge a 1 m bound.
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
    return ca.Function("segment", [x0, ac, alpha, length], [xs],
                       ["x0", "ac", "alpha", "length"], ["xs"])


@functools.lru_cache(maxsize=None)
def schedule_function(segments, samples, length_in="time", coefficients=EXACT, tol=TOLERANCE):
    """All segments chained: ``(x0[5], ac[N], alpha[N], length[N]) -> xs[5 x N*samples]``."""
    return _chained(segment_integrator(samples, length_in, coefficients, tol), segments)


def _chained(seg, segments):
    """A segment Function ``(x0, *per-segment scalars) -> xs`` chained over ``segments``
    segments, each starting where the one before ended, by one ``mapaccum``."""
    xs_sym = ca.MX.sym("xs0", seg.sparsity_in(0))
    scalars = [ca.MX.sym(f"p{k}") for k in range(1, seg.n_in())]
    block = seg(xs_sym, *scalars)
    stepper = ca.Function("stepper", [xs_sym, *scalars], [block[:, -1], block])
    chained = stepper.mapaccum("chain", segments, [0], [0])
    x0 = ca.MX.sym("x0", seg.sparsity_in(0))
    rows = [ca.MX.sym(seg.name_in(k), 1, segments) for k in range(1, seg.n_in())]
    _, blocks = chained(x0, *rows)
    return ca.Function("schedule", [x0, *rows], [blocks])


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


#: The forms a 3-D flight can integrate.  ``"turning"``: Eqs. 1-2 in a plane whose
#: quaternion turns about r_hat (``dynamics.rhs_turning``, THEORY.md §9.2), the form the
#: verifier judges by and the polish lands on, as the planar verifier flies Eqs. 1-2.
#: ``"cartesian"``: the Cartesian equations (``dynamics.rhs_cartesian``), which use no
#: plane and no polar state, so that a flight on them checks the decomposition, and
#: the gap between the two forms is part of the verifier's error (THEORY.md §5.5).
FORMS_3D = ("turning", "cartesian")


def _rates3d(form, ac, R, T, N):
    """The state of a 3-D flight in ``form``, its time derivative (its last row, t, has
    rate 1) and dt/dtheta, theta the angle the Sun-sail line sweeps."""
    if form == "turning":
        z = ca.SX.sym("z", 9)  # [r, theta, v_r, v_theta, quaternion, t]
        rates = ca.vertcat(rhs_turning(z[:4], z[4:8], ac, R, T, N), 1)
        # The plane turns about r_hat only, so its theta is the angle swept (§9.3).
        return z, rates, z[0] / z[3]
    if form == "cartesian":
        z = ca.SX.sym("y", 7)
        return z, ca.vertcat(rhs_cartesian(z[:6], ac, R, T, N), 1), 1 / swept_angle_rate(z[:6])
    raise ValueError(f"form must be one of {FORMS_3D}, not {form!r}")


def _from_cartesian(form, y):
    """A Cartesian state with t (7 rows) as the state of ``form``."""
    if form == "cartesian":
        return y
    x, quat = polar3d_from_cartesian(y[:6])
    return ca.vertcat(x, quat, y[6])


def _to_cartesian(form, zs):
    """The columns of ``zs``, states of ``form``, as Cartesian states with t."""
    if form == "cartesian":
        return zs
    columns = [ca.vertcat(cartesian_from_polar3d(z[:4], z[4:8] / ca.norm_2(z[4:8])), z[8])
               for z in ca.horzsplit(zs)]
    return ca.horzcat(*columns)


@functools.lru_cache(maxsize=None)
def segment_integrator3d(samples, length_in="time", coefficients=EXACT, tol=TOLERANCE,
                         form="turning"):
    """CVODES over one segment of constant pitch and clock in three dimensions, sampled
    at tau = k / samples, integrating ``form`` (:data:`FORMS_3D`).

    Returns ``(y0[7], ac, alpha, delta, length) -> ys[7 x samples]``, y = [x, y, z, vx,
    vy, vz, t] canonical (any fixed frame, the ecliptic of J2000 for real bodies), so
    that both forms are called alike; ``length`` is a duration (TU) or the angle the
    Sun-sail line sweeps (rad, ``dynamics.swept_angle_rate``).
    """
    ac, alpha, delta, length = (ca.SX.sym(n) for n in ("ac", "alpha", "delta", "length"))
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)
    z, rates, dt_dtheta = _rates3d(form, ac, R, T, N)
    if length_in == "time":
        ode = rates * length
    elif length_in == "theta":
        ode = rates * dt_dtheta * length
    else:
        raise ValueError(f"length_in must be 'time' or 'theta', not {length_in!r}")
    grid = [k / samples for k in range(1, samples + 1)]
    opts = {"abstol": tol, "reltol": tol, "max_num_steps": MAX_STEPS[length_in],
            "linear_multistep_method": "adams",
            "disable_internal_warnings": True, "show_eval_warnings": False}
    integ = ca.integrator("segment3d", "cvodes",
                          {"x": z, "p": ca.vertcat(ac, alpha, delta, length), "ode": ode},
                          0, grid, opts)
    y0 = ca.MX.sym("y0", 7)
    ac, alpha, delta, length = (ca.MX.sym(n) for n in ("ac", "alpha", "delta", "length"))
    zs = integ(x0=_from_cartesian(form, y0), p=ca.vertcat(ac, alpha, delta, length))["xf"]
    return ca.Function("segment3d", [y0, ac, alpha, delta, length], [_to_cartesian(form, zs)],
                       ["y0", "ac", "alpha", "delta", "length"], ["ys"])


@functools.lru_cache(maxsize=None)
def schedule_function3d(segments, samples, length_in="time", coefficients=EXACT,
                        tol=TOLERANCE, form="turning"):
    """All 3-D segments chained: ``(y0[7], ac[N], alpha[N], delta[N], length[N]) ->
    ys[7 x N*samples]`` (:func:`segment_integrator3d`)."""
    return _chained(segment_integrator3d(samples, length_in, coefficients, tol, form),
                    segments)


def simulate3d(y0, alphas, deltas, lengths, ac, throttles=None, samples=1, length_in="time",
               coefficients=EXACT, tol=TOLERANCE, form="turning"):
    """Fly the motion in three dimensions from ``y0`` under a schedule of pitch and clock
    angles, integrating ``form`` (:data:`FORMS_3D`).

    Parameters
    ----------
    y0 : array_like, shape (6,)
        Cartesian state [x, y, z, vx, vy, vz], canonical units.
    alphas, deltas, lengths : array_like, shape (N,)
        Pitch and clock (rad) and length of each segment: duration (TU) if
        ``length_in`` is ``"time"``, the angle the Sun-sail line sweeps (rad) if
        ``"theta"``.
    ac, throttles, samples, coefficients, tol
        As :func:`simulate`.
    form : str
        What CVODES integrates (:data:`FORMS_3D`); the states given and returned are
        Cartesian either way.

    Returns
    -------
    numpy.ndarray, shape (7, N * samples + 1)
        [x, y, z, vx, vy, vz, t] at the start and at every sample.

    Raises
    ------
    SimulationError
        If CVODES stops short.
    """
    alphas = np.atleast_1d(np.asarray(alphas, float))
    n = alphas.size
    kappa = np.ones(n) if throttles is None else np.asarray(throttles, float)
    fun = schedule_function3d(n, samples, length_in, coefficients, tol, form)
    start = np.r_[np.asarray(y0, float), 0.0]
    try:
        with SignalsHeld(), quiet_stderr():
            ys = np.array(fun(start, ac * kappa, alphas,
                              np.atleast_1d(np.asarray(deltas, float)),
                              np.atleast_1d(np.asarray(lengths, float))))
    except RuntimeError as err:
        raise SimulationError(str(err).strip().splitlines()[-1]) from None
    return np.column_stack([start, ys])


@functools.lru_cache(maxsize=None)
def _segments_function3d(segments, length_in, coefficients, tol, form):
    return segment_integrator3d(1, length_in, coefficients, tol, form).map(segments)


def fly_segments3d(starts, ac, alphas, deltas, lengths, length_in="time",
                   coefficients=EXACT, tol=TOLERANCE, form="turning"):
    """Every segment flown in ``form`` from its own start, not chained
    (:func:`fly_segments` in three dimensions).

    ``starts`` is [7 x N] Cartesian states with t; ``ac`` (times the throttle),
    ``alphas``, ``deltas`` and ``lengths`` per segment.  Returns the ends [7 x N].

    Raises
    ------
    SimulationError
        If CVODES cannot fly a segment.
    """
    n = np.shape(starts)[1]
    fun = _segments_function3d(n, length_in, coefficients, tol, form)
    rows = [np.reshape(v, (1, -1)) for v in (ac, alphas, deltas, lengths)]
    try:
        with SignalsHeld(), quiet_stderr():
            return np.array(fun(starts, *rows))
    except RuntimeError as err:
        raise SimulationError(str(err).strip().splitlines()[-1]) from None
