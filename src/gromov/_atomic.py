"""Atomic file and folder writes.

Every output file is written under a temporary name in the target's own folder (so on the
same file system), flushed to disk, and moved onto the target with :func:`os.replace`, an
atomic rename: a reader, or a process killed half-way, sees the previous complete file or the
new complete one, never a truncated or mixed one. Two processes writing the same target each
write their own temporary file; the last rename wins and the target is always one complete
file.

Temporary files are named ``.NAME.XXXXXXXX.tmpSUFFIX`` (``full.npz`` ->
``.full.3f9a0c1e.tmp.npz``): hidden, recognisable, and ending in the target's suffix for the
writers that look at it (:func:`numpy.savez` appends ``.npz`` to a name without it, matplotlib
picks the image format from it). Any exception, :class:`KeyboardInterrupt` included, removes
it. A process killed by a signal that cannot be caught (SIGKILL, a power cut) leaves it behind;
it is never mistaken for the target, and the next write of the same target deletes it: a writer
holds an advisory lock (:func:`fcntl.flock`) on its temporary file or folder for as long as it
writes, the system releases the lock when the process ends however it ends, and a temporary of
the target's name pattern that nobody holds is stale. Where there is no ``flock`` (Windows) or
the file system cannot lock, temporaries left by killed processes stay until deleted by hand.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import os
import re
import secrets
import shutil
import stat
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:   # Windows
    fcntl = None

__all__ = ["atomic_folder", "atomic_path", "atomic_savez_compressed", "atomic_write_bytes",
           "atomic_write_text"]


def _target(path) -> Path:
    """The file the rename must replace: ``path``, or where it points if it is a symlink."""
    p = Path(os.fspath(path))
    return Path(os.path.realpath(p)) if p.is_symlink() else p


def _stem_suffix(target: Path) -> tuple[str, str]:
    suffix = target.suffix if target.stem else ""
    return (target.name[:len(target.name) - len(suffix)] if suffix else target.name), suffix


def _temp_name(target: Path, tag: str = "tmp") -> Path:
    stem, suffix = _stem_suffix(target)
    return target.with_name(f".{stem}.{secrets.token_hex(4)}.{tag}{suffix}")


# --------------------------------------------------------------------------- stale temporaries
def _try_lock(fd: int) -> bool | None:
    """Take the exclusive advisory lock of ``fd`` without waiting: True if taken, False if
    another open file holds it, None where the system or the file system cannot lock."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:
        return None
    return True


def _same_file(path: Path, fd: int) -> bool:
    """Whether ``path`` is still the file or folder open as ``fd``."""
    try:
        a, b = os.lstat(path), os.fstat(fd)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


_HELD: set[int] = set()
"""Descriptors holding the locks of this process's temporaries."""


def _release(fd: int | None) -> None:
    """Close a lock's descriptor (releasing the lock), if this process holds it."""
    if fd is not None and fd in _HELD:
        _HELD.discard(fd)
        os.close(fd)


def _forget_in_child() -> None:
    """After ``fork``: close the child's copies of the lock descriptors, so the lock is the
    writer's alone and a killed writer's temporaries are stale even while workers it forked
    live on (a lock is released when every descriptor sharing it is closed)."""
    for fd in _HELD:
        with contextlib.suppress(OSError):
            os.close(fd)
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_in_child)


def _claim(path: Path, fd: int | None = None) -> tuple[bool, int | None]:
    """Lock the temporary ``path`` this process has just created (``fd``: open on it).

    Returns ``(kept, fd)``: ``fd`` holds the lock until closed (None where locks are not
    available); ``kept`` is False when a cleaner of stale temporaries took ``path`` in the
    moment between its creation and the lock (it deletes it; the writer picks another name).
    """
    if fd is None:
        if fcntl is None:
            return True, None
        try:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except FileNotFoundError:
            return False, None
        except OSError:
            return True, None
    locked = _try_lock(fd)
    if locked is None:
        os.close(fd)
        return True, None
    if locked and _same_file(path, fd):
        _HELD.add(fd)
        return True, fd
    os.close(fd)
    return False, None


def _open_to_lock(path: Path, *, folder: bool) -> int | None:
    """Open ``path`` (not following a symlink) to take its lock; None if it cannot be.

    A file is opened for writing where it may be (NFS takes an exclusive ``flock`` only on
    such files), else for reading (a temporary given the mode of a read-only target)."""
    for mode in ([os.O_RDONLY | os.O_DIRECTORY] if folder else [os.O_RDWR, os.O_RDONLY]):
        try:
            return os.open(path, os.O_NOFOLLOW | mode)
        except PermissionError:
            continue
        except OSError:
            return None
    return None


def _remove_stale(target: Path, *, folder: bool) -> None:
    """Delete the temporaries of ``target`` (:func:`_temp_name`) that no writer holds.

    A temporary's writer holds its lock until it is done; the system releases it when the
    writer ends, however it ends (SIGKILL included), so an unheld temporary is one a killed
    writer left. Temporaries held by a running writer, other names and anything that cannot
    be locked (see :func:`_try_lock`) are left alone; errors are ignored.
    """
    if fcntl is None:
        return
    stem, suffix = _stem_suffix(target)
    pattern = re.compile(re.escape(f".{stem}.") + "[0-9a-f]{8}" + re.escape(f".tmp{suffix}"))
    parent = target.parent
    try:
        with os.scandir(parent) as it:
            names = [e.name for e in it if pattern.fullmatch(e.name)]
    except OSError:
        return
    for name in names:
        path = parent / name
        fd = _open_to_lock(path, folder=folder)
        if fd is None:
            continue
        try:
            if (stat.S_ISDIR(os.fstat(fd).st_mode) != folder or _try_lock(fd) is not True
                    or not _same_file(path, fd)):
                continue
            if folder:
                shutil.rmtree(path, ignore_errors=True)
            else:
                os.unlink(path)
        except OSError:
            pass
        finally:
            os.close(fd)


def _fsync_path(path: Path, *, folder: bool = False) -> None:
    """Flush ``path`` to disk; folders where the OS cannot (Windows, some file systems): skipped."""
    if folder and os.name == "nt":
        return
    try:
        fd = os.open(path, os.O_RDONLY if os.name != "nt" else os.O_RDWR)
    except OSError:
        if folder:
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not folder:
            raise
    finally:
        os.close(fd)


def _as_target_error(exc: OSError, target: Path) -> OSError:
    """The same error naming the target, not the temporary file (``No such file or
    directory: 'out/x.npz'``)."""
    return type(exc)(exc.errno, exc.strerror, str(target))


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path to write in place of ``path``, moved onto it on success.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write. A symlink is followed (the file it points to is replaced). A
        target that exists and is not a regular file (``/dev/null``, a FIFO) is written
        directly, without a temporary file.

    Yields
    ------
    Path
        An empty file ``.NAME.XXXXXXXX.tmpSUFFIX`` in the target's folder, created with the
        usual permissions (``0o666`` less the umask), or those of the file it replaces. Write
        it (by name, truncating) inside the ``with`` block.

    Notes
    -----
    On leaving the block normally the temporary file is flushed to disk (``fsync``),
    renamed onto the target (:func:`os.replace`) and the folder flushed, so the rename itself
    survives a crash. On any exception, :class:`KeyboardInterrupt` included, the temporary
    file is removed and the exception re-raised; the target is untouched.

    Examples
    --------
    >>> with atomic_path("distances.npz") as tmp:          # doctest: +SKIP
    ...     np.savez_compressed(tmp, distances=d)
    """
    target = _target(path)
    try:
        st = target.stat()
    except OSError:
        st = None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(target))
    if st is not None and not stat.S_ISREG(st.st_mode):
        yield target    # a device or pipe: nothing to replace
        return
    _remove_stale(target, folder=False)
    while True:
        tmp = _temp_name(target)
        try:
            fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise _as_target_error(exc, target) from None
        if fcntl is None:   # Windows renames no file open here: no lock, nothing held open
            os.close(fd)
            lock = None
            break
        kept, lock = _claim(tmp, fd)
        if kept:
            break
    try:
        yield tmp
        if st is not None:
            os.chmod(tmp, stat.S_IMODE(st.st_mode))
        _fsync_path(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    finally:
        _release(lock)
    _fsync_path(target.parent, folder=True)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | os.PathLike, text: str, *, encoding: str = "utf-8",
                      newline: str | None = None) -> None:
    """Write ``text`` to ``path`` atomically (:func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding=encoding, newline=newline) as fh:
        fh.write(text)


def atomic_savez_compressed(path: str | os.PathLike, **arrays) -> Path:
    """:func:`numpy.savez_compressed` written atomically; like numpy, ``.npz`` is appended to a
    name without it. Returns the path written."""
    import numpy as np

    name = os.fspath(path)
    target = Path(name if name.endswith(".npz") else name + ".npz")
    with atomic_path(target) as tmp:
        np.savez_compressed(tmp, **arrays)
    return target


# --------------------------------------------------------------------------- folders
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one atomic step (Linux ``renameat2(RENAME_EXCHANGE)``);
    False where the system cannot."""
    if not hasattr(os, "uname") or os.uname().sysname != "Linux":
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                          ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder to fill in place of the folder ``path``, swapped in on success.

    Parameters
    ----------
    path : str or os.PathLike
        The folder to write; its parent is created if needed. An existing folder there is
        replaced as a whole (its files are deleted) once the new one is complete.

    Yields
    ------
    Path
        An empty folder ``.NAME.XXXXXXXX.tmp`` beside ``path``.

    Notes
    -----
    On leaving the block normally every file in the temporary folder is flushed to disk, then
    the folder takes the place of ``path``: a single atomic exchange of the two on Linux
    (``renameat2(RENAME_EXCHANGE)``), elsewhere the old folder is first renamed aside to
    ``.NAME.XXXXXXXX.old`` -- a crash in between leaves no ``path`` but both complete folders
    under those names. The old folder is then deleted. On any exception the temporary folder
    is deleted and ``path`` is untouched. A writer killed by SIGKILL leaves its temporary
    folder (on Linux, after the exchange, the old folder being deleted under that name); the
    next write of ``path`` deletes it (see :mod:`gromov._atomic`). A ``.old`` folder is left
    for the user.
    """
    target = _target(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale(target, folder=True)
    while True:
        tmp = _temp_name(target)
        try:
            os.mkdir(tmp, 0o777)
        except FileExistsError:
            continue
        kept, lock = _claim(tmp)
        if kept:
            break
    try:
        yield tmp
        for root, _, files in os.walk(tmp):
            for f in files:
                p = Path(root) / f
                if p.is_file() and not p.is_symlink():
                    _fsync_path(p)
            _fsync_path(Path(root), folder=True)
        if target.is_dir() and _exchange(tmp, target):
            old = tmp
        elif target.is_dir():
            old = _temp_name(target, "old")
            os.rename(target, old)
            os.rename(tmp, target)
        else:
            old = None
            os.rename(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        _release(lock)
        raise
    _fsync_path(target.parent, folder=True)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    _release(lock)
