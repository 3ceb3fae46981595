"""Publishing files: files whole or not at all, folders as one set, checked before a solve.

:func:`check_output_dir` checks an output folder before any solve, creating nothing; :func:`publish`
swaps a run's whole set of files in at once, so that a reader sees the old set or the new one, never
a mix; :func:`atomic_path` writes one file under a temporary name and renames it into place.  Files
and folders are created 0666/0777 less the umask, as ``open`` and ``mkdir`` would.
"""

import contextlib
import ctypes
import errno
import os
import secrets
import shutil
import sys
from pathlib import Path

from esail_opt.errors import InputError, OutputError
from esail_opt.runtime import processes, signals

#: Longest file or folder name most file systems take (ext4, xfs, tmpfs), bytes.
NAME_MAX = 255
#: Staging folders of :func:`publish` and :func:`check_output_dir`,
#: ``.<name>.tmp-<pid>-<random>``: one whose pid is dead, a killed run's, is removed.
_STAGING = ".{name}.tmp-"


def _fail(path, err, doing="write"):
    """The one-line OutputError for an OSError while writing ``path``."""
    reason = os.strerror(err.errno) if err.errno else str(err)
    hint = ("free some space there" if err.errno in (errno.ENOSPC, errno.EDQUOT)
            else "choose another --out")
    return OutputError(f"cannot {doing} {str(path)!r}: {reason} ({hint})")


def check_name(name, what="output folder name"):
    """``name`` if it is one safe path component, else InputError: not empty, ``.`` or ``..`` (which
    would write into an existing folder), no ``/`` or NUL, at most :data:`NAME_MAX` UTF-8 bytes."""
    text = str(name)
    if text in ("", ".", ".."):
        raise InputError(f"{what} = {text!r} is not a folder name (not '', '.' or '..')")
    if "\0" in text:
        raise InputError(f"{what} = {text!r} holds a NUL character")
    if "/" in text or os.sep in text:
        raise InputError(f"{what} = {text!r} holds a '/' (one folder name is expected)")
    size = len(text.encode("utf-8", "surrogateescape"))
    if size > NAME_MAX:
        raise InputError(f"{what} = {text[:40]!r}... is {size} bytes long, outside "
                         f"[1, {NAME_MAX}]")
    return text


def check_output_dir(path, name=None, files=()):
    """Check, before any solve, that the output folder ``path`` (``--out``, or
    ``results/<problem name>``) can be published; return it as a Path.  Creates nothing, not even
    :func:`publish`'s parents, and removes only the staging folders a killed run left beside it.
    ``name``, the user-given name of the folder, must be one safe component (:func:`check_name`);
    ``files`` are the names the run writes as files there, where a folder (the user's) is refused.

    Raises InputError if the last component is not a safe name, or the folder is a symbolic link
    (dangling or not; folders above it may be links), or is or holds the working folder; OutputError
    if it cannot be created or written (a path under a regular file, a file in its place, a folder
    in place of one of ``files``, a read-only or full file system).
    """
    if name is not None:
        check_name(name, "problem name (the output folder's name)")
    path = _checked_out_path(path)
    _refuse_folders_in_the_way(path, files)
    base, first = _nearest_folder(path)
    _probe(path, base, first)
    return path


def _refuse_folders_in_the_way(target, files):
    """OutputError if ``target`` holds a folder where the run writes a file: the set
    is swapped in whole, so that folder, the user's, would be deleted with the old set."""
    for name in files:
        entry = Path(target) / name
        if entry.is_dir() and not entry.is_symlink():
            raise OutputError(f"cannot write {str(entry)!r}: a folder of that name is in "
                              "the way, and replacing the set would delete it (move it, "
                              "or choose another --out)")


def check_output_file(path):
    """Check, before the work, that the file ``path`` (an ``--out`` that names a file)
    can be written where it is: OutputError if a folder stands in its place or a file
    stands in place of a folder above it.  Creates nothing."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"cannot write {str(path)!r}: a folder of that name is in the "
                          "way (--out names a file here; choose another)")
    _nearest_folder(path)
    return path


def _checked_out_path(raw):
    """``raw`` as a Path, refused (InputError) if it is no safe folder name or is a
    symbolic link, or (OutputError) if a file stands in its place."""
    path = Path(raw)
    if "\0" in str(path):
        raise InputError(f"output folder {str(path)!r} holds a NUL character")
    for part in path.parts:
        if len(part.encode("utf-8", "surrogateescape")) > NAME_MAX:
            raise InputError(f"output folder {str(path)[:60]!r}...: a component is longer "
                             f"than {NAME_MAX} bytes")
    # The last component as the user wrote it: Path turns "results/." into "results",
    # but the user meant the folder itself, which cannot be swapped for a new one.
    check_name(os.fspath(raw).rstrip("/").rpartition("/")[2] or os.fspath(raw),
               "output folder name")
    if path.is_symlink():
        # The set is swapped in by renaming: through a link it would replace the link,
        # and a journal appended through it would land where the link points.
        raise InputError(f"output folder {str(path)!r} is a symbolic link (to "
                         f"{os.readlink(path)!r}); give the folder itself, not a link, "
                         "or another --out")
    if path.exists() and not path.is_dir():
        raise OutputError(f"cannot write the output folder {str(path)!r}: a file of that "
                          "name is in the way (choose another --out)")
    if path.exists():
        here, out = Path.cwd().resolve(), path.resolve()
        if here == out or out in here.parents:
            # Swapped in by renaming, it would leave the shell in a deleted folder.
            raise InputError(f"output folder {str(path)!r} is the working folder or holds "
                             "it; give a folder below it (for example --out results/run)")
    return path


def _nearest_folder(path):
    """The nearest existing folder above ``path`` and the name of its entry on the way
    to ``path`` (``path``'s own name when its parent exists); OutputError if the
    nearest existing entry above is not a folder."""
    first = path.name
    for above in path.parents:
        if above.exists() or above.is_symlink():
            if not above.is_dir():
                raise OutputError(f"cannot create the output folder {str(path)!r}: "
                                  f"{str(above)!r} is a file, not a folder (choose "
                                  "another --out)")
            return above, first
        first = above.name
    return Path(path.anchor or "."), first  # pragma: no cover - "/" and "." exist


def _probe(path, base, first):
    """Write one block in a staging folder made in ``base`` for its entry ``first``, then remove it,
    so that an unwritable folder or a full disk is an OutputError before the run."""
    try:
        if base == path.parent:
            _remove_stale(base, first)
        probe = _make_staging(base, first)
        try:
            with open(probe / "probe", "wb") as handle:
                handle.write(b"\0" * 4096)  # one block: a full disk fails here
                handle.flush()
                os.fsync(handle.fileno())
        finally:
            shutil.rmtree(probe, ignore_errors=True)
        if path.is_dir() and not os.access(path, os.W_OK | os.X_OK):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))
    except OSError as err:
        raise _fail(path, err, "write the output folder") from None


def _make_staging(parent, name):
    """Create and return an empty staging folder for ``name`` in ``parent``."""
    for _ in range(100):
        staging = Path(parent, f"{_STAGING.format(name=name)}{os.getpid()}-"
                               f"{secrets.token_hex(4)}")
        try:
            os.mkdir(staging, 0o777)  # less the umask, like any folder the user makes
            return staging
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no free staging folder name", str(parent))


def _remove_stale(parent, name):
    """Remove staging folders of ``name`` whose process is gone (a killed run's)."""
    processes.remove_dead(parent, _STAGING.format(name=name))


# ---------------------------------------------------------------- the swap

#: renameat2's flag that swaps two existing paths in one step (Linux >= 3.15).
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _libc_renameat2():
    """glibc's ``renameat2``, or None where there is none (other systems, old glibc)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        function = libc.renameat2
    except (OSError, AttributeError):
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                         ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


_renameat2 = _libc_renameat2()


def _exchange(a, b):
    """Swap the paths ``a`` and ``b`` (both existing) in one step; False if the system
    or the file system cannot (then nothing changed)."""
    if _renameat2 is None:
        return False
    result = _renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b),
                        _RENAME_EXCHANGE)
    if result == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(b))


def _swap_in(staging, target):
    """Put ``staging`` at ``target``; return the path now holding the old set, or None.  An
    existing target is exchanged by ``renameat2(RENAME_EXCHANGE)`` and never stops existing;
    without that, the old set is renamed aside and the new one in: an instant without a folder,
    never a mixed one.  ``rename`` fails onto a non-empty folder, so a concurrent writer is
    retried, not overwritten half-way."""
    for _ in range(20):
        try:
            os.rename(staging, target)  # no target yet, or an empty one
            return None
        except OSError as err:
            if err.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                raise
        if _exchange(staging, target):
            return staging
        aside = _make_staging(target.parent, target.name)
        os.rmdir(aside)
        try:
            os.rename(target, aside)
        except FileNotFoundError:
            continue  # another writer moved it just now: try again
        try:
            os.rename(staging, target)
        except OSError:
            with contextlib.suppress(OSError):
                os.rename(aside, target)  # put the old set back
            raise
        return aside
    raise OSError(errno.EBUSY, "other writers kept replacing it", str(target))


def _carry_over(target, staging, family):
    """Link the entries of the existing ``target`` that are not the writer's
    (``family``) into ``staging``, so that a user's own files, or a sweep's journal,
    stay in the folder; the writer's old files are dropped with the old set."""
    try:
        entries = list(os.scandir(target))
    except FileNotFoundError:
        return
    for entry in entries:
        if entry.name in family or os.path.lexists(staging / entry.name):
            continue
        destination = staging / entry.name
        if entry.is_dir(follow_symlinks=False):
            # Folders cannot be hard-linked: a foreign one (rare, small) is copied.
            shutil.copytree(entry.path, destination, symlinks=True)
            continue
        try:
            os.link(entry.path, destination, follow_symlinks=False)
        except OSError:
            shutil.copy2(entry.path, destination, follow_symlinks=False)


@contextlib.contextmanager
def publish(target, family=()):
    """Yield a staging folder for a run's files; on success it becomes ``target`` (whose parents are
    created).  ``family`` names the entries the writer owns: those of the old set that the new one
    does not write are dropped with it (a stale ``schedule_closed_form.csv`` never sits beside an
    unpolished solution); every other entry, the user's or a journal, is carried over.

    A reader sees the whole old set until the swap (:func:`_swap_in`), then the new one; by path it
    may see the old ``x`` and the new ``y`` unless it holds the folder open.  Of two writers of a
    folder, one set is left whole; the next run removes a killed run's staging folder.  Raises
    OutputError, one line, for an OSError in writing or swapping; ``target`` keeps its old set.
    """
    target = Path(target)
    family = set(family)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale(target.parent, target.name)
        staging = _make_staging(target.parent, target.name)
    except OSError as err:
        raise _fail(target, err) from None
    old = None
    try:
        try:
            yield staging
            _refuse_folders_in_the_way(
                target, [e.name for e in os.scandir(staging) if e.is_file()])
            with signals.blocked():
                _carry_over(target, staging, family)
                _fsync_tree(staging)
                old = _swap_in(staging, target)
        except OSError as err:
            raise _fail(target, err) from None
    finally:
        with signals.blocked():
            # After a swap ``old`` holds the old set; before one, staging holds a part.
            for leftover in (old, staging):
                if leftover is not None and os.path.lexists(leftover) and \
                        Path(leftover) != target:
                    shutil.rmtree(leftover, ignore_errors=True)


def _fsync_tree(folder):
    """Flush the files of ``folder`` to disk, so that the swap never publishes a set
    whose data a power cut could still lose."""
    for entry in os.scandir(folder):
        if entry.is_file(follow_symlinks=False):
            fd = os.open(entry.path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        elif entry.is_dir(follow_symlinks=False):
            _fsync_tree(entry.path)


# ---------------------------------------------------------------- one file


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``, renamed onto it on success and removed on failure or
    interrupt; it is created 0666 less the umask (``mkstemp``'s 0600 would survive the rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{path.suffix}"
        try:
            os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            break
        except FileExistsError:
            continue
    else:  # pragma: no cover - 100 random names taken
        raise FileExistsError(errno.EEXIST, "no free temporary name", str(path))
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)
