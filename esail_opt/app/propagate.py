"""What ``propagate`` writes for one fixed attitude (:func:`run`) or a grid of them
(:func:`run_grid`), in the boundary's units, and a grid's table and picture; the flights
are :mod:`esail_opt.propagation.fixed_attitude`'s."""

import math

import numpy as np

from esail_opt.errors import InputError
from esail_opt.physics import constants as units
from esail_opt.physics.elements import classical_columns
from esail_opt.physics.thrust import EXACT
from esail_opt.propagation.fixed_attitude import (FixedAttitudeCase, closed_form,
                                                  cvodes_at_theta, eps_over_swept_angles,
                                                  relative_error, samples_for, swept_angle)

METHODS = ("closed-form", "cvodes", "both")


def to_boundary(xs):
    """Samples in the boundary's units, as the JSON and plots speak them."""
    return {
        "t_days": units.time_to_days(xs[4]).tolist(),
        "theta_deg": np.degrees(xs[1]).tolist(),
        "r_au": xs[0].tolist(),
        "vr_km_s": units.speed_to_km_s(xs[2]).tolist(),
        "vtheta_km_s": units.speed_to_km_s(xs[3]).tolist(),
    }


def _eps_entries(case, closed):
    """The propagate JSON's eps, its coverage and the range of theta it was taken over."""
    eps, whole, end = relative_error(case, closed)
    source = ("the closed form's own arc: the angle its clock spans in the horizon" if whole
              else "the angles CVODES reaches in the horizon (it escapes short of the "
                   "closed form's span)")
    theta_range = {"from_deg": math.degrees(closed[1, 0]), "to_deg": math.degrees(end),
                   "source": source}
    return {"eps": eps, "eps_over_whole_arc": whole, "eps_theta_range": theta_range}


def run(case, method="both", samples=None):
    """What ``esail-opt propagate`` writes: one object per method, and eps for both."""
    if method not in METHODS:
        raise InputError(f"method = {method!r} is not one of {', '.join(METHODS)}")
    samples = samples_for(case) if samples is None else samples
    out = {
        "input": {
            "a0_au": case.a0_au, "e0": case.e0, "nu0_deg": case.nu0_deg,
            "ac_mm_s2": case.ac_mm_s2, "alpha_deg": case.alpha_deg, "years": case.years,
            "samples": samples, "b1": case.coefficients[0], "b2": case.coefficients[1],
        }
    }
    if method in ("closed-form", "both"):
        closed = closed_form(case, samples)
        out["closed_form"] = to_boundary(closed)
    if method in ("cvodes", "both"):
        # A first run in time finds the angle at the horizon; the second samples it.
        out["cvodes"] = to_boundary(cvodes_at_theta(case, swept_angle(case), samples))
    if method == "both":
        out.update(_eps_entries(case, closed))
    return out


# -- Grids: many fixed attitudes at once (``esail-opt propagate`` with ranges) --

#: The fields a grid may range over, slowest-varying first, and the CLI options naming them.
GRID_FIELDS = {"a0_au": "a0", "e0": "e0", "nu0_deg": "nu0", "ac_mm_s2": "ac",
               "alpha_deg": "alpha"}
#: Most cases one grid may hold: each costs two CVODES flights.
MAX_GRID_CASES = 20_000
#: What a grid's picture may show: a column of the grid's table and its axis label.
PLOT_KEYS = {"eps": ("eps_percent", r"$\epsilon$ (Eq. 27) [%]"),
             "a": ("closed_form_a_au", "closed form: final a [au]"),
             "e": ("closed_form_e", "closed form: final e")}
#: The grid table's columns, in order (inputs first).
GRID_COLUMNS = (*GRID_FIELDS, "years", "swept_deg", "eps_percent", "closed_form_a_au",
                "closed_form_e", "closed_form_r_au", "closed_form_t_days", "cvodes_a_au",
                "cvodes_e", "cvodes_r_au")


def grid_cases(values, years):
    """Every combination of ``values`` (field of :data:`GRID_FIELDS` -> numbers), the first
    field varying slowest; InputError, before anything is flown, for a value outside its
    field's range or more than :data:`MAX_GRID_CASES` cases."""
    import itertools

    axes = [list(values[field]) for field in GRID_FIELDS]
    count = math.prod(len(axis) for axis in axes)
    if count > MAX_GRID_CASES:
        raise InputError(f"the grid has {count} cases; allowed [1, {MAX_GRID_CASES}] "
                         "(fewer COUNTs)")
    return [FixedAttitudeCase(a0_au=a0, e0=e0, nu0_deg=nu0, ac_mm_s2=ac, alpha_deg=alpha,
                              years=years)
            for a0, e0, nu0, ac, alpha in itertools.product(*axes)]


def run_grid(values, years, samples=None):
    """What ``esail-opt propagate`` writes for ranges: each case flown as Figs. 3-4 fly
    theirs (:func:`eps_over_swept_angles`), to the angle CVODES sweeps in the horizon.  A
    dict: ``input`` (axes and years), ``ranged`` (fields with more than one value),
    ``columns`` (:data:`GRID_COLUMNS`, a list each, a row per case: eps of Eq. 27 in
    percent, the closed form's final osculating a, e, r and own clock, CVODES's a, e and r)
    and ``invalid`` ({row index: reason}, that case's results null).
    """
    cases = grid_cases(values, years)
    results = eps_over_swept_angles(cases, samples)
    good = [k for k, r in enumerate(results) if r.error is None]
    nan = np.full(len(cases), np.nan)
    closed_a, closed_e, cvodes_a, cvodes_e = (nan.copy() for _ in range(4))
    closed_r, closed_t, cvodes_r = nan.copy(), nan.copy(), nan.copy()
    if good:
        ends = np.column_stack([results[k].closed[:, -1] for k in good])
        numeric = np.column_stack([results[k].numeric[:, -1] for k in good])
        closed_a[good], closed_e[good] = classical_columns(ends)
        cvodes_a[good], cvodes_e[good] = classical_columns(numeric)
        closed_r[good], cvodes_r[good] = ends[0], numeric[0]
        closed_t[good] = units.time_to_days(ends[4])
    columns = {field: [getattr(c, field) for c in cases] for field in GRID_FIELDS}
    columns.update({
        "years": [years] * len(cases),
        "swept_deg": [math.degrees(r.span) for r in results],
        "eps_percent": [100 * r.eps for r in results],
        "closed_form_a_au": closed_a.tolist(), "closed_form_e": closed_e.tolist(),
        "closed_form_r_au": closed_r.tolist(), "closed_form_t_days": closed_t.tolist(),
        "cvodes_a_au": cvodes_a.tolist(), "cvodes_e": cvodes_e.tolist(),
        "cvodes_r_au": cvodes_r.tolist(),
    })
    return {
        "input": {"axes": {field: [float(v) for v in values[field]] for field in GRID_FIELDS},
                  "years": years, "samples": samples, "b1": EXACT[0], "b2": EXACT[1]},
        "ranged": [field for field in GRID_FIELDS if len(values[field]) > 1],
        "columns": columns,
        "invalid": {str(k): str(r.error) for k, r in enumerate(results) if r.error},
        "note": "each case flown to the angle CVODES (tolerance 1e-12) sweeps in the horizon, "
                "as the paper's Figs. 3-4: eps_percent is Eq. 27 over that angle (100 max "
                "|r_cvodes - r_closed_form| / r0); closed_form_* at that angle (t_days is its "
                "own clock), cvodes_* at the horizon; null where the closed form does not hold",
    }


def grid_csv(data):
    """The grid's table as CSV text: a header of :data:`GRID_COLUMNS`, a row per case."""
    columns = data["columns"]
    lines = [",".join(GRID_COLUMNS)]
    for k in range(len(columns["eps_percent"])):
        lines.append(",".join("" if columns[c][k] is None or not math.isfinite(columns[c][k])
                              else repr(float(columns[c][k])) for c in GRID_COLUMNS))
    return "\n".join(lines) + "\n"


def grid_figure(data, plot="eps", ax=None):
    """A grid's ``plot`` (a key of :data:`PLOT_KEYS`) over its ranged axes: a line for one,
    else a map over the first two (grey where empty) at the first value of the others."""
    from esail_opt.app.plots import axes_or_new

    column, label = PLOT_KEYS[plot]
    fig, ax = axes_or_new(ax, figsize=(7, 4.5))
    axes = data["input"]["axes"]
    shape = [len(axes[f]) for f in GRID_FIELDS]
    values = np.array([np.nan if v is None else v for v in data["columns"][column]],
                      float).reshape(shape)
    ranged = data["ranged"] or [list(GRID_FIELDS)[-1]]
    names = list(GRID_FIELDS)
    index = tuple(slice(None) if f in ranged[:2] else 0 for f in names)
    section = values[index]
    fixed = [f"{f} = {axes[f][0]:g}" for f in names if f not in ranged[:2]]
    if len(ranged) == 1:
        ax.plot(axes[ranged[0]], section, "o-")
        ax.set_xlabel(ranged[0])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    else:
        x, y = axes[ranged[0]], axes[ranged[1]]
        mesh = ax.pcolormesh(x, y, np.ma.masked_invalid(section).T, shading="nearest",
                             cmap="viridis")
        ax.set_facecolor("0.85")
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set_xlabel(ranged[0])
        ax.set_ylabel(ranged[1])
    ax.set_title(f"{data['input']['years']:g} years, " + ", ".join(fixed), fontsize=8)
    return fig
