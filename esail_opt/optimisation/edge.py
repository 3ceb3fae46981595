"""The edge of the feasible: the shortest flight found feasible from one departure.

A fixed-time problem whose solve finds no point may simply be too short a flight (an
E-sail's thrust never points more than 19.5 deg from the outward radial).
:func:`nearest_feasible` walks its time of flight down to the shortest at which the
closed-form NLP converges, from the first feasible of longer solves
(:func:`_first_feasible_longer`) or a given start, by halving (:func:`_halve`), and flies
that flight as any run is flown.
"""

import dataclasses
from dataclasses import dataclass
from typing import Any

from esail_opt.errors import NoStart
from esail_opt.optimisation.error_control import MAX_SUB_ARCS, sub_arcs_within_cap
from esail_opt.optimisation.ipopt import (build_solver, ipopt_options, solve_problem,
                                          solve_transcription)
from esail_opt.optimisation.seed import initial_guess

__all__ = ["Edge", "EDGE_DAYS", "LONGER", "NoLongerPoint", "WALK_ITERATIONS", "at_tof",
           "nearest_feasible", "walk", "walks"]

#: The walk halves the interval between the longest time found infeasible and the
#: shortest found feasible until it is this short, days.
EDGE_DAYS = 4.0
#: Ipopt iterations of each warm step of the walk; a step that finds no point within them
#: counts as beyond the edge (steps inside it took under 70, steps past it 500 or more).
WALK_ITERATIONS = 150
#: Times of flight at which a fixed-time problem that found no point is solved again, as
#: multiples of the asked one, until one converges: the walk to the edge starts there.
LONGER = (1.1, 1.25, 1.5, 2.0)


class NoLongerPoint(Exception):
    """No longer time of flight from the departure found a point either; the message says
    how far the walk tried and why it stopped, in words that end a failed run's note."""


@dataclass(frozen=True)
class Edge:
    """The edge of the feasible from one departure.

    ``flight`` is the shortest flight found feasible, flown and judged (a ``pipeline.Run``,
    or the verified start the caller gave when nothing shorter verifies); its ``problem``
    carries the time of flight.  The edge lies between it and ``infeasible_tof_days``, the
    longest time of flight found with no point, days.  ``iterations``: Ipopt iterations
    the walk spent, infeasible probes included.
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


def nearest_feasible(problem, solve_unwalked, fly, start=None, progress=None):
    """The :class:`Edge` from the departure of ``problem`` (fixed-time, :func:`walks`, no
    point at its time of flight).  Without ``start``, raises :class:`NoLongerPoint` when no
    longer solve (:data:`LONGER`) converges.

    ``solve_unwalked(problem, progress)`` -> ``pipeline.Run``: a lone solve without a walk, for
    a longer time of flight whose single solve found no point; ``fly(problem, result, transcription,
    progress=)`` -> ``pipeline.Run``: ``pipeline.run_from_optimum``.  ``start``, a verified flight
    from the same departure at a longer time of flight, replaces the longer solves and stays the
    edge unless a shorter flight verifies; without it the walk's flight is returned even
    when it does not verify.  ``progress(text)`` gets one line per solve.
    """
    say = progress or (lambda text: None)
    cell, result, tr, infeasible, iterations = walk(problem, solve_unwalked, start, say)
    if start is not None and not cell.objective.tof_days < start.problem.objective.tof_days:
        return Edge(start, infeasible, iterations)  # no step below the start converged
    say(f"{problem.name}: the shortest flight found feasible is "
        f"{cell.objective.tof_days:.4g} d; error control and verification")
    run = fly(cell, result, tr, progress=say)
    if start is not None and not run.verified:
        return Edge(start, infeasible, iterations)
    return Edge(run, infeasible, iterations)


def walk(problem, solve_unwalked, start=None, progress=None):
    """The shortest time of flight from ``problem``'s departure, at least its own, at
    which its closed-form NLP converges, walked from ``start`` or else from the first longer solve
    of :func:`_first_feasible_longer` that converges (arguments as for :func:`nearest_feasible`).

    Returns ``(Problem, NLPResult, Transcription, infeasible_tof_days, iterations)``, the
    converged optimum there with its problem and NLP; raises :class:`NoLongerPoint` when
    none converges.
    """
    say = progress or (lambda text: None)
    if start is None:
        return _halve(problem, *_first_feasible_longer(problem, solve_unwalked, say), say)
    return _halve(problem, start.problem, start.result, start.transcription, 0,
                  problem.objective.tof_days, say)


def _halve(problem, cell, result, tr, iterations, lo, say):
    """The walk of :func:`walk`, from the converged ``result`` of ``cell`` (its NLP
    ``tr``), ``lo`` the longest time of flight found infeasible: halve towards ``lo`` to
    within :data:`EDGE_DAYS`, each step warm on the same NLP (the time of flight is a
    parameter, ``Transcription.at``).  A step beyond :data:`WALK_ITERATIONS` counts as
    infeasible, so the edge may lie a little shorter than reported, never longer."""
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


def _first_feasible_longer(problem, solve_unwalked, say):
    """The solves (:func:`_solve_at`) at :data:`LONGER` multiples of ``problem``'s time of
    flight, up to the first that converges: (problem, NLPResult, Transcription,
    iterations spent, longest time of flight found infeasible); NoLongerPoint if none does."""
    asked = problem.objective.tof_days
    lo, iterations = asked, 0
    for factor in LONGER:
        say(f"{problem.name}: no point at {lo:.6g} d; solving at {asked * factor:.6g} d")
        try:
            longer = at_tof(problem, asked * factor)
            cell, result, tr, spent = _solve_at(longer, solve_unwalked, say)
        except NoStart as why:
            # The seed escapes before the time of flight; a longer flight's would too.
            say(f"{problem.name}: no seed at {asked * factor:.6g} d: {why}")
            tried = ("no longer flight was tried" if lo == asked else
                     f"no longer flight from the same departure, up to {lo:.6g} d, found a "
                     "point either")
            raise NoLongerPoint(f"{tried}: at {asked * factor:.6g} d the seed cannot be "
                                "flown") from None
        iterations += spent
        if result.outcome.converged:
            return cell, result, tr, iterations, lo
        lo = asked * factor
    raise NoLongerPoint(f"no longer flight from the same departure, up to {lo:.6g} d "
                        f"({LONGER[-1]:g} times the asked), found a point either")


def _solve_at(problem, solve_unwalked, say):
    """One solve of :func:`_first_feasible_longer`: a single solve from ``problem``'s seed and, when
    that finds no point, ``solve_unwalked(problem, say)``: (problem, NLPResult, Transcription,
    Ipopt iterations of both).  Raises NoStart when the seed cannot be flown.  The solve_unwalked
    solve's turn-count search finds points the cheap single solve misses, which would
    otherwise leave the walk starting weeks above the edge."""
    guess = initial_guess(problem)
    problem = sub_arcs_within_cap(problem, guess, MAX_SUB_ARCS)
    result, tr = solve_problem(problem, guess=guess, progress=say)
    if result.outcome.converged:
        return problem, result, tr, result.iterations
    say(f"{problem.name}: no point from the seed at {problem.objective.tof_days:.6g} d; "
        "solving it as a lone solve")
    run = solve_unwalked(problem, say)
    return run.problem, run.result, run.transcription, result.iterations + run.result.iterations
