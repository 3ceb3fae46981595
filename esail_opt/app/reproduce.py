"""The paper's figures, each computed into its JSON data and drawn from that data alone
(``*_figure(data, ax=None)``, or ``axes=`` for several panels; a Figure of its own without).
``FIGURES`` maps a name to ``fn(out, progress=None)``, which writes the JSON and the PNG
and returns their paths; ``progress(text)`` hears how far a long figure has got."""

import dataclasses
import math
from pathlib import Path

import numpy as np

from esail_opt.app.outputs import save_figure, write_json
from esail_opt.app.plots import axes_or_new
from esail_opt.physics import constants as units
from esail_opt.physics.closed_form import theta_max_circular
from esail_opt.physics.elements import ac_tilde
from esail_opt.physics.thrust import EXACT, radial_transverse
from esail_opt.propagation.fixed_attitude import FixedAttitudeCase, eps_over_swept_angles

#: The maps' grid: 5 deg in pitch (so +/-45 deg is on it) and 0.005 mm/s^2 in a_c.
ALPHA_DEG = np.linspace(-90, 90, 37)
AC_MM_S2 = np.linspace(0.005, 0.1, 20)
YEARS = 5.0
#: Mercury as the paper prints it: 0.308 au is nearly Mercury's perihelion radius,
#: not its semimajor axis (0.387 au); the printed value is kept (THEORY.md §6.5).
MERCURY = {"a0": 0.308, "e0": 0.206, "nu0": 0.0}
#: Where Eq. 27's maximum is taken in Figs. 3-4, as the JSON says it.
SWEPT_SOURCE = ("the angle swept by CVODES on Eqs. 1-2 (tolerance 1e-12) in 5 years from "
                "the departure, per cell; the closed form, a function of theta, is evaluated "
                "at the same angles (32 per revolution, at least 200)")


def _write(out, name, data, fig):
    """Write ``<out>/<name>.json`` and ``.png`` atomically; return both paths."""
    out = Path(out)
    write_json(out / f"{name}.json", data)
    save_figure(fig, out / f"{name}.png")
    return [out / f"{name}.json", out / f"{name}.png"]


def _contour_levels(data, log):
    return np.logspace(np.log10(data.min()), np.log10(data.max()), 6) if log else 8


def grid_figure(data, key, label, title, scale=1.0, log=False, mark_max=True, ax=None):
    """A map of ``data[key]`` (times ``scale``) over pitch and a_c, as Figs. 2-4:
    ``data[key][i][j]`` at ``data["alpha_deg"][i]``, ``data["ac_mm_s2"][j]``, null grey."""
    from matplotlib.colors import LogNorm

    fig, ax = axes_or_new(ax, figsize=(7, 4.5))
    alpha, ac = np.asarray(data["alpha_deg"]), np.asarray(data["ac_mm_s2"])
    values = scale * np.array(data[key], dtype=float)
    masked = np.ma.masked_invalid(values)
    norm = LogNorm(vmin=masked.min(), vmax=masked.max()) if log else None
    mesh = ax.pcolormesh(alpha, ac, masked.T, shading="nearest", norm=norm, cmap="viridis")
    ax.set_facecolor("0.85")
    cs = ax.contour(alpha, ac, masked.T, colors="white", linewidths=0.7,
                    levels=_contour_levels(masked, log))
    ax.clabel(cs, fontsize=7, fmt="%.3g")
    ax.figure.colorbar(mesh, ax=ax, label=label)
    if mark_max:
        i, j = np.unravel_index(np.nanargmax(values), values.shape)
        ax.plot(alpha[i], ac[j], "r*", ms=10, label=f"max {values[i, j]:.3g}")
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlabel(r"pitch angle $\alpha_n$ [deg]")
    ax.set_ylabel(r"characteristic acceleration $a_c$ [mm/s$^2$]")
    ax.set_title(title, fontsize=10)
    ax.set_xticks(np.arange(-90, 91, 30))
    return fig


_FIG2_TITLE = (r"Fig. 2: $\theta_{max} = 1/(T\,\tilde a_c)$, circular orbit at 1 au "
               r"(grey: T $\leq$ 0, unbounded)")


def theta_max_figure(data, ax=None):
    """Fig. 2 from its JSON data: theta_max on a log scale, grey where unbounded."""
    return grid_figure(data, "theta_max_deg", r"$\theta_{max}$ [deg]", _FIG2_TITLE, log=True,
                       mark_max=False, ax=ax)


def eps_figure(data, ax=None):
    """Fig. 3 or 4 from its JSON data: eps in percent, its maximum starred."""
    return grid_figure(data, "eps", r"$\epsilon$ [%]", data["figure"], scale=100.0, ax=ax)


def fig2(out, progress=None):
    """Fig. 2: theta_max = 1 / (T a~_c), circular orbit at 1 au; null at T <= 0 (q3 never falls)."""
    theta_max = np.full((ALPHA_DEG.size, AC_MM_S2.size), np.nan)
    for i, alpha in enumerate(ALPHA_DEG):
        _, T = radial_transverse(math.radians(alpha))
        if T > 1e-12:
            actil = ac_tilde(units.accel_from_mm_s2(AC_MM_S2), 1.0)
            theta_max[i] = np.degrees(theta_max_circular(actil, T))
    data = {
        "figure": "Fig. 2: maximum angle of the first-order solution, circular parking orbit, "
                  "r0 = 1 au",
        "alpha_deg": ALPHA_DEG.tolist(),
        "ac_mm_s2": AC_MM_S2.tolist(),
        "theta_max_deg": [[None if np.isnan(v) else float(v) for v in row] for row in theta_max],
        "max_theta_max_deg": float(np.nanmax(theta_max)),
        "theta_range": {"from_deg": 0.0, "to_deg": None,
                        "source": "none: theta_max is the closed form's own bound on theta; "
                                  "no horizon and no integration enter"},
        "note": "theta_max_deg[i][j] is at alpha_deg[i], ac_mm_s2[j]; null where T <= 0 "
                "(q3 never decreases, no limit)",
    }
    return _write(out, "fig2", data, theta_max_figure(data))


def eps_map(a0, e0, nu0, label, progress=None):
    """Eq. 27 over the grid, closed form against CVODES: ``eps`` and the angle (rad) CVODES
    swept in YEARS, over which it was taken, each (ALPHA_DEG.size, AC_MM_S2.size)."""
    grid = [(float(alpha), float(ac)) for alpha in ALPHA_DEG for ac in AC_MM_S2]
    cases = [FixedAttitudeCase(a0, e0, nu0, ac, alpha, YEARS)
             for alpha, ac in grid]
    results = eps_over_swept_angles(cases)
    for (alpha, ac), result in zip(grid, results):
        if result.error is not None:
            raise RuntimeError(f"{label}: at alpha = {alpha:g} deg, a_c = {ac:g} "
                               f"mm/s^2: {result.error}")
    shape = (ALPHA_DEG.size, AC_MM_S2.size)
    eps = np.array([r.eps for r in results]).reshape(shape)
    swept = np.array([r.span for r in results]).reshape(shape)
    if progress is not None:
        progress(f"{label}: {eps.size} cases, max eps {100 * eps.max():.2f} %")
    return eps, swept


def _eps_figure(name, title, a0, e0, nu0, out, progress):
    eps, swept = eps_map(a0, e0, nu0, name, progress)
    data = {
        "figure": title,
        "a0_au": a0, "e0": e0, "nu0_deg": nu0, "years": YEARS,
        "alpha_deg": ALPHA_DEG.tolist(),
        "ac_mm_s2": AC_MM_S2.tolist(),
        "eps": eps.tolist(),
        "max_eps": float(eps.max()),
        "theta_range": {"from_deg": nu0, "to_deg": (nu0 + np.degrees(swept)).tolist(),
                        "source": SWEPT_SOURCE},
        "note": "eps[i][j] is Eq. 27 at alpha_deg[i], ac_mm_s2[j]: max over theta from "
                "theta_range's from_deg to its to_deg[i][j] of |r_cvodes - r_closed_form| / r0, "
                "closed form without rectification",
    }
    return _write(out, name, data, eps_figure(data))


def fig3(out, progress=None):
    """Fig. 3: eps over 5 years from the circular orbit at 1 au."""
    return _eps_figure("fig3", "Fig. 3: relative error $\\epsilon$ (Eq. 27) over the angle "
                       "CVODES covers in 5 years, circular orbit at 1 au", 1.0, 0.0, 0.0, out,
                       progress)


def fig4(out, progress=None):
    """Fig. 4: eps over 5 years from the Mercury case as printed (a0 = 0.308 au)."""
    return _eps_figure("fig4", "Fig. 4: relative error $\\epsilon$ (Eq. 27) over the angle "
                       "CVODES covers in 5 years,\na0 = 0.308 au (as printed), e0 = 0.206, "
                       "nu0 = 0", MERCURY["a0"], MERCURY["e0"], MERCURY["nu0"], out, progress)


FIGURES = {"fig2": fig2, "fig3": fig3, "fig4": fig4}


# -- Sec. 3: the 10-year orbit raising (Figs. 5-7) and how rectification converges --

#: The paper's Sec. 3 case: a_c = 0.1 mm/s^2, alpha_n = 45 deg, circular at 1 au, 10 years,
#: one rectification every six months (19 rectifications, 20 arcs).
RAISING = {"ac_mm_s2": 0.1, "alpha_deg": 45.0, "r0_au": 1.0, "years": 10.0, "arcs": 20}
#: Plot samples per arc (at most 9 deg of theta each) and CVODES/Ref. [10] plot points
#: (about 1.5 days apart): both resolve the one-year short-period oscillation.
SAMPLES_PER_ARC = 20
DENSE_POINTS = 2400
CURVE_NAMES = {
    "cvodes": "numerical integration (CVODES, tol 1e-12)",
    "ref10": "Ref. [10] (r'' neglected in Eq. 1)",
    "closed_form": "closed form, 19 rectifications (20 arcs)",
}
_STYLES = {"cvodes": ("k", "-"), "ref10": ("tab:blue", "--"), "closed_form": ("tab:red", "-.")}
_RAISING_TEXT = "10-year orbit raising, a_c = 0.1 mm/s^2, alpha_n = 45 deg, r0 = 1 au, e0 = 0"
_RAISING_TITLE = (r"10-year orbit raising, $a_c$ = 0.1 mm/s$^2$, $\alpha_n$ = 45 deg, "
                  r"$r_0$ = 1 au, $e_0$ = 0")


def _raising_inputs():
    """Departure state, pitch (rad), a_c and horizon of the Sec. 3 case, canonical units."""
    alpha = math.radians(RAISING["alpha_deg"])
    circle = np.array([RAISING["r0_au"], 0.0, 0.0, RAISING["r0_au"] ** -0.5])
    ac = units.accel_from_mm_s2(RAISING["ac_mm_s2"])
    return circle, alpha, ac, units.time_from_years(RAISING["years"])


def raising_curves():
    """Figs. 5-7's three trajectories, canonical rows [r, theta, v_r, v_theta, t]: the closed
    form's arcs are found in time (six months of its clock each, as the paper rectifies),
    then the same arcs re-sampled in theta: the time propagator's cost grows with samples."""
    from esail_opt.propagation.arcs import FIRST_ORDER
    from esail_opt.propagation.rectified import propagate
    from esail_opt.propagation.radial_balance import radial_balance_function
    from esail_opt.propagation.simulate import simulate

    x0, alpha, ac, horizon = _raising_inputs()
    arcs = RAISING["arcs"]
    points, _ = propagate(x0, [alpha] * arcs, [horizon / arcs] * arcs, ac, length_in="time",
                          model=FIRST_ORDER)
    closed, q3 = propagate(x0, [alpha] * arcs, np.diff(points[1]), ac,
                           samples=SAMPLES_PER_ARC, model=FIRST_ORDER)
    if np.any(q3 <= 0):
        raise RuntimeError("an arc of the closed form went past theta_max (q3 <= 0)")
    cvodes = simulate(x0, [alpha], [horizon], ac, samples=DENSE_POINTS)
    R, T = radial_transverse(alpha)
    t = np.linspace(0.0, horizon, DENSE_POINTS + 1)
    ref10 = np.vstack([np.array(radial_balance_function(t.size)(t[None, :], x0[0], ac, R, T,
                                                                 0.0)), t])
    # CVODES at the closed form's sample times, for the errors reported beside the plots.
    at_closed = simulate(x0, [alpha] * (arcs * SAMPLES_PER_ARC), np.diff(closed[4]), ac)
    return {"cvodes": cvodes, "ref10": ref10, "closed_form": closed,
            "cvodes_at_closed_form": at_closed,
            "clock_mismatch": float(np.max(np.abs(closed[4, ::SAMPLES_PER_ARC] - points[4])))}


def _errors(curves):
    """Largest and final |dr|/r0 of the closed form and Ref. [10] against CVODES at equal times."""
    r0 = RAISING["r0_au"]
    closed, truth = curves["closed_form"], curves["cvodes_at_closed_form"]
    ref10, dense = curves["ref10"], curves["cvodes"]
    return {
        "closed_form_max_dr_over_r0": float(np.max(np.abs(closed[0] - truth[0])) / r0),
        "closed_form_final_dr_au": float(closed[0, -1] - truth[0, -1]),
        "closed_form_final_dtheta_deg": float(np.degrees(closed[1, -1] - truth[1, -1])),
        "ref10_max_dr_over_r0": float(np.max(np.abs(ref10[0] - dense[0])) / r0),
        "ref10_final_dr_au": float(ref10[0, -1] - dense[0, -1]),
        "ref10_final_dtheta_deg": float(np.degrees(ref10[1, -1] - dense[1, -1])),
        "closed_form_clock_mismatch_tu": curves["clock_mismatch"],
        "note": "errors at equal times against CVODES; the closed form's samples are "
                "equally spaced in theta within each arc, CVODES was flown to the same times",
    }


def _raising_json(figure, curves, series):
    """A figure's JSON: the case, the errors, and ``series(xs)`` of each curve."""
    data = {
        "figure": figure,
        "case": dict(RAISING, rectifications=RAISING["arcs"] - 1, b1=EXACT[0], b2=EXACT[1]),
        "curves": CURVE_NAMES,
        "errors": _errors(curves),
    }
    for key in CURVE_NAMES:
        xs = curves[key]
        data[key] = {"t_days": units.time_to_days(xs[4]).tolist(), **series(xs)}
    # From the closed form's own samples, so that omega is unwrapped as along the curve.
    data["rectification_points"] = {
        key: values[::SAMPLES_PER_ARC] for key, values in data["closed_form"].items()
    }
    return data


def raising_panels(data, keys, ylabels, title, axes=None):
    """Stacked panels (Figs. 5-6), one per key (``axes``: one Axes each), of the three
    curves and the rectification points (squares) against time in days."""
    fig, axes = axes_or_new(axes, len(keys), 1, figsize=(7, 2.4 * len(keys) + 0.6),
                            sharex=True, squeeze=False)
    axes = np.ravel(axes)
    for curve in CURVE_NAMES:
        color, style = _STYLES[curve]
        for ax, key in zip(axes, keys):
            ax.plot(data[curve]["t_days"], data[curve][key], color=color, ls=style, lw=1.1,
                    label=CURVE_NAMES[curve])
    for ax, key, label in zip(axes, keys, ylabels):
        ax.plot(data["rectification_points"]["t_days"], data["rectification_points"][key],
                "s", mfc="none", mec="tab:red", ms=4)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [days]")
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    return fig


def states_figure(data, axes=None):
    """Fig. 5 from its JSON data: r, v_r and v_theta against time."""
    return raising_panels(data, ["r_au", "vr_km_s", "vtheta_km_s"],
                          ["r [au]", r"$v_r$ [km/s]", r"$v_\theta$ [km/s]"],
                          "Fig. 5: " + _RAISING_TITLE + "\nclosed form: 19 rectifications "
                          "(20 arcs, squares)", axes)


def fig5(out, progress=None):
    """Fig. 5: r, v_r and v_theta against time, the three models."""

    def series(xs):
        return {"r_au": xs[0].tolist(), "vr_km_s": units.speed_to_km_s(xs[2]).tolist(),
                "vtheta_km_s": units.speed_to_km_s(xs[3]).tolist()}

    data = _raising_json("Fig. 5: " + _RAISING_TEXT + "; closed form with 19 "
                         "rectifications (20 arcs)", raising_curves(), series)
    return _write(out, "fig5", data, states_figure(data))


def osculating(xs):
    """Osculating a (au), e, omega (deg, unwrapped) and h (au^2/day) of polar states."""
    from esail_opt.physics.elements import classical_columns

    a, e, omega, h = classical_columns(xs, 4)
    # At e = 0 (the departure) the apse line is undefined and atan2 returns 0.
    omega = np.degrees(np.unwrap(omega))
    return {"a_au": a.tolist(), "e": e.tolist(), "omega_deg": omega.tolist(),
            "h_au2_day": (h / units.TU_DAYS).tolist()}


def elements_figure(data, axes=None):
    """Fig. 6 from its JSON data: osculating a, e, omega and h against time."""
    return raising_panels(data, ["a_au", "e", "omega_deg", "h_au2_day"],
                          ["a [au]", "e", r"$\omega$ [deg]", r"h [au$^2$/day]"],
                          "Fig. 6: osculating elements, " + _RAISING_TITLE
                          + "\nclosed form: 19 rectifications (20 arcs, squares)", axes)


def fig6(out, progress=None):
    """Fig. 6: osculating a, e, omega and h against time, the three models."""
    data = _raising_json("Fig. 6: osculating elements, " + _RAISING_TEXT
                         + "; closed form with 19 rectifications (20 arcs)", raising_curves(),
                         osculating)
    data["note"] = ("omega is measured from the departure radius (the parking orbit has no "
                    "apse line); it is unwrapped, and meaningless while e is near 0")
    return _write(out, "fig6", data, elements_figure(data))


def raising_trajectory_figure(data, ax=None):
    """Fig. 7 from its JSON data: the trajectories and the rectification points."""
    fig, ax = axes_or_new(ax, figsize=(6.5, 6.5))
    for curve in CURVE_NAMES:
        color, style = _STYLES[curve]
        ax.plot(data[curve]["x_au"], data[curve]["y_au"], color=color, ls=style, lw=1,
                label=CURVE_NAMES[curve])
    points = data["rectification_points"]
    ax.plot(points["x_au"], points["y_au"], "s", mfc="none", mec="tab:red", ms=5,
            label="rectification points (start, 19 rectifications, end)")
    ax.plot(0, 0, "o", color="orange", ms=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [au]")
    ax.set_ylabel("y [au]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("Fig. 7: " + _RAISING_TITLE, fontsize=9)
    return fig


def fig7(out, progress=None):
    """Fig. 7: the polar trajectory with the rectification points (squares)."""

    def series(xs):
        return {"x_au": (xs[0] * np.cos(xs[1])).tolist(), "y_au": (xs[0] * np.sin(xs[1])).tolist(),
                "r_au": xs[0].tolist(), "theta_deg": np.degrees(xs[1]).tolist()}

    data = _raising_json("Fig. 7: trajectory, " + _RAISING_TEXT
                         + "; closed form with 19 rectifications (20 arcs)", raising_curves(),
                         series)
    return _write(out, "fig7", data, raising_trajectory_figure(data))


#: Arc counts of the convergence study; each doubles the last.
CONVERGENCE_ARCS = [5, 10, 20, 40, 80, 160, 320, 640, 1280, 2560]
#: The order is fitted from this count on: arcs of a quarter revolution and more are
#: outside the asymptotic regime (the error changes sign between 20 and 40 arcs).
FIT_FROM_ARCS = 160


def _slope(arcs, errors, start=FIT_FROM_ARCS):
    """Least-squares slope of log(error) against log(arcs) over arcs >= start."""
    arcs, errors = np.asarray(arcs, float), np.abs(np.asarray(errors, float))
    keep = arcs >= start
    return float(np.polyfit(np.log(arcs[keep]), np.log(errors[keep]), 1)[0])


def convergence_errors(arcs=CONVERGENCE_ARCS, progress=None):
    """Final errors of the rectified closed form against CVODES after 10 years, for N equal
    arcs, plain and with Richardson extrapolation from N and 2N arcs (cost 3N), each where
    it exists: arcs of equal duration (time exact) give r and theta at 10 years; arcs of
    equal angle, totalling CVODES's swept angle (theta exact), the time of flight and r."""
    from esail_opt.propagation.arcs import FIRST_ORDER
    from esail_opt.propagation.rectified import propagate
    from esail_opt.propagation.simulate import simulate

    x0, alpha, ac, horizon = _raising_inputs()
    truth = simulate(x0, [alpha], [horizon], ac)[:, -1]
    span = truth[1] - x0[1]
    rows = {key: [] for key in ("plain", "richardson")}
    models = {"plain": FIRST_ORDER,
              "richardson": dataclasses.replace(FIRST_ORDER, extrapolate=True)}
    for n in arcs:
        for key, model in models.items():
            timed, q3_t = propagate(x0, [alpha] * n, [horizon / n] * n, ac, length_in="time",
                                    model=model)
            angled, q3_a = propagate(x0, [alpha] * n, [span / n] * n, ac, length_in="theta",
                                     model=model)
            if min(q3_t.min(), q3_a.min()) <= 0:
                raise RuntimeError(f"{n} arcs: an arc went past theta_max")
            rows[key].append({
                "r": abs(timed[0, -1] - truth[0]),
                "theta": abs(math.degrees(timed[1, -1] - truth[1])),
                "tof": abs(units.time_to_days(angled[4, -1] - truth[4])),
                "r_same_theta": abs(angled[0, -1] - truth[0]),
            })
        if progress is not None:
            progress(f"convergence: {n} arcs, |dr| = {rows['plain'][-1]['r']:.3e} au plain, "
                     f"{rows['richardson'][-1]['r']:.3e} au Richardson")
    return truth, rows


#: The study's error columns: the field in ``convergence_errors``'s rows, the JSON name.
_ERROR_COLUMNS = {"r": "err_r_au", "theta": "err_theta_deg", "tof": "err_tof_days",
                  "r_same_theta": "err_r_same_theta_au"}
#: The errors whose convergence order is fitted and plotted.
_RATED = ("err_r_au", "err_theta_deg", "err_tof_days")
_CONVERGENCE_DEFINITIONS = {
    "err_r_au": "|r - r_cvodes| at 10 years, N arcs of equal duration (10 years / N)",
    "err_theta_deg": "|theta - theta_cvodes| at 10 years, the same equal-duration arcs",
    "err_tof_days": "|t - 10 years| where the closed form reaches the angle swept by CVODES "
                    "in 10 years, N arcs of equal angle (with equal durations the time of "
                    "flight is exact by construction)",
    "err_r_same_theta_au": "|r - r_cvodes| at that same angle, equal-angle arcs",
    "richardson": "2 x(2N arcs) - x(N arcs) at the end; cost 3N arcs evaluated",
    "slope": f"least-squares slope of log(error) vs log(arcs) for arcs >= {FIT_FROM_ARCS}",
}


def _convergence_rates(data, arcs):
    """The fitted slopes, the 640-over-20 ratios and the equal-cost comparison."""
    arcs = list(arcs)
    i20, i640 = arcs.index(20), arcs.index(640)
    richardson = data["richardson"]
    return {
        "slope": {key: {"plain": _slope(arcs, data[key]),
                        "richardson": _slope(arcs, richardson[key])} for key in _RATED},
        "err_640_over_err_20": {key: data[key][i640] / data[key][i20] for key in _RATED},
        # Richardson at 3N arcs against plain at 4N, the grid's next count: this favours plain.
        "equal_cost": {
            "note": "Richardson at cost 3N against plain at 4N arcs (the next grid point above)",
            "richardson_arcs_cost": [3 * n for n in arcs[:-2]],
            "plain_arcs": [4 * n for n in arcs[:-2]],
            "err_r_au_ratio_plain_over_richardson": [
                data["err_r_au"][i + 2] / richardson["err_r_au"][i] for i in range(len(arcs) - 2)
            ],
        },
    }


def _convergence_json(truth, rows, arcs):
    """The study's JSON: the case, the CVODES truth, the errors of both schemes, the rates."""

    def columns(scheme):
        return {name: [row[field] for row in rows[scheme]]
                for field, name in _ERROR_COLUMNS.items()}

    arcs = [int(n) for n in arcs]
    data = {
        "figure": "Convergence of the rectified closed form with the number of arcs: "
                  + _RAISING_TEXT,
        "case": dict(RAISING, b1=EXACT[0], b2=EXACT[1]),
        "truth_cvodes": {"r_au": float(truth[0]), "theta_deg": float(np.degrees(truth[1])),
                         "tof_days": float(units.time_to_days(truth[4]))},
        "definitions": _CONVERGENCE_DEFINITIONS,
        "arcs": arcs,
        **columns("plain"),
        "richardson": {"arcs": arcs, "cost_arcs": [3 * n for n in arcs], **columns("richardson")},
    }
    data.update(_convergence_rates(data, arcs))
    return data


def convergence_figure(data, axes=None):
    """The convergence study from its JSON data: log-log errors against arcs evaluated."""
    fig, axes = axes_or_new(axes, 1, 3, figsize=(12, 4))
    arcs = np.asarray(data["arcs"], float)
    labels = {"err_r_au": "final |dr| [au]", "err_theta_deg": r"final |d$\theta$| [deg]",
              "err_tof_days": "time-of-flight error [days]"}
    for ax, key in zip(np.ravel(axes), _RATED):
        slope = data["slope"][key]
        ax.loglog(arcs, data[key], "o-", color="tab:red",
                  label=f"plain (slope {slope['plain']:.2f})")
        ax.loglog(data["richardson"]["cost_arcs"], data["richardson"][key], "s--",
                  color="tab:green", label=f"Richardson, N & 2N (slope {slope['richardson']:.2f})")
        ax.loglog(arcs, data[key][-1] * arcs[-1] / arcs, ":", color="0.5", label="1/N")
        ax.set_xlabel("arcs evaluated (plain: N; Richardson: 3N)")
        ax.set_ylabel(labels[key])
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle("Rectified closed form vs CVODES after 10 years: " + _RAISING_TITLE
                 + "\n(r, theta: arcs of equal duration; time of flight: arcs of equal angle)",
                 fontsize=9)
    return fig


def convergence(out, progress=None):
    """Final errors after 10 years against the number of rectification arcs, log-log."""
    truth, rows = convergence_errors(progress=progress)
    data = _convergence_json(truth, rows, CONVERGENCE_ARCS)
    return _write(out, "convergence", data, convergence_figure(data))


FIGURES.update({"fig5": fig5, "fig6": fig6, "fig7": fig7, "convergence": convergence})
