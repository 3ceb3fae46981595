"""``esail-opt-bench plots``: the main job's two figures, drawn as ``solve`` draws them
(the timeline in a forked child while the trajectory is drawn here) against one after
the other in this process, timed in one run.

The solution is the main job's (``earth_mars_min_time``, polished, as ``esail-opt solve
problems/earth_mars_min_time.py --polish`` writes it), solved once before the timing.
Both ways draw the same figures into PNG files of the same bytes; only the wall time of
drawing and writing them is compared.
"""

import tempfile
from pathlib import Path

from esail_opt.app import plots
from esail_opt.app.files import save_figure, write_json
from esail_opt.app.solution import solve
from esail_opt.bench.timing import median_seconds, print_table
from esail_opt.optimisation.problem_file import shipped_problem

PROBLEM = "earth_mars_min_time"


def _one_after_the_other(solution, folder):
    save_figure(plots.trajectory_figure(solution), folder / "trajectory.png", dpi=plots.DPI)
    save_figure(plots.timeline_figure(solution), folder / "timeline.png", dpi=plots.DPI)


def run(out, repeats):
    """Time :func:`esail_opt.app.plots.write_plots` against drawing the figures one
    after the other; writes ``plots.json`` and returns its path.

    ``ratio`` is serial_seconds / write_plots_seconds, each the median of ``repeats``
    calls after a warm-up (the first figure of a process loads its fonts).
    """
    solution = solve(shipped_problem(PROBLEM), polish=True)
    with tempfile.TemporaryDirectory(prefix="esail_bench_plots_") as scratch:
        at_once, serial = Path(scratch, "at_once"), Path(scratch, "serial")
        at_once.mkdir()
        serial.mkdir()
        parallel_s = median_seconds(lambda: plots.write_plots(solution, at_once), repeats)
        serial_s = median_seconds(lambda: _one_after_the_other(solution, serial), repeats)
        same = all((at_once / n).read_bytes() == (serial / n).read_bytes()
                   for n in ("trajectory.png", "timeline.png"))
    data = {"problem": PROBLEM, "repeats": repeats, "write_plots_seconds": parallel_s,
            "serial_seconds": serial_s, "ratio": serial_s / parallel_s,
            "same_bytes": same,
            "how": "median wall time of drawing and writing trajectory.png and "
                   "timeline.png; write_plots draws the timeline in a forked child"}
    print_table(f"plots: {PROBLEM} (polished), median of {repeats}",
                [("write_plots", parallel_s, "s (timeline in a forked child)"),
                 ("one after the other", serial_s, "s"),
                 ("ratio", serial_s / parallel_s, "(serial / write_plots)"),
                 ("same bytes", str(same), "")])
    path = Path(out) / "plots.json"
    write_json(path, data)
    return path
