"""Click parameter types for files and folders that check what they name while the options
are parsed, and say what is wrong in one line (:class:`~motionlab.errors.InputError`, exit 2)
instead of click's usage text."""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Any

import click

from motionlab.atomic import TMP_NAME_EXTRA, check_name_length, check_regular, special_kind
from motionlab.errors import InputError

#: what a file option's file is, for the remedy of a device or FIFO given as one
_WHAT = {"map_path": "a sensor map", "marker_map": "a marker map", "reference": "a reference"}


class InputFile(click.ParamType):
    """A file to read: a folder (other than an x-IMU3 export's) or an unreadable file is
    refused; a missing one is left to the reader, which says so."""

    name = "file"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        path = Path(value)
        check_name_length(path)
        try:
            os.stat(path)
        except OSError as exc:  # a missing file is the reader's to name
            if exc.errno == errno.ELOOP:
                raise InputError("is a symbolic link that leads back to itself (a loop)", path,
                                 remedy="give the file's own path") from None  # fmt: skip
        if path.is_dir():
            from motionlab.io import folder_refused
            from motionlab.io.ximu3 import is_export

            if is_export(path):  # the x-IMU3 GUI writes a folder per device
                return str(value)
            raise folder_refused(path)
        what = _WHAT.get(param.name if param is not None else "", "a recording")
        check_regular(path, what=what)  # before any open: a FIFO without a writer blocks it
        if path.exists():
            try:
                with open(path, "rb") as f:
                    f.read(1)
            except OSError as exc:
                raise InputError(
                    f"cannot read the file ({exc.strerror or exc})",
                    path,
                    remedy="check its permissions",
                ) from None
        return str(value)


class OutputFile(click.ParamType):
    """A file to write: an existing folder of that name is refused."""

    name = "file"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        check_name_length(value, TMP_NAME_EXTRA)  # written as a temporary file first
        if Path(value).is_dir():
            raise InputError("output is a folder", value, remedy="give a file name")
        return str(value)


class Folder(click.ParamType):
    """A folder (to read or to write into): an existing file of that name is refused."""

    name = "folder"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        path = Path(value)
        check_name_length(path)
        if path.exists() and not path.is_dir():
            what = special_kind(path) or "a file"  # /dev/full said "is a file"
            raise InputError(f"is {what}, expected a folder", path, remedy="give a folder")
        return str(value)


INPUT_FILE = InputFile()
OUTPUT_FILE = OutputFile()
FOLDER = Folder()
