"""The NLP's start: a seed flown at constant pitch, and the :class:`Guess` every start is.

The seed's nodes are those the NLP's own segments reach (``optimisation.nodes``), so a
solve starts with every continuity constraint met.  A result of another NLP becomes a
start as a :class:`Guess` too (``NLPResult.as_guess``, :func:`lifted_guess`).  The
constant-pitch starts of each revolution class (:func:`window_starts`,
:func:`rendezvous_starts`, :func:`fallback_starts`) are made here for the searches over
classes (``optimisation.multistart``, ``optimisation.classes``).
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from esail_opt.bodies import dates
from esail_opt.errors import InputError, NoStart
from esail_opt.optimisation.nodes import flown_segments
from esail_opt.propagation.arcs import FIRST_ORDER
from esail_opt.propagation.rectified import propagate

#: Initial-guess propagation step, rad: a sub-arc short enough for the closed form at
#: a_c = 1 mm/s^2 (THEORY.md §5.2: sub-arcs of about a tenth of a radian).
GUESS_STEP = 0.05
#: The seed's constant-pitch propagation: the paper's first-order arcs, GUESS_STEP long
#: (a seed needs no more).
GUESS_MODEL = FIRST_ORDER
#: Guess steps per call of the (cached) rectified propagator.
GUESS_CHUNK = 200


@dataclass
class Guess:
    """A start of the NLP in canonical units, and the revolution class it belongs to,
    which every NLP built from it keeps: ``revolutions_k``, a rendezvous' whole turns
    between sail and body, and ``theta_window`` (rad), a box on the final polar angle
    (``optimisation.multistart``).  ``throttle`` None means full thrust everywhere.
    """

    alpha: np.ndarray
    lengths: np.ndarray
    nodes: np.ndarray  # 5 x N: [r, theta, v_r, v_theta, t] at each segment's end
    nu0: float
    revolutions_k: int = 0
    throttle: np.ndarray = None
    theta_window: tuple = None
    epoch: float = 0.0  # departure, TU since J2000 (dated problems)
    ac_scale: float = 1.0  # a_c over the sail's (MinAcceleration)
    vinf_angle: float = 0.0  # excess velocity's direction, rad (BodyDeparture)
    delta: np.ndarray = None  # clock per segment, rad (three dimensions; None: 0)


def _fly_until(problem, x0, alpha, stop, what):
    """The angle (rad) flown at constant pitch from x0 in GUESS_STEP arcs to where
    ``stop(xs)`` returns a (fractional) index.  Raises NoStart if the flight leaves the
    closed form's validity (escape, q3 <= 0) or flies ``max_revolutions`` first."""
    limit = 2 * math.pi * problem.max_revolutions
    ac = problem.sail.ac
    coeff = problem.sail.coefficients
    state, flown, t0 = np.asarray(x0, float), 0.0, 0.0
    while flown < limit:
        xs, q3 = propagate(state, np.full(GUESS_CHUNK, alpha), np.full(GUESS_CHUNK, GUESS_STEP),
                           ac, samples=1, coefficients=coeff, model=GUESS_MODEL)
        xs[4] += t0
        hit = stop(xs)
        if hit is not None:
            return flown + GUESS_STEP * hit
        bad = ~np.isfinite(xs[0, 1:]) | (xs[0, 1:] <= 0) | ~(q3 > 0)
        if bad.any():
            left = flown + GUESS_STEP * np.flatnonzero(bad)[0]
            raise NoStart(
                f"no start: {_pitch(problem, alpha)} the sail leaves the closed form's "
                f"validity (it escapes the Sun, or q3 <= 0) after {left:.3g} rad, without "
                f"reaching {what}; the closed form cannot follow an escape"
                + _seed_ac_hint(problem))
        flown += GUESS_STEP * GUESS_CHUNK
        state, t0 = xs[:4, -1], xs[4, -1]
    raise NoStart(f"no start: {_pitch(problem, alpha)} the sail does not reach {what} within "
                  f"max_revolutions = {problem.max_revolutions:g} turns (raise it for a "
                  "longer spiral)")


def _pitch(problem, alpha):
    """The seed's pitch as a failure names it: the user's field if the file set it."""
    deg = math.degrees(alpha)
    if problem.guess_alpha_deg is not None:
        return f"at guess_alpha_deg = {deg:g} deg"
    return f"at the seed's constant pitch of {deg:g} deg (guess_alpha_deg sets another),"


def _seed_ac_hint(problem):
    """What else a MinAcceleration user can change when its seed escapes: the sail's
    a_c only seeds the search."""
    if not problem.objective.free_acceleration:
        return ""
    return (f"; a smaller sail.ac_mm_s2 may stay bound (a MinAcceleration sizes a_c "
            f"itself: {problem.sail.ac_mm_s2:g} mm/s^2 only seeds it)")


def _crossing(values, level):
    """Fractional index where the finite leading part of ``values`` first reaches
    ``level`` (from either side), or None."""
    bad = np.flatnonzero(~np.isfinite(values))
    values = values[: bad[0]] if bad.size else values
    if values.size < 2:
        return None
    side = np.sign(values - level)
    change = np.flatnonzero(side[1:] != side[0])
    if not change.size:
        return None
    i = change[0]
    a, b = values[i], values[i + 1]
    return i + (level - a) / (b - a) if b != a else float(i)


def guess_alpha(problem):
    """Constant pitch (rad) of the seeding propagation: the problem's, else +-45 deg by
    whether the target lies outward, clipped to the pitch bounds."""
    if problem.guess_alpha_deg is not None:
        deg = problem.guess_alpha_deg
    else:
        radius = problem.aim_radius_au()
        deg = -45.0 if radius is not None and radius < problem.x0()[0] else 45.0
    lo, hi = problem.sail.alpha_min_deg, problem.sail.alpha_max_deg
    return math.radians(min(max(deg, lo), hi))


#: The a_c a MinAcceleration's seed flies at, as fractions of the sail's, tried in turn
#: until one stays bound for the time of flight (a seed that escapes is no start).  A
#: throttled sail's seed tries those within its throttle bounds as its throttle: at full
#: thrust a strong sail's seed escapes before a far target.
SEED_AC_SCALES = (1.0, 0.5, 0.25, 0.125)


def initial_guess(problem):
    """Seed the NLP from a forward rectified propagation at one constant pitch: a
    :class:`Guess`.

    The angle flown to the target radius (minimum time) or the fixed time of flight is
    cut into N equal segments, N from ``Segments.count_for``; the guess fixes the NLP's
    size.  A MinAcceleration's (a throttled sail's) seed flies at the first of
    :data:`SEED_AC_SCALES` whose flight stays bound, as ``ac_scale`` (``throttle``).
    Raises NoStart, the sail's own a_c's, when no seed can be flown.
    """
    first = None
    for scale in _seed_scales(problem):
        try:
            return _seeded(problem, scale)
        except NoStart as err:
            first = first or err
    raise first


def _seed_scales(problem):
    """The fractions of the sail's a_c that :func:`initial_guess` tries, in turn."""
    if problem.objective.free_acceleration:
        return SEED_AC_SCALES
    if problem.sail.throttle:
        lo, hi = problem.throttle_bounds()
        return tuple(s for s in SEED_AC_SCALES if lo <= s <= hi) or (1.0,)
    return (1.0,)


def _seeded(problem, scale):
    """:func:`initial_guess` flown at ``scale`` times the sail's a_c: as the a_c's
    scale for a MinAcceleration, else as the throttle of a throttled sail."""
    flown = problem if scale == 1 else dataclasses.replace(
        problem, sail=dataclasses.replace(problem.sail, ac_mm_s2=problem.sail.ac_mm_s2 * scale))
    x0 = problem.x0()
    alpha = guess_alpha(problem)
    tof = problem.fixed_tof()
    if tof is not None:
        angle = _fly_until(flown, x0, alpha, lambda xs: _crossing(xs[4], tof),
                           f"the time of flight ({problem.objective.tof_days:g} days)")
    else:
        radius = problem.aim_radius_au()
        angle = _fly_until(flown, x0, alpha, lambda xs: _crossing(xs[0], radius),
                           f"the target radius ({radius:g} au)")
    n = problem.segments.count_for(angle)
    lengths = np.full(n, angle / n)
    # In three dimensions the seed's clock is 0: the planar flight in a fixed plane.
    xs = flown_segments(problem, np.full(n, alpha), lengths,
                        problem.plane_x0() if problem.three_d() else x0,
                        throttle=np.full(n, scale))
    nodes = xs[:, 1:]
    t0 = problem.epoch()
    k = _turns_behind(problem, alpha, nodes, t0) if problem.tracks_body() else 0
    nu0 = math.radians(getattr(problem.departure, "nu_deg", 0.0))
    angle = problem.departure.seed_angle() if problem.dated() else 0.0
    sizing = problem.objective.free_acceleration
    return Guess(np.full(n, alpha), lengths, nodes, nu0, k, epoch=t0, vinf_angle=angle,
                 delta=np.zeros(n) if problem.three_d() else None,
                 ac_scale=scale if sizing else 1.0,
                 throttle=None if sizing or scale == 1 else np.full(n, scale))


def _turns_behind(problem, alpha, nodes, t0):
    """The seed's whole turns behind its target body, where the body is known at the
    seed's arrival; a seed that arrives after that, or whose segments leave the closed
    form's validity on the way, has no start to give."""
    if not np.all(np.isfinite(nodes[:, -1])):
        raise NoStart(f"no start: {_pitch(problem, alpha)} the seed's segments leave the "
                      "closed form's validity before they end")
    try:
        return problem.target.turns_behind(nodes[1, -1], nodes[4, -1], t0)
    except InputError:
        arrival = dates.iso_from_jd(dates.jd_from_tu(t0 + nodes[4, -1]))
        window = getattr(problem.target, "arrival_window", None)
        raise NoStart(
            f"no start: {_pitch(problem, alpha)} the sail reaches its target only on "
            f"{arrival} TDB, after {dates.TRACK_SPAN[1]}, the last date the bodies are "
            "tracked on" + (f", and after its arrival window closes ({window[1]})"
                            if window else "")
            + "; depart earlier, or give the sail more acceleration") from None


def split_guess(problem, guess, x_start, parts):
    """``guess`` with every segment cut into ``parts`` equal ones of the same attitude
    and throttle, its nodes flown again from ``x_start`` (the NLP's start)."""
    def cut(values):
        return None if values is None else np.repeat(np.asarray(values, float), parts)

    alpha, lengths, throttle, delta = (cut(v) for v in (guess.alpha, guess.lengths,
                                                          guess.throttle, guess.delta))
    lengths = lengths / parts
    kappa = np.ones(alpha.size) if throttle is None else throttle
    xs = flown_segments(problem, alpha, lengths, x_start, throttle=guess.ac_scale * kappa,
                        delta=delta)
    return dataclasses.replace(guess, alpha=alpha, lengths=lengths, throttle=throttle,
                               delta=delta, nodes=xs[:, 1:])


def lifted_guess(problem, guess):
    """A planar start (``guess``, of the same problem with ``planar=True``) as a start of
    the 3-D ``problem``: the same pitches, lengths, throttles and a_c scale, the clock at
    0, and the nodes flown from the departure's own plane, so only the target's rows are
    off."""
    kappa = np.ones(guess.alpha.size) if guess.throttle is None else np.asarray(guess.throttle)
    xs = flown_segments(problem, guess.alpha, guess.lengths,
                        problem.departure.plane_state_at(guess.epoch, guess.vinf_angle),
                        throttle=guess.ac_scale * kappa)
    return dataclasses.replace(guess, nodes=xs[:, 1:], delta=np.zeros(guess.alpha.size))


# ---------------------------------------------------------------- constant-pitch starts

#: Fractions of the way from the seed's pitch to +-90 deg scanned for seeds: nearer +-90 deg,
#: less transverse thrust and more turns before the spiral first reaches the target radius.
SEED_FRACTIONS = (0.0, 0.5, 0.75, 0.875, 0.9375, 0.96875, 0.984375, 0.9921875)


@dataclass
class Start:
    """One start of a search over classes: its label, revolution class and seed (which
    carries the class)."""

    label: str
    revolutions: int  # the class: the window's k, or the rendezvous k
    guess: Guess

    @property
    def window(self):
        """(lo, hi) final polar angle, rad, or None (free)."""
        return self.guess.theta_window


def seed_pitches(problem):
    """Constant pitches (rad) of the seeds: from the problem's own seed pitch towards
    +-90 deg (the side of its sign), by :data:`SEED_FRACTIONS`, within the sail's bounds."""
    alpha = guess_alpha(problem)
    edge = math.pi / 2 if alpha >= 0 else -math.pi / 2
    lo, hi = problem.alpha_bounds()
    return [min(max(alpha + f * (edge - alpha), lo), hi) for f in SEED_FRACTIONS]


def constant_pitch_seeds(problem):
    """Seeds of :func:`seed_pitches` that reach the target radius (not escaping first nor
    winding past ``max_revolutions``): {alpha: Guess}."""
    seeds = {}
    for alpha in seed_pitches(problem):
        try:
            seeds[alpha] = initial_guess(dataclasses.replace(
                problem, guess_alpha_deg=math.degrees(alpha)))
        except NoStart:
            continue
    return seeds


def _stretched(problem, guess, total):
    """``guess`` with its segments stretched to sweep ``total`` rad, nodes re-flown
    (continuity exact), or None if that flight leaves the closed form's validity."""
    lengths = guess.lengths * (total / float(np.sum(guess.lengths)))
    start = problem.plane_x0() if problem.three_d() else problem.x0()
    xs = flown_segments(problem, guess.alpha, lengths, start, delta=guess.delta)
    if not np.all(np.isfinite(xs)):
        return None
    return dataclasses.replace(guess, lengths=lengths, nodes=xs[:, 1:])


def window_starts(problem, classes):
    """Starts of an orbit transfer's revolution windows ``classes`` (whole turns k): the
    first constant-pitch seed whose final angle lies in the window, else the nearest one
    that stays valid stretched to the window's middle; else the window is skipped."""
    theta0 = float(problem.x0()[1])
    seeds = constant_pitch_seeds(problem)
    starts = []
    for k in classes:
        window = (theta0 + 2 * math.pi * k, theta0 + 2 * math.pi * (k + 1))
        inside = [(a, g) for a, g in seeds.items()
                  if window[0] <= g.nodes[1, -1] <= window[1]]
        if inside:
            alpha, guess = inside[0]
            label = f"window {k}-{k + 1} rev, constant pitch {math.degrees(alpha):.4g} deg"
        else:
            middle = 2 * math.pi * (k + 0.5)
            near = sorted(seeds.items(), key=lambda ag: abs(ag[1].nodes[1, -1] - theta0 - middle))
            guess = None
            for alpha, g in near:
                guess = _stretched(problem, g, middle)
                if guess is not None:
                    break
            if guess is None:
                continue
            label = (f"window {k}-{k + 1} rev, constant pitch {math.degrees(alpha):.4g} deg "
                     f"stretched to {k + 0.5:g} rev")
        starts.append(Start(label, k, dataclasses.replace(guess, theta_window=window)))
    return starts


def rendezvous_starts(problem, classes, seeds=None):
    """Starts of a rendezvous's turn counts k in ``classes``: the first seed that winds k
    itself (``Guess.revolutions_k``), else a pitch bisected to wind k (:func:`_winding`),
    else the seed whose count is nearest, with k imposed (a poor start: it can take several
    times the iterations, and be stopped as hopeless).  ``seeds``: ``problem``'s
    :func:`constant_pitch_seeds`, if the caller has them."""
    seeds = constant_pitch_seeds(problem) if seeds is None else seeds
    starts = []
    for k in classes:
        alpha, guess = min(seeds.items(), key=lambda ag: abs(ag[1].revolutions_k - k))
        if guess.revolutions_k != k:
            alpha, guess = _winding(problem, seeds, k) or (alpha, guess)
        label = f"rendezvous k = {k}, constant pitch {math.degrees(alpha):.4g} deg"
        if guess.revolutions_k != k:
            label += f" (a pitch that by itself winds k = {guess.revolutions_k})"
        starts.append(Start(label, k, dataclasses.replace(guess, revolutions_k=k)))
    return starts


#: The most pitch bisections :func:`_winding` makes between two seeds.
WIND_BISECTIONS = 4


def _winding(problem, seeds, k):
    """A constant-pitch seed (alpha, Guess) whose own turn count is ``k``, bisected in
    pitch between two neighbouring ``seeds`` (in :func:`seed_pitches`'s order) whose
    counts bracket k; None when no two do, or the bisections do not land on k."""
    pairs = list(seeds.items())
    for (a, ga), (b, gb) in zip(pairs, pairs[1:]):
        if not min(ga.revolutions_k, gb.revolutions_k) < k < max(ga.revolutions_k,
                                                                   gb.revolutions_k):
            continue
        for _ in range(WIND_BISECTIONS):
            mid = 0.5 * (a + b)
            try:
                guess = initial_guess(dataclasses.replace(problem,
                                                          guess_alpha_deg=math.degrees(mid)))
            except NoStart:
                return None
            if guess.revolutions_k == k:
                return mid, guess
            if (guess.revolutions_k - k) * (ga.revolutions_k - k) > 0:
                a, ga = mid, guess
            else:
                b = mid
        return None
    return None

def fallback_starts(problem, guess):
    """Other starts for a solve whose first start did not converge, free of any window:
    for a rendezvous the turn counts around ``guess``'s (one below, one and two above),
    for an orbit transfer the other constant-pitch seeds of :func:`seed_pitches`."""
    if problem.tracks_body():
        k = guess.revolutions_k
        # A real body's k counts turns since 2000, so may be negative.
        real = getattr(problem.target, "body", None) is not None
        return rendezvous_starts(problem, [c for c in (k + 1, k - 1, k + 2) if real or c >= 0])
    seeds = constant_pitch_seeds(problem)
    own = guess_alpha(problem)
    return [Start(f"constant pitch {math.degrees(a):.4g} deg", 0, g)
            for a, g in seeds.items() if a != own]
