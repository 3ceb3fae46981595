"""Benchmarks, and the reference solvers they time.

``BENCHES`` maps a name to ``fn(out_dir, repeats)``, the ``run`` of the module of that name
(``solve``: :mod:`.solve_speed`; ``rockit``: :mod:`.rockit_baseline`; ``pykep``:
:mod:`.pykep_zoh`), which runs the benchmark, writes its files under ``out_dir`` and returns
the path of its JSON (``esail-opt-bench NAME``, :mod:`.cli`).

Their problems are the shipped problem files, loaded by name, so an installed package runs
every bench and a bench always solves the file a user sees.  :mod:`.collocation` is the
independent solver the tests' reference optima came from; :mod:`.taylor` flies heyoka.  The
benches import the layers below and the application modules, none of which imports them.
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
