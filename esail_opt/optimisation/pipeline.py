"""The data path of one run: seed -> closed-form NLP -> Ipopt -> other starts -> error
control -> CVODES verification -> polish, returned as a typed :class:`Run`.

This is the one module that strings the optimisation stages together; the application
(``app.solution``, the global search, sweeps) calls :func:`solve` or :func:`finish` and
only writes down what they return.  Whether a stage runs is decided from the
:class:`Outcome` of the stage before it (``Outcome.found``: converged or acceptable), and
``Outcome`` itself lives in ``optimisation.outcome``, below ``optimisation.ipopt``:
``ipopt`` tags each result with it and this module, which imports ``ipopt``, exports it,
so the two never import each other.

Numbers are those of the stages themselves: nothing here changes a result, it only
decides what runs next and adds up Ipopt's iterations and seconds over the run.
"""

import dataclasses
from dataclasses import dataclass
from typing import Optional, Tuple

from esail_opt.errors import InputError
from esail_opt.optimisation import multistart, scan
from esail_opt.optimisation import polish as polishing
from esail_opt.optimisation.error_control import MAX_SUB_ARCS, ErrorControl, Round, control_error
from esail_opt.optimisation.ipopt import (NLPResult, ipopt_options, primal_warm_options,
                                          solve_problem)
from esail_opt.optimisation.outcome import Outcome
from esail_opt.optimisation.problem import Problem, Tolerance
from esail_opt.optimisation.transcription import (Transcription, initial_guess,
                                                  sub_arcs_within_cap)
from esail_opt.optimisation.verify import Verification, verify, within

__all__ = ["Outcome", "Round", "StartTried", "PolishRun", "Run", "solve", "finish",
           "POLISH_TOLERANCE"]

#: What a polished schedule must meet (1 m and 1 mm/s), against the target and against
#: the polished NLP's own final node.
POLISH_TOLERANCE: Tolerance = polishing.TOLERANCE


@dataclass(frozen=True)
class StartTried:
    """One start of the closed-form NLP: where it came from and how Ipopt ended."""

    label: str
    status: str
    iterations: int


@dataclass(frozen=True)
class PolishRun:
    """The polish of a run: the optimum re-solved on Eqs. 1-2 in time, and its flight.

    Attributes
    ----------
    result : NLPResult or None
        The polished optimum (``optimisation.polish.polish``); None when the closed form
        found nothing to polish (its ``note`` says so).
    check : Verification or None
        The CVODES flight of the polished schedule.
    verified : bool
        Ipopt converged and the flight, its verifier's error included, is within
        :attr:`tolerance` of both the target and the polished NLP's final node.
    note : str
        One line: the verdict and, when not verified, why.
    tolerance : Tolerance
        :data:`POLISH_TOLERANCE`.
    within_nlp, within_target : bool
        The two halves of the verdict (``within_target`` is True without a target).
    closed_form_objective : float
        The objective of the closed-form optimum the polish started from.
    """

    result: Optional[NLPResult]
    check: Optional[Verification]
    verified: bool
    note: str
    tolerance: Tolerance = POLISH_TOLERANCE
    within_nlp: bool = False
    within_target: bool = False
    closed_form_objective: Optional[float] = None

    @property
    def ran(self):
        """Whether the polish ran (False: the closed form found nothing to polish)."""
        return self.result is not None


@dataclass(frozen=True)
class Run:
    """One run of the pipeline, in canonical units, as the stages left it.

    Attributes
    ----------
    problem : Problem
        The problem as last solved: its ``segments`` are the count used and the sub-arcs
        the error control ended with.
    result : NLPResult
        The closed-form optimum after the error control (or the last solve, when Ipopt
        found nothing); ``iterations`` and ``solve_seconds`` cover every solve of the
        run up to the polish.
    transcription : Transcription or None
        Its NLP.
    starts : tuple of StartTried
        The starts tried when the first did not find a point (empty otherwise).
    error_control : ErrorControl or None
        Its rounds and per-segment local errors; None when the closed form found nothing.
    check : Verification
        The CVODES flight of ``result``'s schedule.
    verified : bool
        Converged, and ``check`` meets ``problem.tolerance`` with the verifier's error
        added.  The polish's own verdict is in ``polish``.
    note : str
        One line: the verdict, and why when not verified.
    sub_arcs_requested : int
        The problem file's sub-arcs, before the seed or the error control raised them.
    polish : PolishRun or None
        Only when asked for.
    """

    problem: Problem
    result: NLPResult
    transcription: Optional[Transcription]
    starts: Tuple[StartTried, ...]
    error_control: Optional[ErrorControl]
    check: Verification
    verified: bool
    note: str
    sub_arcs_requested: int
    polish: Optional[PolishRun] = None

    @property
    def outcome(self):
        """The :class:`Outcome` of the closed-form solve the run ended with."""
        return self.result.outcome


def _quiet(text):
    """The progress callback of a caller that wants none."""


def solve(problem, segments=None, progress=None, samples=16, polish=False):
    """Run the whole pipeline on ``problem``.

    Parameters
    ----------
    problem : Problem
    segments : int, optional
        Override the problem's number of control segments N (>= 1).
    progress : callable, optional
        ``progress(text)`` is called at each stage and every few seconds of Ipopt.
    samples : int
        Flight samples per segment for the plots (the verdicts do not depend on them).
    polish : bool
        Then polish the optimum (``optimisation.polish``) and verify that schedule too.

    Returns
    -------
    Run

    Raises
    ------
    InputError
        ``segments`` is not an integer >= 1 (before any solve starts).
    """
    if segments is not None:
        if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
            raise InputError(f"segments = {segments!r} is outside [1, inf)")
        problem = problem.with_segments(segments)
    say = progress or _quiet
    seg = problem.segments
    count = (f"{seg.count} segments" if seg.per_revolution is None
             else f"{seg.per_revolution} segments per revolution")
    guess, seed = None, None
    if problem.free_date():
        seed = scan.seed_free_date(problem, say)
        problem, guess = seed.problem, seed.guess
    # A free date's guess is the optimum of its best date: a start Ipopt keeps to
    # (primal_warm_options), and no staging from it.
    options = None if guess is None else primal_warm_options(ipopt_options())
    if guess is None:
        guess = initial_guess(problem)
        problem = sub_arcs_within_cap(problem, guess, MAX_SUB_ARCS)
    say(f"{problem.name}: building the NLP ({count} x {problem.segments.sub_arcs} sub-arcs)")
    result, tr = solve_problem(problem, guess=guess, progress=say,
                               staged=not problem.free_date(), options=options)
    starts = ()
    if not result.outcome.found:
        result, tr, starts = _other_starts(problem, result, tr, say)
    elif problem.objective.free_acceleration and problem.tracks_body():
        result, tr, starts = _least_acceleration_class(problem, result, tr, say)
    if seed is not None:
        # The scan that chose the date is part of the run's Ipopt record.
        result.iterations += seed.iterations
        result.solve_seconds += seed.seconds
    say(f"{problem.name}: {result.status} after {result.iterations} iterations; "
        + ("error control until the flight meets the tolerance" if result.outcome.found
           else "no start found a point; flying the last iterate to report its miss"))
    return finish(problem, result, tr, samples=samples, polish=polish, progress=say,
                  starts=starts, sub_arcs_requested=seg.sub_arcs)


def _other_starts(problem, result, tr, say):
    """Ipopt's "infeasible" from one start is a local statement: before giving up, try
    the starts the global search would (other turn counts on a rendezvous body, other
    constant-pitch seeds of an orbit transfer), and keep the first that finds a point.

    Returns the (result, transcription) to go on with and a StartTried per start.
    """
    records = [StartTried("the problem's own seed", result.status, result.iterations)]
    if problem.target is None or getattr(problem.departure, "free_anomaly", False):
        return result, tr, tuple(records)
    seconds = result.solve_seconds
    for start in multistart.fallback_starts(problem, tr.guess):
        say(f"{problem.name}: {result.status}; trying {start.label}")
        other, other_tr = solve_problem(problem, guess=start.guess, progress=say)
        records.append(StartTried(start.label, other.status, other.iterations))
        # The run's Ipopt record covers every start it took to get here.
        if other.outcome.found:
            other.iterations += sum(r.iterations for r in records[:-1])
            other.solve_seconds += seconds
            return other, other_tr, tuple(records)
        seconds += other.solve_seconds
    result.iterations = sum(r.iterations for r in records)
    result.solve_seconds = seconds
    return result, tr, tuple(records)


def _least_acceleration_class(problem, result, tr, say):
    """The least a_c over the turn counts k on the target body, for a MinAcceleration
    rendezvous (``multistart.descend_turns`` from the seed's k, each k a cold solve
    from its own seed).  A warm-started scan drifts to the better k where a lone solve
    would stay, and the two would then disagree on what the same cell needs
    (``test_a_lone_min_acceleration_solve_beats_the_turn_counts_beside_it``).

    Returns the (result, transcription) of the least a_c found and a StartTried per
    class solved.
    """
    records = [StartTried(f"the problem's own seed (k = {result.revolutions_k})",
                          result.status, result.iterations)]
    seconds = [result.solve_seconds]

    def solve_class(k):
        start = multistart.rendezvous_starts(problem, [k])[0]
        say(f"{problem.name}: trying the turn count k = {k}")
        other, other_tr = solve_problem(problem, guess=start.guess, progress=say)
        records.append(StartTried(start.label, other.status, other.iterations))
        seconds.append(other.solve_seconds)
        return (other, other_tr) if other.outcome.found else None

    (best, best_tr), _ = multistart.descend_turns(
        result.revolutions_k, (result, tr), solve_class,
        lambda a, b: a[0].objective < b[0].objective)
    # The run's Ipopt record covers every class it solved.
    best.iterations = sum(r.iterations for r in records)
    best.solve_seconds = sum(seconds)
    return best, best_tr, tuple(records)


def finish(problem, result, tr=None, samples=16, polish=False, progress=None, starts=(),
           sub_arcs_requested=None):
    """The stages after a closed-form optimum is found: error control, CVODES
    verification and, with ``polish``, the polish.

    :func:`solve` is this after the solve; the global search calls it for each optimum
    it keeps.

    Parameters
    ----------
    problem : Problem
    result : NLPResult
        A closed-form optimum of ``problem`` (any outcome: one not found is only
        verified, and its note says why it is not).
    tr : Transcription, optional
        ``result``'s NLP: the error control re-solves it warm; without it a new one is
        built.  Either way the error control and the polish keep ``result``'s revolution
        class.
    samples, polish, progress
        As for :func:`solve`.
    starts : sequence of StartTried
        The starts tried before this one.
    sub_arcs_requested : int, optional
        The problem file's sub-arcs when the seed already raised them (default the
        problem's).

    Returns
    -------
    Run
    """
    requested = sub_arcs_requested or problem.segments.sub_arcs
    say = progress or _quiet
    controlled = None
    if result.outcome.found:
        # Its last round's verification is the run's: flown with the plots' samples.
        controlled = control_error(problem, result, tr, say, samples=samples)
        # The run's Ipopt record covers the first solve and every round after it.
        iterations = result.iterations + sum(r.iterations for r in controlled.history[1:])
        seconds = result.solve_seconds + controlled.history[-1].seconds
        problem, result, tr = controlled.problem, controlled.result, controlled.transcription
        result.iterations, result.solve_seconds = iterations, seconds
        check = controlled.check
    else:
        check = verify(problem, result, samples)
    verified, note = check.judge(problem)
    verified = verified and result.converged
    if not result.converged:
        note = f"NOT verified: Ipopt ended {result.status}" + (
            "" if result.outcome is not Outcome.INFEASIBLE else
            f" from {len(starts) or 1} start(s); no start found a feasible point, which "
            "does not prove the target unreachable")
    run = Run(problem=problem, result=result, transcription=tr, starts=tuple(starts),
              error_control=controlled, check=check, verified=verified, note=note,
              sub_arcs_requested=requested)
    if not polish:
        return run
    return dataclasses.replace(run, polish=_polish(problem, result, samples, say))


def _polish(problem, result, samples, say):
    """Polish ``result`` and judge the polished flight against :data:`POLISH_TOLERANCE`."""
    # A closed form that found no optimum has nothing worth polishing.
    if not result.outcome.found:
        return PolishRun(None, None, False,
                         f"NOT polished: the closed-form solve ended {result.status}",
                         closed_form_objective=result.objective)
    if result.delta is not None:
        return PolishRun(None, None, False, "NOT polished: the polish flies the planar "
                         "model only; solve with planar=True to polish",
                         closed_form_objective=result.objective)
    say(f"{problem.name}: polishing on the exact Eqs. 1-2 in time ({result.alpha.size} segments)")
    exact, _ = polishing.polish(problem, result)
    say(f"{problem.name}: polish {exact.status} after {exact.iterations} iterations; "
        "verifying on CVODES")
    check = verify(problem, exact, samples)
    within_all, note = check.judge(problem, POLISH_TOLERANCE, against_nlp=True)
    verified = exact.converged and within_all
    if not exact.converged:
        note = f"NOT verified: Ipopt did not converge ({exact.status}); {note}"
    elif verified:
        note = f"exact: {note}"
    return PolishRun(exact, check, verified, note, POLISH_TOLERANCE,
                     within_nlp=within(check.misses, POLISH_TOLERANCE, "nlp"),
                     within_target=(problem.target is None
                                    or within(check.misses, POLISH_TOLERANCE)),
                     closed_form_objective=result.objective)

