"""heyoka's Taylor integrator flying Eqs. 1-2 under a piecewise-constant pitch, and the
Cartesian equations in three dimensions under a piecewise-constant pitch and clock: the
strongest integrator the propagation and ensemble benches set against the closed form.
heyoka is the ``bench`` extra (:func:`available`); nothing imports it at module level.

The package's own equations (``physics.dynamics.rhs``, ``rhs_cartesian``) are replayed on
heyoka's expressions (:func:`replay`), so heyoka flies the same formula as CVODES, written
nowhere a second time.  The thrust's components are runtime parameters, so a schedule
changes them between arcs without compiling again.

The arcs are flown one by one (``propagate_until`` each arc's end in batch mode, one SIMD
lane a case, on the calling thread), each from an exact state with its own thrust, as
CVODES restarts on each segment: across a thrust jump inside a step the Taylor series is
wrong, and heyoka's step control would not see it.
"""

import collections
import functools

import casadi as ca
import numpy as np

from esail_opt.physics import dynamics
from esail_opt.physics.thrust import EXACT, radial_transverse, radial_transverse_normal


def available():
    """Whether heyoka imports (the ``bench`` extra is installed)."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        return False
    return True


def _ops(hy):
    """heyoka's form of each CasADi SX operation Eqs. 1-2 are built from."""
    return {
        ca.OP_ADD: lambda a, b: a + b, ca.OP_SUB: lambda a, b: a - b,
        ca.OP_MUL: lambda a, b: a * b, ca.OP_DIV: lambda a, b: a / b,
        ca.OP_NEG: lambda a: -a, ca.OP_SQ: lambda a: a**2, ca.OP_TWICE: lambda a: 2.0 * a,
        ca.OP_INV: lambda a: 1.0 / a, ca.OP_SQRT: hy.sqrt,
        ca.OP_POW: lambda a, b: a**b, ca.OP_CONSTPOW: lambda a, b: a**b,
        ca.OP_SIN: hy.sin, ca.OP_COS: hy.cos,
    }


def system():
    """Eqs. 1-2 (``dynamics.rhs``) as heyoka's ODE system: (variable, derivative) for r,
    theta, v_r, v_theta, canonical units, with ``par[0]`` = a_c R and ``par[1]`` = a_c T
    (:func:`replay`, whose NotImplementedError it may raise)."""
    import heyoka as hy

    x, push = ca.SX.sym("x", 4), ca.SX.sym("push", 2)
    # a_c = 1 with R, T standing for a_c R and a_c T.
    fun = ca.Function("eqs_1_2", [x, push], [dynamics.rhs(x, 1.0, push[0], push[1])])
    return replay(fun, hy.make_vars("r", "theta", "v_r", "v_theta"))


def cartesian_system():
    """The Cartesian equations (``dynamics.rhs_cartesian``) as heyoka's ODE system:
    (variable, derivative) for x, y, z, vx, vy, vz, canonical units, with ``par[0..2]`` =
    a_c R, a_c T, a_c N (:func:`replay`).  The expressions have no floating-point type,
    so the same system serves doubles and quadruple precision."""
    import heyoka as hy

    y, push = ca.SX.sym("y", 6), ca.SX.sym("push", 3)
    # a_c = 1 with the pushes standing for a_c R, a_c T and a_c N.
    fun = ca.Function("cartesian", [y, push],
                      [dynamics.rhs_cartesian(y, 1.0, *ca.vertsplit(push))])
    return replay(fun, hy.make_vars("x", "y", "z", "vx", "vy", "vz"))


def replay(fun, variables):
    """The SX Function ``fun(state, push) -> rates`` as heyoka's ODE system: its
    instructions replayed on heyoka's expressions, ``state`` as ``variables`` and
    ``push`` as the runtime parameters ``par[0]``, ``par[1]``, ...; a list of (variable,
    derivative).  NotImplementedError if ``fun`` uses an operation not in :func:`_ops`.
    """
    import heyoka as hy

    inputs = (variables, [hy.par[k] for k in range(fun.size1_in(1))])
    ops, work, rates = _ops(hy), {}, [None] * len(variables)
    for k in range(fun.n_instructions()):
        op, args, out = fun.instruction_id(k), fun.instruction_input(k), fun.instruction_output(k)
        if op == ca.OP_INPUT:
            work[out[0]] = inputs[args[0]][args[1]]
        elif op == ca.OP_OUTPUT:
            rates[out[1]] = work[args[0]]
        elif op == ca.OP_CONST:
            work[out[0]] = hy.expression(float(fun.instruction_constant(k)))
        elif op in ops:
            work[out[0]] = ops[op](*(work[j] for j in args))
        else:
            raise NotImplementedError(f"CasADi operation {op} has no heyoka form here")
    return list(zip(variables, rates))


@functools.lru_cache(maxsize=None)
def integrator(tol, batch_size=None):
    """A heyoka batch integrator of :func:`system` at tolerance ``tol``, compiled once per
    process, tolerance and ``batch_size`` (cases side by side, one a SIMD lane; default
    heyoka's recommended SIMD width).  :func:`fly` sets its state, time and parameters."""
    import heyoka as hy

    size = batch_size or hy.recommended_simd_size()
    return hy.taylor_adaptive_batch(system(), np.zeros((4, size)), tol=tol,
                                    pars=np.zeros((2, size)))


@functools.lru_cache(maxsize=None)
def cartesian_integrator(tol, batch_size=None):
    """:func:`integrator` of :func:`cartesian_system`, in doubles."""
    import heyoka as hy

    size = batch_size or hy.recommended_simd_size()
    return hy.taylor_adaptive_batch(cartesian_system(), np.zeros((6, size)), tol=tol,
                                    pars=np.zeros((3, size)))


def fly(ta, x0, acs, alphas, durations, coefficients=EXACT):
    """M cases of a piecewise-constant pitch schedule flown on Eqs. 1-2 by ``ta``
    (:func:`integrator`), ``ta.batch_size`` at a time.  ``x0`` (4,) or (M, 4) is the polar
    start, canonical; ``acs``, ``alphas``, ``durations`` (M, N) each arc's a_c (canonical,
    times any throttle), pitch (rad) and duration (TU); ``coefficients`` the thrust's
    (b1, b2).  Returns (M, 5, N): each case's [r, theta, v_r, v_theta, t] at every arc's
    end.  RuntimeError if heyoka stops short of a case's last arc (a non-finite state).
    """
    return _flown(ta, prepare(ta.batch_size, x0, acs, alphas, durations, coefficients))


def fly3d(ta, y0, acs, alphas, deltas, durations, coefficients=EXACT):
    """:func:`fly` in three dimensions on the Cartesian equations, ``ta`` from
    :func:`cartesian_integrator`: ``y0`` (6,) or (M, 6) Cartesian, canonical; ``deltas``
    (M, N) each arc's clock (rad), ``acs`` times any thrust factor too.  Returns
    (M, 7, N): each case's [x, y, z, vx, vy, vz, t] at every arc's end."""
    return _flown(ta, prepare3d(ta.batch_size, y0, acs, alphas, deltas, durations,
                                coefficients))


def _flown(ta, lanes):
    """:func:`fly_prepared` with each arc's end time as a last row, by case:
    (M, rows + 1, N)."""
    flown = np.concatenate([fly_prepared(ta, lanes), lanes.ends[:, None, :]], axis=1)
    return flown[:, :, :lanes.cases].transpose(2, 1, 0)


#: Prepared lanes: the number of cases, the start states (rows x lanes), the thrust's
#: runtime parameters (parameters x N x lanes) and the arcs' end times (N x lanes).
Lanes = collections.namedtuple("Lanes", "cases starts pushes ends")


def prepare(size, x0, acs, alphas, durations, coefficients=EXACT):
    """:func:`fly`'s arguments as its lanes take them, ``size`` cases a block: the
    start states (4 x lanes), the thrust parameters a_c R and a_c T (2 x N x lanes)
    and the arcs' end times (N x lanes), the cases padded to whole blocks with the
    last one."""
    acs, alphas = (np.atleast_2d(np.asarray(v, float)) for v in (acs, alphas))
    R, T = (np.array(v, float).reshape(alphas.shape)
            for v in radial_transverse(ca.DM(alphas), coefficients))
    return _lanes(size, x0, acs * np.stack([R, T]), durations)


def prepare3d(size, y0, acs, alphas, deltas, durations, coefficients=EXACT):
    """:func:`fly3d`'s arguments as its lanes take them (:func:`prepare` in three
    dimensions): start states 6 x lanes, thrust parameters a_c R, a_c T and a_c N
    (3 x N x lanes), end times N x lanes."""
    acs, alphas, deltas = (np.atleast_2d(np.asarray(v, float)) for v in (acs, alphas, deltas))
    R, T, N = (np.array(v, float).reshape(alphas.shape)
               for v in radial_transverse_normal(ca.DM(alphas), ca.DM(deltas), coefficients))
    return _lanes(size, y0, acs * np.stack([R, T, N]), durations)


def _lanes(size, starts, pushes, durations):
    """Lanes of ``size`` cases a block from start states (rows,) or (M, rows), the
    thrust's parameters (P, M, N) and durations (N,) or (M, N)."""
    cases, arcs = pushes.shape[1:]
    lanes = np.r_[np.arange(cases), np.full(-cases % size, cases - 1)]
    starts = np.atleast_2d(np.asarray(starts, float))
    starts = np.broadcast_to(starts, (cases, starts.shape[1]))[lanes].T
    ends = np.cumsum(np.broadcast_to(np.asarray(durations, float), (cases, arcs)), axis=1)
    return Lanes(cases, starts.copy(), pushes[:, lanes].transpose(0, 2, 1).copy(),
                 ends[lanes].T.copy())


def fly_prepared(ta, lanes, steps=True):
    """The flight of :func:`fly` or :func:`fly3d` from its prepared ``lanes``: the states at
    every arc's end, shape (N, rows, lanes).  ``steps`` False leaves out heyoka's
    ``propagate_until`` calls and their check (the states are then the starts), to time the
    Python loop around them."""
    size, ends = ta.batch_size, lanes.ends
    out = np.empty((ends.shape[0], lanes.starts.shape[0], ends.shape[1]))
    state, pars = ta.state, ta.pars
    for first in range(0, ends.shape[1], size):
        block = slice(first, first + size)
        state[:] = lanes.starts[:, block]
        ta.set_time(0.0)
        # Lanes ending together take one float: heyoka reads it faster than an array.
        shared = (ends[:, block] == ends[:, first:first + 1]).all()
        times = ends[:, first].tolist() if shared else ends[:, block]
        for k in range(ends.shape[0]):
            pars[:] = lanes.pushes[:, k, block]
            if steps:
                ta.propagate_until(times[k])
            out[k, :, block] = state
        if steps and not (np.array_equal(ta.time, ends[-1, block]) and np.isfinite(state).all()):
            raise RuntimeError(f"heyoka stopped short of the last arc in cases "
                               f"{first} to {first + size - 1}")
    return out
