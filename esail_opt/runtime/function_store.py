"""CasADi Functions, and the arrays they are fitted to, kept on disk and read back: the
package's one cache folder.

Some Functions cost a noticeable part of a short solve to build in every process (the
closed form's arcs, :mod:`esail_opt.propagation.graph_store`; the bodies' splines and
samples, :mod:`esail_opt.bodies.track`), and one read back is the one built, number for
number.  A caller names an entry by a hash of everything that decides it, so anything that
could make it differ reads another file.  A file holds the SHA-256 of its payload on its
first line (one that does not match is said in one line, built again and rewritten), is
renamed into place, so parallel workers never read half a file, and follows the umask, so a
cache folder can be shared.  A folder that cannot be written is left alone: the compiled
libraries' warning (:mod:`esail_opt.propagation.compiled`) already says so.
``ESAIL_OPT_CACHE`` chooses the folder (default ``$XDG_CACHE_HOME/esail_opt``, else
``~/.cache/esail_opt``).
"""

import hashlib
import io
import logging
import os
import uuid
from pathlib import Path

import casadi as ca
import numpy as np

log = logging.getLogger("esail_opt")


def cache_dir():
    """The package's cache folder (see the module's docstring)."""
    if os.environ.get("ESAIL_OPT_CACHE"):
        return Path(os.environ["ESAIL_OPT_CACHE"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "esail_opt"


def path_of(kind, name, decided_by, suffix=".casadi"):
    """Where the Function (or, with ``suffix=".npy"``, the array) ``name`` of ``kind``
    (a sub-folder: ``graphs``, ``tracks``) is stored, given the bytes or text
    ``decided_by`` that decide it."""
    data = decided_by.encode() if isinstance(decided_by, str) else bytes(decided_by)
    return cache_dir() / kind / f"{name}-{hashlib.sha256(data).hexdigest()[:32]}{suffix}"


def _read_checked(path):
    """The payload stored at ``path`` (bytes), or None if it is missing or does not
    match its checksum (said in one line)."""
    try:
        data = path.read_bytes()
    except OSError:  # missing, or in a folder that cannot be read: nothing stored
        return None
    checksum, _, payload = data.partition(b"\n")
    if hashlib.sha256(payload).hexdigest().encode() != checksum:
        return _damaged(path, "its checksum does not match (the file was truncated or "
                              "changed)")
    return payload


def read(path):
    """The Function stored at ``path``, or None if it is missing or damaged (its checksum does
    not match or it is no Function: said in one line)."""
    payload = _read_checked(path)
    if payload is None:
        return None
    try:
        return ca.Function.deserialize(payload.decode())
    except UnicodeDecodeError:
        return _damaged(path, "it is not text")
    except RuntimeError:
        return _damaged(path, "it does not read back as a CasADi Function")


def read_array(path):
    """The numpy array stored at ``path`` by :func:`write_array`, or None if it is
    missing or damaged (said in one line, as :func:`read`)."""
    payload = _read_checked(path)
    if payload is None:
        return None
    try:
        return np.load(io.BytesIO(payload), allow_pickle=False)
    except ValueError:
        return _damaged(path, "it does not read back as an array")


def _damaged(path, why):
    log.warning("esail-opt: the stored %s is damaged: %s; building it again", path.name, why)
    return None


def _write_checked(path, payload):
    """Store ``payload`` (bytes) at ``path`` under its checksum, atomically; a folder
    that cannot be written is left alone (what was built works)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp")
        try:
            with open(tmp, "xb") as out:
                out.write(hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    except OSError:
        pass


def write(path, fun):
    """Store ``fun`` at ``path`` atomically (:func:`read` reads it back)."""
    _write_checked(path, fun.serialize().encode())


def write_array(path, array):
    """Store the numpy ``array`` at ``path`` atomically, number for number."""
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(array), allow_pickle=False)
    _write_checked(path, buffer.getvalue())


def kept(path, build):
    """The Function stored at ``path``, or ``build()``'s, stored there."""
    fun = read(path)
    if fun is None:
        fun = build()
        write(path, fun)
    return fun
