"""The reference: Eqs. 1-2 integrated by CVODES under a piecewise-constant attitude.

Every segment is one CVODES call on tau in [0, 1] with its length (a time, or an angle)
as a parameter, so one integrator serves every segment, chained by ``mapaccum``.  The
state is ``[r, theta, v_r, v_theta, t]``, canonical; in three dimensions a flight takes
and returns Cartesian states, whichever form it integrates (:data:`FORMS_3D`).
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
#: its own error.  Against DOP853 (rtol 1e-13), CVODES's final positions on the shipped
#: schedules were off by up to 13 m at 1e-13 and 0.25 m at 3e-16: 1e-12 cannot judge 1 m.
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
    """CVODES over one constant-attitude segment, sampled at tau = k / samples:
    ``(x0[5], ac, alpha, length) -> xs[5 x samples]``, ``length`` the duration (TU) or
    angle (rad), ``ac`` canonical, times the throttle."""
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
    # In theta an escaping orbit's angle tends to a finite limit: a smaller step budget
    # fails fast.  Adams, as the paper's reference: on these non-stiff orbits ~50x more
    # accurate than BDF at the same tolerance, and faster.
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
    """Every segment flown on Eqs. 1-2 from its own start, not chained, for a defect
    correction: ``starts`` [5 x N] (canonical, with t), ``ac`` (times the throttle),
    ``alphas`` and ``lengths`` per segment; returns the ends [5 x N].  SimulationError
    if CVODES cannot fly a segment (an escaping arc)."""
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

    ``x0`` (4,) is the polar state [r, theta, v_r, v_theta], canonical; ``alphas`` (rad),
    ``lengths`` (durations, TU, or with ``length_in="theta"`` angles, rad) and
    ``throttles`` (factors on ``ac``, default 1) are (N,); ``ac`` is canonical;
    ``samples`` are output points per segment, equal in its independent variable; ``tol``
    is CVODES's relative and absolute tolerance.  Returns [r, theta, v_r, v_theta, t] at
    the start and every sample, (5, N samples + 1); SimulationError if CVODES stops short,
    e.g. in theta on an escaping orbit.
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


#: The forms a 3-D flight can integrate: ``"turning"``, Eqs. 1-2 in a turning plane
#: (``dynamics.rhs_turning``), which the verifier judges by and the polish lands on;
#: ``"cartesian"`` (``dynamics.rhs_cartesian``), which checks that decomposition, the gap
#: between the two being part of the verifier's error (THEORY.md §5.5).
FORMS_3D = ("turning", "cartesian")


def _rates3d(form, ac, R, T, N):
    """The state of a 3-D flight in ``form`` (t last), its time derivative and dt/dtheta,
    theta the angle the Sun-sail line sweeps."""
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
    at tau = k / samples, integrating ``form`` (:data:`FORMS_3D`): ``(y0[7], ac, alpha,
    delta, length) -> ys[7 x samples]``, y = [x, y, z, vx, vy, vz, t] canonical in any
    fixed frame, ``length`` a duration (TU) or the angle the Sun-sail line sweeps (rad).
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
    """:func:`simulate` in three dimensions, integrating ``form`` (:data:`FORMS_3D`).

    ``y0`` (6,) is the Cartesian start state, canonical; ``alphas``, ``deltas`` (rad) and
    ``lengths`` (N,) per segment, a length the duration (TU) or, with
    ``length_in="theta"``, the angle the Sun-sail line sweeps (rad).  Returns
    [x, y, z, vx, vy, vz, t] at the start and every sample, (7, N samples + 1);
    SimulationError if CVODES stops short.
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
    """:func:`fly_segments` in three dimensions and in ``form``: ``starts`` [7 x N]
    Cartesian states with t, ``deltas`` per segment too; returns the ends [7 x N], or
    raises SimulationError as there."""
    n = np.shape(starts)[1]
    fun = _segments_function3d(n, length_in, coefficients, tol, form)
    rows = [np.reshape(v, (1, -1)) for v in (ac, alphas, deltas, lengths)]
    try:
        with SignalsHeld(), quiet_stderr():
            return np.array(fun(starts, *rows))
    except RuntimeError as err:
        raise SimulationError(str(err).strip().splitlines()[-1]) from None
