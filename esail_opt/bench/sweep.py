"""``esail-opt-bench sweep``: a sweep's wall time on a process pool of 1 worker against
2, the same sweep, one run."""

import os
import statistics
import tempfile
import time
from pathlib import Path

from esail_opt.bench.timing import print_table, runs_of

#: The sweep's problem file (its workers load its text): Earth-Mars minimum time, coarser
#: than the shipped one so that each member takes seconds, not the bench minutes.
SWEEP_SOURCE = '''
import esail_opt as eo

problem = eo.Problem(
    name="bench_sweep_earth_mars",
    departure=eo.ParkingOrbit(a_au=1.0),
    sail=eo.Sail(ac_mm_s2=1.0),
    segments=eo.Segments(count=20, sub_arcs=2),
    objective=eo.MinTime(),
    target=eo.CircularOrbit(radius_au=1.524),
)
'''
#: The sweep's parameter: 8 values of a_c in [0.6, 1.6] mm/s^2.
SWEEP_PARAM = "ac_mm_s2=0.6:1.6:8"


def _timed_sweeps(path, runs):
    """Run the sweep of the problem file at ``path`` ``runs`` times on each pool size,
    alternating; returns {workers: (wall seconds, sums of member seconds)} and the last
    rows of each, without their times."""
    from esail_opt.app import sweep as family

    timed = {1: ([], []), 2: ([], [])}
    rows = {}
    for run in range(runs):
        for workers in (1, 2):
            print(f"bench sweep: run {run + 1}/{runs}, {workers} worker(s) ...", flush=True)
            start = time.perf_counter()
            result = family.run(path, SWEEP_PARAM, workers=workers)
            timed[workers][0].append(time.perf_counter() - start)
            timed[workers][1].append(sum(r["seconds"] for r in result["rows"]))
            rows[workers] = [{k: v for k, v in row.items() if k != "seconds"}
                             for row in result["rows"]]
    return timed, rows


def run(out, repeats):
    """One sweep on 1 worker and on 2; writes ``sweep.json`` and returns its path.

    The members (:data:`SWEEP_SOURCE` over :data:`SWEEP_PARAM`) outweigh the pool's start-up.
    The wall time covers the whole ``sweep.run`` (pool start, every member, shutdown); the
    pool sizes alternate over ``runs_of(repeats)`` runs and the medians count, so that a
    burst of load hits both alike.  Whether both return the same rows is recorded.
    """
    from esail_opt.app.outputs import write_json

    runs = runs_of(repeats)
    # Recorded so that a ratio near 1 on a busy machine reads as what it is.
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="esail_bench_sweep_") as tmp:
        path = Path(tmp) / "bench_sweep_earth_mars.py"
        path.write_text(SWEEP_SOURCE)
        timed, rows = _timed_sweeps(path, runs)
    one, two = statistics.median(timed[1][0]), statistics.median(timed[2][0])
    data = {
        "case": {"problem": "Earth-Mars minimum time, 1 au -> 1.524 au, 20 segments x 2 "
                            "sub-arcs", "param": SWEEP_PARAM, "members": len(rows[1])},
        "runs": runs,
        "cpus": os.cpu_count(),
        "one_worker_seconds": one,
        "two_workers_seconds": two,
        "ratio": one / two,
        "one_worker_runs_seconds": timed[1][0],
        "two_workers_runs_seconds": timed[2][0],
        "member_seconds_sum_one_worker": statistics.median(timed[1][1]),
        "member_seconds_sum_two_workers": statistics.median(timed[2][1]),
        "load_average_1_5_15_before": list(load_before),
        "load_average_1_5_15_after": list(os.getloadavg()),
        "converged": sum(1 for r in rows[1] if r["converged"]),
        "identical_rows": rows[1] == rows[2],
        "how": "wall time of esail_opt.app.sweep.run (spawned process pool start, all members, "
               "shutdown), median over alternating runs, same machine and run; ratio = "
               "one_worker_seconds / two_workers_seconds (2 would be perfect scaling)",
    }
    print_table(f"bench sweep: {data['case']['members']} members, median of {runs}", [
        ("1 worker", one, "s"),
        ("2 workers", two, "s"),
        ("ratio 1 / 2 workers", data["ratio"], ""),
        ("sum of member times, 1 worker", data["member_seconds_sum_one_worker"], "s"),
        ("load average before / after",
         f"{load_before[0]:.2f} / {data['load_average_1_5_15_after'][0]:.2f}", ""),
        ("identical rows", str(data["identical_rows"]), ""),
    ])
    path = Path(out) / "sweep.json"
    write_json(path, data)
    return path
