"""``esail-opt-bench figures``: the two figures of a solve, drawn by the figures' worker
as ``esail-opt solve --polish`` draws them (the timeline's closed form drawn while the
polish runs) and as it draws them without a draft, against the same figures drawn one
after the other in this process."""

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from esail_opt.bench.timing import print_table

#: The solve whose figures are drawn: the README's main job, polished.
PROBLEM = "earth_mars_min_time"
#: Seconds given to a new worker to import matplotlib and make the timeline's frame, as
#: the solve gives it, before its figures are timed.
READY_SECONDS = 3.0


def _pixels(paths):
    from PIL import Image

    return {Path(p).name: np.asarray(Image.open(p)) for p in paths}


def _worker_seconds(solution, out, throttled, drafted=False):
    """Hand-over to files written, through a worker started :data:`READY_SECONDS`
    before (``drafted``: and handed the solution's draft then, as before a polish);
    returns (seconds, paths)."""
    from esail_opt.app.plot_worker import PlotWorker

    with PlotWorker(throttled=throttled) as worker:
        if drafted:
            worker.draft(solution.without_polish())
        time.sleep(READY_SECONDS)
        start = time.perf_counter()
        worker.start(solution, out)
        paths = worker.written()
        return time.perf_counter() - start, paths


def _here_seconds(solution, out):
    from esail_opt.app import plots

    start = time.perf_counter()
    paths = plots.write_plots(solution, out)
    return time.perf_counter() - start, paths


def run(out, repeats):
    """Solve :data:`PROBLEM` with its polish, then draw its figures ``repeats`` times
    each way (at most 5), alternating; writes ``figures.json`` and returns its path.

    The worker's time runs from :meth:`~esail_opt.app.plot_worker.PlotWorker.start` to
    :meth:`~esail_opt.app.plot_worker.PlotWorker.written` returning, which is what the
    main job waits for after its solve; the baseline is
    :func:`esail_opt.app.plots.write_plots` in this process, which has drawn them once
    before (matplotlib imported, its caches warm).  Both ways must give the same pixels.
    """
    import esail_opt as eo
    from esail_opt.app.files import write_json
    from esail_opt.optimisation.problem_file import shipped_problem

    runs = max(1, min(repeats, 5))
    print(f"bench figures: solving {PROBLEM} with its polish ...", flush=True)
    problem = shipped_problem(PROBLEM)
    solution = eo.solve(problem, polish=True)
    throttled = problem.throttled()
    timed = {"drafted": [], "worker": [], "here": []}
    with tempfile.TemporaryDirectory(prefix="esail_bench_figures_") as tmp:
        ways = {"drafted": lambda: _worker_seconds(solution, Path(tmp), throttled, True),
                "worker": lambda: _worker_seconds(solution, Path(tmp), throttled),
                "here": lambda: _here_seconds(solution, Path(tmp))}
        # One untimed run each (imports, compiles, caches), whose pixels are compared.
        drawn = {way: _pixels(draw()[1]) for way, draw in ways.items()}
        for k in range(runs):
            print(f"bench figures: run {k + 1}/{runs} ...", flush=True)
            for way, draw in ways.items():
                timed[way].append(draw()[0])
    same = all(drawn[way].keys() == drawn["here"].keys()
               and all(np.array_equal(drawn[way][k], drawn["here"][k]) for k in drawn["here"])
               for way in ("drafted", "worker"))
    drafted, worker, here = (statistics.median(timed[way]) for way in ("drafted", "worker",
                                                                       "here"))
    data = {
        "case": {"problem": PROBLEM, "polished": True, "figures": sorted(drawn["here"])},
        "runs": runs,
        "drafted_worker_seconds": drafted,
        "worker_seconds": worker,
        "in_process_seconds": here,
        "ratio_in_process_over_drafted_worker": here / drafted,
        "ratio_in_process_over_worker": here / worker,
        "drafted_worker_runs_seconds": timed["drafted"],
        "worker_runs_seconds": timed["worker"],
        "in_process_runs_seconds": timed["here"],
        "same_pixels": same,
        "how": "worker: PlotWorker.start to PlotWorker.written returning, the worker started "
               f"{READY_SECONDS:g} s before (drafted: and handed the timeline's draft "
               "then); in process: plots.write_plots; medians over alternating runs after "
               "one untimed run each",
    }
    print_table(f"bench figures: {PROBLEM} polished, median of {runs}", [
        ("worker with the draft (hand-over to files written)", drafted, "s"),
        ("worker without a draft", worker, "s"),
        ("in this process, one after the other", here, "s"),
        ("ratio in process / worker with the draft",
         data["ratio_in_process_over_drafted_worker"], ""),
        ("ratio in process / worker", data["ratio_in_process_over_worker"], ""),
        ("same pixels", str(same), ""),
    ])
    path = Path(out) / "figures.json"
    write_json(path, data)
    return path
