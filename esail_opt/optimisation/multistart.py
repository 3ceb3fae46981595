"""Global search of a minimum-time problem over its revolution classes.

Ipopt finds the local optimum whose basin holds its start, and a basin is set above all by
the turns round the Sun, so the search solves one NLP per revolution class: for an orbit
transfer, class k boxes the final polar angle into [theta0 + 2 pi k, theta0 + 2 pi (k + 1)]
(``Guess.theta_window``), and a window whose bound is active holds only the class's best
transfer (``Candidate.free`` False), not a local optimum; for a rendezvous, k is the whole
turns between sail and body at arrival (``Guess.revolutions_k``), and each class holds a
free optimum, as theta_f = phi_body(t_f) + 2 pi k splits the feasible set by k.  Starts that
reach the same optimum become one :class:`Candidate`.
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from esail_opt.errors import InputError
from esail_opt.optimisation.ipopt import (NLPResult, ipopt_options, primal_warm_options,
                                          solve_problem)
from esail_opt.optimisation.seed import (Start, guess_alpha, lifted_guess, rendezvous_starts,
                                         window_starts)

#: Two results are one optimum when their times of flight agree to this fraction and
#: their revolutions to :data:`SAME_REVOLUTIONS`: optima that pass +-90 deg pitch in
#: different segments differ by ~1e-4 of the tof and are one transfer.
SAME_TOF = 1e-3
SAME_REVOLUTIONS = 0.02
#: A final angle this close to a window's edge (rad) means the edge is active.
EDGE_TOLERANCE = 1e-6


@dataclass
class Candidate:
    """One distinct optimum the search found.

    ``result``: the fastest closed-form optimum of the starts that reached it, with its
    ``theta_window`` only when that bound is active (the error control and the polish must
    keep it then).  ``revolutions``: turns swept, (theta_f - theta_0) / 2 pi.  ``free``:
    a local optimum of the problem as posed, not one confined by its window ``[k, k + 1]``
    (or None).  ``found_from``: labels of the starts that reached it.
    """

    result: NLPResult
    revolutions: float
    free: bool
    window: list = None
    found_from: list = field(default_factory=list)

    @property
    def revolutions_k(self):
        """The rendezvous turn count its NLP used (0 for an orbit transfer)."""
        return self.result.revolutions_k

    @property
    def tof(self):
        """Closed-form time of flight, TU."""
        return float(np.sum(self.result.durations))


def _check(problem):
    if problem.objective.fixed_time:
        raise InputError(f"objective = {type(problem.objective).__name__}: the revolution "
                         "search is for minimum-time problems (objective = MinTime)")
    if getattr(problem.departure, "free_anomaly", False):
        raise InputError("departure.free_anomaly = True: the revolution search counts turns "
                         "from a fixed departure angle; fix the departure anomaly")


def swept_angle(result):
    """Polar angle a result sweeps from departure to arrival, rad."""
    return float(result.nodes[1, -1] - result.x_start[1])


#: Turn counts tried on each side of the first by :func:`descend_turns`.
TURN_STEPS = 8


#: What a ``solve`` of :func:`descend_turns` returns for a count judged no better without a
#: point (a probe stopped as hopeless, a count known far worse): it ends the direction.
NO_BETTER = object()


def descend_turns(k0, best, solve, better, steps=TURN_STEPS, gaps=0):
    """(best, every solve made in order) over the turn counts k on a body, stepping from
    ``k0`` (solved as ``best``) one turn at a time each way while that does better (the a_c
    needed can change by whole factors between counts).  ``solve(k)`` returns a solve of
    class k, None when it found no point, or :data:`NO_BETTER`; ``better(a, b)`` whether a
    beats b.  A direction steps over at most ``gaps`` counts in a row with no point."""
    made = []
    for step in (-1, 1):
        k, missed = k0 + step, 0
        for _ in range(steps):
            other = solve(k)
            made.append(other)
            if other is None and missed < gaps:
                missed, k = missed + 1, k + step
                continue
            if other is None or other is NO_BETTER or not better(other, best):
                break
            best, k, missed = other, k + step, 0
    return best, made


#: A class beside the seed's is first probed with Ipopt capped at PROBE_FACTOR times the
#: seed class's iterations, at least PROBE_MIN: a class with a transfer converges in about
#: the seed's iterations (in 3-D up to twice); one that ends infeasible wanders for hundreds.
PROBE_FACTOR = 3.0
PROBE_MIN = 60
#: A probe capped at a point this close to feasible (largest constraint violation, canonical
#: units) is descending in a class with transfers, so is solved on; one further off is hopeless.
PROBE_FEASIBLE = 1e-6
#: The least cap of a fallback start (another start after the first found no point): no
#: found answer's cost scales it (tests/problems/venus_rendezvous_behind.py's took 184).
FALLBACK_MIN = 300


def probe_cap(iterations, least=PROBE_MIN):
    """The Ipopt iterations of a probe, after a first solve that took ``iterations``:
    :data:`PROBE_FACTOR` times those, at least ``least`` (:data:`PROBE_MIN` for a class
    probe, :data:`FALLBACK_MIN` for a fallback start)."""
    return max(least, int(math.ceil(PROBE_FACTOR * iterations)))


#: A class probe (3-D ones run on the projected model) is stopped as hopeless at the iteration
#: where the answer's solve converged (at least :data:`PROBE_MIN`) if its point is still this
#: far from feasible (largest constraint violation, canonical units) and its objective over
#: HOPELESS_RATIO times the best class's: every such class looked at ended infeasible
#: (results/bench/README.md, "Pace").
HOPELESS_VIOLATION = 1e-3
HOPELESS_RATIO = 2.0


def hopeless_checkpoint(iterations, best):
    """The (iteration, test) checkpoint (``ipopt.build_solver``) that stops a class probe as
    hopeless, after an answer whose solve took ``iterations`` with objective ``best``; None
    for an objective that is not positive."""
    if not best > 0:
        return None

    def hopeless(objective, violation):
        return violation > HOPELESS_VIOLATION and objective > HOPELESS_RATIO * best

    return max(PROBE_MIN, int(iterations)), hopeless


def probe(problem, guess, cap, progress=None, checkpoint=None, staged=True):
    """A solve of ``problem`` from ``guess`` capped at ``cap`` Ipopt iterations, solved on
    uncapped only from a point within :data:`PROBE_FEASIBLE` of feasible.  ``checkpoint``
    (:func:`hopeless_checkpoint`) may stop it earlier (status ``ipopt.STOPPED``); ``staged`` as
    ``ipopt.solve_problem``'s.  Returns (NLPResult, Transcription), the result's iterations and
    seconds covering the probe and what followed it."""
    result, tr = solve_problem(problem, guess=guess, progress=progress, staged=staged,
                               options=ipopt_options(max_iter=cap), checkpoint=checkpoint)
    if not result.outcome.found and result.constraint_violation <= PROBE_FEASIBLE:
        # A nearly feasible point is a start Ipopt should keep to, as a free date's is.
        more, tr = solve_problem(problem, guess=result.as_guess(), progress=progress,
                                 staged=False,
                                 options=primal_warm_options(ipopt_options()))
        result = more.after(result)
    return result, tr


def probe_model(problem):
    """The model :func:`probe_rendezvous_class` probes ``problem``'s classes on: the
    projected one (``planar=True``) for a 3-D problem, else the problem itself."""
    return dataclasses.replace(problem, planar=True) if problem.three_d() else problem


def probe_rendezvous_class(problem, k, cap, progress=None, checkpoint=None, seeds=None):
    """:func:`probe_start` of the rendezvous turn count ``k`` from its seed
    (``seed.rendezvous_starts``; ``seeds``: :func:`probe_model`'s
    ``seed.constant_pitch_seeds``, if given): (NLPResult, Transcription, label of the start)."""
    start = rendezvous_starts(probe_model(problem), [k], seeds)[0]
    return probe_start(problem, start, cap, progress, checkpoint)


def probe_start(problem, start, cap, progress=None, checkpoint=None):
    """:func:`probe` of ``problem`` from ``start``, a ``seed.Start`` of :func:`probe_model`:
    (NLPResult, Transcription, label of the start).  A 3-D start is probed on the projected
    model and lifted (:func:`lift`) if that found a point: from a constant-pitch seed in 3-D,
    Ipopt swings the clock angles far and may end short of feasible at its cap."""
    model = probe_model(problem)
    result, tr = probe(model, start.guess, cap, progress, checkpoint)
    if model is problem:
        return result, tr, start.label
    if not result.outcome.found:
        return result, tr, f"{start.label}, on the projected model (not solved in 3-D)"
    lifted, tr = lift(problem, result, cap, progress)
    return lifted, tr, f"{start.label}, solved on the projected model and lifted into 3-D"


def second_start(problem, k, seeds, seed_k):
    """Another start of the rendezvous turn count ``k`` than the one that solved it: the last
    of ``seeds`` (:func:`probe_model`'s ``seed.constant_pitch_seeds``, in pitch order) that
    winds k, leaving out the pitch that solved it (the problem's own when k is ``seed_k``,
    else the first that winds k); None when no other does.  A class holds several optima, and
    the last seed, furthest in pitch from the first, is likeliest in another basin."""
    winding = [(a, g) for a, g in seeds.items() if g.revolutions_k == k]
    if not winding:
        return None
    used = guess_alpha(probe_model(problem)) if k == seed_k else winding[0][0]
    others = [(a, g) for a, g in winding if not math.isclose(a, used)]
    if not others:
        return None
    alpha, guess = others[-1]
    return Start(f"rendezvous k = {k}, a second start: constant pitch "
                 f"{math.degrees(alpha):.4g} deg", k, guess)


def lift(problem, result, cap, progress=None):
    """:func:`probe` of the 3-D ``problem`` from the optimum ``result`` of its projected
    model, lifted (``seed.lifted_guess``) and capped at ``cap`` iterations;
    (NLPResult, Transcription), the result's Ipopt record covering ``result`` too."""
    lifted, tr = probe(problem, lifted_guess(problem, result.as_guess()), cap, progress,
                       staged=False)
    return lifted.after(result), tr


#: A 3-D rendezvous's turn counts are searched on its projected model (``classes.ClassSearch``
#: on :func:`probe_model`); best projected first, a class is lifted into 3-D while its
#: projected objective is within LIFT_RATIO of the best lifted so far: no class's 3-D
#: objective has come out more than 0.5 % below its projected one.
LIFT_RATIO = 1.1


def searches_classes(problem):
    """Whether a solve of ``problem`` looks at the turn counts beside its seed's: a MinTime
    or MinAcceleration rendezvous departing at a fixed date and angle."""
    objective = problem.objective
    return (problem.tracks_body() and not problem.free_date()
            and not getattr(problem.departure, "free_anomaly", False)
            and (objective.free_acceleration or not objective.fixed_time))


def _on_edge(result, window):
    if window is None:
        return False
    th = float(result.nodes[1, -1])
    return min(abs(th - window[0]), abs(th - window[1])) < EDGE_TOLERANCE * max(1.0, abs(th))


def _same(a, b):
    return (abs(a.revolutions - b.revolutions) < SAME_REVOLUTIONS
            and abs(a.tof - b.tof) < SAME_TOF * max(a.tof, b.tof)
            and a.revolutions_k == b.revolutions_k and a.free == b.free)


def search(problem, extra_revolutions=2, progress=None):
    """Solve the minimum-time ``problem`` (fixed departure angle; else InputError) from
    one start per revolution class, from one below the free optimum's to
    ``extra_revolutions`` (0 to 20) above it; ``progress(text)`` before each start.

    Returns (list of Candidate, list of dict): the distinct converged optima, free ones
    first, each group by time of flight; and one record per start: ``label``,
    ``revolutions`` (the class), ``status``, ``iterations``, ``seconds``, ``tof`` (TU, or
    None) and ``candidate`` (its index in the list, or None when it did not converge).
    """
    _check(problem)
    if isinstance(extra_revolutions, bool) or not isinstance(extra_revolutions, int) \
            or not 0 <= extra_revolutions <= 20:
        raise InputError(f"extra_revolutions = {extra_revolutions!r} is outside [0, 20]")
    say = progress or (lambda text: None)
    say(f"{problem.name}: start 1, the problem's own seed (free)")
    first, tr = solve_problem(problem, progress=progress)
    centre, starts = _class_starts(problem, first, tr, extra_revolutions)
    outcomes = [(Start("the problem's own seed (free)", centre, tr.guess), first)]
    for i, start in enumerate(starts, 2):
        say(f"{problem.name}: start {i}/{len(starts) + 1}, {start.label}")
        outcomes.append((start, solve_problem(problem, guess=start.guess, progress=progress)[0]))
    return _distinct(outcomes)


def _class_starts(problem, first, tr, extra_revolutions):
    """The free start's class and the other starts of :func:`search`: one per class
    from one below it to ``extra_revolutions`` above."""
    rendezvous = problem.tracks_body()
    base_k = tr.guess.revolutions_k
    if rendezvous:
        centre = base_k
    elif first.converged:
        centre = int(swept_angle(first) // (2 * math.pi))
    else:
        centre = int(float(tr.guess.nodes[1, -1] - problem.x0()[1]) // (2 * math.pi))
    # The free start's own window gets a start too: the two can reach one transfer
    # differently, and only one may polish to a verified schedule.
    real = getattr(problem.target, "body", None) is not None
    classes = [k for k in range(centre - 1, centre + extra_revolutions + 1)
               if (real or k >= 0) and not (rendezvous and k == base_k)]
    starts = (rendezvous_starts(problem, classes) if rendezvous
              else window_starts(problem, classes))
    return centre, starts


def _distinct(outcomes):
    """:func:`search`'s return from its (Start, NLPResult) pairs: the distinct converged
    optima, sorted, and one record per start naming the optimum it reached."""
    candidates, records = [], []
    for start, result in outcomes:
        records.append({"label": start.label, "revolutions": start.revolutions,
                        "status": result.status, "iterations": result.iterations,
                        "seconds": result.solve_seconds, "candidate": None,
                        "tof": float(np.sum(result.durations)) if result.converged else None})
        if result.converged:
            _merge(candidates, start, result)
    candidates.sort(key=lambda c: (not c.free, c.tof))
    for record in records:
        for index, c in enumerate(candidates):
            if record["label"] in c.found_from:
                record["candidate"] = index
    return candidates, records


def _merge(candidates, start, result):
    """Add ``result`` to ``candidates``, or to the one it equals (keeping the faster)."""
    window = None if start.window is None else [start.revolutions, start.revolutions + 1]
    free = not _on_edge(result, start.window)
    if free:
        result = dataclasses.replace(result, theta_window=None)
    found = Candidate(result, swept_angle(result) / (2 * math.pi), free, window,
                      [start.label])
    for other in candidates:
        if _same(found, other):
            other.found_from.append(start.label)
            if found.tof < other.tof:
                other.result = found.result
            return
    candidates.append(found)
