"""The data path of one run: seed -> closed-form NLP -> Ipopt -> other starts -> the
turn counts beside the answer's -> error control -> CVODES verification -> polish (or,
for a fixed time with no point, the walk to the shortest feasible time of flight,
``optimisation.edge``), returned as a typed :class:`Run`.

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
from esail_opt.optimisation import edge, multistart, scan
from esail_opt.optimisation import polish as polishing
from esail_opt.optimisation.classes import ClassSearch, finish_best_first
from esail_opt.optimisation.error_control import (MAX_SUB_ARCS, ErrorControl, Round, control_error,
                                                  per_revolution_mesh, sub_arcs_within_cap)
from esail_opt.optimisation.ipopt import (NLPResult, ipopt_options, primal_warm_options,
                                          solve_problem)
from esail_opt.optimisation.outcome import Outcome
from esail_opt.optimisation.problem import Problem, Tolerance
from esail_opt.optimisation.seed import initial_guess
from esail_opt.optimisation.transcription import Transcription
from esail_opt.optimisation.verify import Verification, verify, within

__all__ = ["Outcome", "Round", "StartTried", "ClassTried", "PolishRun", "Run", "solve",
           "finish", "nearest_feasible", "POLISH_TOLERANCE"]

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
class ClassTried:
    """One turn count k on the target body that a solve looked at, and what it gave.

    Attributes
    ----------
    label : str
        Where its start came from.
    revolutions_k : int
        The class: whole turns between the sail and the body at arrival.
    status : str
        Ipopt's return status of its last solve ("Maximum_Iterations_Exceeded" for a
        probe stopped at :data:`multistart.PROBE_FACTOR` times the seed's iterations,
        "User_Requested_Stop" for one stopped as hopeless,
        :func:`multistart.hopeless_checkpoint`).
    iterations : int
        Ipopt iterations spent on it.
    objective : float or None
        Its closed-form objective (canonical units), None when Ipopt found no point; for
        a class that was flown, the one its run ends with, after the error control.
    tof, ac_scale : float or None
        Its time of flight (TU) and a_c over the sail's, None when not found (as
        ``objective``, the run's for a class flown).
    constraint_violation : float
        Of the point it ended at (a probe stopped far from feasible is hopeless).
    verified : bool or None
        Whether its flight met the tolerance; None when it was not flown (it was not
        found, or a better class was verified first).
    chosen : bool
        The class the run returns.
    projected : bool
        Its values are its projected model's: a 3-D run's class not lifted into 3-D
        (``classes.ClassSearch``).
    """

    label: str
    revolutions_k: int
    status: str
    iterations: int
    objective: Optional[float]
    tof: Optional[float]
    ac_scale: Optional[float]
    constraint_violation: float
    verified: Optional[bool] = None
    chosen: bool = False
    projected: bool = False

    @classmethod
    def of(cls, candidate, iterations, run=None, chosen=False):
        """The record of a ``classes.Candidate`` that took ``iterations``, with its
        ``run``'s verdict and values when finished: the error control may move the
        optimum (a 3-D Vesta intercept's went from 552.2 d to 479.3 d)."""
        r = candidate.result
        flown = run is not None and run.result.outcome.found
        values = run.result if flown else r
        found = flown or r.outcome.found
        return cls(candidate.label, r.revolutions_k, r.status, iterations,
                   values.objective if found else None,
                   float(sum(values.durations)) if found else None,
                   values.ac_scale if found else None, r.constraint_violation,
                   None if run is None else run.verified, chosen, candidate.projected)


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
    classes : tuple of ClassTried
        For a MinTime or MinAcceleration rendezvous: each turn count on the body it
        looked at, in the order solved (empty for other problems).
    classes_skipped : str
        One line: the classes it did not look at, and why.
    nearest_feasible : edge.Edge or None
        For a fixed-time solve that found no point: the shortest flight found feasible
        from the same departure (:func:`nearest_feasible`; its ``flight`` is a Run).
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
    classes: Tuple[ClassTried, ...] = ()
    classes_skipped: str = ""
    nearest_feasible: Optional[edge.Edge] = None

    @property
    def outcome(self):
        """The :class:`Outcome` of the closed-form solve the run ended with."""
        return self.result.outcome


def _quiet(text):
    """The progress callback of a caller that wants none."""


def solve(problem, segments=None, progress=None, polish=False):
    """Run the whole pipeline on ``problem``.

    A MinTime or MinAcceleration rendezvous at a fixed departure also looks at the turn
    counts on the body beside the one its seed found (``classes.ClassSearch``) and
    returns the best one whose flight is verified (``Run.classes`` records each).  A
    fixed-time problem with a target that no start finds a point for walks its time of
    flight to the shortest feasible one from the same departure
    (``Run.nearest_feasible``); the run itself stays not verified.

    Parameters
    ----------
    problem : Problem
    segments : int, optional
        Override the problem's number of control segments N (>= 1).
    progress : callable, optional
        ``progress(text)`` is called at each stage and every few seconds of Ipopt.
    polish : bool
        Then polish the optimum (``optimisation.polish``) and verify that schedule too.

    Returns
    -------
    Run

    Raises
    ------
    InputError
        ``segments`` is not an integer >= 1 (before any solve starts).
    NoStart
        No seed can be flown (``seed.initial_guess``): nothing is solved.
    """
    if segments is not None:
        if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
            raise InputError(f"segments = {segments!r} is outside [1, inf)")
        problem = problem.with_segments(segments)
    say = progress or _quiet
    return _polished(_lone(problem, say), polish, say)


def _lone(problem, say, walk=True):
    """The run of :func:`solve` before the polish; ``walk`` False leaves out the walk to
    the shortest feasible flight (:func:`nearest_feasible`, whose rungs are such
    runs).  A 3-D problem's turn counts are searched on its projected model, the best
    lifted (``classes.ClassSearch``), and in 3-D where that leaves no candidate."""
    spent = []
    if problem.three_d() and multistart.searches_classes(problem):
        search = ClassSearch.on_projected_model(problem, say)
        run = _best_verified(search, say)
        if run is not None:
            return run
        say(f"{problem.name}: no turn count lifted into 3-D converged; searching them in 3-D")
        spent = search.solves
    run = _solved(problem, say, walk)
    # The run's Ipopt record covers the projected search it gave up, too.
    return dataclasses.replace(run, result=run.result.after(*spent, stages=False))


def _solved(problem, say, walk=True):
    """The run of :func:`_lone` on ``problem``'s own model."""
    sub_arcs = problem.segments.sub_arcs
    problem, result, tr, starts = _first_solve(problem, say)
    if result.outcome.found and multistart.searches_classes(problem):
        run = _best_verified(ClassSearch(problem, seed=lambda: (problem, result, tr), say=say),
                             say, starts, sub_arcs)
    else:
        run = finish(problem, result, tr, progress=say, starts=starts,
                     sub_arcs_requested=sub_arcs)
        run = dataclasses.replace(run, classes_skipped=_unsearched(problem))
    if walk and not result.outcome.found and edge.walks(problem):
        run = dataclasses.replace(run, nearest_feasible=nearest_feasible(
            problem, progress=say))
    return run


def _first_solve(problem, say):
    """The seed's solve (a free date's from the scan that chose it), and the other
    starts when it found no point: (problem as solved, NLPResult, Transcription,
    starts tried)."""
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
    result, tr = per_revolution_mesh(problem, result, tr, say)
    if seed is not None:
        # The scan that chose the date is part of the run's Ipopt record.
        result.iterations += seed.iterations
        result.solve_seconds += seed.seconds
    say(f"{problem.name}: {result.status} after {result.iterations} iterations; "
        + ("error control until the flight meets the tolerance" if result.outcome.found
           else "no start found a point; flying the last iterate to report its miss"))
    return problem, result, tr, starts


def _unsearched(problem):
    """Why a run looked at no class beside its seed's (``Run.classes_skipped``)."""
    if not problem.tracks_body():
        return ("revolution windows: not searched by a lone solve (esail-opt search "
                "solves one per window)")
    if multistart.searches_classes(problem):
        return "none: no start found a point to compare the other turn counts with"
    return ("turn counts on the body other than the seed's: not searched for this "
            "objective or departure (esail-opt search solves one per turn count)")


def _other_starts(problem, result, tr, say):
    """Ipopt's "infeasible" from one start is a local statement: before giving up, try
    the starts the global search would (other turn counts on a rendezvous body, other
    constant-pitch seeds of an orbit transfer), and keep the first that finds a point.
    Each is a probe (``multistart.probe``) capped at ``multistart.probe_cap`` of the
    first start's iterations, at least ``multistart.FALLBACK_MIN``: from 2035-06-01 to
    Mars in 600 d, where no sail exists, two of the uncapped starts took 3,000 and 1,842
    iterations to fail.

    Returns the (result, transcription) to go on with and a StartTried per start.
    """
    records = [StartTried("the problem's own seed", result.status, result.iterations)]
    if problem.target is None or getattr(problem.departure, "free_anomaly", False):
        return result, tr, tuple(records)
    seconds = result.solve_seconds
    cap = multistart.probe_cap(result.iterations, multistart.FALLBACK_MIN)
    for start in multistart.fallback_starts(problem, tr.guess):
        say(f"{problem.name}: {result.status}; trying {start.label} ({cap} Ipopt "
            "iterations at most unless nearly feasible)")
        other, other_tr = multistart.probe(problem, start.guess, cap, say)
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


def _best_verified(search, say, starts=(), requested=None):
    """The run of the best solved candidate of ``search`` whose flight is verified, or
    of the best if none is (None without one); its ``classes`` record each class the
    search looked at, with the verdicts of those flown."""
    found = [c for c in search.run() if c.solved]
    if not found:
        return None
    # Taken before the finishing makes each result's record the run's.
    spent = [c.result.iterations for c in search.looked_at]
    seconds = sum(c.result.solve_seconds for c in search.looked_at)

    def fly(candidate):
        result = candidate.result
        # The run's Ipopt record covers every class it solved.
        result.iterations, result.solve_seconds = sum(spent), seconds
        if len(found) > 1:
            say(f"{candidate.problem.name}: flying the turn count k = {result.revolutions_k}")
        return finish(candidate.problem, result, candidate.transcription, progress=say,
                      starts=starts, sub_arcs_requested=requested)

    runs = finish_best_first(found, fly)
    chosen = next((run for run in runs if run.verified), runs[0])
    flown = {id(c): run for c, run in zip(found, runs)}
    classes = tuple(ClassTried.of(c, it, flown.get(id(c)), flown.get(id(c)) is chosen)
                    for c, it in zip(search.looked_at, spent))
    return dataclasses.replace(chosen, classes=classes, classes_skipped=search.skipped)


def nearest_feasible(problem, start=None, progress=None):
    """The edge of the feasible from ``problem``'s departure (``edge.nearest_feasible``:
    ``problem`` is a fixed-time problem that found no point, ``start`` an optional
    verified flight at a longer time of flight), its flight flown by :func:`finish`; a
    rung of its ladder whose seed finds no point is a lone solve without a walk of its
    own (:func:`_lone`).  An ``edge.Edge``, or None when the walk found none."""
    return edge.nearest_feasible(problem, _unwalked, finish, start, progress)


def _unwalked(problem, say):
    """A lone solve of ``problem`` (:func:`_lone`) without the walk to the edge: a rung
    of the walk's ladder."""
    return _lone(problem, say, walk=False)


def finish(problem, result, tr=None, polish=False, progress=None, starts=(),
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
    polish, progress
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
        # A class other than the first solve's may fly more turns on the same mesh.
        result, tr = per_revolution_mesh(problem, result, tr, say)
        # Its last round's verification is the run's.
        controlled = control_error(problem, result, tr, say)
        # The run's Ipopt record covers the first solve and every round after it.
        iterations = result.iterations + sum(r.iterations for r in controlled.history[1:])
        seconds = result.solve_seconds + controlled.history[-1].seconds
        problem, result, tr = controlled.problem, controlled.result, controlled.transcription
        result.iterations, result.solve_seconds = iterations, seconds
        check = controlled.check
    else:
        check = verify(problem, result)
    verified, note = verdict(problem, result, check, starts)
    run = Run(problem=problem, result=result, transcription=tr, starts=tuple(starts),
              error_control=controlled, check=check, verified=verified, note=note,
              sub_arcs_requested=requested)
    return _polished(run, polish, say)


def verdict(problem, result, check, starts=()):
    """(verified, note) of ``result`` flown as ``check``: the flight is judged.  A point
    Ipopt left at its acceptable level whose flight meets every bound is verified, and
    the note says that its optimality, not the flight, is unproven; any other point
    Ipopt did not converge to is not verified, the note saying why."""
    verified, note = check.judge(problem)
    if result.outcome is Outcome.ACCEPTABLE and verified:
        return True, (note + "; Ipopt stopped at its acceptable level, so the flight is "
                      "verified but its optimality is not proven (another mesh, "
                      "--segments N, or --polish checks it)")
    if not result.converged:
        return False, f"NOT verified: Ipopt ended {result.status}" + (
            "" if result.outcome is not Outcome.INFEASIBLE else
            f" from {len(starts) or 1} start(s); no start found a feasible point, which "
            "does not prove the target unreachable" + _window_hint(problem)
            + _mesh_hint(result) + _always_on_hint(problem))
    return verified, note


#: Fewer segments than this may be why no start found a point: the note says so.
FEW_SEGMENTS = 8


def _window_hint(problem):
    """The failure note's word on an arrival window: a window the flight must arrive in
    may be all that leaves no point (a transfer found without it arrived later)."""
    window = getattr(problem.target, "arrival_window", None)
    if window is None:
        return ""
    return (f"; the arrival must fall in target.arrival_window = {tuple(window)!r}, which "
            "may be why no point was found: without it a later arrival may be")


def _mesh_hint(result):
    """The failure note's word on a coarse mesh: with a handful of segments the pitch
    takes a handful of values, and no such schedule may arrive (Mercury to Venus on 3
    segments found no point; on 20 it took 262.4 d)."""
    n = result.alpha.size
    if n >= FEW_SEGMENTS:
        return ""
    return (f"; on {n} segments the pitch takes only {n} values: more segments "
            "(segments.count) may find a point")


def _always_on_hint(problem):
    """The failure note's advice for a minimum-time arrival on an orbit (a rendezvous
    or an orbit target) with a sail always on: a throttle.

    Why: an E-sail's radial thrust never falls below about half of its full value at that
    distance, so a sail always on always pushes outward, and at a few mm/s^2 that push
    is a large part of the Sun's pull beyond 1 au.  Such arrivals can find no point
    from any start and be solved with a throttle (results/bench/README.md, section
    "Minimum time with the sail always on").  A fixed time of flight fails for other
    reasons (too short a flight), and an intercept does not match a velocity."""
    if (problem.throttled() or problem.objective.fixed_time
            or not getattr(problem.target, "matches_velocity", True)):
        return ""
    return ("; the sail was always on, and an E-sail always pushes outward: "
            "Sail(throttle=True) lets it lower its tether voltage, which an arrival on "
            "an orbit at a high a_c may need")


def _polished(run, polish, say):
    """``run`` with its polish, when asked for."""
    if not polish:
        return run
    return dataclasses.replace(run, polish=_polish(run.problem, run.result, say))


def _polish(problem, result, say):
    """Polish ``result`` and judge the polished flight against :data:`POLISH_TOLERANCE`."""
    # A closed form that found no optimum has nothing worth polishing.
    if not result.outcome.found:
        return PolishRun(None, None, False,
                         f"NOT polished: the closed-form solve ended {result.status}",
                         closed_form_objective=result.objective)
    say(f"{problem.name}: polishing on {problem.equations()} in time, exactly "
        f"({result.alpha.size} segments)")
    exact, _ = polishing.polish(problem, result)
    say(f"{problem.name}: polish {exact.status} after {exact.iterations} iterations; "
        "verifying on CVODES")
    check = verify(problem, exact)
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

