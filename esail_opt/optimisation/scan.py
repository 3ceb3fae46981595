"""Many cells of one problem on one NLP: launch-window and flight-time scans.

A cell is the problem at one departure date (and, for a fixed-time objective, one time of
flight), both NLP parameters (``Transcription.parameters``): the NLP and its solver are
built once per revolution class, and each later cell is solved warm from a solved neighbour,
a better start than a seed and cheaper than a build.  A warm start keeps to its neighbour's
basin, so a repair pass (:func:`_repair`) solves cells worse than a neighbour again from it.
Turn counts are searched, and every cell error-controlled and verified, as in a lone solve
(``classes.ClassSearch``).
"""

import dataclasses
import functools
import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from esail_opt.bodies import dates
from esail_opt.errors import InputError
from esail_opt.optimisation import multistart
from esail_opt.optimisation.classes import ClassSearch, Ranked, fly_best_first
from esail_opt.optimisation.ipopt import (NLPResult, build_solver, ipopt_options, solve_problem,
                                          solve_transcription)
from esail_opt.optimisation.error_control import MAX_SUB_ARCS, control_error, sub_arcs_within_cap
from esail_opt.optimisation.problem import Problem
from esail_opt.optimisation.seed import initial_guess, lifted_guess, rendezvous_starts
from esail_opt.optimisation.transcription import Transcription
from esail_opt.optimisation.verify import verify

#: Ipopt iterations for a cold look at another revolution class than the seed's.
CLASS_ITERATIONS = 300
#: A MinAcceleration or MinTime scan looks at the turn counts beside every cell's best, but
#: not at one whose estimated optimum (:meth:`CellSolver.estimate`) is at least LOOK_MARGIN
#: times the cell's best: the estimate erred high by 0.7 % at most on the 3-D porkchop
#: bench (erring low costs only a look; results/bench/README.md).
LOOK_MARGIN = 1.1


def at_date(problem, jd, tof_days=None):
    """``problem`` departing at the Julian date ``jd`` (TDB), its date fixed, and with
    ``tof_days`` given its fixed time of flight too: one change, so that the problem's
    checks see the cell's own date and flight together.  Raises InputError for an
    undated departure or, with ``tof_days``, a free-time objective."""
    if not problem.dated():
        raise InputError(f"departure = {type(problem.departure).__name__}: a scan over "
                         "departure dates needs departure = BodyDeparture(...)")
    departure = dataclasses.replace(problem.departure, date=dates.iso_from_jd(jd), window=None)
    if tof_days is None:
        return dataclasses.replace(problem, departure=departure)
    return dataclasses.replace(problem, departure=departure,
                               objective=_objective_at(problem, tof_days))


def _objective_at(problem, tof_days):
    if not problem.objective.fixed_time:
        raise InputError(f"objective = {type(problem.objective).__name__}: a scan over times "
                         "of flight needs a fixed-time objective (e.g. MinAcceleration)")
    return dataclasses.replace(problem.objective, tof_days=tof_days)


@dataclass(frozen=True)
class Cell(Ranked):
    """One solved cell: its problem, the closed-form optimum and its judged flight."""

    problem: Problem
    result: Optional[NLPResult]
    transcription: Optional[Transcription]
    verified: bool
    note: str
    misses: dict
    seconds: float
    start: str  # where its start came from: "seed", "previous", "next"
    # The optimum on the scan's NLP that warms a neighbour (a grown mesh has another layout).
    on_scan_nlp: Optional[NLPResult] = None
    finished: bool = False  # error-controlled and verified
    defects: Optional[np.ndarray] = None  # what on_scan_nlp was solved with

    @property
    def solved(self):
        return self.result is not None and self.result.outcome.found


class CellSolver:
    """One NLP and one warm Ipopt solver per revolution class k (a rendezvous's turn count
    is part of its NLP's constraints; orbit targets have only k = 0), built on the class's
    first cell, solved cold; its mesh then holds for every cell of the scan."""

    def __init__(self, method=None):
        self.nlps = {}  # k -> (Transcription, (solver, monitor), Segments)
        self.segments = None
        self.method = method
        self.last = {}  # k -> the class's last cell, for a solver of projected cells
        self._projected = None
        self.lifters = {}  # k -> (the class's NLP, a cold Ipopt solver on it) (:meth:`lifted`)

    @property
    def projected(self):
        """The solver of this scan's projected cells (:meth:`from_projected`), made on first
        use: a 3-D scan keeps a chain of them beside its own."""
        if self._projected is None:
            self._projected = CellSolver(self.method)
        return self._projected

    def verified_cell(self, cell):
        """The cell after the error control and the CVODES verification of a lone solve
        (other segment methods than the closed form are only verified)."""
        if cell.finished:
            return cell
        started = time.perf_counter()
        problem, result, tr = cell.problem, cell.result, cell.transcription
        warm_solver = None
        if cell.on_scan_nlp is not None:
            warm_solver = self.nlps[cell.on_scan_nlp.revolutions_k][1]
        controlled = (control_error(problem, result, tr, solver=warm_solver,
                                    defects=cell.defects)
                      if result.outcome.found and self.method is None else None)
        on_scan, defects = cell.on_scan_nlp, None
        if controlled is not None:
            if on_scan is not None:
                k = on_scan.revolutions_k
                if controlled.problem.segments != problem.segments:
                    # The class's NLP keeps the finer mesh, so later cells need not grow it.
                    rtr = controlled.transcription
                    self.nlps[k] = (rtr, build_solver(rtr, warm=True),
                                    controlled.problem.segments)
                    self.segments = controlled.problem.segments
                # Defects change little from cell to cell.
                on_scan, defects = controlled.result, controlled.defects
            problem, result, tr = (controlled.problem, controlled.result,
                                   controlled.transcription)
        check = (controlled.check if controlled is not None
                 else verify(problem, result))
        verified, note = check.judge(problem)
        verified = verified and result.converged
        if not result.converged:
            note = f"NOT verified: Ipopt ended {result.status}"
        return dataclasses.replace(cell, problem=problem, result=result, transcription=tr,
                                   verified=verified, note=note, misses=check.misses,
                                   seconds=cell.seconds + time.perf_counter() - started,
                                   finished=True, on_scan_nlp=on_scan, defects=defects)

    @staticmethod
    def _candidate(problem, result, tr, started, start, on_scan_nlp):
        return Cell(problem, result, tr, False, "not yet verified", {},
                    time.perf_counter() - started, start, on_scan_nlp)

    def _meshed(self, problem, guess):
        if self.segments is None:
            problem = sub_arcs_within_cap(problem, guess, MAX_SUB_ARCS)
            self.segments = dataclasses.replace(problem.segments, count=guess.alpha.size,
                                                per_revolution=None)
        # The mesh is fixed by the first seed: its segment count and capped sub-arcs.
        return dataclasses.replace(problem, segments=self.segments), guess

    def cold(self, problem, k=None, start=None):
        """Solve a cell from its own constant-pitch seed, from turn count ``k``'s seed
        (``seed.rendezvous_starts``), or from ``start``, a class-search optimum in class
        ``k`` (in 3-D, the projected model's, lifted); a class's first cell builds its NLP."""
        started = time.perf_counter()
        label = "seed" if k is None else f"class {k}"
        # A class's seed is a look at another basin, not worth a full iteration budget.
        options = None if k is None else ipopt_options(max_iter=CLASS_ITERATIONS)
        if start is not None and problem.three_d():
            label += ", lifted from the projected model"
            seed = lifted_guess(problem, start.as_guess())
        elif start is not None:
            label += ", from the class search"
            seed = start.as_guess()
        else:
            seed = (initial_guess(problem) if k is None
                    else rendezvous_starts(problem, [k])[0].guess)
        problem, seed = self._meshed(problem, seed)
        # A lifted optimum is a start Ipopt keeps to: no staging from it.
        result, tr = solve_problem(problem, self.method, options=options,
                                   guess=seed, staged=start is None)
        k = result.revolutions_k
        on_scan = None
        if k not in self.nlps and result.outcome.found:
            self.nlps[k] = (tr, build_solver(tr, warm=True), problem.segments)
            on_scan = result
        return self._candidate(problem, result, tr, started, label, on_scan)

    def lifted(self, problem, start):
        """Solve a 3-D cell cold from ``start``, an optimum of its projected model, lifted onto
        the scan's NLP of its class (so neighbours start from it), with :data:`CLASS_ITERATIONS`;
        None where the scan has no NLP of that class, or one of another segment count."""
        k = start.revolutions_k
        if k not in self.nlps:
            return None
        started = time.perf_counter()
        base, _, segments = self.nlps[k]
        problem = dataclasses.replace(problem, segments=segments)
        guess = lifted_guess(problem, start.as_guess())
        if guess.alpha.size != base.segments:
            return None
        tr = dataclasses.replace(base.at(problem), x0=base.start_of(problem, guess))
        if self.lifters.get(k, (None,))[0] is not base:
            self.lifters[k] = (base, build_solver(tr, ipopt_options(max_iter=CLASS_ITERATIONS)))
        result = solve_transcription(tr, solver=self.lifters[k][1])
        return self._candidate(problem, result, tr, started,
                               f"class {k}, lifted from the projected model", result)

    def warm(self, problem, neighbour, label):
        """Solve a cell warm from a neighbour's optimum, on its class's NLP."""
        if neighbour is None or neighbour.on_scan_nlp is None:
            return None
        started = time.perf_counter()
        tr, solver, segments = self.nlps[neighbour.on_scan_nlp.revolutions_k]
        start = neighbour.on_scan_nlp
        if start.w.size != tr.x0.size or start.lam_g.size != tr.lbg.size:
            return None  # solved before its class's mesh was refined
        problem = dataclasses.replace(problem, segments=segments)
        tr = tr.at(problem)
        result = solve_transcription(tr, defects=neighbour.defects, warm=neighbour.on_scan_nlp,
                                     solver=solver)
        cell = self._candidate(problem, result, tr, started, label, result)
        return dataclasses.replace(cell, defects=neighbour.defects)

    def estimate(self, problem, neighbour):
        """The objective of ``problem`` in ``neighbour``'s class, to first order by the
        envelope theorem: the neighbour's optimum plus its multipliers times the change of
        its constraints when the parameters move to ``problem``'s.  None where the
        neighbour cannot start the cell (:meth:`warm`)."""
        if neighbour is None or neighbour.on_scan_nlp is None:
            return None
        tr = self.nlps[neighbour.on_scan_nlp.revolutions_k][0]
        start = neighbour.on_scan_nlp
        if start.w.size != tr.x0.size or start.lam_g.size != tr.lbg.size:
            return None
        here = tr.at(problem).constraints(start.w, neighbour.defects)
        there = tr.at(neighbour.problem).constraints(start.w, neighbour.defects)
        return start.objective + float(np.dot(np.ravel(start.lam_g), here - there))

    def in_class(self, problem, chains, k, best=None):
        """``problem`` solved in count ``k``, warm from its chain's last cell, else cold;
        ``multistart.NO_BETTER`` where that cell's :meth:`estimate` is at least
        :data:`LOOK_MARGIN` times ``best``."""
        estimate = (self.estimate(problem, chains[k])
                    if best is not None and k in chains else None)
        if estimate is not None and estimate >= LOOK_MARGIN * best:
            return multistart.NO_BETTER
        return self.warm(problem, chains.get(k), f"class {k}") or self.cold(problem, k)

    def projected_seed(self, problem):
        """The seed's solve of ``problem``'s projected model on the scan's mesh, where a
        first cell's class search starts: (model, NLPResult, Transcription)."""
        problem, _ = self._meshed(problem, initial_guess(problem))
        model = multistart.probe_model(problem)
        return (model, *solve_problem(model, guess=initial_guess(model)))

    def from_projected(self, problem, k):
        """A list of the 3-D cell solved in count ``k`` from its projected model's optimum
        (warm from the count's last projected cell), lifted; empty where the projected
        model found no point in that count on the scan's segments.  A warm 3-D solve would
        stay in its neighbour's basin, which ended up to 5 % above a lone solve."""
        flat = self.projected
        model = multistart.probe_model(problem)
        start = flat.warm(model, flat.last.get(k), "projected")
        if start is None or not start.solved or start.result.revolutions_k != k:
            start = flat.cold(model, k)
        # A lift flies the projected segments: the scan's NLP must have as many.
        if (not start.solved or start.result.revolutions_k != k
                or start.result.alpha.size != self.segments.count):
            return []
        flat.last[k] = start
        return [self.lifted(problem, start.result) or self.cold(problem, k, start=start.result)]


def scan(cells, progress=None, method=None, neighbours=None, explore=False, on_cell=None):
    """Solve every Problem of ``cells`` (in the order of a path) on one NLP per class:
    a list of :class:`Cell` in the same order.

    ``method`` replaces the closed form as segment method (``segment_methods``), its
    cells verified without the error control; ``neighbours[i]``, the positions of cell
    i's neighbours (default the cells before and after it); ``explore`` solves the turn
    counts either side of every cell's own, not only the first's; ``on_cell(position,
    cell)`` is called as each cell ends the forward pass, which the repair pass may still
    replace; ``progress(text)`` gets one line per cell.
    """
    solver = CellSolver(method)
    say = progress or (lambda text: None)
    n = len(cells)
    if neighbours is None:
        neighbours = [[j for j in (i - 1, i + 1) if 0 <= j < n] for i in range(n)]
    out, classes = _forward(solver, cells, say, explore, on_cell or (lambda i, cell: None))
    _repair(solver, cells, out, classes, neighbours, say)
    return out


def _forward(solver, cells, say, explore, on_cell):
    """The forward pass: each cell solved warm from the one before it (and in its own
    classes, :func:`_candidates`), then settled (:func:`_settle`).  Returns the cells
    and, per cell, the set of revolution classes its solves tried."""
    n = len(cells)
    out = []
    classes = []  # per cell, the revolution classes its solves tried
    chains = {}  # revolution class -> its last cell solved on the scan's NLP
    for i, problem in enumerate(cells):
        ranked, made = _candidates(solver, problem, out[-1] if out else None, chains, explore)
        for c in made:
            if c.on_scan_nlp is not None:
                chains[c.on_scan_nlp.revolutions_k] = c
        out.append(_settle(solver, ranked))
        classes.append({c.result.revolutions_k for c in made if c.result is not None})
        say(_line(i, n, out[-1]))
        on_cell(i, out[-1])
    return out, classes


def _repair(solver, cells, out, classes, neighbours, say):
    """The repair pass, back along the path and forward again, replacing cells of ``out`` in
    place (and adding to ``classes`` the classes tried): a cell is solved again once from each
    neighbour start in a class it has not tried, that this pass solved again, or that did better
    where the cell is a spike (:func:`_spike`); on smooth slopes a neighbour finds nothing new."""
    n = len(cells)
    taken = {}  # (cell, neighbour) -> the neighbour's start last taken for the cell
    renewed = set()  # the cells this pass solved again
    for order in (range(n - 1, -1, -1), range(n)):
        for i in order:
            for j in neighbours[i]:
                other = out[j]
                if other.on_scan_nlp is None or taken.get((i, j)) is other.on_scan_nlp:
                    continue
                k = other.on_scan_nlp.revolutions_k
                if k in classes[i] and j not in renewed and not (
                        _spike(i, out, cells, neighbours) and _rank(other) < _rank(out[i])):
                    continue
                classes[i].add(k)
                taken[(i, j)] = other.on_scan_nlp
                again = _again(solver, cells[i], other, j, out[i])
                if again is not None:
                    out[i] = again
                    renewed.add(i)
                    say(_line(i, n, again) + f" (again, from cell {j + 1})")


def _again(solver, problem, other, j, cell):
    """``problem`` solved again warm from the neighbour ``other`` (cell ``j``) and finished,
    if that ranks better than ``cell``; else None.  Only a better closed-form optimum (or
    any, for a cell that did not verify) is worth its error control."""
    again = solver.warm(problem, other, f"from {j}")
    if again is None or not again.solved:
        return None
    if not (again.objective < cell.objective or not cell.verified):
        return None
    again = solver.verified_cell(again)
    return again if _rank(again) < _rank(cell) else None


def _settle(solver, ranked):
    """The cell among a cell's solves (``ranked``, best first): the best that verifies,
    finished (error control and verification) best first until one does."""
    return min(fly_best_first(ranked, solver.verified_cell), key=_rank)


def _candidates(solver, problem, previous, chains, explore):
    """A cell's solves, ranked best first and in the order made: warm from the previous
    cell, then its turn counts (``classes.ClassSearch``), each warm from its chain in
    ``chains`` or cold; a first cell's searched as a lone solve's."""
    search = ClassSearch(
        problem, first=previous is None, explore=explore,
        seed=functools.partial(solver.projected_seed, problem),
        lift=lambda on_mesh, projected, cap: solver.cold(
            on_mesh, projected.result.revolutions_k, start=projected.result),
        solve_class=functools.partial(solver.in_class, problem, chains),
        from_projected=functools.partial(solver.from_projected, problem),
        cold=functools.partial(solver.cold, problem))
    ranked = search.run([solver.warm(problem, previous, "previous")])
    return ranked, search.candidates


def _spike(i, out, cells, neighbours):
    """Whether cell i is worse than each of its neighbours with the same objective (and
    has at least one)."""
    same = [j for j in neighbours[i] if _comparable(cells[i], cells[j])]
    return bool(same) and all(_rank(out[j]) < _rank(out[i]) for j in same)


def _comparable(a, b):
    """Whether two cells' objectives compare: equal fixed times of flight, or neither fixed."""
    ta = a.objective.tof_days if a.objective.fixed_time else None
    tb = b.objective.tof_days if b.objective.fixed_time else None
    return ta == tb


def _rank(cell):
    """Verified first, then the smaller objective."""
    return (not cell.verified, cell.objective)


def _line(i, n, cell):
    what = (f"{cell.result.status}" if cell.result is not None else "no result")
    if cell.solved:
        factor, unit = cell.problem.objective.shown_as()
        what += f", objective {cell.objective * factor:.6g}{unit}"
    return (f"cell {i + 1}/{n}: {what}, {'verified' if cell.verified else 'NOT verified'}, "
            f"{cell.seconds:.2f} s")


#: Days between the cells of the coarse scan that seeds a free departure date, and the
#: least and most cells it takes.
SEED_SPACING_DAYS = 60.0
SEED_CELLS = (4, 16)


@dataclass(frozen=True)
class Seed:
    """What :func:`seed_free_date` found: the problem on the scan's mesh, the start at its
    best cell (None when no cell converged), and the scan's cost (the Ipopt iterations
    of the cells it kept, its wall seconds), which belongs to the run it seeds."""

    problem: object
    guess: Optional[object]
    iterations: int
    seconds: float


def seed_free_date(problem, progress=None):
    """A start (a :class:`Seed`) for a problem whose departure date is free in a window: the
    best cell of a coarse scan of the window at fixed dates, in 3-D ranked on the projected
    model (:func:`_lifted_seed`) unless its best does not converge in 3-D."""
    if problem.three_d():
        seed = _lifted_seed(problem, progress)
        if seed.guess is not None:
            return seed
        (progress or (lambda text: None))(
            f"{problem.name}: the projected model's best date did not converge in three "
            "dimensions; scanning the window in three dimensions")
        scanned = _scanned_seed(problem, progress)
        return dataclasses.replace(scanned, iterations=scanned.iterations + seed.iterations,
                                   seconds=scanned.seconds + seed.seconds)
    return _scanned_seed(problem, progress)


def _best_date(problem, progress, projected=False):
    """The coarse scan of ``problem``'s window (``projected``: a 3-D problem's projected
    model): (its best solved cell or None, the Ipopt iterations of the cells it kept)."""
    lo, hi = problem.departure.window_jd
    count = int(np.clip(math.ceil((hi - lo) / SEED_SPACING_DAYS) + 1, *SEED_CELLS))
    (progress or (lambda text: None))(
        f"{problem.name}: seeding the free departure date by a scan of {count} dates"
        + (" in the projected model" if projected else ""))
    cells = scan([at_date(problem, jd) for jd in np.linspace(lo, hi, count)], progress,
                 explore=True)
    iterations = sum(c.result.iterations for c in cells if c.result is not None)
    solved = [c for c in cells if c.solved]
    return (min(solved, key=_rank) if solved else None), iterations


def _free_seed(problem, cell_problem, start, iterations, started):
    """The :class:`Seed` of the free-date ``problem`` at ``start``, an optimum of the
    fixed-date ``cell_problem``, on that cell's mesh."""
    meshed = dataclasses.replace(problem, segments=dataclasses.replace(
        cell_problem.segments, count=start.alpha.size, per_revolution=None))
    return Seed(meshed, start.as_guess(), iterations, time.perf_counter() - started)


def _scanned_seed(problem, progress):
    started = time.perf_counter()
    best, iterations = _best_date(problem, progress)
    if best is None:
        return Seed(problem, None, iterations, time.perf_counter() - started)
    return _free_seed(problem, best.problem, best.on_scan_nlp or best.result, iterations,
                      started)


def _lifted_seed(problem, progress):
    """A 3-D free date seeded from the projected model (the plane change moves each date's
    optimum little, and its scan costs a fraction of a 3-D one): its best date's optimum lifted
    (``seed.lifted_guess``) and solved as a 3-D cell; ``guess`` None when either finds nothing."""
    started = time.perf_counter()
    best, iterations = _best_date(multistart.probe_model(problem), progress, projected=True)
    if best is None:
        return Seed(problem, None, iterations, time.perf_counter() - started)
    cell = dataclasses.replace(best.problem, planar=problem.planar)
    start = best.on_scan_nlp or best.result
    result, _ = solve_problem(cell, guess=lifted_guess(cell, start.as_guess()),
                              staged=False, progress=progress)
    iterations += result.iterations
    if not result.outcome.found:
        return Seed(problem, None, iterations, time.perf_counter() - started)
    return _free_seed(problem, cell, result, iterations, started)
