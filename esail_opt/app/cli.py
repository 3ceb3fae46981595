"""The ``esail-opt`` command line.

Each subcommand parses its options here and hands the work to the module that
owns it.  Bad input ends in one line on stderr and exit status 2; see :data:`EPILOG`
for every exit status.
"""

import argparse
import errno
import logging
import signal
import sys

from esail_opt.errors import InputError, OutputError, Terminated

EXIT_INPUT = 2
#: An output that cannot be written (a full disk, a read-only folder): not 1, which
#: says "solved but not verified".
EXIT_OUTPUT = 3
#: The shell's convention for a run stopped by SIGINT (128 + 2).
EXIT_INTERRUPTED = 130
EPILOG = ("exit status: 0 converged and verified; 1 not converged or not verified (one "
          "line says which bound was missed); 2 bad input (nothing solved); 3 an output "
          "could not be written (full disk, read-only or unsafe folder; the old files "
          "stay); 1 also when a Dask cluster is lost (the journal keeps what finished); 130 interrupted by SIGINT, 143 by SIGTERM (nothing half-written)")


def _number(text):
    """argparse type: any float, NaN included, so range checks can name the field."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _add_propagate(sub):
    p = sub.add_parser(
        "propagate",
        help="fly one fixed attitude from a parking orbit (closed form and/or CVODES)",
        description="Fly one fixed pitch angle from a parking orbit with the paper's "
        "closed form (no rectification; it ends where its own clock reaches the "
        "horizon) and/or CVODES on Eqs. 1-2, and write the samples as JSON.  With both, "
        "eps (Eq. 27) is taken over the closed form's arc; `reproduce fig3|fig4` take it "
        "over the angle swept by CVODES in the horizon, as the paper does.",
    )
    p.add_argument("--a0", type=_number, default=1.0, help="parking orbit semimajor axis, au (default 1)")
    p.add_argument("--e0", type=_number, default=0.0, help="parking orbit eccentricity, [0, 1) (default 0)")
    p.add_argument("--nu0", type=_number, default=0.0, help="departure true anomaly, deg (default 0)")
    p.add_argument("--ac", type=_number, required=True, help="characteristic acceleration, mm/s^2, > 0")
    p.add_argument("--alpha", type=_number, required=True, help="pitch angle, deg, in [-90, 90]")
    p.add_argument("--years", type=_number, required=True, help="horizon, years, > 0")
    p.add_argument("--method", choices=("closed-form", "cvodes", "both"), default="both")
    p.add_argument("--samples", type=int, default=None,
                   help="sample intervals, equal in theta (default: 32 per parking-orbit period, at least 200)")
    p.add_argument("--out", default=None, help="JSON file to write (default: print a summary only)")
    p.set_defaults(run=_run_propagate)


def _run_propagate(args):
    from esail_opt.app import fixed_attitude
    from esail_opt.app.files import write_json

    case = fixed_attitude.FixedAttitudeCase(a0_au=args.a0, e0=args.e0, nu0_deg=args.nu0,
                                            ac_mm_s2=args.ac, alpha_deg=args.alpha,
                                            years=args.years)
    if args.samples is not None and args.samples < 1:
        raise InputError(f"samples = {args.samples} is outside [1, inf)")
    print(f"propagating {args.years:g} years at alpha = {args.alpha:g} deg ({args.method}) ...",
          file=sys.stderr)
    result = fixed_attitude.run(case, args.method, args.samples)
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
    if args.out:
        write_json(args.out, result)
        print(f"wrote {args.out}")
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
    asks: importing that module (scipy, matplotlib, the paper's cases) took 1.7 s, which
    every other command paid for at start-up."""

    def __contains__(self, name):
        return name in _figures()

    def __iter__(self):
        return iter(sorted(_figures()))


def _run_reproduce(args):
    progress = progress_printer("reproduce")
    written = _figures()[args.figure](args.out, progress)
    progress.done()
    for path in written:
        print(f"wrote {path}")
    return 0


def _add_bench(sub):
    from esail_opt import bench

    p = sub.add_parser("bench", help="benchmarks, each against a baseline timed in the same run")
    p.add_argument("name", nargs="+", choices=sorted(bench.BENCHES),
                   help="one or more benchmarks, run one after another in this run")
    p.add_argument("--out", default="results/bench", help="output directory (default results/bench)")
    p.add_argument("--repeats", type=int, default=20, help="timed runs per method (median; default 20)")
    p.set_defaults(run=_run_bench)


def _run_bench(args):
    from esail_opt import bench

    if args.repeats < 1:
        raise InputError(f"repeats = {args.repeats} is outside [1, inf)")
    for name in dict.fromkeys(args.name):
        print(f"wrote {bench.BENCHES[name](args.out, args.repeats)}")
    return 0


def _add_tolerance(p):
    p.add_argument("--tol-km", type=_number, default=None,
                   help="bound on the flown position miss, km (default: the problem's, "
                        "10000 unless it sets one)")
    p.add_argument("--tol-m-s", type=_number, default=None,
                   help="bound on the flown velocity miss, m/s (default: the problem's, 10)")


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
    """``progress(text)`` for long work: on a terminal one line rewritten in place (call
    ``.done()`` to erase it), in a log one plain line per message; both end in " ...",
    which sets them apart from the verdict and the errors."""
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
        "refine the closed form (defect correction against Eqs. 1-2, more sub-arcs where "
        "it is strained) until the schedule, flown on Eqs. 1-2 with CVODES, meets the "
        "tolerance, and write solution.json, schedule.csv, trajectory.png and "
        "timeline.png.  With --polish, then re-solve the same schedule on exact CVODES "
        "arcs of Eqs. 1-2 in time and verify that it flies to within 1 m and 1 mm/s.  "
        "Exit status 0 only for a converged and verified solve (and polish); 1 with one "
        "line saying which bound was missed and by how much; 2 for bad input; 3 when the "
        "output folder cannot be written (checked before the solve); 130 when "
        "interrupted, 143 on SIGTERM (nothing half-written).",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--segments", type=int, default=None,
                   help="number of control segments N, >= 1 (default: the problem's)")
    _add_tolerance(p)
    p.add_argument("--out", default=None, help="output directory (default results/<problem name>)")
    p.add_argument("--polish", action="store_true",
                   help="refine the optimum on the exact Eqs. 1-2 (in time), held to 1 m and 1 mm/s")
    p.set_defaults(run=_run_solve)


def _run_solve(args):
    from pathlib import Path

    from esail_opt.app import solution

    from esail_opt.app.files import check_output_dir

    problem = _load(args)
    out = Path(args.out) if args.out else Path("results") / problem.name
    check_output_dir(out, name=None if args.out else problem.name)  # before the solve
    progress = progress_printer("solve")
    sol = solution.solve(problem, progress=progress, polish=args.polish)
    progress.done()
    for path in sol.write(out):
        print(f"wrote {path}")
    print(sol.summary())
    if sol.verified:
        return 0
    reason = sol["verification_note"] if not sol["verified"] else sol["polish"]["note"]
    print(f"esail-opt solve: {reason}", file=sys.stderr)
    return 1


def _add_search(sub):
    p = sub.add_parser(
        "search", help="global search of a minimum-time problem over revolution classes",
        description="Solve the minimum-time problem in PROBLEM.py once per revolution class "
        "(the free start; then final-angle windows of whole revolutions for an orbit "
        "transfer, or the sail's whole turns on the body for a rendezvous), polish every "
        "distinct optimum on the exact Eqs. 1-2, rank them on the verified exact time of "
        "flight, and write search.json, search.csv, search.png and best/.  Exit status 0 "
        "when the best optimum's polish is verified to 1 m and 1 mm/s, 1 otherwise.",
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
    p.set_defaults(run=_run_search)


def _run_search(args):
    from pathlib import Path

    from esail_opt.app import search
    from esail_opt.app.files import check_output_dir

    problem = _load(args)
    out = Path(args.out) if args.out else Path("results") / f"{problem.name}_search"
    check_output_dir(out, name=None if args.out else out.name)  # before the search
    progress = progress_printer("search")
    data, solutions = search.run(problem, args.extra_revolutions, polish=not args.no_polish,
                                 progress=progress)
    if not data["rows"]:
        # Ipopt's failures from every start say nothing about the target's reachability.
        print(f"esail-opt search: no start converged ({len(data['starts'])} starts); "
              "nothing written", file=sys.stderr)
        return 1
    for path in search.write(data, solutions, out):
        print(f"wrote {path}")
    print("\n".join(search.summary(data)))
    if data["best"]["verified"]:
        return 0
    print("esail-opt search: the best optimum is NOT verified (see search.json)", file=sys.stderr)
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
        "Sweepable names: " + ", ".join(_sweepable()) + ".",
    )
    p.add_argument("problem_file", metavar="PROBLEM.py", help="problem file defining `problem`")
    p.add_argument("--param", required=True, metavar="NAME=START:STOP:COUNT",
                   help="parameter and its grid, e.g. ac_mm_s2=0.2:2:10 (COUNT values, ends included)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes, >= 1 (default: min(COUNT, CPUs))")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on this Dask distributed scheduler instead (needs the dask extra)")
    p.add_argument("--polish", action="store_true",
                   help="also polish every member on the exact Eqs. 1-2 (in time)")
    p.add_argument("--out", default=None,
                   help="output directory (default results/<problem name>_sweep_<NAME>)")
    p.add_argument("--resume", action="store_true",
                   help="keep the members journaled in the output directory's sweep.jsonl "
                   "and run only the others (without it the journal starts afresh)")
    _add_tolerance(p)
    p.set_defaults(run=_run_sweep)


def _sweepable():
    from esail_opt.app.sweep import SWEEPABLE

    return SWEEPABLE


def _run_sweep(args):
    from pathlib import Path

    from esail_opt.app import sweep

    name = args.param.partition("=")[0].strip()
    # The folder first: the journal goes there while the members run.
    out = Path(args.out) if args.out else sweep.default_out_dir(args.problem_file, args.param)
    result = sweep.run(args.problem_file, args.param, workers=args.workers,
                       scheduler=args.scheduler, polish=args.polish, out_dir=out,
                       resume=args.resume, tol_km=args.tol_km, tol_m_s=args.tol_m_s,
                       progress=lambda row, done, total: _sweep_line(row, done, total, name))
    for path in sweep.write(result, out):
        print(f"wrote {path}")
    resumed = f", {len(result['resumed'])} kept from the journal" if result["resumed"] else ""
    print(f"{len(result['rows']) - result['failed']}/{len(result['rows'])} members converged "
          f"and verified in {result['wall_seconds']:.1f} s ({result['executor']}{resumed})")
    return 0 if result["failed"] == 0 else 1


def build_parser():
    parser = argparse.ArgumentParser(
        prog="esail-opt", description="E-sail trajectory propagation and optimisation",
        epilog=EPILOG)
    sub = parser.add_subparsers(dest="command", required=True)
    _add_propagate(sub)
    _add_reproduce(sub)
    _add_bench(sub)
    _add_solve(sub)
    _add_search(sub)
    _add_sweep(sub)
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


def _terminate(signum, frame):
    """SIGTERM handler: stop the way Ctrl-C stops (see :class:`Terminated`)."""
    raise Terminated(signum)


def main(argv=None):
    args = build_parser().parse_args(argv)
    # The command line only writes files; library callers keep whatever backend they chose.
    import matplotlib

    matplotlib.use("Agg")
    _show_library_log()
    import threading

    from esail_opt.app.parallel import ClusterLost

    previous = None
    if (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL):
        # kill, systemd and batch schedulers send SIGTERM: clean up as for Ctrl-C.
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return args.run(args)
    except InputError as err:
        print(f"esail-opt {args.command}: error: {err}", file=sys.stderr)
        return EXIT_INPUT
    except OutputError as err:
        print(f"esail-opt {args.command}: error: {err}", file=sys.stderr)
        return EXIT_OUTPUT
    except ClusterLost as err:
        print(f"esail-opt {args.command}: {err}", file=sys.stderr)
        return 1
    except OSError as err:
        if err.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EROFS):
            raise
        # A full or read-only disk met outside the output writers (a bench, a plot).
        print(f"esail-opt {args.command}: error: cannot write "
              f"{err.filename or 'an output'}: {err.strerror}", file=sys.stderr)
        return EXIT_OUTPUT
    except KeyboardInterrupt as err:
        signum = err.signum if isinstance(err, Terminated) else signal.SIGINT
        what = "interrupted" if signum == signal.SIGINT else \
            f"stopped by {signal.Signals(signum).name}"
        print(f"\nesail-opt {args.command}: {what}; nothing half-done was written",
              file=sys.stderr)
        return 128 + signum
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
