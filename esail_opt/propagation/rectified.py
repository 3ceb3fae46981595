"""The rectified closed-form propagator: closed-form arcs restarted arc by arc.

How the arcs are flown -- the paper's first-order arc or the second-order one, the exact
angular momentum imposed or not, sub-arcs, Richardson extrapolation, the quadrature's
nodes -- is one value, :class:`.arcs.ArcModel`, which every builder here takes as
``model``; its default is the NLP's model (second-order arcs), and the paper's
first-order rectification is ``arcs.FIRST_ORDER``.

At each rectification point the arc is restarted from the current
osculating orbit: new r0, new a~_c, and a new reference direction, here the
current radius (``esail_opt.physics.closed_form.arc_frame``), which is defined
for every orbit, circular ones included.  The pitch and the throttle may change
there.  A segment's length is an angle, or a duration, which a first-order arc meets
on the closed form's own clock by Newton's method and a second-order arc by a short
Taylor series of Eqs. 1-2 from the angle a cheap clock guesses
(:func:`timed_arc_function`).

The chain is one ``casadi.Function``: an SX arc (for durations with its root or its
series unrolled inside), accumulated over the segments with ``mapaccum``.  Its state is
``[r, theta, v_r, v_theta, t]``, canonical units, as in :mod:`.simulate`.

With N first-order arcs the error falls like 1/N, with second-order ones like 1/N^2;
``model.extrapolate`` cancels that leading term by Richardson extrapolation from N and
2N arcs (:func:`rectified_function`).
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
    """The Function an arc of ``model.order`` is sampled with, at ``model.nodes``:
    :func:`panel_function` (order 1, from one sample to the next) or
    :func:`end_function` (order 2, from the arc's start)."""
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
    """One first-order arc (the paper's, by construction: free panels between the
    caller's angles) sampled at angles the caller gives.

    ``(x0[5], ac, alpha, phis[1 x (samples + 1)]) -> (states[4 x samples],
    elapsed[1 x samples], q3[1 x samples])``: the panels run from ``phis[k]`` to
    ``phis[k + 1]`` (angles from the arc's start, rad), ``elapsed`` is the time from
    ``phis[0]`` to each panel's end and ``q3`` the validity margin there.  It is the
    sampling :func:`arc_function` does with equal steps; here the steps are free, so that
    arcs of different sample counts can share one mapped call (pad a shorter arc with
    repeats of its last angle: an empty panel adds no time and keeps the state).
    """
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, phis = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("phis", 1, samples + 1)
    piece = panel_function(coefficients=coefficients, nodes=nodes).map(samples)
    states, dts, q3s = piece(x0, ac, alpha, phis[:, :-1], phis[:, 1:])
    return ca.Function("angles", [x0, ac, alpha, phis], [states, ca.cumsum(dts, 1), q3s],
                       ["x0", "ac", "alpha", "phis"], ["states", "elapsed", "q3"])


#: Options of the MX Functions built over compiled panels.  Inlined, an NLP segment is
#: one flat MX graph of panel calls, whose derivatives are cheaper to evaluate than those
#: through nested map and mapaccum Functions.
FLAT = {"always_inline": True}


@functools.lru_cache(maxsize=None)
def arc_function(samples, *, coefficients=EXACT, model=ArcModel()):
    """One closed-form arc of ``model`` sampled at phi_k = dtheta k / samples,
    k = 1..samples.

    Returns a Function ``(x0[5], ac, alpha, dtheta) -> (xs[5 x samples], q3)``
    where ``ac`` already includes any throttle, the time row of ``xs`` continues from
    x0's, and ``q3`` is the validity margin at the arc's end (positive is valid).
    One arc: ``model.sub_arcs`` and ``model.extrapolate`` belong to the chains of
    :func:`rectified_function`.  With ``model.order`` 1 the sample intervals double as
    the panels of the time quadrature.  ``model.order`` 2 flies the second-order arc
    (:func:`end_function`): each sample is then its own arc end from x0, with the
    nodes of its own quadratures, so the arc's end does not depend on ``samples``.
    The samples are a ``map`` of one panel Function, so building it costs the same for
    any count; ``expand()`` it where one flat SX expression is wanted.  With
    ``model.invariant`` every sample's v_theta is replaced by h / r, h the exact
    angular momentum at the sample's (quadrature) time; r, v_r and t stay the closed
    form's, and so does q3, which measures the first-order arc's validity.  With
    ``model.native`` (where :func:`flies_native`) the panels are the compiled ones
    (:func:`native_panel`), called once per sample, and the arc is inlined wherever it
    is called (see :data:`FLAT`).
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


#: Order of the Taylor series of Eqs. 1-2 (``physics.dynamics.taylor_step``) that flies
#: a timed second-order arc from the angle :func:`clock_guess` finds to the asked
#: duration (see :func:`timed_arc_function`).  The series' truncation falls like the
#: step to the sixth power, far below the closed form's own error even at the guess's
#: largest misses (arcs of two revolutions); order 3 would save a tenth of the arc's
#: instructions for a truncation that falls only like the fourth.
TAYLOR_ORDER = 5
#: Newton steps of the first-order arcs' clock, from the Keplerian guess alone.  There
#: the rate is the clock's derivative to its quadrature, so Newton's method converges
#: quadratically: on the paper's scenario the residual is at rounding level; on an
#: e = 0.53 arc of 9 rad (4 panels) it is 1e-11 rad, where the old starting-rate guess
#: left 1e-3 rad after the same five steps (tests check both).
NEWTON_STEPS = 5
#: Newton iterations of Kepler's equation inside the guess.  It is only a guess, so
#: a case where these have not converged (e near 1) costs accuracy of the start only.
KEPLER_STEPS = 6


def kepler_angle(arc, duration):
    """Angle the arc's osculating Keplerian orbit sweeps in ``duration`` (units sqrt(r0^3/mu)).

    The first-order clock differs from Kepler's by O(a~_c), so this is where
    Newton's method on the closed form's clock starts.  It is written in the
    differences of the anomalies from the arc's start, with e sin E0 and e cos E0
    formed from the eccentricity vector, so that it is smooth (derivatives
    included) at e = 0, where the anomalies themselves are undefined:

    * Delta M = duration (1 - e^2)^{3/2} / h0^3 (the mean motion in the arc's units);
    * Kepler's equation in Delta E: Delta E - e sin(E0 + Delta E) + e sin E0 = Delta M;
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


#: Simpson panels of the cheap clock in :func:`clock_guess` (even).
GUESS_PANELS = 6


def clock_guess(arc, duration):
    """Starting angle for the root of the clock: :func:`kepler_angle`, then one Newton
    step on a cheap first-order clock (``duration`` in units sqrt(r0^3/mu)).

    The Keplerian sweep misses the thrust's drift of the clock, O(a~_c) of the arc's
    time (up to 0.26 TU on the bench's grid).  The cheap clock keeps the Keplerian part
    exact and integrates the first-order remainder rate(q_1) - h0^3 / w^2, which
    vanishes at 0, by the composite Simpson rule on :data:`GUESS_PANELS` panels of
    [0, phi]: that many evaluations of the first-order elements, against the clock's
    2 x nodes of first- and second-order ones.  On the bench's grid the guess's
    residual falls from 8e-2 to 3e-4 TU (median) and from 0.26 to 3e-2 TU (largest;
    2 panels left 0.1 TU, from arcs of two revolutions, where few panels alias the
    orbit's period).
    """
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
    """As :func:`arc_function` (``model`` as there, never compiled), but the last input
    is a duration (TU), and the arc ends exactly that long after x0.

    * Order 1: the arc angle is the root of t(dtheta) = duration on the closed form's
      clock, by :data:`NEWTON_STEPS` Newton steps from :func:`kepler_angle`, unrolled
      in SX, on the rate dt/dtheta = r0^{3/2} / (q3 s^2) of the first-order elements,
      which is the clock's derivative to its quadrature.
    * Order 2: the arc is flown to the angle of :func:`clock_guess`, and the part of
      the duration that its clock did not cover (the third output) is flown by the
      Taylor series of Eqs. 1-2 to :data:`TAYLOR_ORDER` (``dynamics.taylor_step``).
      Each evaluation of the second-order clock costs as much as the arc, so a root
      on it cost four arcs' worth (a Newton step and secant steps) where this costs
      one and a short series.  The part left is the guess's miss, a small fraction of
      the arc, and it is flown on the exact equations: the arc's end differs from
      the end at the clock's root by how far the closed form's own error moves over
      that part, not by the series' truncation.  With ``model.invariant`` v_theta is
      then h / r at the asked time.

    Intermediate samples stay at equal fractions of the angle the arc was flown to.
    The outputs are ``(xs, q3, remainder)``: the states, the validity margin at the
    arc's end, and the part of the duration the closed form's clock did not cover
    (TU): for order 1 what the Newton steps left (the end is then that early), for
    order 2 what the series flew.
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
    # The expanded arc rebuilds the arc's constants that the guess already formed;
    # eliminating common subexpressions saves instructions without changing any
    # arithmetic.
    return ca.Function(
        "timed_arc", [x0, ac, alpha, duration], [xs, q3, remainder],
        ["x0", "ac", "alpha", "duration"], ["xs", "q3", "remainder"], {"cse": True},
    )


@functools.lru_cache(maxsize=None)
def rectified_function(segments, *, samples=1, length_in="theta", coefficients=EXACT,
                       model=ArcModel()):
    """A schedule of ``segments`` constant-pitch segments flown on ``model``'s arcs, as
    one Function.

    ``(x0[5], ac[1 x N], alpha[1 x N], length[1 x N]) -> (xs[5 x N S samples],
    q3[1 x N S])`` with ``ac`` per segment (characteristic acceleration times throttle)
    and S = ``model.sub_arcs``: every segment is S arcs of a S-th of its length, each
    sampled at ``samples`` points (:func:`arc_function`, or :func:`timed_arc_function`
    for ``length_in="time"``, where a sub-arc lasts a S-th of the segment's duration),
    and q3 is each arc's validity margin at its end.

    With ``model.extrapolate`` the whole chain is flown twice, as it is and with every
    arc halved, and the two are combined at every sample they share, which are all of
    them in theta: (2^p x_halves - x_whole) / (2^p - 1), p = ``model.order``, the order
    in the arcs' length of the error at a fixed point of the trajectory (THEORY.md
    §5.2-5.3); q3 is then the smallest margin of an arc and its two halves.  The chains
    restart from their own arcs' ends, not from the combined states: the extrapolation
    is of the chain, and a caller that restarts every segment from a node of its own
    (the NLP) calls this per segment.  The cost is three times the arcs.  In time the
    samples inside an arc are at angles the whole and the halves do not share, so there
    an extrapolated chain has one sample per arc.

    With ``model.native`` (where :func:`flies_native`) the chain is unrolled over the
    compiled arcs and inlined (:data:`FLAT`); otherwise the accumulated map holds one
    copy of the arc for any N.
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
        # One graph for any N: the accumulated map holds one copy of the arc.
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
    """Each column of ``row`` ``times`` times, side by side.  Slices of the result are the
    original entries again (no matrix product between them), which keeps an inlined
    graph small."""
    return ca.horzcat(*[row[:, k] for k in range(row.shape[1]) for _ in range(times)])


@functools.lru_cache(maxsize=None)
def _extrapolated(arcs, samples, length_in, coefficients, model):
    """(2^p x_halves - x_whole) / (2^p - 1) at every sample of ``arcs`` chained arcs of
    the one-arc ``model``, p its order, with the smallest q3 of an arc and its halves."""
    native = flies_native(coefficients=coefficients, model=model, length_in=length_in)
    whole = _chain(arcs, samples, length_in, coefficients, model)
    halves = _chain(2 * arcs, samples, length_in, coefficients, model)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, length = (ca.MX.sym(n, 1, arcs) for n in ("ac", "alpha", "length"))
    coarse, q3_coarse = whole(x0, ac, alpha, length)
    fine, q3_fine = halves(x0, _repeated(ac, 2), _repeated(alpha, 2), _repeated(length, 2) / 2)
    # Sample j of a whole arc sits where sample 2j + 1 of its two halves does.
    shared = fine[:, 1::2]
    # The smallest validity margin met by either run: an extrapolation is only as
    # valid as the arcs it is built from.
    q3 = ca.fmin(q3_coarse, ca.fmin(q3_fine[:, 0::2], q3_fine[:, 1::2]))
    combined = 2 * shared - coarse if model.order == 1 else (4 * shared - coarse) / 3
    return ca.Function(
        "extrapolated", [x0, ac, alpha, length], [combined, q3],
        ["x0", "ac", "alpha", "length"], ["xs", "q3"], FLAT if native else {},
    )


def propagate(x0, alphas, lengths, ac, *, throttles=None, samples=1, length_in="theta",
              coefficients=EXACT, model=ArcModel()):
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
        Points per arc, equally spaced in theta; with first-order arcs they also set
        the time quadrature's panels.
    coefficients : tuple
        (b1, b2) of Eqs. 3-4.
    model : ArcModel
        How the arcs are flown (:func:`rectified_function`); default the NLP's.  The
        paper's plain rectification is ``arcs.FIRST_ORDER``.

    Returns
    -------
    xs : numpy.ndarray, shape (5, N * S * samples + 1)
        [r, theta, v_r, v_theta, t] at the start and at every sample, S =
        ``model.sub_arcs``: the rectification points are every ``samples``-th column,
        the segments' ends every ``S * samples``-th.  Extrapolated, the independent
        variable's row (t for lengths in time, theta for angles) is exact and the
        others carry the extrapolated estimate.
    q3 : numpy.ndarray, shape (N * S,)
        Validity margin at each arc's end (extrapolated: the smallest of the arc and its
        halves); non-positive means the first-order arc went past theta_max.
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
