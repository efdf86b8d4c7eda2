"""The click options of ``motionlab run`` and ``motionlab batch``, made from one table: the
fields of :class:`motionlab.pipeline.PipelineOptions` and their
:class:`~motionlab.pipeline.RunOption` (flag, help text, kind, manifest key). A new run option is
one field there; ``run``, ``batch``, the flag table and the manifest keys follow."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from motionlab.cli.paths import FOLDER, INPUT_FILE
from motionlab.pipeline import RUN_OPTIONS, PipelineOptions, RunOption

_TYPES: dict[str, Any] = {"int": int, "file": INPUT_FILE, "folder": FOLDER}
_DEFAULTS = {f.name: f.default for f in dataclasses.fields(PipelineOptions)}


def _shown(name: str, option: RunOption) -> str:
    """The default as ``motionlab batch --help`` says it."""
    default = _DEFAULTS[name]
    if option.kind == "bool":
        return "on" if default else "off"
    return str(default)


def _click_option(name: str, option: RunOption, batch: bool) -> Callable:
    """One click option of field ``name``: ``run``'s with the field's default, or ``batch``'s
    (no default, so that the manifest's setting stays; its key and default in the help)."""
    kw: dict[str, Any] = {"help": option.help}
    default = _DEFAULTS[name]
    if option.kind in _TYPES:
        kw["type"] = _TYPES[option.kind]
    if option.kind == "choice":
        kw["type"] = click.Choice(option.choices)
    if option.kind == "flag":
        kw["is_flag"] = True
    if option.kind == "off":
        kw.update(is_flag=True, flag_value=False)
    if batch:
        said = "" if default is None else f"; default: {_shown(name, option)}"
        kw["help"] = f"{option.help} [manifest key '{option.manifest}'{said}]"
        kw["default"] = None
    elif default is dataclasses.MISSING:
        kw["required"] = True
    else:
        kw.update(default=default, show_default=option.show_default)
    return click.option(option.flag, name, **kw)


def _apply(names: list[str], batch: bool) -> Callable[[Callable], Callable]:
    def decorate(fn: Callable) -> Callable:
        for name in reversed(names):
            fn = _click_option(name, RUN_OPTIONS[name], batch)(fn)
        return fn

    return decorate


#: every option of ``motionlab run``, as click options named by the fields
run_click_options = _apply(list(RUN_OPTIONS), batch=False)
#: the options a study sets (``RunOption.batch``), as ``motionlab batch`` flags
batch_click_options = _apply([n for n, o in RUN_OPTIONS.items() if o.batch], batch=True)


def run_values(params: dict[str, Any], batch: bool = False) -> dict[str, Any]:
    """The :class:`PipelineOptions` fields among click's ``params`` (files and folders as
    :class:`~pathlib.Path`); for ``batch``, only the options given."""
    out = {}
    for name, option in RUN_OPTIONS.items():
        if name not in params or (batch and not option.batch):
            continue
        value = params[name]
        if value is not None and option.kind in ("file", "folder"):
            value = Path(value)
        if value is not None or not batch:
            out[name] = value
    return out
