"""CasADi Functions compiled to C once, cached on disk, and loaded by name.

Why: on the closed-form NLP nearly all of Ipopt's time is spent evaluating the
constraint Jacobian and the Hessian of the Lagrangian, and CasADi's virtual machine
runs about 8 ns per SX instruction.  The same instructions compiled by gcc -O1 ran
10 to 20 times faster on a segment's derivatives.

What is compiled is one small SX Function, the closed form's arc (the NLP's second-order
``rectified.end_function``, about 1,200 instructions), with the three derivatives
an NLP asks of it through a ``map``: its Jacobian (constraint Jacobian), its first
reverse derivative (gradient of the Lagrangian) and that one's Jacobian (Hessian of
the Lagrangian).  CasADi's ``external`` finds them in the library by the names CasADi
gives them (``jac_<name>``, ``adj1_<name>``, ``jac_adj1_<name>``), and the segments
are chained from it in MX as before.  Compiling whole segments instead was measured
and rejected: a Richardson segment of 3 sub-arcs has a 382,000-instruction Hessian
block that took gcc 146 s, where the arc's library takes 15-20 s and serves every
segment count, sub-arc count and extrapolation setting.  On Earth-Venus (30 x 3,
equal lengths) the compiled arcs solved in 0.82 s against 3.71 s for the expanded SX
segment, in the same 35 iterations to the same optimum.

The segment's own MX graph -- the arc calls and the chain rule between them, which on
the virtual machine was still about 40 % of a Hessian of the Lagrangian and 65 % of a
constraint Jacobian -- is compiled as well, with the arcs left as calls into their
library (``compiled(segment, calls=(panel,))``): the segment's library is linked
against the arc's, so gcc sees a few thousand small matrix operations, not the arcs'
instructions again, and takes 6-12 s per sub-arc count and extrapolation setting
(Linux only: the link uses GNU ld's ``-l:`` and an rpath of ``$ORIGIN``).

The cache is a directory of shared libraries named by a hash of the Function's
serialised graph, the CasADi version, the compiler's own version line and the flags
(and the names of the libraries it calls).
A library is built under a temporary name and renamed into place, and a lock file per
hash makes parallel workers (``esail-opt sweep``) wait for one compile instead of each
running their own.  Without a C compiler, or when a compile fails, the Function stays
on the virtual machine and one log line says so.

Environment:

* ``ESAIL_OPT_COMPILE=0`` forces the virtual machine (no compiler is looked for);
* ``ESAIL_OPT_CACHE`` sets the cache directory (default ``$XDG_CACHE_HOME/esail_opt``,
  else ``~/.cache/esail_opt``);
* ``CC`` names the compiler (default ``cc``).
"""

import contextlib
import functools
import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: parallel workers may compile twice
    fcntl = None

log = logging.getLogger("esail_opt")

#: -O1 by measurement on a 3-sub-arc segment's Hessian block: -O0 compiled it in 10.9 s
#: against 23.8 s but ran it at 186 against 60 us a call.  On the arc's Hessian block,
#: -O2 and -O3 compiled in 14 s against 5 s and ran no faster (7.5-7.9 us a mapped call).
FLAGS = ("-O1", "-fPIC")
#: Raised whenever what is written into a library changes, so old libraries are ignored.
RECIPE = "segment+jac+adj1+jac_adj1 v1"
#: Values of ESAIL_OPT_COMPILE that force the virtual machine.
OFF = ("0", "off", "no", "false", "vm")

#: What this process has loaded, by library key (a failure keeps ``fun`` itself), and
#: the compilers found missing (None), so each is looked at and reported once.
_loaded = {}


def enabled():
    """Whether compiling is allowed (``ESAIL_OPT_COMPILE`` not set to 0/off)."""
    return os.environ.get("ESAIL_OPT_COMPILE", "1").strip().lower() not in OFF


def cache_dir():
    """The directory the libraries are cached in (see the module's docstring)."""
    if os.environ.get("ESAIL_OPT_CACHE"):
        return Path(os.environ["ESAIL_OPT_CACHE"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "esail_opt"


@functools.lru_cache(maxsize=None)
def _compiler_identity(compiler):
    """The compiler's path and first ``--version`` line, or None if it does not run."""
    path = shutil.which(compiler)
    if path is None:
        return None
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return path, (out.stdout.splitlines() or [""])[0]


def derivatives(fun):
    """``fun`` and the derivative Functions the NLP's map asks of it, by CasADi's names."""
    adjoint = fun.reverse(1)
    return [fun, fun.jacobian(), adjoint, adjoint.jacobian()]


def _key(fun, identity, links=()):
    """The library's name: ``fun``'s name and a hash of all that shapes its code, the keys
    of the libraries it calls included (``links``; none for a Function that calls none,
    whose key is then what it always was)."""
    digest = hashlib.sha256()
    for part in (RECIPE, ca.__version__, identity[1], " ".join(FLAGS), fun.serialize(),
                 *links):
        digest.update(part.encode())
        digest.update(b"\0")
    return f"{fun.name()}-{digest.hexdigest()[:24]}"


@contextlib.contextmanager
def _locked(path):
    """Hold an exclusive lock on ``path`` (created if missing) while inside."""
    with open(path, "a") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(handle, fcntl.LOCK_UN)


def _build(fun, compiler, target, links=()):
    """Generate C for ``fun`` and its derivatives and link them into ``target``.

    Each Function is its own translation unit, compiled in parallel (the Hessian block
    is most of the time), and the library is renamed into place only when it is whole.
    ``links`` are the keys of cached libraries (in ``target``'s folder) whose Functions
    ``fun`` calls: the generated code calls their symbols, and the library finds them
    beside itself when it is loaded (an rpath of ``$ORIGIN``).
    """
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".build-") as tmp:
        tmp = Path(tmp)
        sources = []
        for i, f in enumerate(derivatives(fun)):
            source = tmp / f"part{i}.c"
            gen = ca.CodeGenerator(source.name, {"with_header": False})
            gen.add(f)
            gen.generate(str(tmp) + os.sep)
            sources.append(source)

        def compile_one(source):
            obj = source.with_suffix(".o")
            subprocess.run([compiler, *FLAGS, "-c", str(source), "-o", str(obj)],
                           check=True, capture_output=True, text=True)
            return obj

        # The largest translation unit (the Hessian block) first, so it is never last.
        with ThreadPoolExecutor(max(1, min(len(sources), os.cpu_count() or 1))) as pool:
            objects = list(pool.map(compile_one, sources[::-1]))
        partial = tmp / "lib.so"
        linked = [f"-L{target.parent}", *(f"-l:{key}.so" for key in links),
                  "-Wl,-rpath,$ORIGIN"] if links else []
        subprocess.run([compiler, "-shared", "-o", str(partial), *map(str, objects), *linked,
                        "-lm"], check=True, capture_output=True, text=True)
        os.replace(partial, target)


def compiled(fun, calls=()):
    """``fun`` backed by its cached C library, or ``fun`` itself on the virtual machine.

    Parameters
    ----------
    fun : casadi.Function
        An SX Function (the closed form's arc), or an MX Function over the compiled
        versions of the Functions in ``calls`` (the NLP's segment over its arcs); its
        name names the library's symbols.
    calls : sequence of casadi.Function
        The Functions, as given to this function, whose libraries ``fun``'s code calls
        (each compiled first if it is not yet).  Its library is linked against theirs,
        so their code is not compiled again.  If any of them stays on the virtual
        machine, so does ``fun``.

    Returns
    -------
    casadi.Function
        An ``external`` with the same inputs and outputs, whose Jacobian, reverse
        derivative and Hessian block are compiled too; or ``fun`` when compiling is off
        (``ESAIL_OPT_COMPILE=0``), no C compiler runs, or the compile fails (one warning
        on the ``esail_opt`` logger for the last two).
    """
    if not enabled():
        return fun
    compiler = os.environ.get("CC", "cc")
    identity = _compiler_identity(compiler)
    if identity is None:
        if compiler not in _loaded:
            log.warning("esail-opt: no C compiler (%r does not run); the NLP stays on "
                        "CasADi's virtual machine, several times slower "
                        "(ESAIL_OPT_COMPILE=0 silences this)", compiler)
        _loaded[compiler] = None
        return fun
    if calls and not sys.platform.startswith("linux"):
        # Its library finds theirs by an rpath of $ORIGIN and GNU ld's -l:name, which
        # only Linux's toolchain is known here to take: elsewhere it stays on the VM.
        return fun
    links = []
    for callee in calls:
        if compiled(callee) is callee:
            return fun  # its callees were reported; nothing to link against
        links.append(_key(callee, identity))
    key = _key(fun, identity, links)
    if key in _loaded:
        return _loaded[key]
    folder = cache_dir()
    target = folder / f"{key}.so"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _locked(folder / f"{key}.lock"):
            if not target.exists():
                log.info("esail-opt: compiling %r and its derivatives to C, once per "
                         "machine; about %d s (cache: %s) ...", fun.name(),
                         10 if links else 20, folder)
                start = time.perf_counter()
                _build(fun, identity[0], target, links)
                log.info("esail-opt: compiled in %.1f s", time.perf_counter() - start)
        loaded = ca.external(fun.name(), str(target))
    except (OSError, subprocess.CalledProcessError, RuntimeError) as err:
        detail = getattr(err, "stderr", None) or str(err)
        log.warning("esail-opt: compiling %s failed (%s); the NLP stays on CasADi's virtual "
                    "machine", fun.name(), detail.strip().splitlines()[0] if detail else err)
        loaded = fun  # not retried in this process: one line is enough
    _loaded[key] = loaded
    return loaded
