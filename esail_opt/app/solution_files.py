"""A :class:`~esail_opt.app.solution.Solution`'s folder: solution.json, the schedules as
CSV, a 3-D flight as a CCSDS OEM, and the figures, written as one set."""

import csv
import io
import math
from pathlib import Path

import numpy as np

from esail_opt.app import schema
from esail_opt.app.files import publish, write_json
from esail_opt.app.oem import states_km_km_s, write_oem
from esail_opt.bodies import dates
from esail_opt.errors import FigureError

#: Every file :func:`write` may put in its folder: the set that a new write replaces
#: whole (anything else in the folder is the user's and stays).
SOLUTION_FILES = ("solution.json", "schedule.csv", "schedule_polished.csv",
                  "trajectory.png", "timeline.png", "trajectory.oem")


def schedule_csv(sol, polished=False):
    """The schedule as CSV text, one row per segment (the rows of ``sol.schedule``, or
    with ``polished`` of ``sol.polish.schedule``), every number to the digit, so that
    flying the file reproduces the flight that was verified.  (At 10 significant
    digits a polished 2500-day schedule, flown from the CSV, ended 3.5 m from its
    target where the same schedule at full precision ends 8 mm from it.)  A null of
    the file (a NaN the JSON could not hold) is written as nan."""
    schedule = sol.polish.schedule if polished else sol.schedule
    columns = schedule.columns
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in schedule:
        writer.writerow([repr(float(math.nan if getattr(row, c) is None else getattr(row, c)))
                         for c in columns])
    return buf.getvalue()


def write(sol, out_dir, plots=True):
    """Write solution.json, schedule.csv (and schedule_polished.csv after a polish),
    trajectory.oem for a 3-D flight and (with ``plots``) the two PNGs into ``out_dir``,
    as one set (:func:`esail_opt.app.files.publish`): a reader of the folder sees the
    previous run's files or these, never a mix, and files of the user's own stay.  The
    figures are drawn here, one after the other (:func:`esail_opt.app.plots.write_plots`).

    Returns the list of paths written.

    Raises
    ------
    OutputError
        The folder cannot be written (one line; the old set stays as it was).
    FigureError
        A figure could not be drawn: the rest of the set was published all the same
        (the error's ``written``), without that figure.
    """
    out = Path(out_dir)
    failures = []
    with publish(out, family=SOLUTION_FILES) as stage:
        names = ["solution.json", "schedule.csv"]
        write_json(stage / names[0], sol.to_json())
        (stage / names[1]).write_text(schedule_csv(sol))
        if sol.polished:
            names.append("schedule_polished.csv")
            (stage / names[-1]).write_text(schedule_csv(sol, polished=True))
        if _write_oem(sol, stage / "trajectory.oem"):
            names.append("trajectory.oem")
        if plots:
            from esail_opt.app import plots as plotting

            drawn, failures = plotting.write_plots(sol, stage)
            names += [p.name for p in drawn]
    written = [out / name for name in names]
    if failures:
        raise FigureError(failures, written)
    return written


def _write_oem(sol, path):
    """The CVODES flight of a 3-D solution as ``trajectory.oem`` (``app.oem``); False,
    and nothing written, for a planar one, a failed flight, or one whose time does not
    advance: the last iterate of a solve that found no point can hold a segment of
    negative duration, and such a flight is no ephemeris."""
    flight = sol.trajectory_cvodes
    if flight is None or flight.three_d is None or not sol.dated:
        return False
    days = np.asarray(flight.t_days, float)
    if not np.all(np.diff(days) > 0):
        return False
    states = schema.state_from_fields(
        {k: flight.three_d[k] for k in schema.STATE_KEYS}, "trajectory.cvodes")
    write_oem(path, sol.problem.name, np.full(days.size, dates.jd_from_iso(
        sol.departure_date)), states_km_km_s(states), jd2=days)
    return True


def plot(sol):
    """The trajectory and timeline figures of ``sol``, drawn and returned unsaved
    (:func:`write` saves them)."""
    from esail_opt.app import plots as plotting

    return plotting.trajectory_figure(sol), plotting.timeline_figure(sol)
