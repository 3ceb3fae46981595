"""The ``esail-opt-bench`` command: run benchmarks by name.

The benchmarks are the top layer, so they have their own command (also ``python -m
esail_opt.bench``): as a subcommand, ``esail-opt``'s import of them would run upward.
Errors become one line and an exit status as in ``esail-opt`` (``app.cli.run_command``).
"""

import argparse

from esail_opt.app.cli import run_command
from esail_opt.bench import BENCHES, ensemble, stages
from esail_opt.errors import InputError

PROG = "esail-opt-bench"
EPILOG = ("exit status: 0 every benchmark named ran and wrote its files; 2 bad input "
          "(nothing run); 3 an output could not be written; 130 interrupted by SIGINT, "
          "143 by SIGTERM")


def build_parser():
    """The command's options: benchmark names, ``--out``, ``--repeats`` and the options
    of single benches (``--problem``, ``--flights``, ``--solution``)."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="benchmarks, each against a baseline timed in the same run",
        epilog=EPILOG)
    parser.add_argument("name", nargs="+", choices=sorted(BENCHES),
                        help="one or more benchmarks, run one after another in this run")
    parser.add_argument("--out", default="results/bench",
                        help="output directory (default results/bench)")
    parser.add_argument("--repeats", type=int, default=20,
                        help="timed runs per method (median; default 20)")
    parser.add_argument("--problem", choices=stages.PROBLEMS, default=stages.PROBLEMS[0],
                        help="the shipped problem the stages bench solves (default "
                        f"{stages.PROBLEMS[0]}); the other benches ignore it")
    parser.add_argument("--flights", type=int, default=ensemble.FLIGHTS,
                        help="flights of the ensemble bench (default "
                        f"{ensemble.FLIGHTS}); the other benches ignore it")
    parser.add_argument("--solution", default=ensemble.SOLUTION,
                        help="the solved rendezvous folder the ensemble bench flies (default "
                        f"{ensemble.SOLUTION}); the other benches ignore it")
    return parser


def _options(name, args):
    """The options of the bench ``name`` beyond ``out`` and ``repeats``."""
    if name == "stages":
        return {"problem": args.problem}
    if name == "ensemble":
        return {"flights": args.flights, "solution": args.solution}
    return {}


def _run(args):
    if args.repeats < 1:
        raise InputError(f"repeats = {args.repeats} is outside [1, inf)")
    if args.flights < 1:
        raise InputError(f"flights = {args.flights} is outside [1, inf)")
    # A name given twice runs once: each run rewrites the same files.
    for name in dict.fromkeys(args.name):
        print(f"wrote {BENCHES[name](args.out, args.repeats, **_options(name, args))}")
    return 0


def main(argv=None):
    """Parse ``argv`` (default ``sys.argv[1:]``), run the benchmarks, return the exit status."""
    args = build_parser().parse_args(argv)
    return run_command(PROG, _run, args)
