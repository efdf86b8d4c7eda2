"""YAML input that cannot hang, eat memory or crash: the base loader of every YAML file a user
gives (protocols, sensor and marker maps, batch manifests).

- Aliases are bounded: the document, with every alias expanded, may hold at most
  :data:`MAX_NODES` nodes (a "billion laughs" of a few hundred bytes is refused at once), and
  a recursive alias is refused.
- A value the safe constructors cannot build (``2026-02-30``: a date that does not exist,
  ``!!int abc``) is a :class:`yaml.YAMLError` with its line, not a ``ValueError``.

:func:`read_yaml_text` reads the file itself: a folder, an unreadable, binary or oversized file
is an :class:`~motionlab.errors.InputError`.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Hashable, Iterable
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import ConstructorError

from motionlab.atomic import check_regular
from motionlab.errors import InputError, shorten

#: nodes a document may hold with its aliases expanded
MAX_NODES = 50_000
#: the largest YAML file read (bytes); protocols and maps are a few kB
MAX_BYTES = 4 << 20


class _Refused(ConstructorError):
    """A document refused by :class:`BoundedSafeLoader`, with its own remedy."""

    def __init__(self, problem: str, mark: yaml.Mark | None, remedy: str) -> None:
        super().__init__(None, None, problem, mark)
        self.remedy = remedy


#: libyaml's parser where PyYAML was built with it (a 3-MB study manifest: 12 s in the pure-
#: Python one), else the pure-Python one; the constructors are the same
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class BoundedSafeLoader(_SAFE_LOADER):  # type: ignore[misc, valid-type]
    """``yaml.SafeLoader`` with aliases bounded and constructor errors as YAML errors."""

    #: the nodes a document may hold with its aliases expanded
    max_nodes = MAX_NODES

    def get_single_node(self) -> yaml.Node | None:
        # the one entry of both parsers (libyaml's composes in C, past compose_document)
        node = super().get_single_node()
        if node is not None:
            _count_nodes(node, self.max_nodes)
        return node

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, TypeError, OverflowError) as exc:
            value = shorten(node.value) if isinstance(node, yaml.ScalarNode) else node.tag
            raise _Refused(
                f"cannot read {value!r} ({exc})",
                node.start_mark,
                "write a date that exists (YYYY-MM-DD), or quote the value to keep it as text"
                if node.tag.endswith(":timestamp")
                else "fix the value, or quote it to keep it as text",
            ) from None


class LineMap(dict):
    """A YAML mapping that knows the line (1-based) of each key: ``lines``."""

    lines: dict[Any, int]


class LineLoader(BoundedSafeLoader):
    """:class:`BoundedSafeLoader` whose mappings are :class:`LineMap` (protocols, marker maps,
    study manifests), so that an error names the line of its key."""

    #: keep each scalar key as the text written (sensor maps: ``00B421AF``, ``1e3``)
    text_keys = False


class TextKeyLineLoader(LineLoader):
    """:class:`LineLoader` whose scalar keys stay the text written (sensor labels and serials
    that look like numbers)."""

    text_keys = True


def _construct_mapping(loader: LineLoader, node: yaml.MappingNode) -> LineMap:
    written = {id(k) for k, _ in node.value}  # before merge keys (<<: *base) add theirs
    loader.flatten_mapping(node)
    out = LineMap()
    out.lines = {}
    twice: dict[Any, int] = {}
    for key_node, value_node in node.value:
        if loader.text_keys:
            key = (
                key_node.value
                if isinstance(key_node, yaml.ScalarNode)
                else str(loader.construct_object(key_node, deep=True))
            )
        else:
            key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if id(key_node) in written and isinstance(key, Hashable):  # a merged key may be redefined
            if key in twice:  # YAML keeps the last silently: one sensor's segment lost
                raise _Refused(f"key {shorten(key)!r} is written twice (lines {twice[key]} and "
                               f"{line})", key_node.start_mark, "keep one of them")  # fmt: skip
            twice[key] = line
        out[key] = loader.construct_object(value_node, deep=True)
        out.lines[key] = line
    return out


LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _count_nodes(root: yaml.Node, limit: int) -> int:
    """Nodes under ``root`` with aliases expanded; :class:`yaml.YAMLError` past ``limit`` or
    for a recursive alias. Shared nodes are counted once per use, without expanding them."""
    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in active:
            raise _Refused("recursive alias", node.start_mark, "remove the alias (*name)")
        active.add(key)
        n = 1
        if isinstance(node, yaml.SequenceNode):
            n += sum(size(c) for c in node.value)
        elif isinstance(node, yaml.MappingNode):
            n += sum(size(k) + size(v) for k, v in node.value)
        active.discard(key)
        if n > limit:
            raise _Refused(
                f"holds more than {limit} values (aliases expanded)",
                node.start_mark,
                "split it into smaller files, or write aliases (*name) out",
            )
        sizes[key] = n
        return n

    return size(root)


def read_yaml_text(path: str | Path, what: str, remedy: str) -> str:
    """The text of the YAML file ``path`` (a ``what``: "protocol", "sensor map"), with an
    :class:`InputError` for a missing, folder, unreadable, oversized or binary file."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"is a folder, expected a {what} file", path, remedy=remedy)
    check_regular(path, what=f"a {what}")
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise InputError(
                f"{size} bytes: too large for a {what} file (at most {MAX_BYTES >> 20} MiB)",
                path,
                remedy=remedy,
            )
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"no such {what} file", path, remedy="check the path") from None
    except OSError as exc:
        raise InputError(
            f"cannot read the file ({exc.strerror or exc})", path, remedy="check its permissions"
        ) from None
    if b"\x00" in data:
        raise InputError(f"binary file, not a {what}", path, remedy=remedy)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"not UTF-8 text (byte {exc.start})", path, remedy="save it as UTF-8"
        ) from None


def load_yaml(text: str, loader: type[BoundedSafeLoader], path: Path, remedy: str) -> Any:
    """``text`` loaded with ``loader``; every YAML problem an :class:`InputError` with its
    line."""
    try:
        return yaml.load(text, Loader=loader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else None
        problem = getattr(exc, "problem", None) or exc
        remedy = getattr(exc, "remedy", remedy)
        raise InputError(f"not valid YAML ({problem})", path, where, remedy) from None
    except RecursionError:
        raise InputError("nested too deeply", path, remedy=remedy) from None


def did_you_mean(key: object, allowed: Iterable[str]) -> str:
    """A remedy for an unknown key: the closest allowed key, or the list of them."""
    allowed = list(allowed)
    close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
    if close:
        return f"did you mean '{close[0]}'?"
    return f"use one of {', '.join(allowed)}"


#: control characters (C0, DEL, C1, the Unicode line and paragraph separators, lone surrogates):
#: no text a user gives holds one; in the report's fonts and on a terminal they leak out as
#: warnings and escapes (a tab and a line break: only where a text may run over lines)
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\ud800-\udfff]")
#: text that Python reads as a number in e-notation (YAML 1.1 reads it as text: ``1e3``)
_E_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def finite(value: Any) -> float | None:
    """``value`` as a float when it is a finite number (an int or a float, not a bool), else
    ``None``: ``.nan``, ``.inf`` and an integer too large for a float (400 digits) are none."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        x = float(value)
    except OverflowError:
        return None
    return x if math.isfinite(x) else None


def e_notation(value: Any) -> tuple[str, str] | None:
    """For text that is a number in e-notation YAML 1.1 read as text (``1e3``, ``1.0e3``: YAML
    needs a decimal point and a signed exponent), what is wrong and how to write it
    (``1.0e+3``); else ``None``."""
    if not isinstance(value, str) or not _E_NUMBER.fullmatch(value.strip()):
        return None
    mantissa, exponent = re.split("[eE]", value.strip())
    mantissa += "" if "." in mantissa else ".0"
    written = f"{mantissa}e{exponent if exponent[0] in '+-' else '+' + exponent}"
    return (
        f"is text {shorten(repr(value))}: YAML reads e-notation as a number only with a "
        "decimal point and a signed exponent",
        f"write {written} (YAML reads e.g. 1.0e3 as text too)",
    )


def text_problem(value: str, limit: int, lines: bool = False) -> str | None:
    """What is wrong with the free text ``value`` (a name, title, label) to show in a report or
    on a terminal: a control character (a tab or line break allowed where ``lines``), or more
    than ``limit`` characters (a name of 100 000 characters kept the report's wrapping busy for
    minutes); ``None`` when nothing is."""
    bad = sorted({c for c in _CONTROL.findall(value) if not (lines and c in "\t\n")})
    if bad:
        plural = "s" if len(bad) > 1 else ""
        return f"holds the control character{plural} {', '.join(repr(c) for c in bad[:3])}"
    if len(value) > limit:
        return f"is {len(value)} characters long, at most {limit}"
    return None
