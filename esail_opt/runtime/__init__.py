"""The runtime floor, below the trajectory code: what a process needs to run jobs and
keep files, and nothing of the physics.

- :mod:`~esail_opt.runtime.signals`: the one module that installs signal handlers;
- :mod:`~esail_opt.runtime.processes`: whether a process is alive, and children that
  end with their parent;
- :mod:`~esail_opt.runtime.files`: files and folders published whole or not at all;
- :mod:`~esail_opt.runtime.journal`: a scan's rows on disk as they end, and read back;
- :mod:`~esail_opt.runtime.pool`: independent jobs on a process pool or Dask,
  surviving lost workers;
- :mod:`~esail_opt.runtime.function_store`: the package's cache of CasADi Functions
  and arrays.

Settings reach these modules as arguments: a pool's workers are set up by a function
their caller passes (:func:`esail_opt.runtime.pool.run`'s ``setup``).
"""
