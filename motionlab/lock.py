"""One writer at a time: an advisory lock around every read-modify-write of a session file.

A stage command loads a session, computes for seconds or minutes and writes the file back
(atomically, :mod:`motionlab.atomic`). Two such commands on one file would each write their
own copy and the last one would silently drop the other's result, so every command that writes
a session holds :func:`session_lock` from before it reads the file until after it has written
it. A second writer waits up to :func:`wait_s` seconds (``MOTIONLAB_LOCK_WAIT``, default
:data:`DEFAULT_WAIT_S`), then gives up with an :class:`~motionlab.errors.InputError` (exit 2)
that names the process holding the lock (its pid and command line). Readers take no lock:
a session file is replaced by a rename, so a reader sees the old file or the new one.

The lock is ``fcntl.flock`` on a small file beside the session, ``.<name>.lock`` (the session
itself cannot carry it: every write replaces its inode). The kernel releases it when its
process dies, even by SIGKILL, so a killed writer never leaves a session locked; the holder
writes its pid and command line into the file for the message of the next writer, and removes
the file when it is done (a waiter that then holds the lock of a removed file tries again on
the new one). Under the lock, temporary files a killed writer left beside the session
(``.<name>.*.tmp``) are deleted. ``flock`` is POSIX (Linux, macOS); on a system without
``fcntl`` the lock is not taken. On network file systems it is only as good as their lock
support (NFSv4 and SMB with locking enabled honour it).
"""

from __future__ import annotations

import contextlib
import os
import shlex
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from motionlab.errors import InputError, shorten

try:
    import fcntl
except ImportError:  # not POSIX: no advisory locks
    fcntl = None  # type: ignore[assignment]

#: seconds a second writer waits for the lock before it gives up
DEFAULT_WAIT_S = 60.0
_POLL_S = 0.05


def wait_s() -> float:
    """Seconds to wait for a session's lock: ``MOTIONLAB_LOCK_WAIT`` if set, else
    :data:`DEFAULT_WAIT_S`."""
    text = os.environ.get("MOTIONLAB_LOCK_WAIT", "")
    try:
        value = float(text)
    except ValueError:
        return DEFAULT_WAIT_S
    return value if value >= 0 else DEFAULT_WAIT_S


def lock_path(path: str | Path) -> Path:
    """The lock file of the session ``path``: ``.<name>.lock`` in its folder."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


def holder(lock: Path) -> str:
    """``pid 123: motionlab fuse s.h5`` from the lock file (empty if it cannot be read)."""
    try:
        text = lock.read_text(encoding="utf-8", errors="replace").strip()
    except OSError:
        return ""
    pid, _, command = text.partition(" ")
    return f"pid {pid}: {shorten(command, 120)}" if pid.isdigit() else ""


def _sweep(path: Path) -> None:
    """Delete the temporary files of writers of ``path`` that died (we hold the lock)."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        with contextlib.suppress(OSError):
            tmp.unlink()


def _acquire(lock: Path, wait: float, target: Path) -> int:
    """An open descriptor of ``lock`` holding ``flock(LOCK_EX)`` on the file now at ``lock``."""
    deadline = time.monotonic() + wait
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            if time.monotonic() >= deadline:
                who = holder(lock) or "another process"
                raise InputError(
                    f"is being written by another motionlab ({who}); waited {wait:g} s",
                    target,
                    remedy="run this again when it has finished (MOTIONLAB_LOCK_WAIT=seconds "
                    "waits longer)",
                ) from None
            time.sleep(_POLL_S)
            continue
        try:  # the holder before us may have removed the file: lock the one now there
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)


def command_line() -> str:
    """This process's command line, ``motionlab ...`` for ``python -m motionlab ...`` and for
    the installed executable's full path (``/usr/local/bin/motionlab ...``)."""
    argv = list(sys.argv) or ["?"]
    if Path(argv[0]).name in ("__main__.py", "motionlab"):
        argv[0] = "motionlab"
    return shlex.join(argv)


@contextlib.contextmanager
def session_lock(path: str | Path, wait: float | None = None) -> Iterator[None]:
    """Hold the write lock of the session file ``path`` (which need not exist yet).

    Waits up to ``wait`` seconds (default :func:`wait_s`) for another writer, then raises
    :class:`~motionlab.errors.InputError` naming it. Re-entrant within one thread: an inner
    lock of a path the thread already holds is a no-op (``run`` inside ``batch``).
    """
    path = Path(path)
    key = str(path.absolute())
    held = _held()
    if fcntl is None or key in held or not path.parent.is_dir():
        yield
        return
    lock = lock_path(path)
    try:
        fd = _acquire(lock, wait_s() if wait is None else wait, path)
    except OSError:  # a read-only folder: the write fails later with its own message
        yield
        return
    held.add(key)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()} {command_line()}\n".encode("utf-8", "replace"))
        _sweep(path)
        yield
    finally:
        held.discard(key)
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)


_LOCAL = threading.local()


def _held() -> set[str]:
    """Absolute paths of the sessions this thread holds the lock of."""
    if not hasattr(_LOCAL, "held"):
        _LOCAL.held = set()
    return _LOCAL.held
