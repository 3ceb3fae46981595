"""The rectified closed-form propagator: closed-form arcs restarted arc by arc.

Every builder takes how the arcs are flown as one ``model`` (:class:`.arcs.ArcModel`;
default the NLP's, ``arcs.FIRST_ORDER`` the paper's).  Each arc restarts from the
current osculating orbit, its reference direction the current radius
(``closed_form.arc_frame``), defined for circular orbits too; the pitch and throttle may
change there.  A segment's length is an angle or a duration (:func:`timed_arc_function`).
The chain is one ``casadi.Function`` of state ``[r, theta, v_r, v_theta, t]``, canonical,
as in :mod:`.simulate`.  With N arcs the error falls like 1/N at first order, 1/N^2 at
second; ``model.extrapolate`` cancels that term (:func:`rectified_function`).
"""

import functools
import itertools

import casadi as ca
import numpy as np

from esail_opt.physics.closed_form import SecondOrderArc, arc_frame, arc_state
from esail_opt.physics.dynamics import angular_momentum, taylor_step
from esail_opt.physics.thrust import EXACT, radial_transverse
from esail_opt.propagation.arcs import PANEL_NODES, ArcModel
from esail_opt.propagation.compiled import compiled
from esail_opt.propagation.graph_store import stored


@functools.lru_cache(maxsize=None)
@stored
def panel_function(*, coefficients=EXACT, nodes=PANEL_NODES):
    """One first-order closed-form arc between two of its angles: ``(x0[5], ac, alpha,
    phi_a, phi_b) -> (state at phi_b [4], time from phi_a to phi_b, q3 at phi_b)``, an SX
    Function."""
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
@stored
def end_function(*, coefficients=EXACT, nodes=PANEL_NODES):
    """One second-order arc from its start to an angle (``closed_form.SecondOrderArc``):
    ``(x0[5], ac, alpha, phi) -> (state at phi [4], time from 0 to phi, q3 at phi)``,
    an SX Function; q3 is the first-order arc's validity margin."""
    x0 = ca.SX.sym("x0", 5)
    ac, alpha, phi = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("phi")
    R, T = radial_transverse(alpha, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    second = SecondOrderArc(arc, phi, nodes)
    return ca.Function(
        "arc_end", [x0, ac, alpha, phi],
        [arc_state(x0[:4], arc, phi, second.q_end), x0[0] ** 1.5 * second.time,
         second.q_first[2]],
    )


def piece_function(*, coefficients=EXACT, model=ArcModel()):
    """:func:`panel_function` (order 1) or :func:`end_function` (order 2) at
    ``model.nodes``: the Function an arc of ``model`` is sampled with."""
    if model.order == 1:
        return panel_function(coefficients=coefficients, nodes=model.nodes)
    return end_function(coefficients=coefficients, nodes=model.nodes)


def native_panel(*, coefficients=EXACT, model=ArcModel()):
    """The compiled :func:`piece_function` (``propagation.compiled``), or None when it
    stays on CasADi's virtual machine (compiling off, no compiler, a failed compile)."""
    piece = piece_function(coefficients=coefficients, model=model)
    fast = compiled(piece)
    return None if fast is piece else fast


def flies_native(*, coefficients=EXACT, model=ArcModel(), length_in="theta"):
    """Whether ``model``'s arcs are flown compiled: asked for (``model.native``), lengths
    in theta (timed arcs are one SX root-finding expression), and a compiled
    :func:`native_panel` exists."""
    return (model.native and length_in == "theta"
            and native_panel(coefficients=coefficients, model=model) is not None)


@functools.lru_cache(maxsize=None)
def angles_function(samples, *, coefficients=EXACT, nodes=PANEL_NODES):
    """One first-order arc sampled at angles the caller gives: ``(x0[5], ac, alpha,
    phis[1 x (samples + 1)]) -> (states[4 x samples], elapsed[1 x samples], q3[1 x samples])``,
    panels from ``phis[k]`` to ``phis[k + 1]`` (rad from the arc's start), ``elapsed`` the
    time from ``phis[0]``, ``q3`` the validity margin.  A shorter arc may be padded with its
    last angle: an empty panel adds no time and keeps the state."""
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, phis = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("phis", 1, samples + 1)
    piece = panel_function(coefficients=coefficients, nodes=nodes).map(samples)
    states, dts, q3s = piece(x0, ac, alpha, phis[:, :-1], phis[:, 1:])
    return ca.Function("angles", [x0, ac, alpha, phis], [states, ca.cumsum(dts, 1), q3s],
                       ["x0", "ac", "alpha", "phis"], ["states", "elapsed", "q3"])


#: Options of the MX Functions built over compiled panels: inlined, a segment's
#: derivatives are cheaper than through nested map and mapaccum Functions.
FLAT = {"always_inline": True}


@functools.lru_cache(maxsize=None)
def arc_function(samples, *, coefficients=EXACT, model=ArcModel()):
    """One closed-form arc of ``model`` sampled at phi_k = dtheta k / samples,
    k = 1..samples: ``(x0[5], ac, alpha, dtheta) -> (xs[5 x samples], q3)``, ``ac``
    including any throttle, the time row continuing from x0's, ``q3`` the first-order
    validity margin at the end (positive is valid).

    ``model.sub_arcs`` and ``model.extrapolate`` are ignored (:func:`rectified_function`).
    At order 1 the sample intervals are the time quadrature's panels; at order 2 each
    sample is its own arc end from x0, so the end does not depend on ``samples``.  With
    ``model.invariant`` v_theta is h / r, h the exact angular momentum at the sample's
    time.  With ``model.native`` (where :func:`flies_native`) the compiled panels are
    called once per sample and the arc is inlined (:data:`FLAT`).
    """
    order, nodes, invariant = model.order, model.nodes, model.invariant
    native = flies_native(coefficients=coefficients, model=model)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, dtheta = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("dtheta")
    if native:
        # Angles and running times as plain expressions, not slices of a row: every
        # node of this graph is differentiated in every direction the NLP asks for.
        piece = native_panel(coefficients=coefficients, model=model)
        ends = [dtheta * (k / samples) for k in range(1, samples)] + [dtheta]
        if order == 1:
            calls = [piece(x0, ac, alpha, a, b) for a, b in zip([0] + ends[:-1], ends)]
        else:
            calls = [piece(x0, ac, alpha, b) for b in ends]
        states, dts, q3s = (ca.horzcat(*parts) for parts in zip(*calls))
        elapsed = (ca.horzcat(*itertools.accumulate(call[1] for call in calls))
                   if order == 1 else dts)
    else:
        phis = dtheta * ca.DM(np.arange(samples + 1) / samples).T
        if order == 1:
            states, elapsed, q3s = angles_function(samples, coefficients=coefficients,
                                                   nodes=nodes)(x0, ac, alpha, phis)
        else:
            piece = piece_function(coefficients=coefficients, model=model).map(samples)
            states, elapsed, q3s = piece(x0, ac, alpha, phis[:, 1:])
    times = x0[4] + elapsed
    if invariant:
        T = radial_transverse(alpha, coefficients)[1]
        h = angular_momentum(x0, ac, T, elapsed)
        states = ca.vertcat(states[:3, :], h / states[0, :])
    return ca.Function(
        "arc", [x0, ac, alpha, dtheta], [ca.vertcat(states, times), q3s[-1]],
        ["x0", "ac", "alpha", "dtheta"], ["xs", "q3"], FLAT if native else {},
    )


#: Order of the Taylor series of Eqs. 1-2 that flies a timed second-order arc from
#: :func:`clock_guess`'s angle to the asked duration: its truncation, like the step^6, is far
#: below the closed form's error at the guess's largest misses; order 3 would save only a tenth.
TAYLOR_ORDER = 5
#: Newton steps of the first-order arcs' clock from the Keplerian guess: the rate is the
#: clock's derivative to its quadrature, so they converge quadratically (1e-11 rad left
#: on an e = 0.53 arc of 9 rad).
NEWTON_STEPS = 5
#: Newton iterations of Kepler's equation inside the guess; unconverged (e near 1), they
#: cost only the start's accuracy.
KEPLER_STEPS = 6


def kepler_angle(arc, duration):
    """Angle the arc's osculating Keplerian orbit sweeps in ``duration`` (units sqrt(r0^3/mu)),
    in the differences of the anomalies from the arc's start, with e sin E0 and e cos E0 from
    the eccentricity vector, so that it is smooth, derivatives included, at e = 0:

    * Delta M = duration (1 - e^2)^{3/2} / h0^3;
    * Delta E - e sin(E0 + Delta E) + e sin E0 = Delta M;
    * f - E = 2 atan2(beta sin E, 1 - beta cos E), beta = e / (1 + sqrt(1 - e^2)).
    """
    kep = arc.kepler
    w0 = 1 + kep.ex
    # At the arc's start, e cos f0 = e_x and e sin f0 = -e_y (theta = 0 there).
    e_sin0 = kep.root * -kep.ey / w0
    e_cos0 = (kep.e2 + kep.ex) / w0
    mean = duration * kep.root**3 * arc.q0[2] ** 3

    def e_sin_cos(delta):
        c, s = ca.cos(delta), ca.sin(delta)
        return e_sin0 * c + e_cos0 * s, e_cos0 * c - e_sin0 * s

    # Start from E = M + e sin M, the classic first-order inversion.
    delta = mean + e_sin_cos(mean)[0] - e_sin0
    for _ in range(KEPLER_STEPS):
        e_sin, e_cos = e_sin_cos(delta)
        delta = delta - (delta - e_sin + e_sin0 - mean) / (1 - e_cos)
    e_sin, e_cos = e_sin_cos(delta)
    b = 1 / (1 + kep.root)  # beta / e
    return delta + 2 * (ca.atan2(b * e_sin, 1 - b * e_cos) - ca.atan2(b * e_sin0, 1 - b * e_cos0))


#: Simpson panels of the cheap clock in :func:`clock_guess` (even; 2 alias the orbit's
#: period on arcs of two revolutions).
GUESS_PANELS = 6


def clock_guess(arc, duration):
    """Starting angle for the root of the clock: :func:`kepler_angle`, which misses the
    thrust's O(a~_c) drift of the clock, then one Newton step on a cheap first-order clock
    (``duration`` in units sqrt(r0^3/mu)): the Keplerian part exact, the first-order remainder
    by the composite Simpson rule on :data:`GUESS_PANELS` panels."""
    kep = arc.kepler
    angle = kepler_angle(arc, duration)

    def remainder(phi):
        return arc.clock_rate(phi) - arc.h0**3 / kep.w(phi) ** 2

    # Simpson's weights 4, 2, 4, ..., 4, 1 after the 0 at the arc's start.
    weights = [4 if j % 2 else 2 for j in range(1, GUESS_PANELS)] + [1]
    integral = sum(w * remainder(angle * (j / GUESS_PANELS))
                   for j, w in enumerate(weights, start=1))
    cheap = arc.h0**3 * kep.i_c(angle) + angle / (3 * GUESS_PANELS) * integral
    return angle - (cheap - duration) / arc.clock_rate(angle)


@functools.lru_cache(maxsize=None)
def angle_for_duration(arc, r0, duration, order, samples, nodes):
    """The arc angle that lasts ``duration`` from radius ``r0``: the second order's clock
    guess, or Newton steps on the first order's quadrature of the time."""
    time_unit = r0 ** 1.5
    if order == 2:
        return clock_guess(arc, duration / time_unit)
    angle = kepler_angle(arc, duration / time_unit)
    for _ in range(NEWTON_STEPS):
        time = time_unit * sum(arc.time(angle * (k - 1) / samples, angle * k / samples,
                                        nodes) for k in range(1, samples + 1))
        angle = angle - (time - duration) / (time_unit * arc.clock_rate(angle))
    return angle


def timed_arc_function(samples, *, coefficients=EXACT, model=ArcModel()):
    """As :func:`arc_function` (never compiled), but the last input is a duration (TU),
    and the arc ends that long after x0: ``-> (xs, q3, remainder)``.

    * Order 1: the angle is the root of the closed form's clock by :data:`NEWTON_STEPS`
      Newton steps from :func:`kepler_angle`, unrolled in SX; ``remainder`` is what they
      left (TU; the end is that early).
    * Order 2: the arc is flown to :func:`clock_guess`'s angle and ``remainder``, the
      guess's miss, by the Taylor series of Eqs. 1-2 (:data:`TAYLOR_ORDER`): a root on
      the second-order clock would cost about four arcs, this one arc and a short series.
      With ``model.invariant`` v_theta is then h / r at the asked time.

    Intermediate samples stay at equal fractions of the angle the arc was flown to.
    """
    order, nodes = model.order, model.nodes
    x0 = ca.SX.sym("x0", 5)
    ac, alpha, duration = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("duration")
    R, T = radial_transverse(alpha, coefficients)
    arc = arc_frame(x0[:4], ac, R, T)
    angle = angle_for_duration(arc, x0[0], duration, order, samples, nodes)
    plain = ArcModel(order, model.invariant, False, 1, nodes, native=False)
    xs, q3 = arc_function(samples, coefficients=coefficients, model=plain).expand()(
        x0, ac, alpha, angle)
    remainder = x0[4] + duration - xs[4, -1]
    if order == 2:
        end = taylor_step(xs[:4, -1], ac, R, T, remainder, TAYLOR_ORDER)
        if model.invariant:
            end = ca.vertcat(end[:3], angular_momentum(x0, ac, T, duration) / end[0])
        xs = ca.horzcat(xs[:, :-1], ca.vertcat(end, x0[4] + duration))
    # The expanded arc rebuilds the constants the guess formed: cse removes them.
    return ca.Function(
        "timed_arc", [x0, ac, alpha, duration], [xs, q3, remainder],
        ["x0", "ac", "alpha", "duration"], ["xs", "q3", "remainder"], {"cse": True},
    )


@functools.lru_cache(maxsize=None)
def rectified_function(segments, *, samples=1, length_in="theta", coefficients=EXACT,
                       model=ArcModel()):
    """A schedule of ``segments`` constant-pitch segments on ``model``'s arcs, as one
    Function ``(x0[5], ac[1 x N], alpha[1 x N], length[1 x N]) -> (xs[5 x N S samples],
    q3[1 x N S])``, ``ac`` per segment (times the throttle), S = ``model.sub_arcs`` equal
    arcs a segment, each sampled at ``samples`` points (:func:`arc_function`, or
    :func:`timed_arc_function` for ``length_in="time"``), q3 each arc's margin at its end.

    With ``model.extrapolate`` the chain is also flown with every arc halved, and the two
    are combined at the samples they share as (2^p x_halves - x_whole) / (2^p - 1),
    p = ``model.order`` (THEORY.md §5.2-5.3); q3 is the smallest of an arc and its halves.
    Each chain restarts from its own arcs' ends, so a caller that restarts every segment
    from its own node (the NLP) calls this per segment.  In time, the whole and the
    halves share only the arcs' ends, so an extrapolated chain has one sample per arc.

    With ``model.native`` (where :func:`flies_native`) the chain is unrolled over the
    compiled arcs and inlined (:data:`FLAT`); otherwise one ``mapaccum`` holds one arc.
    """
    if length_in not in ("theta", "time"):
        raise ValueError(f"length_in must be 'theta' or 'time', not {length_in!r}")
    if model.extrapolate and length_in == "time" and samples != 1:
        raise ValueError(f"an extrapolated chain in time has one sample per arc, not {samples}")
    sub, arc = model.sub_arcs, model.one_arc()
    build = _extrapolated if model.extrapolate else _chain
    chain = build(segments * sub, samples, length_in, coefficients, arc)
    if sub == 1:
        return chain
    native = flies_native(coefficients=coefficients, model=model, length_in=length_in)
    x0 = ca.MX.sym("x0", 5)
    acs, alphas, lengths = (ca.MX.sym(n, 1, segments) for n in ("ac", "alpha", "length"))
    # Divided once, then repeated: the arithmetic of a segment built arc by arc.
    xs, q3 = chain(x0, _repeated(acs, sub), _repeated(alphas, sub),
                   _repeated(lengths / sub, sub))
    return ca.Function(
        "rectified", [x0, acs, alphas, lengths], [xs, q3],
        ["x0", "ac", "alpha", "length"], ["xs", "q3"], FLAT if native else {},
    )


@functools.lru_cache(maxsize=None)
def _chain(arcs, samples, length_in, coefficients, model):
    """``arcs`` arcs of the one-arc ``model``, chained: :func:`rectified_function` with
    one arc a segment and no extrapolation."""
    native = flies_native(coefficients=coefficients, model=model, length_in=length_in)
    if length_in == "theta":
        arc = arc_function(samples, coefficients=coefficients, model=model)
    else:
        arc = timed_arc_function(samples, coefficients=coefficients, model=model)
    x0 = ca.MX.sym("x0", 5)
    acs, alphas, lengths = (ca.MX.sym(n, 1, arcs) for n in ("ac", "alpha", "length"))
    if native:
        x, blocks, q3s = x0, [], []
        for k in range(arcs):
            xs, q3 = arc(x, acs[k], alphas[k], lengths[k])[:2]
            blocks.append(xs)
            q3s.append(q3)
            x = xs[:, -1]
        blocks, q3s = ca.horzcat(*blocks), ca.horzcat(*q3s)
    else:
        xa = ca.MX.sym("x0", 5)
        ac, alpha, length = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("length")
        xs, q3 = arc(xa, ac, alpha, length)[:2]
        step = ca.Function("step", [xa, ac, alpha, length], [xs[:, -1], xs, q3])
        _, blocks, q3s = step.mapaccum("chain", arcs, [0], [0])(x0, acs, alphas, lengths)
    return ca.Function(
        "rectified", [x0, acs, alphas, lengths], [blocks, q3s],
        ["x0", "ac", "alpha", "length"], ["xs", "q3"], FLAT if native else {},
    )


def _repeated(row, times):
    """Each column of ``row`` ``times`` times, side by side, by slices, not a matrix
    product, which keeps an inlined graph small."""
    return ca.horzcat(*[row[:, k] for k in range(row.shape[1]) for _ in range(times)])


@functools.lru_cache(maxsize=None)
def _extrapolated(arcs, samples, length_in, coefficients, model):
    """Extrapolation of :func:`rectified_function` over ``arcs`` chained one-arc ``model`` arcs."""
    native = flies_native(coefficients=coefficients, model=model, length_in=length_in)
    whole = _chain(arcs, samples, length_in, coefficients, model)
    halves = _chain(2 * arcs, samples, length_in, coefficients, model)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, length = (ca.MX.sym(n, 1, arcs) for n in ("ac", "alpha", "length"))
    coarse, q3_coarse = whole(x0, ac, alpha, length)
    fine, q3_fine = halves(x0, _repeated(ac, 2), _repeated(alpha, 2), _repeated(length, 2) / 2)
    # Sample j of a whole arc sits where sample 2j + 1 of its two halves does.
    shared = fine[:, 1::2]
    # An extrapolation is only as valid as the arcs it is built from.
    q3 = ca.fmin(q3_coarse, ca.fmin(q3_fine[:, 0::2], q3_fine[:, 1::2]))
    combined = 2 * shared - coarse if model.order == 1 else (4 * shared - coarse) / 3
    return ca.Function(
        "extrapolated", [x0, ac, alpha, length], [combined, q3],
        ["x0", "ac", "alpha", "length"], ["xs", "q3"], FLAT if native else {},
    )


def propagate(x0, alphas, lengths, ac, *, throttles=None, samples=1, length_in="theta",
              coefficients=EXACT, model=ArcModel()):
    """Rectified closed-form propagation of a piecewise-constant pitch schedule.

    ``x0`` (4,) is the polar state [r, theta, v_r, v_theta], canonical; ``alphas`` (rad),
    ``lengths`` (angles, rad, or with ``length_in="time"`` durations, TU) and
    ``throttles`` (factors on ``ac``, 0 a coast, default 1) are (N,); ``ac`` is canonical;
    ``samples`` are points per arc, equal in theta; ``coefficients`` are (b1, b2) of
    Eqs. 3-4; ``model`` says how the arcs are flown (default the NLP's).  Returns ``xs``
    (5, N S samples + 1), [r, theta, v_r, v_theta, t] at the start and every sample
    (S = ``model.sub_arcs``; extrapolated, the independent variable's row is exact), and
    ``q3`` (N S,), each arc's margin at its end, non-positive past theta_max.
    """
    n = np.size(alphas)
    fun = rectified_function(n, samples=samples, length_in=length_in,
                             coefficients=coefficients, model=model)
    return _fly(fun, x0, alphas, lengths, ac, throttles)


def _fly(fun, x0, alphas, lengths, ac, throttles):
    """Call a schedule Function on numbers: (states with the start prepended, q3)."""
    alphas = np.atleast_1d(np.asarray(alphas, float))
    kappa = np.ones(alphas.size) if throttles is None else np.asarray(throttles, float)
    start = np.r_[np.asarray(x0, float), 0.0]
    xs, q3 = fun(start, ac * kappa, alphas, np.atleast_1d(np.asarray(lengths, float)))
    return np.column_stack([start, np.array(xs)]), np.array(q3).ravel()
