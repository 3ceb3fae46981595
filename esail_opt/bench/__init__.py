"""Benchmarks, and the reference solvers they time.

``BENCHES`` maps a name to ``fn(out_dir, repeats)``, which runs the benchmark, writes its
files under ``out_dir`` and returns the path of its JSON (``esail-opt-bench NAME``, the
command of :mod:`.cli`).
Each is the ``run`` of its own module:

* ``rockit`` (:mod:`.rockit_baseline`): ``esail-opt solve --polish`` against a generic
  RK4 multiple-shooting script of the same transfer written with rockit, whole
  processes side by side;
* ``pykep`` (:mod:`.pykep_zoh`): ``esail-opt solve --polish`` in three dimensions, with
  and without its figures, against a pykep 3 zero-order-hold script of the same
  fixed-date minimum-a_c transfer solved by pygmo's Ipopt, whole processes side by side
  (skipped, and said so, without pykep, heyoka and pygmo);
* ``propagate``, ``solve`` (:mod:`.solve_speed`), ``polish``, ``lowthrust`` and
  ``sweep``: each timed against a baseline measured in the same run (:mod:`.timing`
  holds what they share);
* ``porkchop``: a launch-window scan as shipped (one NLP, warm starts) against RK4
  segments with the same reuse and against every cell solved cold; ``porkchop3d``
  the same in three dimensions;
* ``precision``: solve time against verified accuracy for the closed form, RK4
  (``propagation.rk4``) and CVODES segments;
* ``verifier3d``: the 3-D verifier's flights of polished schedules against heyoka in
  quadruple precision (an accuracy bench: nothing is timed);
* ``stages`` (:mod:`.stages`): where the time of one ``esail-opt solve --polish`` goes,
  stage by stage, in a fresh process (no baseline: the stages sum to the process);
* ``ensemble`` (:mod:`.ensemble`): the flights of ``esail-opt robust`` flown by the
  closed form, by CVODES and by heyoka, time per flight at each one's stated error.

Their problems are the shipped problem files, loaded by name from the package data
``esail_opt.problems`` (``optimisation.problem_file.shipped_problem``), so an installed
package runs every bench and a bench always solves the file a user sees.
:mod:`.collocation` is the independent collocation solver that ``lowthrust`` times and
the tests' reference optima came from; :mod:`.taylor` flies ``propagate``'s batch on
heyoka's Taylor integrator, when the ``bench`` extra is installed.  The benches import the layers below and the
application modules, none of which imports them.
"""

from esail_opt.bench import (ensemble, lowthrust, polish, porkchop, porkchop3d, precision,
                             propagate, pykep_zoh, rockit_baseline, solve_speed, stages,
                             sweep, verifier3d)

BENCHES = {
    "propagate": propagate.run,
    "solve": solve_speed.run,
    "polish": polish.run,
    "lowthrust": lowthrust.run,
    "sweep": sweep.run,
    "rockit": rockit_baseline.run,
    "pykep": pykep_zoh.run,
    "precision": precision.run,
    "porkchop": porkchop.run,
    "verifier3d": verifier3d.run,
    "porkchop3d": porkchop3d.run,
    "stages": stages.run,
    "ensemble": ensemble.run,
}

__all__ = ["BENCHES"]
