"""Reproduction of the paper's figures: each writes a PNG and the JSON of its data."""

import math
import sys
from pathlib import Path

import numpy as np

from esail_opt import fixed_attitude
from esail_opt.files import save_figure, write_json
from esail_opt.physics import constants as units
from esail_opt.physics.closed_form import theta_max_circular
from esail_opt.physics.elements import ac_tilde
from esail_opt.physics.thrust import radial_transverse

#: The maps' grid: 5 deg in pitch (so +/-45 deg is on it) and 0.005 mm/s^2 in a_c.
ALPHA_DEG = np.linspace(-90, 90, 37)
AC_MM_S2 = np.linspace(0.005, 0.1, 20)
YEARS = 5.0
#: Mercury as the paper prints it: 0.308 au is nearly Mercury's perihelion radius,
#: not its semimajor axis (0.387 au); PHYSICS-NOTES.md keeps the printed value.
MERCURY = {"a0": 0.308, "e0": 0.206, "nu0": 0.0}


def _grid_plot(values, label, title, log=False, mark_max=True):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    data = np.ma.masked_invalid(values)
    norm = LogNorm(vmin=data.min(), vmax=data.max()) if log else None
    mesh = ax.pcolormesh(ALPHA_DEG, AC_MM_S2, data.T, shading="nearest", norm=norm, cmap="viridis")
    ax.set_facecolor("0.85")
    cs = ax.contour(ALPHA_DEG, AC_MM_S2, data.T, colors="white", linewidths=0.7,
                    levels=8 if not log else np.logspace(np.log10(data.min()), np.log10(data.max()), 6))
    ax.clabel(cs, fontsize=7, fmt="%.3g")
    fig.colorbar(mesh, ax=ax, label=label)
    if mark_max:
        i, j = np.unravel_index(np.nanargmax(values), values.shape)
        ax.plot(ALPHA_DEG[i], AC_MM_S2[j], "r*", ms=10, label=f"max {values[i, j]:.3g}")
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlabel(r"pitch angle $\alpha_n$ [deg]")
    ax.set_ylabel(r"characteristic acceleration $a_c$ [mm/s$^2$]")
    ax.set_title(title, fontsize=10)
    ax.set_xticks(np.arange(-90, 91, 30))
    return fig


def fig2(out):
    """Fig. 2: theta_max = 1 / (T a~_c) for the circular parking orbit at r0 = 1 au.

    Where T <= 0, q3 never falls and there is no theta_max: such cells are null in
    the JSON and grey in the plot.
    """
    theta_max = np.full((ALPHA_DEG.size, AC_MM_S2.size), np.nan)
    for i, alpha in enumerate(ALPHA_DEG):
        _, T = radial_transverse(math.radians(alpha))
        if T > 1e-12:
            actil = ac_tilde(units.accel_from_mm_s2(AC_MM_S2), 1.0)
            theta_max[i] = np.degrees(theta_max_circular(actil, T))
    out = Path(out)
    data = {
        "figure": "Fig. 2: maximum angle of the first-order solution, circular parking orbit, r0 = 1 au",
        "alpha_deg": ALPHA_DEG.tolist(),
        "ac_mm_s2": AC_MM_S2.tolist(),
        "theta_max_deg": [[None if np.isnan(v) else float(v) for v in row] for row in theta_max],
        "max_theta_max_deg": float(np.nanmax(theta_max)),
        "note": "theta_max_deg[i][j] is at alpha_deg[i], ac_mm_s2[j]; null where T <= 0 "
                "(q3 never decreases, no limit)",
    }
    fig = _grid_plot(theta_max, r"$\theta_{max}$ [deg]",
                     r"Fig. 2: $\theta_{max} = 1/(T\,\tilde a_c)$, circular orbit at 1 au "
                     "(grey: T $\\leq$ 0, unbounded)", log=True, mark_max=False)
    write_json(out / "fig2.json", data)
    save_figure(fig, out / "fig2.png")
    return [out / "fig2.json", out / "fig2.png"]


def eps_map(a0, e0, nu0, label):
    """Eq. 27 over the grid, 5 years, closed form against CVODES."""
    eps = np.empty((ALPHA_DEG.size, AC_MM_S2.size))
    total = eps.size
    for i, alpha in enumerate(ALPHA_DEG):
        for j, ac in enumerate(AC_MM_S2):
            case = fixed_attitude.FixedAttitudeCase(a0, e0, nu0, float(ac), float(alpha), YEARS)
            samples = fixed_attitude.samples_for(case)
            closed = fixed_attitude.closed_form(case, samples)
            eps[i, j], whole = fixed_attitude.relative_error(case, closed)
            if not whole:
                raise RuntimeError(f"{label}: CVODES escaped at alpha={alpha}, ac={ac}")
        done = (i + 1) * AC_MM_S2.size
        print(f"{label}: {done}/{total} cases, max eps so far {100 * eps[: i + 1].max():.2f} %",
              file=sys.stderr, flush=True)
    return eps


def _eps_figure(name, title, a0, e0, nu0, out):
    eps = eps_map(a0, e0, nu0, name)
    out = Path(out)
    data = {
        "figure": title,
        "a0_au": a0, "e0": e0, "nu0_deg": nu0, "years": YEARS,
        "alpha_deg": ALPHA_DEG.tolist(),
        "ac_mm_s2": AC_MM_S2.tolist(),
        "eps": eps.tolist(),
        "max_eps": float(eps.max()),
        "note": "eps[i][j] is Eq. 27 at alpha_deg[i], ac_mm_s2[j]: max over theta of "
                "|r_cvodes - r_closed_form| / r0, closed form without rectification",
    }
    fig = _grid_plot(100 * eps, r"$\epsilon$ [%]", title)
    write_json(out / f"{name}.json", data)
    save_figure(fig, out / f"{name}.png")
    return [out / f"{name}.json", out / f"{name}.png"]


def fig3(out):
    """Fig. 3: eps over 5 years from the circular orbit at 1 au."""
    return _eps_figure("fig3", "Fig. 3: relative error $\\epsilon$ (Eq. 27), 5 years, circular orbit at 1 au",
                       1.0, 0.0, 0.0, out)


def fig4(out):
    """Fig. 4: eps over 5 years from the Mercury case as printed (a0 = 0.308 au)."""
    return _eps_figure("fig4", "Fig. 4: relative error $\\epsilon$ (Eq. 27), 5 years, "
                       "a0 = 0.308 au (as printed), e0 = 0.206, nu0 = 0",
                       MERCURY["a0"], MERCURY["e0"], MERCURY["nu0"], out)


FIGURES = {"fig2": fig2, "fig3": fig3, "fig4": fig4}
