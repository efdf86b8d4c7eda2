"""Readers of vendor and optical files, one module per format, and :func:`read_any`.

Every reader module defines

- ``FORMAT``: a short name (``"xsens"``),
- ``sniff(path, head) -> bool``: whether the file's first bytes (``head``, up to 64 KiB) look like
  this format — the content decides, never the file name alone,
- ``read(path, options=None) -> Recording``: the data in SI units (see :mod:`motionlab.units`)
  with the original units recorded, raising :class:`~motionlab.errors.InputError` with the
  file, the line or channel, and a remedy for anything it cannot read.

``options`` is a dict of reader options (for the generic reader: its YAML column map).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from motionlab.atomic import check_regular
from motionlab.errors import InputError, shorten
from motionlab.isolated import check_hdf5, open_hdf5
from motionlab.session import MarkerSet, SensorStream

HEAD_BYTES = 65536
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

#: reader modules in detection order: specific formats first, the generic reader last
READER_MODULES = (
    "broad",
    "apdm_h5",
    "c3d",
    "trc",
    "opensim",
    "xsens",
    "dot",
    "apdm",
    "ximu3",
    "xio",
    "generic",
)


@dataclass
class Recording:
    """What a reader returns: inertial sensors, optical marker sets, and file-level metadata."""

    sensors: list[SensorStream] = field(default_factory=list)
    markers: list[MarkerSet] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)
    format: str = ""


def _readers():
    for name in READER_MODULES:
        try:
            yield importlib.import_module(f"motionlab.io.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"motionlab.io.{name}":
                raise


def read_head(path: Path) -> bytes:
    with open(path, "rb") as f:
        return f.read(HEAD_BYTES)


def detect_format(path: str | Path, options: dict[str, Any] | None = None) -> str:
    """Name of the reader that recognises ``path`` by its content."""
    return _detect(Path(path), options).FORMAT


def folder_refused(path: Path) -> InputError:
    """The error for a folder given as a recording that is no export folder: its remedy names
    the export folders one level down, if any (a trial folder holding ``imu/`` and the optical
    file beside it), else asks for a file."""
    exports = [m.is_export for m in _readers() if getattr(m, "is_export", None)]
    try:
        below = sorted(p for p in path.iterdir() if p.is_dir() and any(e(p) for e in exports))
    except OSError:
        below = []
    remedy = (
        "give the export folder inside it: " + ", ".join(str(p) for p in below[:3])
        if below
        else "give the file's path"
    )
    return InputError("is a folder, expected a file (or an x-IMU3 export folder)", path,
                      remedy=remedy)  # fmt: skip


def _detect(path: Path, options: dict[str, Any] | None):
    check_regular(path, folder_ok=True)  # a FIFO, socket or device: refused before any read
    if path.is_dir():  # a reader of folders has is_export(path) (x-IMU3: a folder per device)
        for module in _readers():
            if getattr(module, "is_export", None) and module.is_export(path):
                wanted = (options or {}).get("format")
                if wanted and wanted != module.FORMAT:  # else its options are never looked at
                    raise InputError(
                        f"is a {module.FORMAT} export folder, but the map's reader says format "
                        f"'{shorten(str(wanted))}'",
                        path,
                        remedy=f"remove 'format' from the map's reader: (or give "
                        f"'{module.FORMAT}')",
                    )
                return module
        raise folder_refused(path)
    if not path.is_file():
        raise InputError("no such file", path, remedy="check the path")
    try:
        head = read_head(path)
    except OSError as exc:
        raise InputError(
            f"cannot read the file ({exc.strerror or exc})", path, remedy="check its permissions"
        ) from None
    if not head.strip():
        raise InputError("file is empty", path, remedy="export the recording again")
    if options and options.get("format"):
        wanted = options["format"]
        for module in _readers():
            if module.FORMAT == wanted:
                return module
        raise InputError(
            f"unknown format '{wanted}'",
            path,
            remedy=f"use one of {', '.join(m.FORMAT for m in _readers())}",
        )
    if head.startswith(HDF5_SIGNATURE):
        check_hdf5(path)  # a crash in libhdf5 on a damaged file: refused before any sniffer
    for module in _readers():
        if module.sniff(path, head):
            return module
    if head.startswith(HDF5_SIGNATURE):
        _check_hdf5(path)
        raise InputError(
            "unknown file format: HDF5 without the datasets of a BROAD or APDM file",
            path,
            remedy="give a BROAD trial or an APDM .h5 export",
        )
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # a byte-order mark: Excel's "Unicode text"
        raise InputError("text in UTF-16, which motionlab does not read", path,
                         remedy="save or export it as UTF-8 text (CSV)")  # fmt: skip
    if head.startswith(b"MATLAB "):  # a MAT-file's text header (level 5 and 7.3)
        raise InputError(
            "a MATLAB .mat file, which motionlab does not read",
            path,
            remedy="save each sensor's time, acc and gyr as a CSV and read it through a column "
            "map, 'reader:' in the sensor map (docs/ingest.md, 'The map')",
        )
    if b"\x00" in head:  # no column map makes text of it: say what it is (random bytes, a zip)
        raise InputError(
            "binary file of no format motionlab reads",
            path,
            remedy="give a vendor export (text, C3D, TRC, BROAD or APDM HDF5)",
        )
    if len(head) == HEAD_BYTES and b"\n" not in head and b"\r" not in head:
        raise InputError(
            f"its first line runs on past {HEAD_BYTES // 1024} kB without a line break: no "
            "export's header is that long",
            path,
            remedy="export the recording again (the file may be damaged or joined into one line)",
        )
    raise InputError(
        "unknown file format",
        path,
        remedy="give a column map, 'reader:' in map_path= (docs/ingest.md, 'The map')",
        argument="map_path",
    )


def _check_hdf5(path: Path) -> None:
    """Raise :class:`InputError` if h5py cannot open a file that starts like HDF5."""
    message = "HDF5 file is damaged or truncated (h5py cannot open it)"
    open_hdf5(path, message, "copy or export the file again").close()


def read_any(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Detect the format of ``path`` from its content and read it."""
    path = Path(path)
    module = _detect(path, options)
    try:
        rec = module.read(path, options)
    except (OSError, RuntimeError) as exc:  # h5py: damaged data or metadata in the file
        if isinstance(exc, RuntimeError) and module.FORMAT not in ("broad", "apdm_h5"):
            raise
        if isinstance(exc, FileNotFoundError | PermissionError | IsADirectoryError):
            raise InputError(
                f"cannot read the file ({exc.strerror or exc})", path, remedy="check the path"
            ) from None
        detail = shorten(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        raise InputError(
            f"cannot be read, the file is damaged ({detail})",
            path,
            remedy="copy or export the file again",
        ) from None
    rec.format = module.FORMAT
    return rec
