"""The closed form's SX Functions, built once per machine and read back from disk.

Building the arc Functions of :mod:`.rectified` is symbolic work in Python, redone by
every process and a noticeable part of a short solve; reading one back is a small
fraction of that.  A stored graph is named by a hash of the builder's name and keyword
arguments, the CasADi version and the source of :data:`SOURCES`, so any edit to those
modules names new graphs.  Storage is :mod:`esail_opt.runtime.function_store`'s.
"""

import functools
import hashlib
import inspect
from pathlib import Path

import casadi as ca

from esail_opt.runtime import function_store

_PACKAGE = Path(__file__).resolve().parent.parent
#: The modules whose code builds the stored graphs: every formula of the closed form,
#: the thrust model and the constants, and the builders themselves.
SOURCES = (*sorted((_PACKAGE / "physics").glob("*.py")),
           _PACKAGE / "propagation" / "arcs.py", _PACKAGE / "propagation" / "rectified.py")


@functools.lru_cache(maxsize=None)
def source_digest():
    """SHA-256 of :data:`SOURCES` and the CasADi version (read once per process)."""
    digest = hashlib.sha256(ca.__version__.encode())
    for path in SOURCES:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def graph_path(name, kwargs):
    """Where the graph of builder ``name`` called with ``kwargs`` is stored."""
    return function_store.path_of("graphs", name,
                                  repr((name, sorted(kwargs.items()), source_digest())))


def stored(builder):
    """``builder`` (keyword arguments only, returning an SX Function) with its result
    read from the cache when it is there, else built and stored."""

    signature = inspect.signature(builder)

    @functools.wraps(builder)
    def build(**kwargs):
        # The defaults filled in, so that a call naming them finds the same graph.
        bound = signature.bind(**kwargs)
        bound.apply_defaults()
        return function_store.kept(graph_path(builder.__name__, bound.arguments),
                                   lambda: builder(**kwargs))

    return build
