"""The data path of one run, returned as a typed :class:`Run`: seed -> closed-form NLP ->
Ipopt -> other starts -> the turn counts beside the answer's -> error control -> CVODES
verification -> polish (or, for a fixed time with no point, the walk to the shortest
feasible time of flight, ``optimisation.edge``).

The application calls :func:`solve` or :func:`run_from_optimum`.  A stage runs on the
:class:`Outcome` of the one before (``Outcome.found``: converged or acceptable).  Nothing here
changes a result; it decides what runs next and adds up Ipopt's iterations and seconds over
the run.
"""

import dataclasses
from dataclasses import dataclass
from typing import Optional, Tuple

from esail_opt.errors import InputError
from esail_opt.optimisation import edge, multistart, scan
from esail_opt.optimisation import polish as polishing
from esail_opt.optimisation.classes import ClassSearch, fly_best_first
from esail_opt.optimisation.error_control import (MAX_SUB_ARCS, ErrorControl, Round, control_error,
                                                  per_revolution_mesh, sub_arcs_within_cap)
from esail_opt.optimisation.ipopt import (NLPResult, ipopt_options, primal_warm_options,
                                          solve_problem)
from esail_opt.optimisation.outcome import Outcome
from esail_opt.optimisation.problem import Problem, Tolerance
from esail_opt.optimisation.seed import fallback_starts, initial_guess
from esail_opt.optimisation.transcription import Transcription
from esail_opt.optimisation.verify import Verification, verify, within

__all__ = ["Outcome", "Round", "StartTried", "ClassTried", "PolishRun", "Run", "solve",
           "run_from_optimum", "nearest_feasible", "POLISH_TOLERANCE"]

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

    ``label``: where its start came from; ``revolutions_k``: whole turns between sail and body
    at arrival; ``status``, ``iterations``: of its last Ipopt solve
    ("Maximum_Iterations_Exceeded" for a probe at its cap, "User_Requested_Stop" for one stopped
    as hopeless); ``objective`` (canonical), ``tof`` (TU), ``ac_scale`` (a_c over the sail's):
    None without a point, and for a flown class its run's, after the error control;
    ``constraint_violation`` of its last point; ``verified``: None if not flown; ``chosen``: the
    class the run returns; ``projected``: its values are its projected model's (a 3-D run's
    class not lifted, ``classes.ClassSearch``).
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
        """The record of a ``classes.Candidate`` that took ``iterations``, with its ``run``'s
        verdict and values when finished (the error control may move the optimum)."""
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
    """The polish of a run: the optimum re-solved on Eqs. 1-2 in time (``optimisation.polish``;
    ``result`` None when the closed form found nothing to polish), and ``check`` its CVODES
    flight.  ``verified``: Ipopt converged and the flight, its verifier's error included, is
    within ``tolerance`` of the target (``within_target``, True without one) and of the polished
    NLP's final node (``within_nlp``); ``note`` says so, or why not."""

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

    ``problem`` as last solved (the segments used, the error control's final sub-arcs;
    ``sub_arcs_requested`` the problem file's); ``result`` the closed-form optimum after the
    error control (else the last solve), its ``iterations`` and ``solve_seconds`` covering every
    solve before the polish, ``transcription`` its NLP; ``starts`` those tried when the first
    found no point; ``error_control`` None when the closed form found nothing; ``check``
    ``result``'s CVODES flight, ``verified`` when Ipopt converged and it meets
    ``problem.tolerance`` with the verifier's error added, ``note`` the verdict in one line;
    ``polish`` only when asked for; ``classes`` each turn count a MinTime or MinAcceleration
    rendezvous looked at, in solve order, ``classes_skipped`` those it did not and why;
    ``nearest_feasible``, for a fixed time with no point, the shortest flight found feasible
    from the same departure (an ``edge.Edge`` whose ``flight`` is a Run).
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
    """Run the whole pipeline on ``problem``: a :class:`Run`.

    A MinTime or MinAcceleration rendezvous at a fixed departure also looks at the turn counts
    on the body beside its seed's (``classes.ClassSearch``) and returns the best one whose
    flight is verified (``Run.classes`` records each).  A fixed-time problem whose target no
    start finds a point for walks its time of flight to the shortest feasible one from the same
    departure (``Run.nearest_feasible``); the run itself stays not verified.

    ``segments`` (>= 1) overrides the problem's count N; ``progress(text)`` is called at each
    stage and every few seconds of Ipopt; ``polish`` then polishes the optimum and verifies that
    schedule too.  Raises InputError for bad ``segments`` and NoStart when no seed can be flown,
    both before any solve.
    """
    if segments is not None:
        if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
            raise InputError(f"segments = {segments!r} is outside [1, inf)")
        problem = problem.with_segments(segments)
    say = progress or _quiet
    run = _run_before_polish(problem, say)
    return _polished(run, polish, say)


def _run_before_polish(problem, say, walk=True):
    """The run of :func:`solve` before the polish, without the walk to the shortest feasible
    flight when ``walk`` is False (as for :func:`nearest_feasible`'s longer solves).  A 3-D
    problem's turn counts are searched on its projected model, the best lifted
    (``classes.ClassSearch``), and in 3-D where that leaves no candidate."""
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
    """The run of :func:`_run_before_polish` on ``problem``'s own model."""
    sub_arcs = problem.segments.sub_arcs
    problem, result, tr, starts = _first_solve(problem, say)
    if result.outcome.found and multistart.searches_classes(problem):
        run = _best_verified(ClassSearch(problem, seed=lambda: (problem, result, tr), say=say),
                             say, starts, sub_arcs)
    else:
        run = run_from_optimum(problem, result, tr, progress=say, starts=starts,
                     sub_arcs_requested=sub_arcs)
        run = dataclasses.replace(run, classes_skipped=_unsearched(problem))
    if walk and not result.outcome.found and edge.walks(problem):
        try:
            run = dataclasses.replace(run, nearest_feasible=nearest_feasible(
                problem, progress=say))
        except edge.NoLongerPoint as none:
            run = dataclasses.replace(run, note=f"{run.note}; {none}")
    return run


def _first_solve(problem, say):
    """The seed's solve (a free date's from the scan that chose it), and the other starts when
    it found no point: (problem as solved, NLPResult, Transcription, starts tried)."""
    seg = problem.segments
    count = (f"{seg.count} segments" if seg.per_revolution is None
             else f"{seg.per_revolution} segments per revolution")
    guess, seed = None, None
    if problem.free_date():
        seed = scan.seed_free_date(problem, say)
        problem, guess = seed.problem, seed.guess
    # A free date's guess is its best date's optimum: a start Ipopt keeps to, unstaged.
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
    """Ipopt's "infeasible" from one start is a local statement: before giving up, try the
    starts the global search would (other turn counts on a rendezvous body, other constant-pitch
    seeds of an orbit transfer), and keep the first that finds a point.  Each is a probe capped
    at ``multistart.probe_cap`` of the first start's iterations (at least
    ``multistart.FALLBACK_MIN``), as where no sail exists an uncapped start can take thousands
    of iterations to fail.  Returns the (result, transcription) to go on with and a StartTried
    per start."""
    records = [StartTried("the problem's own seed", result.status, result.iterations)]
    if problem.target is None or getattr(problem.departure, "free_anomaly", False):
        return result, tr, tuple(records)
    seconds = result.solve_seconds
    cap = multistart.probe_cap(result.iterations, multistart.FALLBACK_MIN)
    for start in fallback_starts(problem, tr.guess):
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
        return run_from_optimum(candidate.problem, result, candidate.transcription, progress=say,
                      starts=starts, sub_arcs_requested=requested)

    runs = fly_best_first(found, fly)
    chosen = next((run for run in runs if run.verified), runs[0])
    flown = {id(c): run for c, run in zip(found, runs)}
    classes = tuple(ClassTried.of(c, it, flown.get(id(c)), flown.get(id(c)) is chosen)
                    for c, it in zip(search.looked_at, spent))
    return dataclasses.replace(chosen, classes=classes, classes_skipped=search.skipped)


def nearest_feasible(problem, start=None, progress=None):
    """The edge of the feasible from ``problem``'s departure (``edge.nearest_feasible``:
    ``problem`` is a fixed-time problem that found no point, ``start`` an optional
    verified flight at a longer time of flight), its flight flown by :func:`run_from_optimum`; a
    longer solve whose seed finds no point is a lone solve without a walk of its own
    (:func:`_run_before_polish`).  An ``edge.Edge``; without ``start``, raises
    ``edge.NoLongerPoint`` when no longer flight converges."""
    return edge.nearest_feasible(problem, _unwalked, run_from_optimum, start, progress)


def _unwalked(problem, say):
    """A lone solve of ``problem`` without the walk to the edge: one of the walk's longer solves."""
    return _run_before_polish(problem, say, walk=False)


def run_from_optimum(problem, result, tr=None, polish=False, progress=None, starts=(),
           sub_arcs_requested=None):
    """The stages after a closed-form optimum ``result`` of ``problem``: error control, CVODES
    verification and, with ``polish``, the polish; a :class:`Run`.  A ``result`` not found is
    only verified, its note saying why.  ``tr``, ``result``'s NLP, is re-solved warm by the
    error control (else one is built), keeping ``result``'s turn count; ``starts``: those tried
    before this one; ``sub_arcs_requested``: the problem file's sub-arcs when the seed raised
    them."""
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
    """(verified, note) of ``result`` by its flight ``check``.  A point Ipopt left at its
    acceptable level whose flight meets every bound is verified, its optimality unproven (the
    note says so); any other point Ipopt did not converge to is not, the note saying why."""
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
    takes a handful of values, and no such schedule may arrive."""
    n = result.alpha.size
    if n >= FEW_SEGMENTS:
        return ""
    return (f"; on {n} segments the pitch takes only {n} values: more segments "
            "(segments.count) may find a point")


def _always_on_hint(problem):
    """The failure note's advice for a minimum-time arrival on an orbit with a sail always on: a
    throttle.  An E-sail's radial thrust never falls below about half its full value, so at a
    few mm/s^2 it pushes outward by a large part of the Sun's pull beyond 1 au
    (results/bench/README.md, "Minimum time with the sail always on").  A fixed time fails for
    other reasons, and an intercept matches no velocity."""
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

