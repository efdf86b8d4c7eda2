"""Safe output: write to a temporary file in the target folder, then rename into place.

An existing output is replaced only when ``force`` is true; a failure leaves no partial file.
The output gets the permissions a plain ``open(path, "w")`` would give: a new file the mode
the umask allows (0644 under umask 022, not the 0600 of :func:`tempfile.mkstemp`), a replaced
file (an in-place stage) the mode it had.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

from motionlab.errors import InputError, shorten

#: what a path that is not a regular file is, by its ``stat`` type
_KINDS = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def _kind(mode: int) -> str | None:
    """What a ``stat`` mode is when it is a FIFO, a socket or a device, else ``None``."""
    return next((kind for test, kind in _KINDS if test(mode)), None)


def special_kind(path: str | Path) -> str | None:
    """What ``path`` is when it exists and is a FIFO, a socket or a device (by ``stat``, so a
    link is followed), else ``None``."""
    try:
        return _kind(os.stat(path).st_mode)
    except OSError:
        return None


def check_regular(path: str | Path, folder_ok: bool = False, what: str = "a recording") -> None:
    """Raise :class:`InputError` when ``path`` exists and is not a regular file: a FIFO, a
    socket or a device (whose read could block forever, or never end), or a folder (unless
    ``folder_ok``: a reader of device folders takes one; ``what`` the file should be, for the
    remedy). Looks with ``stat`` only, never
    opens, so that it cannot block; a missing path is left to the reader, which says so."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    if stat.S_ISDIR(mode):
        if not folder_ok:
            raise InputError("is a folder, expected a file", path, remedy="give the file's path")
        return
    kind = _kind(mode)
    if kind:
        raise InputError(
            f"is {kind}, not a regular file; it is not read",
            path,
            remedy=f"give {what} saved as a file",
        )


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` name one file (links and relative paths resolved)."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)  # no RuntimeError on a symlink loop


def refuse_input_as_output(path: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Raise :class:`InputError` when ``path`` is one of ``inputs``: an input is never
    overwritten, not even with ``--force``."""
    for item in inputs:
        if item is not None and same_file(path, item):
            raise InputError(
                "the output is also an input; inputs are never overwritten",
                path,
                remedy="give the output another name",
            )


def refuse_folder_holding_inputs(folder: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Raise :class:`InputError` when the output ``folder`` is one of ``inputs`` or holds one
    (at any depth): outputs are written into it, so an input there could be replaced; refused
    even with ``--force``."""
    root = Path(os.path.realpath(folder))  # Path.resolve raises on a symlink loop
    for item in inputs:
        if item is None:
            continue
        p = Path(os.path.realpath(item))
        if p == root or root in p.parents:
            raise InputError(
                f"the output folder {'is' if p == root else 'holds'} the input "
                f"{shorten(p.name)}; inputs are never overwritten",
                folder,
                remedy="write the outputs into another folder",
            )


def refuse_folder_in_input_folder(folder: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Raise :class:`InputError` when the output ``folder`` is an input folder (an x-IMU3
    export, a trial folder) or lies inside one: the outputs would be added to the recording,
    and the next read of that folder would meet them; refused even with ``--force``."""
    root = Path(os.path.realpath(folder))  # also for a folder not created yet
    for item in inputs:
        if item is None or not Path(item).is_dir():
            continue
        p = Path(os.path.realpath(item))
        if p == root or p in root.parents:
            raise InputError(
                f"the output folder is {'the' if p == root else 'inside the'} input folder "
                f"{shorten(p.name)}; inputs are never modified",
                folder,
                remedy="write the outputs into a folder outside the recording",
            )


def check_folder_writable(folder: str | Path, path: str | Path | None = None) -> None:
    """Raise :class:`InputError` unless a file can be created in ``folder`` (tried, so that
    read-only mounts and permissions count, also for root)."""
    folder = Path(folder)
    try:
        fd, probe = tempfile.mkstemp(prefix=".motionlab-probe.", dir=folder)
    except OSError as exc:
        raise InputError(
            f"output folder is not writable ({exc.strerror or exc})",
            path or folder,
            remedy="choose another folder",
        ) from None
    os.close(fd)
    os.unlink(probe)


#: what the temporary file's name adds to the output's (``.NAME.XXXXXXXX.tmp``)
TMP_NAME_EXTRA = 14


def check_name_length(path: str | Path, extra: int = 0) -> None:
    """Raise :class:`InputError` when a part of ``path`` is longer than its file system takes
    (``NAME_MAX``, 255 bytes on most), with ``extra`` bytes more for the last part (a temporary
    file's name); a part that does not exist yet is measured against the nearest folder that
    does."""
    parts = Path(path).parts
    for k, part in enumerate(parts):
        folder = Path(*parts[:k]) if k else Path(".")
        while not folder.is_dir() and folder != folder.parent:
            folder = folder.parent
        try:
            limit = os.pathconf(folder if folder.is_dir() else ".", "PC_NAME_MAX")
        except (OSError, ValueError):
            limit = 255
        size = len(os.fsencode(part)) + (extra if k == len(parts) - 1 else 0)
        if size > limit:
            raise InputError(
                f"a name of {len(os.fsencode(part))} bytes: too long for the file system "
                f"(at most {limit - (extra if k == len(parts) - 1 else 0)})",
                shorten(part, 40),
                remedy="give a shorter name",
            )


def check_output(path: str | Path, force: bool, inputs: Iterable[str | Path | None] = ()) -> Path:
    """Validate an output path before any work is done; raise :class:`InputError` if unusable.

    ``inputs`` are the command's input files and folders: an output naming one of them, or
    inside an input folder, is refused even with ``force``. A path ending in a separator
    names a folder; a symbolic link, even to nowhere, is an existing output.
    """
    if str(path).endswith(("/", os.sep)):
        raise InputError("ends in a separator: a folder, expected a file", Path(path),
                         remedy="give a file name")  # fmt: skip
    path, inputs = Path(path), list(inputs)
    check_name_length(path, TMP_NAME_EXTRA)
    refuse_input_as_output(path, inputs)
    refuse_folder_in_input_folder(path.parent, inputs)
    if (path.exists() or path.is_symlink()) and not force:  # where: the folder (a user cannot
        raise InputError(  # tell which one otherwise)
            "output exists", path, f"in {path.parent}", "use force=True to replace it",
            argument="force",
        )  # fmt: skip
    if path.is_dir():
        raise InputError("output is a folder", path, remedy="give a file name")
    kind = special_kind(path)
    if kind:  # the rename would put a file in place of a device node (/dev/full), even as root
        raise InputError(f"output is {kind}, not a regular file; it is never replaced", path,
                         remedy="give a file name")  # fmt: skip
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InputError("output folder does not exist", path, remedy=f"create {parent}")
    if not os.access(parent, os.W_OK):
        raise InputError("output folder is not writable", path, remedy="choose another folder")
    check_folder_writable(parent, path)
    return path


_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process umask (read by setting it and restoring it at once, under a lock)."""
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def output_mode(path: str | Path) -> int:
    """Permission bits for ``path``: those of the existing file, else 0666 minus the umask."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except FileNotFoundError:
        return 0o666 & ~current_umask()


@contextlib.contextmanager
def atomic_path(path: str | Path, force: bool = False) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it onto ``path``.

    Examples
    --------
    >>> with atomic_path("session.h5", force=True) as tmp:   # doctest: +SKIP
    ...     save_session(session, tmp)
    """
    path = check_output(path, force)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, output_mode(path))
        _fsync(tmp)  # the data on disk before the rename: a crash leaves old or new, whole
        os.replace(tmp, path)
    except OSError as exc:
        if exc.errno not in _FULL:
            raise
        raise InputError(
            f"cannot write the file ({exc.strerror or os.strerror(exc.errno)})",
            path,
            remedy="free some space or write elsewhere; "
            + ("the old file is kept" if path.exists() else "nothing was written"),
        ) from None
    finally:
        if tmp.exists():
            tmp.unlink()


#: errno of a write that found no room: disk full, file too large (RLIMIT_FSIZE), quota
_FULL = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT}


def _fsync(path: Path) -> None:
    """Flush ``path``'s data to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
