"""The edge of the feasible: the shortest flight found feasible from one departure.

A fixed-time problem (``MinAcceleration``, say) whose solve finds no point may simply be
too short a flight: an E-sail's thrust never points more than 19.5 deg from the outward
radial.  :func:`nearest_feasible` then walks the time of flight to the shortest one at
which the closed-form NLP converges, flies that flight as any run is flown, and returns
an :class:`Edge`.  The lone solve (``pipeline.Run.nearest_feasible``) and the porkchop
(its cells with no sail, per date) both take the edge from here, through
``pipeline.nearest_feasible``, which hands in the pipeline's own stages.

The walk has two parts.  Without a start, a ladder of single solves at
:data:`LONGER` multiples of the asked time of flight finds one that converges
(:func:`_ladder`).  From there, or from a start the caller gives (a porkchop's verified
cell of the same date), the time of flight is halved towards the longest one found
infeasible, each step warm on the same NLP, to within :data:`EDGE_DAYS`
(:func:`_halve`).
"""

import dataclasses
from dataclasses import dataclass
from typing import Any

from esail_opt.errors import NoStart
from esail_opt.optimisation.error_control import MAX_SUB_ARCS, sub_arcs_within_cap
from esail_opt.optimisation.ipopt import (build_solver, ipopt_options, solve_problem,
                                          solve_transcription)
from esail_opt.optimisation.seed import initial_guess

__all__ = ["Edge", "EDGE_DAYS", "LONGER", "WALK_ITERATIONS", "at_tof", "nearest_feasible",
           "walk", "walks"]

#: The walk halves the interval between the longest time found infeasible and the
#: shortest found feasible until it is this short, days.
EDGE_DAYS = 4.0
#: Ipopt iterations of each warm step of the walk.  A step that finds no point within
#: them is taken as beyond the edge: the walk then reports a flight a little longer than
#: the edge, never one that is not feasible (from 2035-06-01 to Mars, steps past the
#: edge took 500 to 1,200 iterations to end infeasible, steps inside it 36 to 69).
WALK_ITERATIONS = 150
#: Times of flight at which a fixed-time problem that found no point is solved again, as
#: multiples of the asked one, until one converges: the walk to the edge starts there.
LONGER = (1.1, 1.25, 1.5, 2.0)


@dataclass(frozen=True)
class Edge:
    """The edge of the feasible from one departure.

    Attributes
    ----------
    flight : Run or scan.Cell
        The shortest flight found feasible, flown and judged: a ``pipeline.Run``
        (error-controlled and verified as any run), or the verified start the caller
        gave when the walk found nothing shorter that verifies.  Its ``problem``
        carries the time of flight (``problem.objective.tof_days``).
    infeasible_tof_days : float
        The longest time of flight the walk found no point at: the edge lies between it
        and the flight's.
    iterations : int
        Ipopt iterations the walk spent, its infeasible probes included.
    """

    flight: Any
    infeasible_tof_days: float
    iterations: int

    @property
    def tof_days(self):
        return self.flight.problem.objective.tof_days

    @property
    def verified(self):
        return bool(self.flight.verified)


def walks(problem):
    """Whether a solve of ``problem`` that found no point has an edge to walk to:
    fixed-time problems with a target and a fixed departure."""
    return (problem.objective.fixed_time and problem.target is not None
            and not problem.free_date()
            and not getattr(problem.departure, "free_anomaly", False))


def at_tof(problem, tof_days):
    """``problem`` (fixed-time, :func:`walks`) with its time of flight set to
    ``tof_days``."""
    return dataclasses.replace(problem, objective=dataclasses.replace(problem.objective,
                                                                      tof_days=tof_days))


def nearest_feasible(problem, lone, fly, start=None, progress=None):
    """The :class:`Edge` from ``problem``'s departure, or None when the walk found no
    time of flight at which the closed form converges.

    Parameters
    ----------
    problem : Problem
        A fixed-time problem (:func:`walks`) that found no point at its time of flight.
    lone : callable
        ``lone(problem, progress)`` -> ``pipeline.Run``: a lone solve without a walk of
        its own, for a rung of the ladder whose single solve found no point.
    fly : callable
        ``fly(problem, result, transcription, progress=)`` -> ``pipeline.Run``:
        the error control and the verification of the walk's flight
        (``pipeline.finish``).
    start : optional
        A verified flight from the same departure at a longer time of flight, with its
        ``problem``, ``result`` and ``transcription`` (a porkchop's verified cell of the
        date): the walk starts from it instead of the ladder, and it stays the edge
        when the walk finds nothing shorter, or the shorter flight does not verify.
    progress : callable, optional
        ``progress(text)``: one line per solve.

    Returns
    -------
    Edge or None
        Without ``start``, the walk's flight even when it does not verify (``verified``
        says so); with one, never a flight that does not verify.
    """
    say = progress or (lambda text: None)
    walked = walk(problem, lone, start, say)
    if walked is None:
        return None
    cell, result, tr, infeasible, iterations = walked
    if start is not None and not cell.objective.tof_days < start.problem.objective.tof_days:
        return Edge(start, infeasible, iterations)  # no step below the start converged
    say(f"{problem.name}: the shortest flight found feasible is "
        f"{cell.objective.tof_days:.4g} d; error control and verification")
    run = fly(cell, result, tr, progress=say)
    if start is not None and not run.verified:
        return Edge(start, infeasible, iterations)
    return Edge(run, infeasible, iterations)


def walk(problem, lone, start=None, progress=None):
    """The shortest time of flight from ``problem``'s departure at which its closed-form
    NLP converges, at least ``problem``'s own, from ``start`` (its ``problem``, ``result``
    and ``transcription``) or, without one, from the first rung of :func:`_ladder` that
    converges (``lone`` as for :func:`nearest_feasible`).

    Returns
    -------
    tuple or None
        ``(Problem, NLPResult, Transcription, infeasible_tof_days, iterations)``: the
        converged optimum at that time of flight with its problem and NLP, the longest
        time of flight found infeasible, and the Ipopt iterations spent; None when no
        rung converges.
    """
    say = progress or (lambda text: None)
    if start is None:
        rung = _ladder(problem, lone, say)
        if rung is None:
            return None
        return _halve(problem, *rung, say)
    return _halve(problem, start.problem, start.result, start.transcription, 0,
                  problem.objective.tof_days, say)


def _halve(problem, cell, result, tr, iterations, lo, say):
    """The continuation of :func:`walk` in the time of flight, from the converged
    ``result`` of ``cell`` (its NLP ``tr``), with ``lo`` the longest time of flight found
    infeasible and ``iterations`` already spent.

    The time of flight is halved from ``cell``'s towards ``lo``, each step warm from the
    last converged one on the same NLP (its time of flight is a parameter,
    ``Transcription.at``), to within :data:`EDGE_DAYS`.  A step that does not converge
    within :data:`WALK_ITERATIONS` counts as infeasible, so the edge may lie a little
    shorter than reported, never longer."""
    solver = build_solver(tr, ipopt_options(max_iter=WALK_ITERATIONS), warm=True)
    while cell.objective.tof_days - lo > EDGE_DAYS:
        step = at_tof(cell, 0.5 * (lo + cell.objective.tof_days))
        say(f"{problem.name}: walking the time of flight to {step.objective.tof_days:.6g} d")
        other = solve_transcription(tr.at(step), warm=result, solver=solver, progress=say)
        iterations += other.iterations
        if other.outcome.converged:
            cell, result = step, other
        else:
            lo = step.objective.tof_days
    return cell, result, tr.at(cell), lo, iterations


def _ladder(problem, lone, say):
    """The solves (:func:`_rung`) at :data:`LONGER` multiples of ``problem``'s time of
    flight, up to the first that converges: (problem, NLPResult, Transcription,
    iterations spent, longest time of flight found infeasible), or None."""
    asked = problem.objective.tof_days
    lo, iterations = asked, 0
    for factor in LONGER:
        say(f"{problem.name}: no point at {lo:.6g} d; solving at {asked * factor:.6g} d")
        try:
            cell, result, tr, spent = _rung(at_tof(problem, asked * factor), lone, say)
        except NoStart as why:
            # The rung's seed cannot be flown (it escapes before the time of flight):
            # no point there, and a longer rung's seed flies longer still.
            say(f"{problem.name}: no seed at {asked * factor:.6g} d: {why}")
            return None
        iterations += spent
        if result.outcome.converged:
            return cell, result, tr, iterations, lo
        lo = asked * factor
    return None


def _rung(problem, lone, say):
    """One rung of :func:`_ladder`: a single solve from ``problem``'s seed and, when
    that finds no point, ``lone(problem, say)``: (problem, NLPResult, Transcription,
    Ipopt iterations of both).  Raises NoStart when the seed cannot be flown.

    Why both: the single solve is cheap, and where it converges the walk has always
    started from it; where it does not, the lone solve's turn-count search can still
    find a point, and the walk from a longer rung may stop weeks above the edge."""
    guess = initial_guess(problem)
    problem = sub_arcs_within_cap(problem, guess, MAX_SUB_ARCS)
    result, tr = solve_problem(problem, guess=guess, progress=say)
    if result.outcome.converged:
        return problem, result, tr, result.iterations
    say(f"{problem.name}: no point from the seed at {problem.objective.tof_days:.6g} d; "
        "solving it as a lone solve")
    run = lone(problem, say)
    return run.problem, run.result, run.transcription, result.iterations + run.result.iterations
