"""Native readers run where their crash cannot take the process down (issue 16).

libhdf5 (through h5py) is a C library: a damaged file can make it crash (a segmentation fault
on a byte-flipped attribute heap) or loop instead of raising an error, and neither can be
caught in Python. (C3D files are read by motionlab itself, :mod:`motionlab.io.c3d`.) Two
guards, both in a forked child process:

- :func:`call_isolated` runs a reading function in a child and returns its result (pickled
  through a pipe); the function's own exceptions are raised again in the caller, and a child
  killed by a signal becomes an :class:`~motionlab.errors.InputError` naming the file.
- :func:`check_hdf5` reads every object, attribute and dataset of an HDF5 file in a child
  (a probe), once per file version per process, before the readers open it in-process. Errors
  the probe meets are left to the readers, which name the place; only a crash refuses the file.

Where ``os.fork`` is missing or the process runs other threads (a fork then may copy a lock
held by another thread), both run in-process instead, without the guard.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import h5py

from motionlab.errors import InputError

T = TypeVar("T")

#: files the HDF5 probe read without a crash: (path, size, mtime_ns, inode)
_PROBED: set[tuple[str, int, int, int]] = set()
#: rows per slice when the probe reads a dataset (bounds its memory)
_PROBE_ROWS = 1 << 16
#: a native reader's time limit: this many seconds plus the file's size at the rate below
BASE_S = 10.0
SLOWEST_BYTES_PER_S = 10e6


def can_isolate() -> bool:
    """Whether a child can be forked safely: POSIX and no other thread running."""
    return hasattr(os, "fork") and threading.active_count() == 1


def time_limit(path: Path) -> float:
    """Seconds a native reader may take on ``path``: :data:`BASE_S` + its size at
    :data:`SLOWEST_BYTES_PER_S` (a damaged file can make libhdf5 loop)."""
    try:
        size = path.stat().st_size
    except OSError:
        size = 0
    return BASE_S + size / SLOWEST_BYTES_PER_S


def call_isolated(fn: Callable[..., T], *args: Any, path: Path, what: str) -> T:
    """``fn(*args)`` computed in a forked child; its result or exception comes back here.

    A child killed by a signal (``what`` crashed on a damaged file), or still running after
    :func:`time_limit` (it is then killed), raises :class:`InputError` for ``path``. Runs
    in-process when :func:`can_isolate` is false.
    """
    if not can_isolate():
        return fn(*args)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: compute, send, leave without cleanup
        code = 0
        try:
            os.close(read)
            _quiet_child()
            try:
                payload = pickle.dumps(("ok", fn(*args)), protocol=5)
            except BaseException as exc:  # noqa: BLE001 - sent to the parent, raised there
                try:
                    payload = pickle.dumps(("raise", exc), protocol=5)
                except Exception:  # an exception that does not pickle: its text
                    payload = pickle.dumps(("raise", RuntimeError(str(exc))), protocol=5)
            with os.fdopen(write, "wb") as pipe:
                pipe.write(payload)
        except BaseException:  # noqa: BLE001 - nothing may escape a forked child
            code = 1
        finally:
            os._exit(code)
    os.close(write)
    limit = time_limit(path)
    try:
        data = _read_until(read, time.monotonic() + limit)
    finally:
        os.close(read)
    if data is None:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise InputError(
            f"{what} did not finish reading it in {limit:.0f} s: the file is damaged",
            path,
            remedy="copy or export the file again",
        )
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status) or not data:
        sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else 0
        name = signal.Signals(sig).name if sig in signal.valid_signals() else f"status {status}"
        raise InputError(
            f"{what} crashed reading it ({name}): the file is damaged",
            path,
            remedy="copy or export the file again",
        )
    kind, value = pickle.loads(data)
    if kind == "raise":
        raise value
    return value


def _read_until(fd: int, deadline: float) -> bytes | None:
    """Everything from ``fd`` up to its end, or ``None`` if the end is not reached by
    ``deadline`` (``time.monotonic()``)."""
    chunks = []
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return None
        ready, _, _ = select.select([fd], [], [], remaining)
        if not ready:
            continue
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


def _quiet_child() -> None:
    """The child says nothing itself (a crash dump or a library's message would be a second
    line on stderr): its result or its death is reported by the parent."""
    import faulthandler

    faulthandler.disable()
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    os.close(null)


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def looks_like_hdf5(path: str | Path) -> bool:
    """Whether ``path`` is a file with the HDF5 signature where the format puts it (byte 0, 512,
    1024, 2048…), read in Python: ``h5py.is_hdf5`` asks libhdf5, which may open the file."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            at = 0
            while at + 8 <= size:
                f.seek(at)
                if f.read(8) == HDF5_SIGNATURE:
                    return True
                at = 512 if at == 0 else 2 * at
    except OSError:
        return False
    return False


def check_hdf5(path: str | Path) -> None:
    """Refuse an HDF5 file that crashes libhdf5 when read (probed in a child, see module doc).

    Cached per file version, so that sniffing, checking and reading one file probe it once.
    Returns without probing where :func:`can_isolate` is false.
    """
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return  # the reader says what is wrong
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns, st.st_ino)
    if key in _PROBED or not can_isolate():
        return
    call_isolated(_probe_hdf5, path, path=path, what="the HDF5 library")
    _PROBED.add(key)


def open_hdf5(path: str | Path, message: str, remedy: str) -> h5py.File:
    """``path`` opened for reading with h5py, or an :class:`InputError` (``message``, the path,
    ``remedy``) when h5py cannot open it. Probe a file that may be damaged with
    :func:`check_hdf5` first: a crash inside libhdf5 is no exception to catch."""
    try:
        return h5py.File(path, "r")
    except (OSError, RuntimeError):
        raise InputError(message, path, remedy=remedy) from None


def _probe_hdf5(path: Path) -> None:
    """Touch every group, attribute and dataset value of ``path``; errors are ignored (the
    readers report them with their place), only a crash matters."""
    try:
        f = h5py.File(path, "r")
    except Exception:  # noqa: BLE001
        return
    seen: set[int] = set()

    def attrs(obj: Any) -> None:
        try:
            keys = list(obj.attrs.keys())
        except Exception:  # noqa: BLE001
            return
        for k in keys:
            try:
                obj.attrs[k]
            except Exception:  # noqa: BLE001
                pass

    def dataset(ds: Any) -> None:
        try:
            if ds.shape is None or len(ds.shape) == 0:
                ds[()]
                return
            for i in range(0, ds.shape[0], _PROBE_ROWS):
                ds[i : i + _PROBE_ROWS]
        except Exception:  # noqa: BLE001
            pass

    def walk(group: Any) -> None:
        try:
            address = h5py.h5o.get_info(group.id).addr
        except Exception:  # noqa: BLE001
            return
        if address in seen:
            return
        seen.add(address)
        attrs(group)
        try:
            keys = list(group.keys())
        except Exception:  # noqa: BLE001
            return
        for k in keys:
            try:
                item = group.get(k)
            except Exception:  # noqa: BLE001
                continue
            if isinstance(item, h5py.Group):
                walk(item)
            elif isinstance(item, h5py.Dataset):
                attrs(item)
                dataset(item)

    with f:
        walk(f)
