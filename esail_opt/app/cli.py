"""The ``esail-opt`` command line: each subcommand parses its options here and hands the
work to the module that owns it; :data:`EPILOG` gives every exit status."""

import argparse
import atexit
import contextlib
import errno
import logging
import os
import signal
import sys
import threading

from esail_opt.errors import (FigureError, InputError, NoStart, OutputError, Terminated,
                              number_range)
from esail_opt.runtime.signals import terminate_as_interrupt

EXIT_INPUT = 2
#: An output that cannot be written (full disk, read-only folder); 1 says "not verified".
EXIT_OUTPUT = 3
#: A figure not drawn, the rest of its set written; 3 says the files are not there.
EXIT_FIGURE = 4
#: A file system refusing an output: full, read-only, forbidden, or something in the way.
_OUTPUT_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                  errno.EISDIR, errno.ENOTDIR)
EPILOG = ("exit status: 0 converged and verified; 1 not converged or not verified (one "
          "line says which bound was missed); 2 bad input (nothing written; refused before the "
          "solve, or after it for a flight found to end past the ephemeris); 3 an output "
          "could not be written (full disk, read-only or unsafe folder; the old files "
          "stay); 4 a figure could not be drawn (one line names it; every other file "
          "written); 1 also when no start can be flown (one line says why; nothing "
          "written) and when a Dask cluster is lost (the journal keeps what finished); "
          "130 interrupted by SIGINT, 143 by SIGTERM (nothing half-written)")


def _number(text):
    """argparse type: any float, NaN included, so range checks can name the field."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _numbers(text):
    """argparse type: comma-separated numbers, as :func:`_number` reads each."""
    return tuple(_number(part) for part in text.split(","))


#: eps (Eq. 27, a fraction) above which ``propagate`` warns that one arc is not the flight.
EPS_WARNING = 0.10
RANGE_HELP = "; or START:STOP:COUNT, both ends included, to fly a grid"


def _value_or_range(option, text):
    """A propagate option's values: one number, or a START:STOP:COUNT range
    (:func:`esail_opt.errors.number_range`); InputError naming the option otherwise."""
    if ":" in text:
        return number_range(f"--{option}", text)
    try:
        return [float(text)]
    except ValueError:
        raise InputError(f"--{option} = {text!r} is not a number or START:STOP:COUNT"
                         ) from None


def _add_propagate(sub):
    p = sub.add_parser(
        "propagate",
        help="fly fixed attitudes from a parking orbit (closed form and/or CVODES)",
        description="Fly one fixed pitch angle from a parking orbit with the paper's "
        "closed form (no rectification; it ends where its own clock reaches the "
        "horizon) and/or CVODES on Eqs. 1-2, and write the samples as JSON.  With both, "
        "eps (Eq. 27) is taken over the closed form's arc; `reproduce fig3|fig4` take it "
        "over the angle swept by CVODES in the horizon, as the paper does.  Given a "
        "range (START:STOP:COUNT) for any of --a0, --e0, --nu0, --ac and --alpha, it flies "
        "every case of the grid as Figs. 3-4 do (the closed forms in one batched call) and "
        "writes the grid as JSON (--out), CSV and PNG beside it.",
    )
    p.add_argument("--a0", default="1", help="parking orbit semimajor axis, au (default 1)"
                   + RANGE_HELP)
    p.add_argument("--e0", default="0", help="parking orbit eccentricity, [0, 1) (default 0)"
                   + RANGE_HELP)
    p.add_argument("--nu0", default="0", help="departure true anomaly, deg (default 0)"
                   + RANGE_HELP)
    p.add_argument("--ac", required=True, help="characteristic acceleration, mm/s^2, > 0"
                   + RANGE_HELP)
    p.add_argument("--alpha", required=True, help="pitch angle, deg, in [-90, 90]"
                   + RANGE_HELP)
    p.add_argument("--years", type=_number, required=True, help="horizon, years, > 0")
    p.add_argument("--method", choices=("closed-form", "cvodes", "both"), default="both",
                   help="one case: what to fly (default both); a grid flies both")
    p.add_argument("--samples", type=int, default=None,
                   help="sample intervals, equal in theta (default: 32 per parking-orbit "
                   "period, at least 200; for a grid, per revolution swept)")
    p.add_argument("--plot", choices=("eps", "a", "e"), default="eps",
                   help="a grid's picture: eps (Eq. 27), or the closed form's final a or e")
    p.add_argument("--out", default=None, help="JSON file to write (default: print a summary "
                   "only); a grid's CSV and PNG go beside it")
    p.set_defaults(run=_run_propagate)


def _run_propagate(args):
    from esail_opt.app import propagate
    from esail_opt.propagation import fixed_attitude
    from esail_opt.runtime.files import check_output_file

    values = {field: _value_or_range(option, getattr(args, option))
              for field, option in propagate.GRID_FIELDS.items()}
    if _out(args) is not None:
        check_output_file(args.out)  # before the flights
    if args.samples is not None and args.samples < 1:
        raise InputError(f"samples = {args.samples} is outside [1, inf)")
    if any(":" in getattr(args, option) for option in propagate.GRID_FIELDS.values()):
        return _run_propagate_grid(args, values)
    case = fixed_attitude.FixedAttitudeCase(
        a0_au=values["a0_au"][0], e0=values["e0"][0], nu0_deg=values["nu0_deg"][0],
        ac_mm_s2=values["ac_mm_s2"][0], alpha_deg=values["alpha_deg"][0], years=args.years)
    return _run_propagate_one(args, case)


def _run_propagate_one(args, case):
    from esail_opt.app import propagate
    from esail_opt.app.outputs import write_json

    print(f"propagating {args.years:g} years at alpha = {case.alpha_deg:g} deg "
          f"({args.method}) ...", file=sys.stderr)
    result = propagate.run(case, args.method, args.samples)
    for key in ("closed_form", "cvodes"):
        if key in result:
            last = {name: values[-1] for name, values in result[key].items()}
            print(f"{key:12s} end: t = {last['t_days']:.2f} d, theta = {last['theta_deg']:.2f} deg, "
                  f"r = {last['r_au']:.6f} au, v_r = {last['vr_km_s']:.4f} km/s, "
                  f"v_theta = {last['vtheta_km_s']:.4f} km/s")
    if "eps" in result:
        span = result["eps_theta_range"]
        print(f"eps (Eq. 27) = {100 * result['eps']:.3f} % over theta = {span['from_deg']:.2f} .. "
              f"{span['to_deg']:.2f} deg: {span['source']}")
        if result["eps"] > EPS_WARNING:
            print(f"esail-opt propagate: warning: eps = {100 * result['eps']:.3g} %: one "
                  "closed-form arc this long is not the flight (its error grows with the "
                  "angle it sweeps); `esail-opt solve` restarts the arc (rectification)",
                  file=sys.stderr)
    if args.out:
        write_json(args.out, result)
        print(f"wrote {args.out}")
    return 0


def _run_propagate_grid(args, values):
    from pathlib import Path

    from esail_opt.app import propagate
    from esail_opt.app.outputs import save_figure, write_json
    from esail_opt.runtime.files import atomic_path

    if args.method != "both":
        raise InputError(f"method = {args.method!r} with ranges: a grid flies both; "
                         "allowed: both")
    count = len(propagate.grid_cases(values, args.years))
    print(f"propagating {count} cases of {args.years:g} years ...", file=sys.stderr)
    data = propagate.run_grid(values, args.years, args.samples)
    eps = [v for v in data["columns"]["eps_percent"] if v == v]
    print(f"{count} cases, {len(data['invalid'])} where the closed form does not hold; eps "
          f"(Eq. 27) " + (f"from {min(eps):.3f} to {max(eps):.3f} %" if eps else "nowhere"))
    if args.out:
        out = Path(args.out)
        csv, png = out.with_suffix(".csv"), out.with_suffix(".png")
        with atomic_path(csv) as tmp:
            tmp.write_text(propagate.grid_csv(data))
        save_figure(propagate.grid_figure(data, args.plot), png)
        write_json(out, data)
        print(f"wrote {out}, {csv} and {png}")
    return 0


def _add_reproduce(sub):
    p = sub.add_parser("reproduce", help="reproduce the paper's figures",
                       description="Write a PNG and a JSON for one of the paper's figures.")
    # A metavar keeps argparse from listing the choices (and importing them) at start-up.
    p.add_argument("figure", metavar="FIGURE", choices=_FigureNames(),
                   help="one of %(choices)s")
    p.add_argument("--out", default="results/paper", help="output directory (default results/paper)")
    p.set_defaults(run=_run_reproduce)


def _figures():
    from esail_opt.app import reproduce

    return reproduce.FIGURES


class _FigureNames:
    """The reproduce command's choices, read from ``reproduce.FIGURES`` only when argparse
    asks: that module imports scipy and matplotlib, which no other command needs at start."""

    def __contains__(self, name):
        return name in _figures()

    def __iter__(self):
        return iter(sorted(_figures()))


def _run_reproduce(args):
    from esail_opt.runtime.files import check_output_dir

    out = check_output_dir(_out(args))  # before the figure's work
    progress = progress_printer("reproduce")
    written = _figures()[args.figure](out, progress)
    progress.done()
    for path in written:
        print(f"wrote {path}")
    return 0


def _add_tolerance(p):
    p.add_argument("--tol-km", type=_number, default=None,
                   help="bound on the flown position miss, km (default: the problem's, "
                        "10000 unless it sets one)")
    p.add_argument("--tol-m-s", type=_number, default=None,
                   help="bound on the flown velocity miss, m/s (default: the problem's, 10)")


def _add_no_plots(p, later):
    p.add_argument("--no-plots", action="store_true",
                   help=f"write everything but the figures ({later})")


def _load(args):
    """The problem file with the command line's segments and tolerance applied."""
    from esail_opt.optimisation.problem_file import load_problem

    if getattr(args, "segments", None) is not None and args.segments < 1:
        raise InputError(f"segments = {args.segments} is outside [1, inf)")
    problem = load_problem(args.problem_file)
    if args.segments is not None:
        problem = problem.with_segments(args.segments)
    return problem.with_tolerance(args.tol_km, args.tol_m_s)


def progress_printer(command):
    """``progress(text)`` for long work: on a terminal one line rewritten in place (erased
    by ``.done()``), in a log a line per message; both end in " ..." unlike the verdict."""
    tty = sys.stderr.isatty()

    def progress(text):
        if tty:
            print(f"\r\033[Kesail-opt {command}: {text} ...", end="", file=sys.stderr,
                  flush=True)
        else:
            print(f"esail-opt {command}: {text} ...", file=sys.stderr, flush=True)

    def done():
        if tty:
            print("\r\033[K", end="", file=sys.stderr, flush=True)

    progress.done = done
    return progress


def _add_solve(sub):
    p = sub.add_parser(
        "solve", help="optimise a problem file and verify the result on CVODES",
        description="Solve the problem defined in PROBLEM.py (a file that builds "
        "`problem = esail_opt.Problem(...)`) by closed-form multiple shooting and Ipopt, "
        "control the closed form's error (defect correction against the equations of "
        "motion, more sub-arcs where it is strained) until the schedule, flown on them "
        "with CVODES, meets the tolerance, and write solution.json, schedule.csv, "
        "trajectory.png, timeline.png and, for a dated 3-D flight, trajectory.oem (with "
        "--polish, schedule_closed_form.csv as well).  The equations are Eqs. 1-2 in the plane, and "
        "the Cartesian ones for a real body's problem, which flies in three dimensions "
        "unless it sets planar=True.  With --polish, then re-solve the same schedule on "
        "the exact equations in time and verify that it flies to within 1 m and 1 mm/s.  "
        "Exit status 0 only for a converged and verified solve (and polish); 1 with one "
        "line saying which bound was missed and by how much; 2 for bad input; 3 when the "
        "output folder cannot be written (checked before the solve); 4 when a verified "
        "solve's figure could not be drawn (every other file written); 130 when "
        "interrupted, 143 on SIGTERM (nothing half-written).",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--segments", type=int, default=None,
                   help="number of control segments N, >= 1 (default: the problem's)")
    _add_tolerance(p)
    p.add_argument("--out", default=None, help="output directory (default results/<problem name>)")
    p.add_argument("--polish", action="store_true",
                   help="polish the optimum on the exact equations of motion (in time), held "
                   "to 1 m and 1 mm/s; the files are then the polished flight")
    p.add_argument("--object-name", default=None,
                   help="OBJECT_NAME of trajectory.oem (default: the problem's name)")
    p.add_argument("--object-id", default=None,
                   help="OBJECT_ID of trajectory.oem (default: the object's name)")
    _add_no_plots(p, "`esail-opt plot` draws them later")
    p.set_defaults(run=_run_solve)


def _run_solve(args):
    from pathlib import Path

    from esail_opt.app import report, solution
    from esail_opt.runtime.files import check_output_dir
    from esail_opt.app.solution_files import SOLUTION_FILES

    problem = _load(args)
    out = _out(args) or Path("results") / problem.name
    nearest_out = out.with_name(out.name + "_nearest")
    for folder in (out, nearest_out):  # before the solve
        check_output_dir(folder, name=None if args.out else folder.name, files=SOLUTION_FILES)
    progress = progress_printer("solve")
    sol, near = solution.solve_with_nearest(problem, progress=progress, polish=args.polish)
    progress.done()
    figures = None
    oem_names = {"object_name": args.object_name, "object_id": args.object_id}
    try:
        written = sol.write(out, plots=not args.no_plots, **oem_names)
        if near is not None:
            # The question asked has no sail; the nearest one that flies is a whole answer.
            written += near.write(nearest_out, plots=not args.no_plots, **oem_names)
    except FigureError as err:
        written, figures = err.written, err
    for path in written:
        print(f"wrote {path}")
    print(sol.summary())
    if figures is not None:
        print(f"esail-opt solve: error: {figures}", file=sys.stderr)
    if not sol.verified:
        # A polish that failed leaves the closed-form answer's verdict standing: say both.
        reason = (sol.verification_note if not sol.flight_verified else
                  f"polish {sol.polish.note}; the closed-form answer stays "
                  f"{sol.verification_note}")
        if near is not None:
            reason += ("; " + report.nearest_feasible_line(sol.nearest_feasible)
                       + f", written to {nearest_out}")
        print(f"esail-opt solve: {reason}", file=sys.stderr)
        return 1
    return 0 if figures is None else EXIT_FIGURE


def _add_plot(sub):
    p = sub.add_parser(
        "plot", help="draw a solution's, porkchop's, search's or sweep's figures again from "
        "its files",
        description="Draw the figures of the run in FOLDER again, without solving: "
        "trajectory.png and timeline.png from its solution.json, porkchop.png from its "
        "porkchop.json, search.png from its search.json (a search's best/ is a solution's "
        "folder), sweep.png from its sweep.json.  Exit status 0 when every figure was "
        "written; 2 when FOLDER is not a folder or holds none of these files (or one that "
        "cannot be read); 4 when a figure could not be drawn (the others are written).",
    )
    p.add_argument("folder", metavar="FOLDER", help="a run's output folder, e.g. results/NAME")
    p.set_defaults(run=_run_plot)


#: The records `esail-opt plot` draws from, each with its own figures.
PLOTTED = ("solution.json", "porkchop.json", "search.json", "sweep.json")


def _run_plot(args):
    from pathlib import Path

    folder = Path(args.folder)
    if not folder.is_dir():
        raise InputError(f"folder = {str(folder)!r} is not a folder (a run's output folder "
                         "is expected, e.g. results/NAME)")
    records = [folder / name for name in PLOTTED if (folder / name).is_file()]
    if not records:
        raise InputError(f"folder = {str(folder)!r} holds no {', '.join(PLOTTED[:-1])} or "
                         f"{PLOTTED[-1]} to draw from")
    written, failures = [], []
    for record in records:
        drawn, failed = _plot_record(record)
        written += drawn
        failures += failed
    for path in written:
        print(f"wrote {path}")
    if failures:
        raise FigureError(failures, written)
    return 0


def _plot_record(record):
    """Draw the figures of one of :data:`PLOTTED` into its folder: the paths written and
    one line per figure that could not be drawn."""
    import json

    from esail_opt.app import plots

    if record.name == "solution.json":
        from esail_opt.app.solution import Solution

        return plots.write_plots(Solution.load(record), record.parent)
    try:
        result = json.loads(record.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise InputError(f"{record}: cannot be read as JSON ({err})") from None
    kind = record.stem
    if not isinstance(result, dict) or not isinstance(result.get("rows"), list):
        raise InputError(f"{record}: not a {kind}'s record (no list of rows)")
    if kind == "search":
        from esail_opt.app import search

        return plots.write_figures([("search.png", lambda: search.figure(result))],
                                   record.parent)
    if kind == "sweep":
        from esail_opt.app import sweep

        return plots.write_figures([("sweep.png", lambda: sweep.figure(result))],
                                   record.parent)
    from esail_opt.app import porkchop

    if result.get("cells") != len(result["rows"]):
        raise InputError(f"{record}: holds {len(result['rows'])} rows for its "
                         f"{result.get('cells')!r} cells; run the porkchop again")
    return plots.write_figures([("porkchop.png", lambda: porkchop.figure(result))],
                               record.parent)


def _add_search(sub):
    p = sub.add_parser(
        "search", help="global search of a minimum-time problem over revolution classes",
        description="Solve the minimum-time problem in PROBLEM.py once per revolution class "
        "(the free start; then final-angle windows of whole revolutions for an orbit "
        "transfer, or the sail's whole turns on the body for a rendezvous), polish every "
        "distinct optimum on the exact equations of motion, rank them on the verified "
        "exact time of flight, and write search.json, search.csv, search.png and best/.  "
        "Exit status 0 "
        "when the best optimum's polish is verified to 1 m and 1 mm/s (with --no-polish: "
        "when its closed-form flight meets the problem's tolerance), 1 otherwise.",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--extra-revolutions", type=int, default=2,
                   help="revolution classes above the free optimum's, in [0, 20] (default 2)")
    p.add_argument("--segments", type=int, default=None,
                   help="number of control segments N, >= 1 (default: the problem's)")
    p.add_argument("--no-polish", action="store_true",
                   help="rank on the closed-form times without polishing (faster)")
    _add_tolerance(p)
    p.add_argument("--out", default=None,
                   help="output directory (default results/<problem name>_search)")
    _add_no_plots(p, "`esail-opt plot OUT/best` draws the best optimum's later")
    p.set_defaults(run=_run_search)


def _run_search(args):
    from pathlib import Path

    from esail_opt.app import search
    from esail_opt.runtime.files import check_output_dir

    out = _out(args)
    problem = _load(args)
    out = out or Path("results") / f"{problem.name}_search"
    check_output_dir(out, name=None if args.out else out.name,  # before the search
                     files=search.SEARCH_TABLES)
    progress = progress_printer("search")
    data, solutions = search.run(problem, args.extra_revolutions, polish=not args.no_polish,
                                 progress=progress)
    if not data["rows"]:
        # Ipopt's failures from every start say nothing about the target's reachability.
        print(f"esail-opt search: no start converged ({len(data['starts'])} starts); "
              "nothing written", file=sys.stderr)
        return 1
    for path in search.write(data, solutions, out, plots=not args.no_plots):
        print(f"wrote {path}")
    print("\n".join(search.summary(data)))
    best = data["best"]
    if best["verified"]:
        return 0
    if best["flight_verified"]:
        print("esail-opt search: the best optimum's flight meets the problem's tolerance, "
              f"but its polish is {best['note']}", file=sys.stderr)
    else:
        print("esail-opt search: the best optimum is NOT verified (see search.json)",
              file=sys.stderr)
    return 1


def _add_sweep(sub):
    p = sub.add_parser(
        "sweep", help="solve a problem file over a range of one parameter",
        description="Solve the problem in PROBLEM.py once per value of one parameter, "
        "on a local process pool (or a Dask distributed scheduler), and write sweep.csv, "
        "sweep.json and sweep.png.  A member that fails, does not converge or is not "
        "verified within the tolerance is reported in its row and does not stop the "
        "others; exit status 1 if any is.  Finished members are journaled to sweep.jsonl "
        "in the output directory as they finish; --resume runs only those missing from it.  "
        "A member whose worker process dies is run again on a fresh pool (twice at most).  "
        "Sweepable names: {sweepable}.",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--param", required=True, metavar="NAME=START:STOP:COUNT",
                   help="parameter and its grid, e.g. ac_mm_s2=0.2:2:10 (COUNT values, ends included)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes, in [1, 64] (default: min(COUNT, CPUs))")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on this Dask distributed scheduler instead, tcp://HOST:PORT "
                   "(needs the dask extra)")
    p.add_argument("--polish", action="store_true",
                   help="also polish every member on the exact Eqs. 1-2 (in time)")
    p.add_argument("--robust", type=int, default=0, metavar="RUNS",
                   help="also fly every verified member RUNS times under the varying solar "
                   "wind, open loop and guided, as `esail-opt robust` does with its defaults "
                   "(a dated 3-D rendezvous; default 0: none)")
    p.add_argument("--out", default=None,
                   help="output directory (default results/<problem name>_sweep_<NAME>)")
    p.add_argument("--resume", action="store_true",
                   help="keep the members journaled in the output directory's sweep.jsonl "
                   "and run only the others (without it the journal starts afresh)")
    _add_tolerance(p)
    p.set_defaults(run=_run_sweep)


def _out(args, option="--out"):
    """The folder option ``option`` as a Path, None when it is not given; an empty one
    is refused (it is not the default folder)."""
    from pathlib import Path

    value = getattr(args, option.lstrip("-").replace("-", "_"))
    if value is None:
        return None
    if not str(value).strip():
        raise InputError(f"{option} = {value!r}: give a folder name, or leave {option} "
                         "out")
    return Path(value)


#: Options whose range may start with a minus sign: ``--tof -100:850:2`` reaches the
#: value's own check instead of being taken for an option.
_RANGE_OPTIONS = ("--param", "--depart", "--tof", "--a0", "--e0", "--nu0", "--ac", "--alpha")


def _sweepable():
    from esail_opt.app.sweep import SWEEPABLE

    return ", ".join(SWEEPABLE)


class _Parser(argparse.ArgumentParser):
    """The subcommands' parser: joins a range after an option of :data:`_RANGE_OPTIONS`,
    and fills a description's ``{sweepable}`` only when help is printed, so that building
    the parser (every command does) does not import the sweep module."""

    def parse_known_args(self, args=None, namespace=None):
        args = list(sys.argv[1:] if args is None else args)
        joined = []
        for arg in args:
            if joined and joined[-1] in _RANGE_OPTIONS and arg.startswith("-") \
                    and ":" in arg:
                joined[-1] = f"{joined[-1]}={arg}"
            else:
                joined.append(arg)
        return super().parse_known_args(joined, namespace)

    def format_help(self):
        if self.description and "{sweepable}" in self.description:
            self.description = self.description.replace("{sweepable}", _sweepable())
        return super().format_help()


def _run_sweep(args):
    from esail_opt.app import sweep

    name = args.param.partition("=")[0].strip()
    # The folder first: the journal goes there while the members run.
    out = _out(args) or sweep.default_out_dir(args.problem_file, args.param)
    result = sweep.run(args.problem_file, args.param, workers=args.workers,
                       scheduler=args.scheduler, polish=args.polish, out_dir=out,
                       resume=args.resume, tol_km=args.tol_km, tol_m_s=args.tol_m_s,
                       robust_runs=args.robust,
                       progress=lambda row, done, total: _sweep_line(row, done, total, name))
    for path in sweep.write(result, out):
        print(f"wrote {path}")
    resumed = f", {len(result['resumed'])} kept from the journal" if result["resumed"] else ""
    print(f"{len(result['rows']) - result['failed']}/{len(result['rows'])} members converged "
          f"and verified in {result['wall_seconds']:.1f} s ({result['executor']}{resumed})")
    return 0 if result["failed"] == 0 else 1


def _add_porkchop(sub):
    p = sub.add_parser(
        "porkchop", help="scan a launch window: departure dates, or dates x flight times",
        description="Solve the problem in PROBLEM.py (which departs from a body, "
        "BodyDeparture) at every departure date of --depart, with its own objective; with "
        "--tof, at every (date, time of flight) cell, the objective's time of flight "
        "replaced (a fixed-time objective such as MinAcceleration: the a_c a transfer "
        "needs).  Neighbouring cells share one NLP and warm-start from each other; every "
        "cell is verified by CVODES on the equations of motion (in three dimensions "
        "unless the problem sets planar=True) against the ephemeris.  Writes porkchop.json, "
        "porkchop.csv and porkchop.png; exit status 1 if any cell is not verified.  Runs "
        "on the scan engine: journal (porkchop.jsonl), --resume, retries, Dask.",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--depart", required=True, metavar="START:STOP:COUNT",
                   help="departure dates, ISO 8601 (TDB), e.g. 2030-01-01:2033-01-01:24")
    p.add_argument("--tof", default=None, metavar="START:STOP:COUNT",
                   help="times of flight in days, e.g. 200:400:12 (a two-dimensional scan)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes, in [1, 64] (default: the CPUs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on this Dask distributed scheduler instead, tcp://HOST:PORT "
                   "(needs the dask extra)")
    p.add_argument("--out", default=None,
                   help="output directory (default results/<problem name>_porkchop)")
    p.add_argument("--resume", action="store_true",
                   help="keep the cells journaled in the output directory's porkchop.jsonl")
    p.add_argument("--cells-out", default=None, metavar="DIR",
                   help="also write each verified cell's solution folder (solution.json, "
                   "schedule.csv) into DIR, as its cells end (local pool only)")
    _add_tolerance(p)
    _add_no_plots(p, "`esail-opt plot OUT` draws it later")
    p.set_defaults(run=_run_porkchop)


def _run_porkchop(args):
    from pathlib import Path

    from esail_opt.app import porkchop
    from esail_opt.runtime.files import check_output_dir
    from esail_opt.optimisation.problem_file import load_problem

    out = _out(args) or Path("results") / f"{load_problem(args.problem_file).name}_porkchop"
    check_output_dir(out)
    cells = _out(args, "--cells-out")
    result = porkchop.run(args.problem_file, args.depart, args.tof, workers=args.workers,
                          scheduler=args.scheduler, out_dir=out, resume=args.resume,
                          tol_km=args.tol_km, tol_m_s=args.tol_m_s, progress=_porkchop_lines(),
                          cells_out=cells)
    for path in porkchop.write(result, out, plots=not args.no_plots):
        print(f"wrote {path}")
    best = result["best"]
    if best is not None:
        unit = result["objective_unit"] or ""
        print(f"best: depart {best['departure_date']}, arrive {best['arrival_date']}, "
              f"{best['objective']:.6g} {unit}".rstrip())
        border = porkchop.best_at_border(result)
        if border is not None:
            print(f"  the best cell is at {border} scanned: a better one may lie beyond it")
    print(f"{result['verified_cells']}/{result['cells']} cells verified in "
          f"{result['wall_seconds']:.1f} s ({result['executor']})")
    if result["not_verified"]:
        no_sail = result.get("no_sail_cells", 0)
        of_which = f", {no_sail} of them past the edge of the feasible (no sail)" if no_sail else ""
        print(f"esail-opt porkchop: {result['not_verified']} cell(s) not verified{of_which}",
              file=sys.stderr)
        return 1
    return 0


def _porkchop_lines():
    """A porkchop's progress: a line on stderr per cell as its job's forward pass ends
    it, and one more if the job's end (repair pass, edge of the feasible) changed it."""
    told = {}  # index -> what its line said

    def line(row, done, total):
        cell = row["departure_date"].removesuffix("T00:00:00")
        if row["tof_days_grid"] is not None:
            cell += f", tof {row['tof_days_grid']:g} d"
        if row["verified"]:
            what = f"{row['objective']:.6g} {row['objective_unit'] or ''}, verified".replace(
                " ,", ",")
        elif row["no_sail"]:
            what = "no sail (shorter than the edge of the feasible)"
        else:
            what = f"NOT verified ({row['error']})"
        # A cell told again is a correction (no count), and only if its line changes.
        again = row["index"] in told
        if told.get(row["index"]) == what:
            return
        told[row["index"]] = what
        print(f"esail-opt porkchop: {'' if again else f'[{done}/{total}] '}{cell}: {what}"
              + (" (changed at its job's end)" if again else ""), file=sys.stderr, flush=True)

    return line


def _add_robust(sub):
    from esail_opt.propagation.solar_wind import CORR_DAYS, SIGMA

    p = sub.add_parser(
        "robust", help="fly a solved rendezvous many times under a varying solar wind",
        description="Fly the schedule solved in FOLDER (a dated rendezvous in three "
        "dimensions, as `esail-opt solve` wrote it) RUNS times on the batched closed form, "
        "the thrust times a random factor per arc (mean 1, standard deviation SIGMA, "
        "correlation time CORR_DAYS): open loop, and guided (re-targeted every GUIDE_DAYS "
        "from where the flight is, and on the approach at half GUIDE_DAYS before arrival, "
        "a quarter, and so on down to 1.5 h, the sail having MARGIN more a_c than the "
        "schedule asks).  CHECK flights of each kind are flown again on CVODES.  Writes robust.csv "
        "(each flight's miss and closest approach), robust.json (percentiles and the "
        "fraction within the tolerance, each with its 95 % interval, the checks) and "
        "robust.png into "
        "FOLDER_robust.  Exit status 0 when every checked flight lands where the closed "
        "form said; 1 otherwise; 2 for bad input; 3 when the folder cannot be written.")
    p.add_argument("folder", metavar="FOLDER", help="a solve's output folder (solution.json)")
    p.add_argument("--runs", type=int, default=1000, help="flights of each kind (default 1000)")
    p.add_argument("--sigma", type=_number, default=SIGMA,
                   help=f"standard deviation of the thrust factor, a fraction (default {SIGMA})")
    p.add_argument("--corr-days", type=_number, default=CORR_DAYS,
                   help=f"correlation time of the thrust factor, days (default {CORR_DAYS})")
    p.add_argument("--seed", type=int, default=1, help="seed of the draws (default 1)")
    p.add_argument("--guide-days", type=_number, default=30.0,
                   help="days between re-targetings; 0 flies open loop only (default 30)")
    p.add_argument("--margin", type=_numbers, default=(0.1,),
                   help="the sail's a_c above what the schedule asks, a fraction, for the "
                        "guided flights; several, comma-separated, fly one guided kind "
                        "each (default 0.1)")
    p.add_argument("--check", type=int, default=4,
                   help="flights of each kind flown again on CVODES (default 4)")
    p.add_argument("--out", default=None, help="output folder (default FOLDER_robust)")
    _add_no_plots(p, "robust.csv and robust.json hold every number")
    p.set_defaults(run=_run_robust)


def _run_robust(args):
    from pathlib import Path

    from esail_opt.app import robust
    from esail_opt.runtime.files import check_output_dir
    from esail_opt.app.solution import Solution
    from esail_opt.propagation.solar_wind import SolarWind

    folder = Path(args.folder)
    source = folder / "solution.json" if folder.is_dir() else folder
    if not source.is_file():
        raise InputError(f"FOLDER = {args.folder!r} holds no solution.json; give a folder "
                         "`esail-opt solve` wrote")
    request = robust.Request(runs=args.runs, wind=SolarWind(args.sigma, args.corr_days),
                             seed=args.seed, guide_days=args.guide_days, margins=args.margin,
                             check=args.check)
    sol = Solution.load(source)
    out = _out(args) or source.parent.with_name(source.parent.name + "_robust")
    check_output_dir(out, name=None if args.out else out.name, files=robust.NAMES)
    progress = progress_printer("robust")
    result = robust.run(sol, request, progress)
    progress.done()
    for path in robust.write(result, out, plots=not args.no_plots):
        print(f"wrote {path}")
    print(result.summary())
    if not result.verified:
        print("esail-opt robust: a flight checked on CVODES did not land where the closed "
              "form said (see the check lines above)", file=sys.stderr)
        return 1
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="esail-opt", description="E-sail trajectory propagation and optimisation",
        epilog=EPILOG)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_propagate(sub)
    _add_reproduce(sub)
    _add_solve(sub)
    _add_plot(sub)
    _add_search(sub)
    _add_sweep(sub)
    _add_porkchop(sub)
    _add_robust(sub)
    return parser


def _sweep_line(row, done, total, name):
    """One line on stderr per finished member of a sweep."""
    if row["error"] is None:
        what = f"converged, tof {row['tof_days']:.3f} d"
        if row.get("verified"):
            what += ", verified"
        if row.get("tof_days_exact") is not None:
            what += (f", exact {row['tof_days_exact']:.3f} d "
                     f"({'verified' if row['exact_verified'] else 'NOT verified'})")
        if row.get("robust_guided_p95_km") is not None:
            what += (f", under wind p95 {row['robust_open_p95_km']:.3g} km open loop, "
                     f"{row['robust_guided_p95_km']:.3g} km guided")
    else:
        what = f"FAILED ({row['error']})"
    seconds = f" in {row['seconds']:.1f} s" if row["seconds"] is not None else ""
    print(f"esail-opt sweep: [{done}/{total}] {name} = {row['value']:g}: {what}{seconds}",
          file=sys.stderr, flush=True)


def _show_library_log():
    """Print the package's log lines (a first compile, a fallback) on stderr, bare."""
    logger = logging.getLogger("esail_opt")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False


def main(argv=None):
    args = build_parser().parse_args(argv)
    return run_command(f"esail-opt {args.command}", args.run, args)


def console():
    """The ``esail-opt`` command: :func:`main` on ``sys.argv`` (one BLAS thread unless the
    environment says otherwise: ``esail_opt/__init__.py``), then :func:`end_process`."""
    end_process(main())


def end_process(code):
    """End the process with exit status ``code``: at once, after the exit handlers and the
    flushes, when the command ran alone (Python's teardown of CasADi's graphs changes
    nothing on disk); through Python's shutdown, which joins them, when threads are alive
    or child processes ran (a scan's pool)."""
    code = 0 if code is None else code
    if threading.active_count() > 1 or "multiprocessing" in sys.modules:
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing to say
            stream.flush()
    os._exit(code)


def run_command(label, run, args):
    """Run ``run(args) -> int`` as a command does and return its exit status: the package's
    log lines go to stderr, SIGTERM stops the run as Ctrl-C does, and each exception a user
    can meet becomes one line ``<label>: error: ...`` (``label`` e.g. ``"esail-opt solve"``)
    and its exit status (:data:`EPILOG`).  ``esail-opt-bench`` runs through here too."""
    _show_library_log()
    from esail_opt.runtime.pool import ClusterLost

    try:
        with terminate_as_interrupt():
            return run(args)
    except (InputError, OutputError, FigureError) as err:
        print(f"{label}: error: {err}", file=sys.stderr)
        return (EXIT_INPUT if isinstance(err, InputError)
                else EXIT_OUTPUT if isinstance(err, OutputError) else EXIT_FIGURE)
    except (ClusterLost, NoStart) as err:
        print(f"{label}: {err}", file=sys.stderr)
        return 1
    except OSError as err:
        if err.errno not in _OUTPUT_ERRNOS:
            raise
        # Met outside the output checks; a rename's error names its target second.
        print(f"{label}: error: cannot write "
              f"{err.filename2 or err.filename or 'an output'}: {err.strerror}",
              file=sys.stderr)
        return EXIT_OUTPUT
    except KeyboardInterrupt as err:
        signum = err.signum if isinstance(err, Terminated) else signal.SIGINT
        what = "interrupted" if signum == signal.SIGINT else \
            f"stopped by {signal.Signals(signum).name}"
        print(f"\n{label}: {what}; nothing half-done was written",
              file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    sys.exit(console())
