"""The lines ``esail-opt solve`` prints for a :class:`~esail_opt.app.solution.Solution`,
read from the record alone, so that a solution loaded from its file prints the same."""

from esail_opt.bodies import dates
from esail_opt.optimisation.ipopt import STOPPED


def summary(sol):
    """``sol``'s summary lines: the solve, the flight and its verdict, turn counts, polish."""
    lines = _solve_lines(sol) + _mission_lines(sol) + _flight_lines(sol.verification)
    lines.append(f"  {sol.verification_note}")
    return "\n".join(lines + _class_lines(sol) + _polish_lines(sol))


def _solve_lines(sol):
    """Ipopt's record, the time of flight and the closed form's final state."""
    end = sol.final_state
    # A dated problem's theta counts turns since 2000: the angle reads better, and says it
    # is one, as solution.json keeps the count.
    return [
        f"{sol.problem.name}: {sol.status} "
        f"({'converged' if sol.converged else 'NOT converged'}), "
        f"{sol.iterations} iterations, {sol.solve_seconds:.2f} s, "
        f"{_refinements(len(sol.rounds))}",
        f"  tof {sol.tof_days:.3f} d (closed form), {len(sol.schedule)} segments x "
        f"{sol.problem.sub_arcs} sub-arcs",
        f"  final (closed form): r {end.r_au:.6f} au, theta {end.theta_deg % 360.0:.3f} deg "
        f"(mod 360), a {end.a_au:.6f} au, e {end.e:.5f}",
    ]


def _refinements(rounds):
    """The error control's rounds in the words its progress lines use: round 0 flies the
    first optimum, each later one a refined mesh."""
    if rounds == 0:
        return "no error control"
    if rounds == 1:
        return "error control: round 0 only"
    return f"error control: rounds 0-{rounds - 1} ({rounds - 1} mesh refinement" \
           f"{'s' if rounds > 2 else ''})"


def _flight_lines(v):
    """The CVODES flight: its final state and misses, or why it failed."""
    if v.error:
        return [f"  verification: {v.error}"]
    cv = v.cvodes_final_state
    lines = [f"  CVODES: r {cv.r_au:.6f} au, a {cv.a_au:.6f} au, e {cv.e:.5f}; "
             f"miss vs NLP {v.miss_r_km:.4g} km, {v.miss_v_m_s:.4g} m/s, "
             f"{v.miss_theta_deg:.4g} deg"]
    if v.target_miss_r_km is not None:
        extra = f", {v.target_miss_v_m_s:.4g} m/s" if v.target_miss_v_m_s is not None else ""
        lines.append(f"  CVODES miss vs target: {v.target_miss_r_km:.4g} km{extra}")
    return lines


def _class_line(c, again=False):
    """One turn count looked at (``again``: another start of a count already shown on the
    same model): what it gave, on which model, and whether it was flown and chosen."""
    # The colon keeps a negative count apart from its value ("k = -24: 853.0 d").
    k = f"k = {c.revolutions_k}" + (" (another start)" if again else "") + ":"
    where = " on the ecliptic projection" if c.projected else ""
    if c.tof_days is None and c.status == STOPPED:
        return (f"{k} hopeless{where}, stopped after {c.iterations} iterations "
                f"(still infeasible by {c.constraint_violation:.2g})")
    if c.tof_days is None:
        return f"{k} no point{where} ({c.status} after {c.iterations} iterations)"
    value = (f"{c.ac_mm_s2_required:.4g} mm/s^2" if c.ac_mm_s2_required is not None
             else f"{c.tof_days:.1f} d")
    if c.projected:
        return f"{k} {value}{where}, not flown in 3-D"
    verdict = {True: ", verified", False: ", NOT verified", None: ", not flown"}[c.verified]
    return f"{k} {value}{verdict}" + (" (chosen)" if c.chosen else "")


#: Said under the turn counts when some were only solved on the ecliptic projection.
PROJECTION_NOTE = ("  (a value on the ecliptic projection leaves out the change of plane "
                   "to the target's orbit: it ranks the counts, and is not a flight)")


def _class_lines(sol):
    """The turn counts looked at, and the nearest feasible flight, if any."""
    lines = []
    if sol.classes:
        ranked = sorted(sol.classes, key=lambda c: (c.revolutions_k, not c.chosen))
        shown = [_class_line(c, i > 0 and (ranked[i - 1].revolutions_k, ranked[i - 1].projected)
                             == (c.revolutions_k, c.projected))
                 for i, c in enumerate(ranked)]
        lines.append(f"  turn counts on the body: {'; '.join(shown)}")
        if any(c.projected for c in sol.classes):
            lines.append(PROJECTION_NOTE)
        lines.append(f"  not looked at: {sol.classes_skipped}")
    if sol.nearest_feasible is not None:
        lines.append(f"  nearest feasible: {nearest_feasible_line(sol.nearest_feasible)}")
    return lines


def nearest_feasible_line(n):
    """One line on a ``NearestFeasible``: its date, time of flight and a_c."""
    date = "" if n.departure_date is None else f" departing {n.departure_date}"
    return (f"the shortest flight found feasible{date} takes {n.tof_days:.1f} d at a_c "
            f"{n.ac_mm_s2_required:.4g} mm/s^2 ({'verified' if n.verified else 'NOT verified'}"
            f"; none found at {n.infeasible_tof_days:.1f} d)")


def _binding_windows(sol):
    """A line for each date window whose end the answer sits at: the window, not the
    mission, stopped the optimum there, and a wider one may do better."""
    lines = []
    for verb, when, what, window in (
            ("departs", sol.departure_date, "departure", getattr(sol.problem.departure,
                                                                "window", None)),
            ("arrives", sol.arrival_date, "arrival", getattr(sol.problem.target,
                                                            "arrival_window", None))):
        for end, day in zip(("opens", "closes"), window or ()):
            # The dates are written to the millisecond: a second is well within.
            if abs(dates.jd_from_iso(when) - dates.jd_from_iso(day)) < 1 / 86400:
                lines.append(f"  {verb} as its {what} window {end} ({day}): the window "
                             "binds, and a wider one may do better")
    return lines


def _mission_lines(sol):
    """The dates, the a_c a MinAcceleration found and what the plane hides at a body."""
    lines = []
    if sol.departure_date is not None:
        lines.append(f"  departs {sol.departure_date}, arrives {sol.arrival_date} (TDB)")
        lines += _binding_windows(sol) if sol.converged else []
    if sol.ac_mm_s2_required is not None and sol.converged:
        lines.append(f"  a_c needed: {sol.ac_mm_s2_required:.6g} mm/s^2 (the schedule's "
                     "throttles are fractions of it)")
    elif sol.ac_mm_s2_required is not None:
        lines.append(f"  a_c of Ipopt's last iterate: {sol.ac_mm_s2_required:.6g} mm/s^2 "
                     "(not converged: no answer)")
    body = sol.target_body
    if body is None:
        return lines
    # A rendezvous's relative speed is its velocity miss, printed below.
    speed = ("" if body.relative_speed_km_s is None or body.kind != "BodyIntercept"
             else f", met at {body.relative_speed_km_s:.4g} km/s relative speed")
    off = (None if body.out_of_plane_km is None
           else f"{body.out_of_plane_km:.4g} km out of the ecliptic at arrival")
    if body.normal_miss_km is not None:
        # A version-5 file does not give the body's own distance (schema.upgrade).
        lines.append(f"  {body.name}" + (f" is {off};" if off else ":")
                     + f" the 3-D flight meets it to {body.normal_miss_km:.4g} km along the "
                     f"ecliptic's normal{speed}")
    elif off is not None:
        lines.append(f"  {body.name} is {off}, which the planar model ignores{speed}")
    return lines


def _polish_misses(v):
    """The polished flight's misses, in metres and mm/s (a km reads badly at its scale)."""
    line = (f"  polished CVODES miss vs NLP {1e3 * v.miss_r_km:.3g} m, "
            f"{1e3 * v.miss_v_m_s:.3g} mm/s")
    if v.target_miss_r_km is not None:
        line += f"; vs target {1e3 * v.target_miss_r_km:.3g} m"
        if v.target_miss_v_m_s is not None:
            line += f", {1e3 * v.target_miss_v_m_s:.3g} mm/s"
    # Misses this small are only as good as the verifier that measured them.
    if v.verifier_error_r_km is not None:
        line += f" (verifier's own error {1e3 * v.verifier_error_r_km:.2g} m)"
    return line


def _polish_lines(sol):
    """The polish, if there was one."""
    p = sol.polish
    if p is None:
        return []
    if not p.ran:
        return [f"  polish: {p.note}"]
    lines = [f"  polish: {p.status} ({'converged' if p.converged else 'NOT converged'}), "
             f"{p.iterations} iterations, {p.seconds:.2f} s; exact tof "
             f"{p.tof_days:.3f} d (closed form {sol.tof_days:.3f} d)"]
    if p.verification.error is None:
        lines.append(_polish_misses(p.verification))
    return lines + [f"  polish: {p.note}"]
