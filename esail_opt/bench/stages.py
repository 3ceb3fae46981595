"""``esail-opt-bench stages``: where the time of one ``esail-opt solve --polish`` goes.

One of :data:`PROBLEMS` is solved with the polish in a fresh Python process, so that the
imports are timed as a command pays them.  The child calls what ``esail-opt solve`` calls
(:func:`child`), with the package's own functions wrapped, wherever a module holds them, in
timers that pass everything through and charge the time to the innermost stage running
(exclusive time, as a profiler's own time), so the stages partition the child's wall time.

Stages (:data:`STAGES`): ``imports``, ``load``, ``ephemeris`` (the bodies' tracks), ``seed``,
``nlp_build`` (transcription and ``nlpsol``), ``ipopt`` (each call listed in ``ipopt_calls``
with the pipeline step that made it: ``answer``, ``probes``, ``lift``, ``error control``,
``polish``), ``verification``, ``files``, ``figures_import``, ``figures`` and ``other`` (the
pipeline's own Python).  ``startup_and_exit`` is what the parent's wall time adds.
"""

import contextlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The problem the bench solves by default, and the other it accepts.
PROBLEMS = ("earth_mars_min_ac", "earth_mars_min_ac_planar")

#: Stages in the order a solve meets them (``other`` last).
STAGES = ("imports", "load", "ephemeris", "seed", "nlp_build", "ipopt", "verification",
          "files", "figures_import", "figures", "other")


class StageClock:
    """Exclusive time per stage, charged to the innermost stage open or to ``other``, so the
    stages sum to the time from the clock's start to its last charge.  ``ipopt`` calls are
    also listed one by one, with the pipeline step (:meth:`step`) open at the time."""

    def __init__(self, clock=time.perf_counter):
        self.clock = clock
        self.start = self.mark = clock()
        self.totals = dict.fromkeys(STAGES, 0.0)
        self.frames = []  # [stage, own seconds so far]
        self.steps = []
        self.ipopt_calls = []

    def _charge(self):
        now = self.clock()
        stage = self.frames[-1] if self.frames else None
        if stage is None:
            self.totals["other"] += now - self.mark
        else:
            self.totals[stage[0]] += now - self.mark
            stage[1] += now - self.mark
        self.mark = now

    @contextlib.contextmanager
    def stage(self, name):
        self._charge()
        frame = [name, 0.0]
        self.frames.append(frame)
        try:
            yield frame
        finally:
            self._charge()
            self.frames.pop()

    @contextlib.contextmanager
    def step(self, label):
        self.steps.append(label)
        try:
            yield
        finally:
            self.steps.pop()

    def elapsed(self):
        """Seconds from the clock's start to its last charge."""
        self._charge()
        return self.mark - self.start


def _wrap(function, around):
    def wrapped(*args, **kwargs):
        with around(args, kwargs) as note:
            result = function(*args, **kwargs)
            if note is not None:
                note(result)
            return result
    wrapped.__wrapped__ = function
    return wrapped


def _replace_everywhere(function, wrapped):
    """Put ``wrapped`` wherever a loaded module of the package holds ``function`` by
    name (``from x import f`` copies the name into each module that imports it)."""
    for name, module in list(sys.modules.items()):
        if name.startswith("esail_opt") and module is not None:
            for attr, value in list(vars(module).items()):
                if value is function:
                    setattr(module, attr, wrapped)


def instrument(clock):
    """Wrap the package's stage functions with ``clock``'s timers (the modules must be
    imported)."""
    from esail_opt.bodies import lookup
    from esail_opt.optimisation import (error_control, ipopt, multistart, pipeline, seed,
                                        transcription)
    from esail_opt.optimisation import verify as verify_module

    def staged(name):
        @contextlib.contextmanager
        def around(args, kwargs):
            with clock.stage(name):
                yield None
        return around

    @contextlib.contextmanager
    def ipopt_call(args, kwargs):
        with clock.stage("ipopt") as frame:
            record = {"step": clock.steps[-1] if clock.steps else "answer"}

            def note(result):
                record.update(iterations=int(result.iterations), status=result.status)
            yield note
        record["seconds"] = frame[1]
        clock.ipopt_calls.append(record)

    def stepped(label):
        @contextlib.contextmanager
        def around(args, kwargs):
            with clock.step(label):
                yield None
        return around

    wrappers = [
        (lookup.track_of, staged("ephemeris")), (lookup.track3_on, staged("ephemeris")),
        (seed.initial_guess, staged("seed")),
        (transcription.transcribe, staged("nlp_build")),
        (ipopt.build_solver, staged("nlp_build")),
        (ipopt.solve_transcription, ipopt_call),
        (verify_module.verify, staged("verification")),
        (multistart.probe_start, stepped("probes")), (multistart.lift, stepped("lift")),
        (error_control.control_error, stepped("error control")),
        (pipeline._polish, stepped("polish")),
    ]
    for function, around in wrappers:
        _replace_everywhere(function, _wrap(function, around))


def child(problem_name, out_dir, plots=True):
    """The timed solve, run in a fresh process (:func:`measure` starts it); prints its
    record as one JSON line."""
    clock = StageClock()
    with clock.stage("imports"):
        # What `esail-opt solve` imports before it solves (app.cli, then _run_solve's).
        import esail_opt.app.cli  # noqa: F401
        from esail_opt.app import report, solution  # noqa: F401
        from esail_opt.runtime.files import check_output_dir  # noqa: F401
        from esail_opt.optimisation.problem_file import shipped_problem
    instrument(clock)
    with clock.stage("load"):
        problem = shipped_problem(problem_name)
    sol, _near = solution.solve_with_nearest(problem, polish=True)
    with clock.stage("files"):
        sol.write(Path(out_dir) / "solution", plots=False)
    if plots:
        with clock.stage("figures_import"):
            import matplotlib.pyplot  # noqa: F401

            from esail_opt.app import plots as figures
        with clock.stage("figures"):
            figures.write_plots(sol, Path(out_dir) / "solution")
    wall = clock.elapsed()
    print(json.dumps({"stages": clock.totals, "ipopt_calls": clock.ipopt_calls,
                      "child_seconds": wall, "objective": sol.objective,
                      "verified": bool(sol.verified)}))


# The child loads this file by path, not from the bench package, whose __init__ imports
# every bench and with them what the solve would import, which ``imports`` would miss.
_CHILD = """
import importlib.util, sys
spec = importlib.util.spec_from_file_location("esail_stages_child", sys.argv[1])
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
module.child(sys.argv[2], sys.argv[3], sys.argv[4] == "plots")
from esail_opt.app.cli import end_process
end_process(0)  # as the command ends
"""


def measure(problem_name=PROBLEMS[0], plots=True):
    """One timed solve of ``problem_name`` with the polish in a fresh process: the
    child's record plus ``process_seconds``, the parent's wall time of the process, and
    ``startup_and_exit``, what the stages leave of it."""
    from esail_opt.errors import InputError

    if problem_name not in PROBLEMS:
        raise InputError(f"problem = {problem_name!r} is not one of: {', '.join(PROBLEMS)}")
    with tempfile.TemporaryDirectory(prefix="esail-stages-") as out_dir:
        command = [sys.executable, "-c", _CHILD, str(Path(__file__).resolve()), problem_name,
                   out_dir, "plots" if plots else "no-plots"]
        started = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True)
        process = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"the timed solve failed ({done.returncode}): "
                           f"{done.stderr.strip().splitlines()[-1:]}")
    record = json.loads(done.stdout.strip().splitlines()[-1])
    record.update(problem=problem_name, polish=True, plots=plots, process_seconds=process,
                  startup_and_exit=process - sum(record["stages"].values()))
    return record


def _print(record):
    from esail_opt.bench.timing import print_table

    rows = [(name, record["stages"][name], "s") for name in STAGES]
    rows += [(f"  ipopt {i + 1}: {c['step']}", c["seconds"],
              f"s, {c.get('iterations', '?')} it, {c.get('status', '?')}")
             for i, c in enumerate(record["ipopt_calls"])]
    rows += [("startup and exit", record["startup_and_exit"], "s"),
             ("whole process", record["process_seconds"], "s")]
    print_table(f"stages: {record['problem']}, --polish"
                + ("" if record["plots"] else " --no-plots"), rows)


def run(out, repeats=1, problem=PROBLEMS[0]):
    """Time the stages of one solve (:func:`measure`, with figures), print them and write
    ``stages.json`` (``stages_planar.json`` for the planar twin) under ``out``; returns its
    path.  One process is one sample: ``repeats`` is not used."""
    from esail_opt.app.outputs import write_json

    record = measure(problem)
    _print(record)
    record["how"] = ("one solve with --polish in a fresh process: exclusive wall time per "
                     "stage from timers around the package's functions; process_seconds "
                     "is the parent's wall time of the child process")
    name = "stages.json" if problem == PROBLEMS[0] else "stages_planar.json"
    path = Path(out) / name
    write_json(path, record)
    return path
