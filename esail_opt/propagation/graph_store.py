"""The closed form's SX Functions, built once per machine and read back from disk.

Why: building the arc Functions of :mod:`esail_opt.propagation.rectified` (the
first-order panel and the NLP's second-order arc end) is CasADi's symbolic work in
Python, redone by every process, and a noticeable part of a short solve's whole run;
reading one back from its serialised graph is a small fraction of that.

A stored graph is named by a hash of what decides it: the builder's name and keyword
arguments, the CasADi version, and the source of every module the closed form's
formulas live in (:data:`SOURCES`).  Any edit to those modules therefore names new
graphs, and the old ones are simply never read again.  A file holds the SHA-256 of the
graph on its first line: a file that does not match (truncated, damaged) is said in
one line, built again and rewritten.  Files are written under a temporary name and renamed into place,
so parallel workers never read half a graph, and they follow the umask, as the
compiled libraries do, so that a cache folder can be shared.  When the cache cannot be written (a full
disk, a read-only folder) the Function is built as before; the compiled libraries'
warning (:mod:`esail_opt.propagation.compiled`) already says the folder is unusable.

``ESAIL_OPT_CACHE`` chooses the folder, as for the compiled libraries (a ``graphs``
folder inside it).
"""

import functools
import hashlib
import inspect
import logging
import os
import uuid
from pathlib import Path

import casadi as ca

from esail_opt.propagation.compiled import cache_dir

log = logging.getLogger("esail_opt")

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
    key = hashlib.sha256(repr((name, sorted(kwargs.items()), source_digest())).encode())
    return cache_dir() / "graphs" / f"{name}-{key.hexdigest()[:32]}.casadi"


def _read(path):
    """The Function stored at ``path``, or None if it is missing or damaged: a file that
    does not match its checksum, or does not read back as a Function, is said in one
    line (it is then built again and rewritten)."""
    try:
        checksum, _, text = path.read_text().partition("\n")
    except OSError:  # missing, or in a folder that cannot be read: nothing stored
        return None
    except UnicodeDecodeError:
        return _damaged(path, "it is not text")
    if hashlib.sha256(text.encode()).hexdigest() != checksum:
        return _damaged(path, "its checksum does not match (the file was truncated or "
                              "changed)")
    try:
        return ca.Function.deserialize(text)
    except RuntimeError:
        return _damaged(path, "it does not read back as a CasADi Function")


def _damaged(path, why):
    log.warning("esail-opt: the stored arc graph %s is damaged: %s; building it again",
                path.name, why)
    return None


def _write(path, fun):
    """Store ``fun`` at ``path`` atomically; a folder that cannot be written is left
    alone (the Function was built, and works)."""
    text = fun.serialize()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp")
        try:
            with open(tmp, "x") as out:
                out.write(hashlib.sha256(text.encode()).hexdigest() + "\n" + text)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    except OSError:
        pass


def stored(builder):
    """``builder`` (keyword arguments only, returning an SX Function) with its result
    read from the cache when it is there, else built and stored."""

    signature = inspect.signature(builder)

    @functools.wraps(builder)
    def build(**kwargs):
        # The defaults filled in, so that a call naming them finds the same graph.
        bound = signature.bind(**kwargs)
        bound.apply_defaults()
        path = graph_path(builder.__name__, bound.arguments)
        fun = _read(path)
        if fun is None:
            fun = builder(**kwargs)
            _write(path, fun)
        return fun

    return build
