"""CasADi Functions compiled to C once, cached on disk, and loaded by name.

On the closed-form NLP nearly all of Ipopt's time goes into the constraint Jacobian and the
Hessian of the Lagrangian, which CasADi's virtual machine interprets one SX instruction at a
time; compiled, the same instructions run natively, with the same numbers.  What is compiled
is the closed form's arc (``rectified.end_function``) with the derivatives an NLP's ``map``
asks of it (``jac_<name>``, ``adj1_<name>``, ``jac_adj1_<name>``), not whole segments, whose
Hessian block is far longer to compile and would need one library per layout; the segment's
MX graph is compiled too, linked against the arc's library
(``compiled(segment, calls=(panel,))``; Linux only: GNU ld's ``-l:`` and an rpath of ``$ORIGIN``).

The cache is a directory of shared libraries named by a hash of the serialised graph, the
CasADi version, the compiler's version line, the flags and the libraries called.  A library is
renamed into place whole, then its SHA-256 written beside it, and is loaded only if that
matches: a truncated one would crash the process with SIGBUS.  A lock per hash makes parallel
workers wait for one compile; an interrupted or killed compile is cleaned up (:data:`_REAPER`,
:func:`_sweep_builds`).  Without a compiler, on a failed compile or an unwritable cache, the
Function stays on the virtual machine with one log line per run (:func:`check_cache`).

Environment:

* ``ESAIL_OPT_COMPILE=0`` forces the virtual machine (no compiler is looked for);
* ``ESAIL_OPT_CACHE`` sets the cache directory (default ``$XDG_CACHE_HOME/esail_opt``,
  else ``~/.cache/esail_opt``);
* ``CC`` names the compiler (default ``cc``).
"""

import contextlib
import errno
import functools
import hashlib
import logging
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca

from esail_opt.runtime.function_store import cache_dir
from esail_opt.runtime.processes import alive

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: parallel workers may compile twice
    fcntl = None

log = logging.getLogger("esail_opt")

#: -O1: -O0 runs the Hessian blocks several times slower, -O2 and -O3 compile longer and
#: run no faster.
FLAGS = ("-O1", "-fPIC")
#: Flags that change how the compiler runs but not the code (not in the key): no temporary .s file.
BUILD_FLAGS = ("-pipe",)
#: Raised whenever what is written into a library changes, so old libraries are ignored.
RECIPE = "segment+jac+adj1+jac_adj1 v2 checksummed"
#: The same, for a library of the Function's value alone.
VALUE_RECIPE = "value v1 checksummed"
#: Suffix of a library's checksum file, written after the library itself.
CHECKSUM = ".sha256"
#: Free space a compile needs in the cache (a few MB, and a margin).
MIN_FREE_BYTES = 64 << 20
#: Free inodes a compile needs in the cache (a build creates a dozen files).
MIN_FREE_INODES = 64
#: The file that remembers a compile that ran out of space (see ``_unusable``).
FAILED_MARKER = ".compile-failed"
#: Values of ESAIL_OPT_COMPILE that force the virtual machine.
OFF = ("0", "off", "no", "false", "vm")

#: What this process has loaded, by library key (a failure keeps ``fun`` itself), and
#: the compilers found missing (None), so each is looked at and reported once.
_loaded = {}


def enabled():
    """Whether compiling is allowed (``ESAIL_OPT_COMPILE`` not set to 0/off)."""
    return os.environ.get("ESAIL_OPT_COMPILE", "1").strip().lower() not in OFF


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


def _key(fun, identity, links=(), with_derivatives=True):
    """The library's name: ``fun``'s name and a hash of all that shapes its code, the keys
    of the libraries it calls (``links``) and whether it holds the derivatives."""
    digest = hashlib.sha256()
    recipe = RECIPE if with_derivatives else VALUE_RECIPE
    for part in (recipe, ca.__version__, identity[1], " ".join(FLAGS), fun.serialize(),
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


# ---------------------------------------------------------------- the cache's health


def _digest(path):
    """SHA-256 of the file at ``path``, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _checksum_path(target):
    return target.with_name(target.name + CHECKSUM)


def _publish(partial, target):
    """Rename the whole library ``partial`` onto ``target``, then write its checksum,
    atomically: a library without a matching one is never loaded (:func:`_damage`)."""
    digest = _digest(partial)
    with open(partial, "rb+") as handle:
        os.fsync(handle.fileno())
    os.replace(partial, target)
    record = _checksum_path(target)
    tmp = record.with_name(f".{record.name}.{os.getpid()}")
    with open(tmp, "w") as handle:
        handle.write(f"{digest}  {target.name}\n")
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, record)


def _damage(target):
    """Why the cached library ``target`` must not be loaded, or None if it is whole."""
    record = _checksum_path(target)
    try:
        expected = record.read_text().split()[0]
    except (OSError, IndexError):
        return "it has no checksum (its write was cut off)"
    try:
        found = _digest(target)
    except OSError as err:
        return f"it cannot be read ({err.strerror})"
    if found != expected:
        return "its checksum does not match (the file was truncated or changed)"
    return None


def _remove_entry(target):
    """Remove a cached library and its checksum (missing files are fine)."""
    for path in (target, _checksum_path(target)):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _free_bytes(folder):
    try:
        stat = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    return stat.f_bavail * stat.f_frsize


def _free_inodes(folder):
    """Files that can still be created on ``folder``'s file system, or None where it
    does not count them (``f_files`` of 0)."""
    try:
        stat = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    return stat.f_favail if stat.f_files else None


def _unusable(folder):
    """Why nothing can be compiled into ``folder`` now, in words, or None; after running out
    of space, not until its disk has :data:`MIN_FREE_BYTES` more free than at the failure
    (:data:`FAILED_MARKER`) or a day has passed."""
    if not os.access(folder, os.W_OK | os.X_OK):
        return "it is not writable"
    free = _free_bytes(folder)
    if free is not None and free < MIN_FREE_BYTES:
        return f"its disk has {free / 2**20:.0f} MB free, less than {MIN_FREE_BYTES >> 20} MB"
    inodes = _free_inodes(folder)
    if inodes is not None and inodes < MIN_FREE_INODES:
        return (f"its file system has {inodes} free inodes, less than {MIN_FREE_INODES} "
                "(it is full)")
    marker = folder / FAILED_MARKER
    try:
        age = time.time() - marker.stat().st_mtime
        recorded = int((marker.read_text().split() or ["0"])[0])
    except (OSError, ValueError):
        return None
    if age < 86400 and (free is None or free < recorded + MIN_FREE_BYTES):
        return (f"a compile there ran out of space {age / 60:.0f} min ago and the disk has "
                "not been freed since")
    with contextlib.suppress(OSError):
        marker.unlink()
    return None


def _remember_no_space(folder):
    """Leave the marker of :func:`_unusable` (an empty file still fits on a full disk)."""
    with contextlib.suppress(OSError):
        marker = folder / FAILED_MARKER
        marker.touch()
        marker.write_text(f"{_free_bytes(folder) or 0}\n")


def _sweep_builds(folder):
    """Remove the build folders ``.build-<pid>-...`` whose process is gone, and kill the
    compilers that outlived it (on Linux)."""
    try:
        entries = [e for e in os.scandir(folder) if e.name.startswith(".build-")]
    except OSError:
        return
    for entry in entries:
        pid = entry.name[len(".build-"):].partition("-")[0]
        if pid.isdigit():
            if alive(int(pid)):
                continue
        else:  # a folder of an older version, without a pid: stale after an hour
            with contextlib.suppress(OSError):
                if time.time() - entry.stat().st_mtime < 3600:
                    continue
        _kill_compilers_of(entry.path)
        shutil.rmtree(entry.path, ignore_errors=True)


def _kill_compilers_of(build):
    """SIGKILL every process whose command line names the folder ``build`` (Linux)."""
    proc = Path("/proc")
    if not proc.is_dir():
        return
    needle = os.fsencode(build)
    for entry in proc.iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle in (entry / "cmdline").read_bytes():
                os.kill(int(entry.name), signal.SIGKILL)
        except OSError:
            continue


def _no_space(err):
    """Whether a failed build ran out of disk space."""
    if isinstance(err, OSError):
        return err.errno in (errno.ENOSPC, errno.EDQUOT)
    text = getattr(err, "stderr", None) or ""
    return "No space left on device" in text or "Disk quota exceeded" in text


def _one_line(err):
    """The telling line of a failed compile's output: the first naming an error (gcc's
    first lines are often "In function ..." or "Assembler messages:")."""
    detail = getattr(err, "stderr", None) or str(err)
    lines = [ln.strip() for ln in str(detail).strip().splitlines() if ln.strip()]
    for line in lines:
        if "error" in line.lower() or "fatal" in line.lower():
            return line
    return lines[0] if lines else type(err).__name__


# ---------------------------------------------------------------- building


#: A reaper of one build's compilers, run beside the process that compiles: it reads
#: their process groups, one a line; if its input closes without "done" (the builder was
#: killed), it kills the groups and removes the build folder.
_REAPER = """
import os, shutil, signal, sys
for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(sig, signal.SIG_IGN)
words = sys.stdin.read().split()
if words[-1:] != ["done"]:
    for word in words:
        try:
            os.killpg(int(word), signal.SIGKILL)
        except (OSError, ValueError):
            pass
    shutil.rmtree(sys.argv[1], ignore_errors=True)
"""


class _Compilers:
    """The compiler processes of one build, each in a session of its own, so that an interrupt
    ends them and what they started at once: left running, they would go on filling the
    cache's disk.  For a process killed outright, :data:`_REAPER` ends them.  Their temporary
    files go into the build folder (``TMPDIR``)."""

    def __init__(self, build):
        self.lock = threading.Lock()
        self.running = []
        self.stopped = False
        self.env = dict(os.environ, TMPDIR=str(build))
        self.reaper = subprocess.Popen([sys.executable, "-I", "-S", "-c", _REAPER, str(build)],
                                       stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, start_new_session=True)

    def run(self, command):
        with self.lock:
            if self.stopped:
                raise subprocess.CalledProcessError(-signal.SIGKILL, command, "", "stopped")
            proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True, start_new_session=True, env=self.env)
            self.running.append(proc)
            self._tell(f"{proc.pid}\n")
        out, err = proc.communicate()
        if proc.returncode != 0:
            raise subprocess.CalledProcessError(proc.returncode, command, out, err)

    def _tell(self, text):
        with contextlib.suppress(OSError, ValueError):
            self.reaper.stdin.write(text.encode())
            self.reaper.stdin.flush()

    def kill(self):
        with self.lock:
            self.stopped = True
            for proc in self.running:
                with contextlib.suppress(OSError):
                    os.killpg(proc.pid, signal.SIGKILL)
        for proc in self.running:
            with contextlib.suppress(Exception):
                proc.wait(timeout=5)

    def close(self):
        """Dismiss the reaper: every compiler has ended (or been killed and waited)."""
        with self.lock:
            self._tell("done\n")
            with contextlib.suppress(OSError):
                self.reaper.stdin.close()
        with contextlib.suppress(Exception):
            self.reaper.wait(timeout=5)


def _build(fun, compiler, target, links=(), with_derivatives=True):
    """Generate C for ``fun`` and its derivatives (with ``with_derivatives``), one translation
    unit each, compiled in parallel, and link them into ``target`` (:func:`_publish`).  ``links``
    are the keys of cached libraries beside ``target`` whose Functions ``fun`` calls.  An
    interrupt or error kills the compilers and removes the build folder before propagating."""
    with tempfile.TemporaryDirectory(dir=target.parent,
                                     prefix=f".build-{os.getpid()}-") as tmp:
        tmp = Path(tmp)
        sources = []
        for i, f in enumerate(derivatives(fun) if with_derivatives else [fun]):
            source = tmp / f"part{i}.c"
            gen = ca.CodeGenerator(source.name, {"with_header": False})
            gen.add(f)
            gen.generate(str(tmp) + os.sep)
            sources.append(source)

        def compile_one(source):
            obj = source.with_suffix(".o")
            compilers.run([compiler, *FLAGS, *BUILD_FLAGS, "-c", str(source), "-o", str(obj)])
            return obj

        # The largest translation unit (the Hessian block) first, so it is never last.
        compilers = _Compilers(tmp)
        pool = ThreadPoolExecutor(max(1, min(len(sources), os.cpu_count() or 1)))
        try:
            objects = list(pool.map(compile_one, sources[::-1]))
            partial = tmp / "lib.so"
            linked = [f"-L{target.parent}", *(f"-l:{key}.so" for key in links),
                      "-Wl,-rpath,$ORIGIN"] if links else []
            compilers.run([compiler, "-shared", "-o", str(partial), *map(str, objects),
                           *linked, "-lm"])
        except BaseException:
            compilers.kill()  # before the pool waits for its threads' compilers
            raise
        finally:
            pool.shutdown(wait=True)
            compilers.close()
        _publish(partial, target)


def _said(key):
    """Whether the line about ``key`` (a compiler, a cache folder) was said already in
    this process or its run (:func:`said_already`); it counts as said now."""
    before = (key, True) in _loaded
    _loaded[(key, True)] = None
    return before


def said_already(keys):
    """In a run's worker: the lines about ``keys`` (what the run's :func:`check_cache`
    returned) were said by the run, and are not said again here."""
    for key in keys:
        _loaded[(key, True)] = None


def _warn_no_compiler(compiler):
    """One plain line, once per run, for a compiler that does not run."""
    if not _said(compiler):
        log.warning("esail-opt: no C compiler (%r does not run); the NLP stays on "
                    "CasADi's virtual machine, several times slower "
                    "(ESAIL_OPT_COMPILE=0 silences this)", compiler)


def check_cache():
    """Say now, once, why nothing will compile (no compiler, an unusable cache), so that a
    run's workers need not each say it.  Returns the compiler's name or the cache folder a
    line was said about, for :func:`said_already` (empty when there was nothing to say)."""
    if not enabled():
        return ()
    compiler = os.environ.get("CC", "cc")
    if _compiler_identity(compiler) is None:
        _warn_no_compiler(compiler)
        return (compiler,)
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        reason = _unusable(folder)
    except OSError as err:
        reason = err.strerror or str(err)
    if reason is None:
        return ()
    _warn_unusable(folder, reason)
    return (str(folder),)


def _warn_unusable(folder, reason):
    """One plain line, once per run and folder, for a cache nothing compiles into."""
    if _said(str(folder)):
        return
    log.warning("esail-opt: cannot compile into the cache %s: %s; the NLP stays on CasADi's "
                "virtual machine (several times slower) -- make it a writable folder with "
                "free space, or set ESAIL_OPT_CACHE to one (ESAIL_OPT_COMPILE=0 silences this)",
                folder, reason)


def _load(fun, folder, target, key, build):
    """``external`` of the cached library ``target``, built by ``build()`` if missing;
    a damaged or unloadable one is built again once, with one line; None when nothing
    can be built into ``folder`` (one line says why)."""
    unloadable = None  # the checksum record of a library that would not load
    if target.exists() and _damage(target) is None:
        try:
            return ca.external(fun.name(), str(target))
        except RuntimeError as err:
            unloadable = (_record(target), f"it does not load ({_one_line(err)})")
    reason = _unusable(folder)
    if reason is not None:
        _warn_unusable(folder, reason)
        return None
    with _locked(folder / f"{key}.lock"):
        _sweep_builds(folder)
        if target.exists():
            # Judged again under the lock: another process may have rebuilt it.
            why = _damage(target)
            if why is None and unloadable is not None and _record(target) == unloadable[0]:
                why = unloadable[1]
            if why is not None:
                log.warning("esail-opt: the cached library %s is damaged: %s; removed, "
                            "compiling it again", target.name, why)
                _remove_entry(target)
        if not target.exists():
            build()
    return ca.external(fun.name(), str(target))


def _load_or_vm(fun, folder, target, key, build):
    """:func:`_load`, or ``fun`` itself (on the virtual machine) when nothing can be
    compiled, with one line saying why; a full disk is remembered (:func:`_unusable`)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        loaded = _load(fun, folder, target, key, build)
        return fun if loaded is None else loaded
    except (OSError, subprocess.CalledProcessError, RuntimeError) as err:
        if _no_space(err):
            _remember_no_space(folder)
            _warn_unusable(folder, "its disk is full")
        elif isinstance(err, OSError) and not isinstance(err, subprocess.SubprocessError):
            _warn_unusable(folder, err.strerror or str(err))
        else:
            log.warning("esail-opt: compiling %s failed (%s); the NLP stays on CasADi's "
                        "virtual machine", fun.name(), _one_line(err))
        return fun  # not retried in this process: one line is enough


def _record(target):
    """The text of ``target``'s checksum file, or None."""
    try:
        return _checksum_path(target).read_text()
    except OSError:
        return None


def compiled(fun, calls=(), with_derivatives=True):
    """``fun`` backed by its cached C library, or ``fun`` itself on the virtual machine.

    ``fun`` is an SX Function (the closed form's arc) or an MX Function over the Functions in
    ``calls`` (the NLP's segment over its arcs), which are compiled first and linked against;
    if any of them stays on the virtual machine, so does ``fun``.  Without
    ``with_derivatives`` (a Function only evaluated) the library holds its value alone, a
    fraction of the compile.  Returns an ``external`` with the same inputs and outputs, or
    ``fun`` when compiling is off, no C compiler runs, the cache cannot be written or the
    compile fails (one warning on the ``esail_opt`` logger).
    """
    if not enabled():
        return fun
    compiler = os.environ.get("CC", "cc")
    identity = _compiler_identity(compiler)
    if identity is None:
        _warn_no_compiler(compiler)
        return fun
    if calls and not sys.platform.startswith("linux"):
        # Linked by GNU ld's -l:name and an rpath of $ORIGIN: Linux only.
        return fun
    links = []
    for callee in calls:
        if compiled(callee) is callee:
            return fun  # its callees were reported; nothing to link against
        links.append(_key(callee, identity))
    key = _key(fun, identity, links, with_derivatives)
    if key in _loaded:
        return _loaded[key]
    folder = cache_dir()
    target = folder / f"{key}.so"

    def build():
        log.info("esail-opt: compiling %r and its derivatives to C, once per machine and "
                 "variant; "
                 "about %d s (cache: %s) ...", fun.name(), 10 if links else 20, folder)
        start = time.perf_counter()
        _build(fun, identity[0], target, links, with_derivatives)
        log.info("esail-opt: compiled in %.1f s", time.perf_counter() - start)

    loaded = _load_or_vm(fun, folder, target, key, build)
    _loaded[key] = loaded
    return loaded
