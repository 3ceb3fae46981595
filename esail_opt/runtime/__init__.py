"""The runtime floor, below the trajectory code and knowing nothing of the physics: signal
handlers, live processes, files published whole, a scan's journal, jobs on a process pool
or Dask, and the cache of CasADi Functions.  Settings reach it as arguments (e.g.
:func:`esail_opt.runtime.pool.run`'s ``setup``).
"""
