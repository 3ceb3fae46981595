"""What every timing benchmark shares: the median of timed calls, the printed table,
and the shooting NLP timed with one segment Function or another.

Machines are shared and noisy, so each bench times its subject against a baseline
measured in the same run; only the ratios mean anything.
"""

import dataclasses
import statistics
import time


def median_seconds(fn, repeats, clock=time.perf_counter):
    """Median time of ``repeats`` calls of ``fn()`` after one warm-up call, by ``clock``
    (wall time by default)."""
    fn()
    times = []
    for _ in range(repeats):
        start = clock()
        fn()
        times.append(clock() - start)
    return statistics.median(times)


def print_table(title, rows):
    """Print ``rows`` of (label, value, unit) under a title, aligned."""
    print(title)
    width = max(len(label) for label, _, _ in rows)
    for label, value, unit in rows:
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"  {label:<{width}}  {text} {unit}".rstrip())


def runs_of(repeats):
    """Timed runs of a whole solve: ``repeats`` capped at 3 (a solve takes seconds)."""
    return max(1, min(repeats, 3))


def equal_lengths(problem):
    """``problem`` with equal segment lengths: one NLP from one start, where a free-length
    problem is solved in two stages."""
    return dataclasses.replace(
        problem, segments=dataclasses.replace(problem.segments, equal=True))


def shooting_methods():
    """The closed-form and the CVODES-arc segment methods (``segment_methods``)."""
    from esail_opt.optimisation.segment_methods import CVODES, ClosedForm

    return {"closed_form": ClosedForm(), "cvodes": CVODES()}


def timed_nlps(problem, guess, methods, runs):
    """Solve the NLP of ``problem`` from ``guess`` (shared, so only the arcs differ) with each
    of ``methods`` (name -> segment method), ``runs`` times each.  Returns name ->
    {"seconds", "iterations", "status", "objective", "result"}: the median wall time of
    ``nlpsol`` construction plus the Ipopt solve (MUMPS, exact Hessian), and the last run's
    :class:`~esail_opt.optimisation.ipopt.NLPResult`.
    """
    from esail_opt.optimisation.ipopt import solve_transcription
    from esail_opt.optimisation.transcription import transcribe

    out = {}
    for name, method in methods.items():
        tr = transcribe(problem, method, guess)
        times = []
        for _ in range(runs):
            start = time.perf_counter()
            result = solve_transcription(tr)
            times.append(time.perf_counter() - start)
        out[name] = {"seconds": statistics.median(times), "iterations": result.iterations,
                     "status": result.status, "objective": result.objective,
                     "result": result}
    return out
