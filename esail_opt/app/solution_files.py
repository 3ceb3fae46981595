"""A :class:`~esail_opt.app.solution.Solution`'s folder: solution.json, the schedules as
CSV, a 3-D flight as a CCSDS OEM, and the figures, written as one set."""

import csv
import io
import math
from pathlib import Path

import numpy as np

from esail_opt.app import schema
from esail_opt.app.outputs import write_json
from esail_opt.runtime.files import publish
from esail_opt.app.oem import states_km_km_s, write_oem
from esail_opt.bodies import dates
from esail_opt.errors import FigureError

#: Every file :func:`write` may put in its folder, the set a new write replaces whole
#: (other files are the user's); ``schedule_polished.csv``, an old name of schedule.csv, is
#: listed so that a new write drops it.
SOLUTION_FILES = ("solution.json", "schedule.csv", "schedule_closed_form.csv",
                  "trajectory.png", "timeline.png", "trajectory.oem", "schedule_polished.csv")


def schedule_csv(sol, polished=None):
    """The schedule as CSV text, one row per segment: the flight the verdict is about (the
    polish's after a polish; ``polished`` True or False picks one), every number to the
    last digit, so that flying the file reproduces the verified flight; a null as nan.  A
    dated flight's rows end with the segment's start as an ISO 8601 date (TDB)."""
    if polished is None:
        polished = sol.polished
    schedule = sol.polish.schedule if polished else sol.schedule
    columns = schedule.columns
    # A polish may move a free date's departure: its rows start from its own.
    departure = (polished and sol.polish.departure_date) or sol.departure_date
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns + (("start_date_tdb",) if departure else ()))
    for row in schedule:
        cells = [repr(float(math.nan if getattr(row, c) is None else getattr(row, c)))
                 for c in columns]
        if departure:
            cells.append(dates.iso_from_jd(dates.jd_from_iso(departure) + row.t_days))
        writer.writerow(cells)
    return buf.getvalue()


def write(sol, out_dir, plots=True, object_name=None, object_id=None):
    """Write solution.json, schedule.csv, trajectory.oem for a dated 3-D flight and (with
    ``plots``) the two PNGs into ``out_dir`` as one set (:func:`publish`); their paths.
    After a polish the schedule and the OEM are the polished flight's, and
    schedule_closed_form.csv the closed form's.  ``object_name`` and ``object_id`` are the
    OEM's (the problem's name by default).  OutputError when the folder cannot be written
    (the old set stays); FigureError when a figure was not drawn (the rest published: its
    ``written``)."""
    out = Path(out_dir)
    failures = []
    with publish(out, family=SOLUTION_FILES) as stage:
        names = ["solution.json", "schedule.csv"]
        write_json(stage / names[0], sol.to_json())
        (stage / names[1]).write_text(schedule_csv(sol))
        if sol.polished:
            names.append("schedule_closed_form.csv")
            (stage / names[-1]).write_text(schedule_csv(sol, polished=False))
        if _write_oem(sol, stage / "trajectory.oem", object_name, object_id):
            names.append("trajectory.oem")
        if plots:
            from esail_opt.app import plots as plotting

            drawn, failures = plotting.write_plots(sol, stage)
            names += [p.name for p in drawn]
    written = [out / name for name in names]
    if failures:
        raise FigureError(failures, written)
    return written


def _write_oem(sol, path, object_name, object_id):
    """The flight the verdict is about as ``trajectory.oem``, one data segment per schedule
    segment; False, nothing written, for a planar, undated or failed flight, or one whose
    time does not advance (a failed solve's last iterate can hold a negative duration)."""
    polish = sol.polish if sol.polished else None
    flight = sol.trajectory_polished if polish else sol.trajectory_cvodes
    if flight is None or flight.three_d is None or not sol.dated:
        return False
    days = np.asarray(flight.t_days, float)
    if not np.all(np.diff(days) > 0):
        return False
    dated = polish or sol
    epoch = dated.departure_epoch_days
    jd1 = dates.J2000_JD if epoch is not None else dates.jd_from_iso(dated.departure_date)
    segments = len(dated.schedule)
    per = (days.size - 1) // segments
    breaks = range(per, days.size - 1, per) if per * segments == days.size - 1 else ()
    states = schema.state_from_fields(
        {k: flight.three_d[k] for k in schema.STATE_KEYS}, "trajectory")
    write_oem(path, object_name or sol.problem.name, np.full(days.size, jd1),
              states_km_km_s(states), jd2=days + (epoch or 0.0), object_id=object_id,
              breaks=breaks, comments=_oem_comments(sol, polish))
    return True


def _oem_comments(sol, polish):
    """The OEM's comments: the model, which flight, its verdict, miss and bound."""
    check, bounds = (polish.verification, polish.bounds) if polish else (sol.verification,
                                                                           sol.tolerance)
    verdict = "verified" if (polish.verified if polish else sol.flight_verified) else "NOT verified"
    lines = [f"{sol.problem.name}: an E-sail's heliocentric flight, thrust a_c (1 au / r) "
             "at a pitch and clock angle constant over each segment",
             "flown by CVODES on the equations of motion in 3-D from the departure state; "
             + ("the polished schedule (schedule.csv)" if polish else
                "the closed-form optimum's schedule (schedule.csv)"),
             f"verdict: {verdict} (exit 0 only when verified)"]
    # An intercept meets the body's position only: it has no velocity miss.
    intercept = check.target_miss_v_m_s is None
    if check.target_miss_r_km is not None:
        lines.append(f"miss at arrival: {check.target_miss_r_km:.6g} km"
                     + (" (an intercept, at any relative speed)" if intercept else
                        f", {check.target_miss_v_m_s:.6g} m/s") + " from the target; "
                     f"verifier's own error {check.verifier_error_r_km:.3g} km, "
                     f"{check.verifier_error_v_m_s:.3g} m/s")
    lines.append(f"tolerance: {bounds.position_km:.6g} km"
                 + ("" if intercept else f", {bounds.velocity_m_s:.6g} m/s"))
    lines.append("one data segment per schedule segment: the thrust switches between them, "
                 "so interpolate within a segment only")
    return lines


def plot(sol):
    """The trajectory and timeline figures of ``sol``, unsaved."""
    from esail_opt.app import plots as plotting

    return plotting.trajectory_figure(sol), plotting.timeline_figure(sol)
