"""The rectified closed form in three dimensions: the planar rectified arc inside a plane
that turns, arc after arc (THEORY.md §9).

An arc's polar state is :mod:`.rectified`'s with the (R, T) of
``thrust.radial_transverse_normal``, and its plane turns by ``plane_turn.arc_turn`` with
N.  The state is ``[r, theta, v_r, v_theta, t, qw, qx, qy, qz]``, theta inside the
turning plane, the plane's unit quaternion in ``physics.rotation``'s convention
(``elements.cartesian_from_polar3d`` gives the Cartesian state); at delta = 0 the polar
rows are :mod:`.rectified`'s.  Lengths are angles (rad) or durations; arcs are compiled
where ``model.native`` allows (angles only); ``model.extrapolate`` is refused.
"""

import functools

import casadi as ca
import numpy as np

from esail_opt.errors import InputError
from esail_opt.physics import rotation
from esail_opt.physics.closed_form import SecondOrderArc, arc_frame, arc_state
from esail_opt.physics.dynamics import angular_momentum, plane_rate, taylor_step
from esail_opt.physics.elements import cartesian_from_polar3d
from esail_opt.physics.plane_turn import arc_turn, turned_plane
from esail_opt.physics.thrust import EXACT, radial_transverse_normal
from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.compiled import compiled
from esail_opt.propagation.rectified import FLAT, TAYLOR_ORDER, angle_for_duration

#: Rows of the state: [r, theta, v_r, v_theta, t] and the plane's quaternion.
STATE = 9


def _inputs():
    x0 = ca.SX.sym("x0", STATE)
    return x0, ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("delta")


@functools.lru_cache(maxsize=None)
def panel_function3d(*, coefficients=EXACT, nodes=8):
    """A first-order arc between two of its angles: ``(x0[9], ac, alpha, delta, phi_a,
    phi_b) -> (state at phi_b [9], time from phi_a to phi_b, q3 at phi_b)``, the state's
    time row x0's (the caller adds the panels' times), its plane turned over [0, phi_b]."""
    x0, ac, alpha, delta = _inputs()
    phi_a, phi_b = ca.SX.sym("phi_a"), ca.SX.sym("phi_b")
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    dt = x0[0] ** 1.5 * arc.time(phi_a, phi_b, nodes)
    plane = turned_plane(x0[5:], x0[1], arc_turn(arc, N, phi_b, order=1))
    state = ca.vertcat(arc_state(x0[:4], arc, phi_b), x0[4], plane)
    return ca.Function("panel3d", [x0, ac, alpha, delta, phi_a, phi_b],
                       [state, dt, arc.q(phi_b)[2]])


@functools.lru_cache(maxsize=None)
def end_function3d(*, coefficients=EXACT, nodes=2):
    """A second-order arc from its start to an angle: ``(x0[9], ac, alpha, delta, phi) ->
    (state at phi [9], time from 0 to phi, q3 at phi)``, q3 the first-order margin."""
    x0, ac, alpha, delta = _inputs()
    phi = ca.SX.sym("phi")
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    second = SecondOrderArc(arc, phi, nodes)
    plane = turned_plane(x0[5:], x0[1], arc_turn(arc, N, phi, order=2, nodes=nodes))
    state = ca.vertcat(arc_state(x0[:4], arc, phi, second.q_end), x0[4], plane)
    return ca.Function("arc_end3d", [x0, ac, alpha, delta, phi],
                       [state, x0[0] ** 1.5 * second.time, second.q_first[2]],
                       {"cse": True})


def piece_function3d(*, coefficients=EXACT, model=ArcModel()):
    """:func:`panel_function3d` (order 1) or :func:`end_function3d` (order 2) at
    ``model.nodes``."""
    if model.order == 1:
        return panel_function3d(coefficients=coefficients, nodes=model.nodes)
    return end_function3d(coefficients=coefficients, nodes=model.nodes)


@functools.lru_cache(maxsize=None)
def native_piece3d(*, coefficients=EXACT, model=ArcModel()):
    """The compiled :func:`piece_function3d` (with its derivatives), or None where it
    stays on the virtual machine."""
    if not model.native:
        return None
    piece = piece_function3d(coefficients=coefficients, model=model)
    fast = compiled(piece)
    return None if fast is piece else fast


def _samples(x0, ac, alpha, delta, dtheta, samples, coefficients, model):
    """(states[9 x samples], elapsed[1 x samples], q3[1 x samples]) of one arc, through
    the compiled piece called once per sample where it exists, else a ``map``."""
    order = model.order
    fast = native_piece3d(coefficients=coefficients, model=model)
    if fast is not None:
        ends = [dtheta * (k / samples) for k in range(1, samples)] + [dtheta]
        if order == 1:
            calls = [fast(x0, ac, alpha, delta, a, b) for a, b in zip([0] + ends[:-1], ends)]
        else:
            calls = [fast(x0, ac, alpha, delta, b) for b in ends]
        states, dts, q3s = (ca.horzcat(*parts) for parts in zip(*calls))
        return states, ca.cumsum(dts, 1) if order == 1 else dts, q3s
    phis = dtheta * ca.DM(np.arange(samples + 1) / samples).T
    piece = piece_function3d(coefficients=coefficients, model=model).map(samples)
    if order == 1:
        states, dts, q3s = piece(x0, ac, alpha, delta, phis[:, :-1], phis[:, 1:])
        return states, ca.cumsum(dts, 1), q3s
    return piece(x0, ac, alpha, delta, phis[:, 1:])


@functools.lru_cache(maxsize=None)
def arc_function3d(samples, *, coefficients=EXACT, model=ArcModel()):
    """One 3-D arc of ``model`` sampled at phi_k = dtheta k / samples, k = 1..samples:
    ``(x0[9], ac, alpha, delta, dtheta) -> (xs[9 x samples], q3)``, as
    ``rectified.arc_function`` (the invariant with the in-plane T), the plane turned from
    x0's at each sample."""
    x0, ac, alpha, delta, dtheta = (ca.MX.sym(n, s) for n, s in (
        ("x0", STATE), ("ac", 1), ("alpha", 1), ("delta", 1), ("dtheta", 1)))
    states, elapsed, q3s = _samples(x0, ac, alpha, delta, dtheta, samples, coefficients,
                                    model)
    if model.invariant:
        T = radial_transverse_normal(alpha, delta, coefficients)[1]
        h = angular_momentum(x0, ac, T, elapsed)
        states = ca.vertcat(states[:3, :], h / states[0, :], states[4:, :])
    states = ca.vertcat(states[:4, :], x0[4] + elapsed, states[5:, :])
    native = native_piece3d(coefficients=coefficients, model=model) is not None
    return ca.Function("arc3d", [x0, ac, alpha, delta, dtheta], [states, q3s[-1]],
                       ["x0", "ac", "alpha", "delta", "dtheta"], ["xs", "q3"],
                       FLAT if native else {})


@functools.lru_cache(maxsize=None)
def timed_arc_function3d(samples, *, coefficients=EXACT, model=ArcModel()):
    """As :func:`arc_function3d` (never compiled), but the last input is a duration (TU)
    and the arc ends that long after x0, as ``rectified.timed_arc_function`` does it: ``->
    (xs[9 x samples], q3, remainder)``.  At order 2 the plane turns over the remainder at
    its rate at the remainder's midpoint, an error third order in the remainder.
    """
    order, nodes = model.order, model.nodes
    x0, ac, alpha, delta = _inputs()
    duration = ca.SX.sym("duration")
    R, T, N = radial_transverse_normal(alpha, delta, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    angle = angle_for_duration(arc, x0[0], duration, order, samples, nodes)
    plain = ArcModel(order, model.invariant, False, 1, nodes, native=False)
    xs, q3 = arc_function3d(samples, coefficients=coefficients, model=plain).expand()(
        x0, ac, alpha, delta, angle)
    remainder = x0[4] + duration - xs[4, -1]
    if order == 2:
        last = xs[:, -1]
        middle = taylor_step(last[:4], ac, R, T, remainder / 2, TAYLOR_ORDER)
        turn = plane_rate(middle, ac, N) * remainder
        plane = rotation.multiply(last[5:], rotation.from_rotation_vector(turn))
        end = taylor_step(last[:4], ac, R, T, remainder, TAYLOR_ORDER)
        if model.invariant:
            end = ca.vertcat(end[:3], angular_momentum(x0, ac, T, duration) / end[0])
        xs = ca.horzcat(xs[:, :-1], ca.vertcat(end, x0[4] + duration, plane))
    return ca.Function(
        "timed_arc3d", [x0, ac, alpha, delta, duration], [xs, q3, remainder],
        ["x0", "ac", "alpha", "delta", "duration"], ["xs", "q3", "remainder"], {"cse": True})


@functools.lru_cache(maxsize=None)
def rectified3d_function(segments, *, samples=1, length_in="theta", coefficients=EXACT,
                         model=ArcModel()):
    """A schedule of ``segments`` segments of constant pitch and clock, each
    ``model.sub_arcs`` equal arcs, as one Function: ``(x0[9], ac[1 x N], alpha[1 x N],
    delta[1 x N], length[1 x N]) -> (xs[9 x N S samples], q3[1 x N S])``, lengths in
    theta (rad) or, with ``length_in="time"``, durations (TU, never compiled), ``ac`` per
    segment (times any throttle).  InputError with ``model.extrapolate``."""
    if model.extrapolate:
        raise InputError("arc_model.extrapolate = True is not available in three "
                         "dimensions; use False")
    if length_in not in ("theta", "time"):
        raise ValueError(f"length_in must be 'theta' or 'time', not {length_in!r}")
    sub, one = model.sub_arcs, model.one_arc()
    if length_in == "time":
        timed = timed_arc_function3d(samples, coefficients=coefficients, model=one)
        ins = timed.mx_in()
        arc = ca.Function("arc3d", ins, timed.call(ins)[:2])
        native = False
    else:
        arc = arc_function3d(samples, coefficients=coefficients, model=one)
        native = native_piece3d(coefficients=coefficients, model=one) is not None
    x0 = ca.MX.sym("x0", STATE)
    rows = [ca.MX.sym(n, 1, segments) for n in ("ac", "alpha", "delta", "length")]
    lengths = rows[3] / sub
    if native:
        x, blocks, q3s = x0, [], []
        for k in range(segments * sub):
            xs, q3 = arc(x, *(row[k // sub] for row in rows[:3]), lengths[k // sub])
            blocks.append(xs)
            q3s.append(q3)
            x = xs[:, -1]
        return ca.Function("rectified3d", [x0, *rows], [ca.horzcat(*blocks), ca.horzcat(*q3s)],
                           ["x0", "ac", "alpha", "delta", "length"], ["xs", "q3"], FLAT)
    xa = ca.MX.sym("x0", STATE)
    ac, alpha, delta, length = (ca.MX.sym(n) for n in ("ac", "alpha", "delta", "length"))
    xs, q3 = arc(xa, ac, alpha, delta, length)
    step = ca.Function("step", [xa, ac, alpha, delta, length], [xs[:, -1], xs, q3])
    chain = step.mapaccum("chain3d", segments * sub, [0], [0])
    # Each segment's entry S times over, the length divided once: its S arcs.
    per_arc = [ca.repmat(row, sub, 1).reshape((1, segments * sub))
               for row in (*rows[:3], lengths)]
    _, blocks, q3s = chain(x0, *per_arc)
    return ca.Function("rectified3d", [x0, *rows], [blocks, q3s],
                       ["x0", "ac", "alpha", "delta", "length"], ["xs", "q3"])


def propagate3d(x0, quat0, alphas, deltas, lengths, ac, *, throttles=None, samples=1,
                length_in="theta", coefficients=EXACT, model=ArcModel()):
    """Rectified closed-form propagation in three dimensions, as ``rectified.propagate``
    (no extrapolation) with ``quat0`` (4,) the start plane's unit quaternion (``x0`` inside
    it; ``elements.polar3d_from_cartesian`` gives both) and ``deltas`` (N,) the clock
    angles, rad.  Returns ``xs`` (9, N S samples + 1), [r, theta, v_r, v_theta, t, qw, qx,
    qy, qz] at the start and every sample, and ``q3`` (N S,), the margin at each arc's end.
    """
    alphas = np.atleast_1d(np.asarray(alphas, float))
    n = alphas.size
    kappa = np.ones(n) if throttles is None else np.asarray(throttles, float)
    fun = rectified3d_function(n, samples=samples, length_in=length_in,
                               coefficients=coefficients, model=model)
    start = np.r_[np.asarray(x0, float), 0.0, np.asarray(quat0, float)]
    xs, q3 = fun(start, ac * kappa, alphas, np.atleast_1d(np.asarray(deltas, float)),
                 np.atleast_1d(np.asarray(lengths, float)))
    return np.column_stack([start, np.array(xs)]), np.array(q3).ravel()


@functools.lru_cache(maxsize=None)
def cartesian_function():
    """[x, y, z, vx, vy, vz, t] of one 3-D state column (see :func:`cartesian_states`)."""
    x = ca.SX.sym("x", STATE)
    return ca.Function("cartesian", [x], [ca.vertcat(cartesian_from_polar3d(x[:4], x[5:]),
                                                      x[4])])


def cartesian_states(xs):
    """[x, y, z, vx, vy, vz, t] (7, K) of every column of a 3-D state array ``xs`` (9, K),
    in the fixed frame of the planes' quaternions."""
    xs = np.asarray(xs, float)
    return np.array(cartesian_function().map(xs.shape[1])(xs))
