"""The turn-count search of a rendezvous, one for a lone solve and for a scan's cell.

A rendezvous's turn count k (whole turns between the sail and the body at arrival)
splits its feasible set into one basin per k, and Ipopt stays in the basin of its start:
:class:`ClassSearch` looks at the counts, and the caller finishes its ranked candidates
best first until one verifies (:func:`fly_best_first`).
"""

import dataclasses
import math
import threading
from dataclasses import dataclass
from typing import Callable, Optional

import casadi as ca

from esail_opt.optimisation import ipopt, multistart
from esail_opt.optimisation.error_control import (MAX_SUB_ARCS, per_revolution_mesh,
                                                  sub_arcs_within_cap)
from esail_opt.optimisation.ipopt import AT_CAP, STOPPED, NLPResult, solve_problem
from esail_opt.optimisation.problem import Problem
from esail_opt.optimisation.seed import constant_pitch_seeds, initial_guess
from esail_opt.optimisation.transcription import Transcription, segment_threads

__all__ = ["Candidate", "ClassSearch", "Ranked", "Undecided", "fly_best_first"]


class Undecided(Exception):
    """A probe of a count that neither converged nor was judged hopeless by its cap."""


class Ranked:
    """A candidate, ranked by ``solved`` and ``objective`` (+inf when not solved)."""

    @property
    def objective(self):
        return self.result.objective if self.solved else math.inf


@dataclass(frozen=True)
class Candidate(Ranked):
    """One count's solve; ``transcription`` None marks a count left on the projected
    model, ``projected`` one whose values are the projected model's."""

    problem: Problem
    label: str
    result: NLPResult
    transcription: Optional[Transcription]
    projected: bool = False

    @property
    def solved(self):
        return self.transcription is not None and self.result.outcome.found


def _rank(candidate):
    """Solved first, then the smaller objective."""
    return (not candidate.solved, candidate.objective)


@dataclass
class ClassSearch:
    """The turn-count search of ``problem``, over :class:`Ranked` candidates with a ``problem``,
    ``result`` and ``transcription`` (:class:`Candidate`, a scan's ``Cell``).

    ``seed()`` -> (model, NLPResult, Transcription) is the solve on the model searched.
    ``lift(problem, candidate, cap)`` makes a candidate of ``problem`` (on the model's mesh) from an
    optimum of the model within ``cap`` iterations; without it the model's optima are the
    candidates, with it a probe undecided at its cap ends the search.  ``first``: no neighbour
    starts this solve; ``explore``: look beside the seed's count at every solve of a scan.  A scan's
    strategies: ``solve_class(k, best=None)`` a candidate in count k (``multistart.NO_BETTER`` where
    its estimate is far above ``best``), ``from_projected(k)`` count k's candidates lifted from the
    projected model, ``cold()`` one from the seed.

    After :meth:`run`: ``candidates`` in the order made; ``looked_at``, each count probed (lifted
    where it was); ``skipped``, the counts not solved and why; ``solves``, the Ipopt results spent,
    for a caller that gives the search up.
    """

    problem: Problem
    seed: Callable
    lift: Optional[Callable] = None
    say: Callable = lambda text: None
    first: bool = True
    explore: bool = False
    solve_class: Optional[Callable] = None
    from_projected: Optional[Callable] = None
    cold: Optional[Callable] = None
    candidates: list = dataclasses.field(default_factory=list)
    looked_at: list = dataclasses.field(default_factory=list)
    skipped: str = ""
    solves: list = dataclasses.field(default_factory=list)

    @classmethod
    def on_projected_model(cls, problem, say):
        """The search of a 3-D ``problem``'s counts on its projected model
        (``multistart.probe_model``), the best lifted into 3-D (``multistart.lift``): a 3-D
        iteration costs about twice a projected one, and the counts rank nearly alike on both."""
        def seed():
            model = multistart.probe_model(problem)
            guess = initial_guess(model)
            model = sub_arcs_within_cap(model, guess, MAX_SUB_ARCS)
            say(f"{problem.name}: searching the turn counts on the projected model "
                f"({model.segments.sub_arcs} sub-arcs), then lifting the best into 3-D")
            result, tr = solve_problem(model, guess=guess, progress=say)
            return (model,) + per_revolution_mesh(model, result, tr, say)

        def lift(on_mesh, projected, cap):
            result, tr = multistart.lift(on_mesh, projected.result, cap, say)
            return Candidate(on_mesh, f"{projected.label}, solved on the projected model "
                             "and lifted into 3-D", result, tr)

        return cls(problem, seed=seed, lift=lift, say=say)

    def run(self, starts=()):
        """The candidates, ranked best first (solved first, then by objective): the
        given ``starts`` (None left out), then the search's."""
        self.candidates = tried = [c for c in starts if c is not None]
        objective = self.problem.objective
        # The counts are searched from the seed by a lone solve and a scan's first cell.
        searches = (self.first and not self.explore
                    and multistart.searches_classes(self.problem))
        if searches:
            tried += self._searched()
        # A scan's cell of a rendezvous looks on, count by count, from its chains.
        looks_on = self.solve_class is not None and self.problem.tracks_body()
        sizing = objective.free_acceleration
        if looks_on and (self.explore or not ((sizing or searches)
                                              and any(c.solved for c in tried))):
            self._own_classes(tried)
        if looks_on and (sizing or not objective.fixed_time):
            # The best count drifts over a chart; a warm chain keeps its own even when far worse.
            self._descend(tried)
        best = min((c for c in tried if c.solved), key=_rank, default=None)
        if (looks_on and self.from_projected is not None and self.problem.three_d()
                and best is not None and not self.first and not self.explore):
            tried += self.from_projected(best.result.revolutions_k)
        if self.cold is not None and not any(c.solved for c in tried):
            tried.append(self.cold())
        return sorted(tried, key=_rank)

    def _searched(self):
        """The candidates, in the order made: the counts probed from the seed's (:meth:`_probed`)
        and, with a lift, the best lifted, each within ``multistart.LIFT_RATIO`` of the best lifted
        so far.  A count undecided at its cap ends the search: there the projection is a poor guide
        (a count that does not converge on it can be the best in 3-D)."""
        model, result, tr = self.seed()
        self.solves = [result]
        if not result.outcome.found:
            self.say(f"{self.problem.name}: the projected model found no point")
            return []
        try:
            searched = self._probed(model, result, tr)
        except Undecided as why:
            self.say(f"{self.problem.name}: {why}")
            return []
        ks = [c.result.revolutions_k for c in searched]
        self.skipped = (f"turn counts k < {min(ks)} and k > {max(ks)}: not solved (each "
                        "way, the search stops at the first count that does no better "
                        "than the best, or at the second in a row with no point)")
        if self.lift is None:
            self.looked_at = searched
            return list(searched)
        self.looked_at = [dataclasses.replace(
            c, label=f"{c.label}, on the projected model (not solved in 3-D)",
            transcription=None, projected=True) for c in searched]
        on_mesh = dataclasses.replace(self.problem, segments=model.segments)
        cap = multistart.probe_cap(searched[0].result.iterations)
        # Best projected first, one per count (its best projected start).
        order = sorted((i for i, c in enumerate(searched) if c.result.outcome.found),
                       key=lambda i: searched[i].result.objective)
        lifted, best = {}, math.inf
        for i in order:
            k = searched[i].result.revolutions_k
            if searched[i].result.objective > multistart.LIFT_RATIO * best:
                break
            if k not in lifted:
                self.say(f"{self.problem.name}: lifting the turn count k = {k} into 3-D")
                lifted[k] = self.looked_at[i] = self.lift(on_mesh, searched[i], cap)
                best = min(best, lifted[k].objective)
        self.solves = [c.result for c in self.looked_at]
        return list(lifted.values())

    def _probed(self, model, result, tr):
        """The counts beside ``result``'s on ``model``, probed one turn at a time each way while
        each does better, the best from a second start too: :class:`Candidate` in the order solved,
        the seed's first (its k is only what a constant pitch winds, and the objective can change by
        whole factors between counts).  Each probe is capped (``multistart.probe_cap``) and stopped
        when hopeless (``multistart.hopeless_checkpoint``); with a lift, one ending at its cap
        raises :class:`Undecided`.  With two cores (:func:`_runs_ahead`) the count above the seed's
        is probed ahead in a thread (:class:`_Ahead`), to the same candidates."""
        # The found solve's own iterations, not the run's (other starts before it).
        own = dataclasses.replace(result, iterations=sum(it for _, it in result.stages))
        searched = [Candidate(model, f"the seed's class (k = {result.revolutions_k})", own, tr)]
        # Every count's seed comes from the same constant-pitch flights.
        seeds = constant_pitch_seeds(multistart.probe_model(model))
        # A real body's k counts from the turns both bodies made since 2000, so it may be
        # negative; an idealised body's counts from its phase at departure.
        real = getattr(model.target, "body", None) is not None
        cap = multistart.probe_cap(own.iterations)

        k0 = result.revolutions_k
        ahead = []  # the probe of k0 + 1, run in a thread while the search goes down

        def line(k, checkpoint, how=""):
            self.say(f"{model.name}: probing the turn count k = {k}{how}"
                     f" ({cap} Ipopt iterations at most unless nearly feasible"
                     + ("" if checkpoint is None else
                        f", stopped at {checkpoint[0]} if hopeless by then") + ")")

        def probe_class(k, checkpoint):
            return multistart.probe_rendezvous_class(model, k, cap, self.say, checkpoint,
                                                     seeds)

        def best_found():
            return min(c.result.objective for c in list(searched) if c.result.outcome.found)

        def probe(k, start=None):
            checkpoint = multistart.hopeless_checkpoint(own.iterations, best_found())
            made = None
            if start is not None:
                line(k, checkpoint, " again from a second start")
                made = multistart.probe_start(model, start, cap, self.say, checkpoint)
            elif ahead and ahead[0].k == k:
                made = ahead.pop().result(checkpoint)
                if made is None:
                    line(k, checkpoint, " again: the best found since would have stopped "
                                        "it sooner")
            else:
                line(k, checkpoint)
                if k == k0 - 1 and _runs_ahead() and (real or k0 + 1 >= 0):
                    line(k0 + 1, checkpoint, " alongside")
                    ahead.append(_Ahead(k0 + 1, probe_class, own.iterations, best_found))
            if made is None:
                made = probe_class(k, checkpoint)
            other, other_tr, label = made
            searched.append(Candidate(model, label, other, other_tr,
                                      model.three_d() and not other.outcome.found))
            if self.lift is not None:
                self.solves.append(other)
            return other

        def solve_class(k):
            if k < 0 and not real:
                return multistart.NO_BETTER
            other = probe(k)
            if self.lift is not None and other.status == AT_CAP:
                raise Undecided(f"k = {k} ended {other.status} on the projected model")
            if other.outcome.found:
                return searched[-1]
            return multistart.NO_BETTER if other.status == STOPPED else None

        try:
            best, _ = multistart.descend_turns(k0, searched[0], solve_class,
                                               lambda a, b: a.objective < b.objective,
                                               gaps=1)
        finally:
            for left in ahead:  # the search ended before it reached k0 + 1
                left.call_off()
        # One count holds several local optima: the best one is solved from a second
        # start as well, where another constant pitch winds its count.
        k = best.result.revolutions_k
        start = multistart.second_start(model, k, seeds, result.revolutions_k)
        if start is not None:
            probe(k, start)
        return searched

    def _own_classes(self, tried):
        """The count the problem's own seed favours (a warm start keeps its neighbour's),
        and those either side for a first solve or one that explores, added to ``tried``."""
        own = initial_guess(self.problem).revolutions_k
        wanted = [own - 1, own + 1, own] if self.first or self.explore else [own]
        for k in wanted:
            if k not in {c.result.revolutions_k for c in tried if c.result is not None}:
                tried.append(self.solve_class(k))

    def _descend(self, tried):
        """The counts beyond the best of ``tried`` while the objective keeps falling
        (``multistart.descend_turns``), added to ``tried``."""
        solved = {c.result.revolutions_k: c for c in tried if c.solved}
        if not solved:
            return

        def solve_class(k):
            if k in solved:
                return solved[k]
            candidate = self.solve_class(k, min(c.objective for c in tried if c.solved))
            if candidate is multistart.NO_BETTER:
                return candidate
            tried.append(candidate)
            return candidate if candidate.solved else None

        best = min(solved.values(), key=lambda c: c.objective)
        multistart.descend_turns(best.result.revolutions_k, best, solve_class,
                                 lambda a, b: a.objective < b.objective)


def _runs_ahead():
    """Whether a class probe may run in a thread beside the search's: with two cores
    or more for this process, and a CasADi whose symbolics are thread-safe (Ipopt then
    runs without Python's lock, so two probes take the time of one)."""
    return (segment_threads() > 1
            and "CASADI_WITH_THREADSAFE_SYMBOLICS" in ca.CasadiMeta.compiler_flags())


class _Ahead:
    """The probe ``probe(k, checkpoint)`` of count ``k``, in a thread of its own while the search
    goes down; its hopeless test (``multistart.hopeless_checkpoint`` after a solve of
    ``iterations``) judges it against ``best()``, the best found when its checkpoint comes.  The
    search asks for it in turn (:meth:`result`) with the checkpoint it has then, whose best may be
    lower still.  A hopeless test only stops more against a lower best, so the probe run ahead is
    the one the search would have made unless the test would now have stopped it at a checkpoint it
    passed (judged on its objective and violation there); such a probe is called off and made again.
    So the candidates, and their order, are those of probing one count after another."""

    def __init__(self, k, probe, iterations, best):
        self.k, self.seen = k, []  # (objective, violation, stopped) at each checkpoint
        self._stop, self._made = threading.Event(), {}
        start = multistart.hopeless_checkpoint(iterations, best())

        def test(objective, violation):
            now = multistart.hopeless_checkpoint(iterations, best())
            stopped = now is not None and bool(now[1](objective, violation))
            self.seen.append((objective, violation, stopped))
            return stopped

        def run():
            ipopt.STOP.set(self._stop)  # this thread's own Ipopt runs only
            try:
                self._made["value"] = probe(k, None if start is None else (start[0], test))
            except BaseException as err:  # raised where the search asks for it
                self._made["error"] = err

        self._thread = threading.Thread(target=run, name=f"esail_opt probe k = {k}")
        self._thread.start()

    def result(self, checkpoint):
        """The probe's (NLPResult, Transcription, label), or None if ``checkpoint``
        would have stopped it where it went on (it is then called off)."""
        def stale():
            return checkpoint is not None and any(
                checkpoint[1](objective, violation) and not stopped
                for objective, violation, stopped in list(self.seen))

        if stale():
            self.call_off()
            return None
        try:
            self._thread.join()
        except BaseException:  # Ctrl-C or SIGTERM while waiting: stop it too
            self.call_off()
            raise
        if "error" in self._made:
            raise self._made["error"]
        return None if stale() else self._made["value"]

    def call_off(self):
        """Stop the probe at its next Ipopt iteration, and wait for its thread."""
        self._stop.set()
        self._thread.join()


def fly_best_first(ranked, fly):
    """``fly(candidate)`` of each of ``ranked`` in order until a flown one is ``verified``:
    the flown, in that order."""
    flown = []
    for candidate in ranked:
        flown.append(fly(candidate))
        if flown[-1].verified:
            break
    return flown
