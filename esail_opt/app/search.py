"""The global search job: every revolution class of a minimum-time problem, flown and ranked.

``esail-opt search PROBLEM.py`` runs :func:`esail_opt.optimisation.multistart.search`, finishes
every distinct optimum (:func:`esail_opt.optimisation.pipeline.run_from_optimum`), ranks them
(:func:`_rank_key`) and writes the tables, the figure and the best optimum's files (:func:`write`).
"""

from pathlib import Path

from esail_opt.app.outputs import csv_text, save_figure, write_json

from esail_opt.runtime.files import publish
from esail_opt.app.record import plain
from esail_opt.app.solution import Solution
from esail_opt.errors import FigureError
from esail_opt.optimisation import multistart, pipeline
from esail_opt.physics import constants as units

FIELDS = ("rank", "revolutions", "free_local_optimum", "window_rev", "rendezvous_k",
          "tof_days_closed_form", "tof_days_exact", "verified", "flight_verified",
          "polish_status",
          "closed_form_target_miss_km",
          "polished_target_miss_km", "note", "found_from")


def _rank_key(row):
    """Optima whose flight meets the problem's tolerance first (as a lone solve holds its answer),
    then fastest: on the exact (polished) time where the polish is verified, else the closed form's,
    so that a polish not verifiable to 1 m does not put a faster transfer below a slower one."""
    exact = row["tof_days_exact"] if row["verified"] else None
    return (not row["flight_verified"],
            exact if exact is not None else row["tof_days_closed_form"])


def run(problem, extra_revolutions=2, polish=True, progress=None):
    """Search ``problem`` over its revolution classes (``multistart.search``, whose
    ``extra_revolutions`` this is); verify, ``polish`` (on Eqs. 1-2; else the ranking uses
    closed-form times) and rank the optima; ``progress(text)`` at each stage.  Returns the table
    (``rows``, best first; ``starts``, a record per start) and each row's Solution, in order."""
    say = progress or (lambda text: None)
    candidates, starts = multistart.search(problem, extra_revolutions, progress)
    rows, solutions = [], []
    for i, c in enumerate(candidates, 1):
        say(f"{problem.name}: optimum {i}/{len(candidates)} ({c.revolutions:.2f} rev): "
            f"verifying{' and polishing' if polish else ''}")
        flown = pipeline.run_from_optimum(problem, c.result, polish=polish, progress=progress)
        sol = Solution.of(flown)
        rows.append(_row(c, sol, i - 1))
        solutions.append(sol)
    rows, solutions = _ranked(rows, solutions, starts)
    data = {
        "problem": problem.name,
        "extra_revolutions": extra_revolutions,
        "polished": polish,
        "rows": rows,
        "best": rows[0] if rows else None,
        "free_local_optima": sum(1 for r in rows if r["free_local_optimum"]),
        "starts": starts,
        "how": ("one Ipopt start per revolution class (multistart.search); rows are the "
                "distinct converged optima, ranked on the exact time of flight of the "
                "polished schedules verified to 1 m and 1 mm/s, then on the closed-form "
                "time; free_local_optimum is False where the revolution window's bound is "
                "active (the best transfer with that many revolutions, not a local "
                "optimum of the problem as posed)"),
    }
    return plain(data), solutions


def _row(candidate, sol, index):
    """The table's row of one optimum: the ``candidate`` of ``multistart.search`` (its
    position ``index``) and its finished :class:`Solution`."""
    c, p = candidate, sol.polish
    return {
        "revolutions": c.revolutions,
        "free_local_optimum": c.free,
        "window_rev": c.window,
        "rendezvous_k": c.revolutions_k,
        "tof_days_closed_form": sol.tof_days,
        "tof_days_exact": None if p is None else p.tof_days,
        "verified": sol.verified,
        "flight_verified": sol.flight_verified,
        "polish_status": None if p is None else p.status,
        "closed_form_target_miss_km": sol.verification.target_miss_r_km,
        "polished_target_miss_km": (None if p is None or p.verification is None
                                    else p.verification.target_miss_r_km),
        "note": sol.verification_note if p is None else p.note,
        "found_from": c.found_from,
        "candidate": index,
    }


def _ranked(rows, solutions, starts):
    """The rows and their solutions ranked best first (:func:`_rank_key`), each row
    given its ``rank``; each start record (changed in place) names the rank of the
    optimum it found instead of its candidate index, and its time of flight in days."""
    order = sorted(range(len(rows)), key=lambda j: _rank_key(rows[j]))
    rows = [dict(rows[j], rank=r) for r, j in enumerate(order, 1)]
    solutions = [solutions[j] for j in order]
    for record in starts:
        if record["candidate"] is not None:
            record["candidate"] = next(r["rank"] for r in rows
                                       if r["candidate"] == record["candidate"])
        tof = record.pop("tof")
        record["tof_days"] = None if tof is None else units.time_to_days(tof)
    for row in rows:
        row.pop("candidate")
    return rows, solutions


def table_csv(data):
    """The ranked optima as CSV text (``found_from`` joined by "; ")."""
    rows = [dict(row, found_from="; ".join(row["found_from"]),
                 window_rev=(None if row["window_rev"] is None
                             else "{}-{}".format(*row["window_rev"])))
            for row in data["rows"]]
    return csv_text(rows, FIELDS)


def figure(data, ax=None):
    """:func:`run`'s table as revolutions against time of flight, on ``ax`` or a new Figure: free
    local optima filled, window-bound results hollow, the best ringed (times as :func:`_tof`)."""
    fresh = ax is None
    if fresh:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.4, 4.4)).subplots()
    for free, style in ((True, dict(color="tab:blue", label="free local optimum")),
                        (False, dict(facecolors="none", edgecolors="tab:orange",
                                     label="best in its revolution window (bound active)"))):
        pts = [r for r in data["rows"] if r["free_local_optimum"] is free]
        if pts:
            ax.scatter([r["revolutions"] for r in pts], [_tof(r) for r in pts], s=46, zorder=3,
                       **style)
    unverified = [r for r in data["rows"] if not r["verified"]]
    if unverified and data["polished"]:
        ax.scatter([r["revolutions"] for r in unverified], [_tof(r) for r in unverified],
                   marker="x", s=70, color="tab:red", zorder=5,
                   label="polish not verified to 1 m (closed-form time)")
    best = data["best"]
    if best is not None:
        ax.scatter([best["revolutions"]], [_tof(best)], s=180, facecolors="none",
                   edgecolors="k", zorder=4, label=f"best: {_tof(best):.2f} d")
    for r in data["rows"]:
        name = f"#{r['rank']}" + (f" k={r['rendezvous_k']}" if r["window_rev"] is None
                                  and r["rendezvous_k"] else "")
        ax.annotate(name, (r["revolutions"], _tof(r)), textcoords="offset points",
                    xytext=(7, -3), fontsize=8)
    ax.set_xlabel("revolutions, (theta_f - theta_0) / 360 deg")
    ax.set_ylabel("time of flight, days")
    exact = "exact (polished, verified) where available" if data["polished"] else "closed form"
    ax.set_title(f"{data['problem']}: optima by revolutions ({exact})", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if fresh:
        ax.figure.tight_layout()
    return ax.figure


def _tof(row):
    """A row's plotted time of flight, days: exact if polished and verified, else closed form."""
    exact = row["tof_days_exact"]
    return exact if row["verified"] and exact is not None else row["tof_days_closed_form"]


#: The files :func:`write` puts in its folder, and with best/ all it replaces as one set.
SEARCH_TABLES = ("search.json", "search.csv", "search.png")
SEARCH_FILES = SEARCH_TABLES + ("best",)


def write(data, solutions, out_dir, plots=True):
    """Write search.json, search.csv, search.png and best/ (the best optimum's solution files) into
    ``out_dir`` as one set (:func:`~esail_opt.runtime.files.publish`), without ``plots`` no figures;
    returns the paths written.  OutputError if the folder cannot be written; FigureError, after the
    set is written, if a figure of best/ could not be drawn."""
    out = Path(out_dir)
    names = ["search.json", "search.csv"] + (["search.png"] if plots else [])
    failed = None
    with publish(out, family=SEARCH_FILES) as stage:
        write_json(stage / names[0], data)
        (stage / names[1]).write_text(table_csv(data))
        if plots:
            save_figure(figure(data), stage / names[2])
        try:
            best = solutions[0].write(stage / "best", plots=plots) if solutions else []
        except FigureError as err:
            best, failed = err.written, err
    written = [out / name for name in names] + [out / "best" / p.name for p in best]
    if failed is not None:
        raise FigureError(failed.failures, written)
    return written


def summary(data):
    """The ranked table as text lines, days and revolutions."""
    lines = [f"{data['problem']}: {len(data['rows'])} distinct optima from "
             f"{len(data['starts'])} starts, {data['free_local_optima']} of them free local optima"]
    for r in data["rows"]:
        kind = ("free local optimum" if r["free_local_optimum"]
                else f"window {r['window_rev'][0]}-{r['window_rev'][1]} rev, bound active")
        if not data["polished"]:
            exact = "verified, not polished" if r["verified"] else "not verified"
        else:
            exact = (f"exact {r['tof_days_exact']:.3f} d (verified)" if r["verified"]
                     else "exact: not verified")
        lines.append(f"  #{r['rank']}: {r['revolutions']:.3f} rev, closed form "
                     f"{r['tof_days_closed_form']:.3f} d, {exact}; {kind}")
    return lines
