"""The study manifest: which sessions make up a study, and with which protocol.

A manifest is a YAML file (``study.yaml``)::

    protocol: knee                      # protocol file (relative to this file) or packaged name
    map: maps/knee_sensors.yaml         # optional sensor map for raw recordings
    sessions:
      - subject: S01
        visit: baseline
        files: raw/S01/baseline/*.txt   # a glob, a file, an x-IMU3 export folder, or a list
      - subject: S01
        visit: week6
        files: [raw/S01/week6/thigh.txt, raw/S01/week6/shank.txt]
        reference: raw/S01/week6/mocap.c3d   # optional optical reference
        markers: maps/markers.yaml           # optional marker map of the reference
        map: maps/other.yaml                 # optional, replaces the top-level map
        seed: 3                              # optional, replaces the study's setting
      - {subject: S02, visit: baseline, files: sim/S02_baseline.h5}   # a motionlab session file

The options of ``motionlab run`` are keys too, at the top (the whole study) or in a session (that
session): ``calibration`` (folder of sensor calibrations, ``--calibration``), ``seed``
(integer, ``--seed``), ``filter`` (estimator name, ``--filter``), ``orientation`` (``fused`` or
``vendor``, ``--orientation``), ``magnetometer`` (true/false, ``--magnetometer``) and
``clock_sync`` (true/false, ``--no-clock-sync``): the fields of
:class:`~motionlab.pipeline.PipelineOptions` whose :class:`~motionlab.pipeline.RunOption` says
``batch``. An unknown key is an error naming its line.

Relative paths are relative to the manifest's folder. ``subject`` and ``visit`` name the output
folder ``OUTDIR/<subject>/<visit>/``: letters, digits, space, ``_ . + -``. A session that repeats
another's files with the same map, reference, marker map and options is an error (its numbers
would count twice in the study tables). The structure is checked
on load (:class:`~motionlab.errors.InputError` naming the key and its line); a session whose files
do not exist is kept with its ``problem`` set, so that the rest of the study still runs.
"""

from __future__ import annotations

import glob
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from motionlab.errors import InputError
from motionlab.fusion import registry
from motionlab.pipeline import RUN_OPTIONS
from motionlab.protocol import load_protocol, resolve_protocol_path
from motionlab.session import is_session_file
from motionlab.yamlsafe import LineLoader, load_yaml, read_yaml_text

#: manifest keys of the options of ``motionlab run`` → :class:`motionlab.pipeline.PipelineOptions`
#: field (the options whose :class:`~motionlab.pipeline.RunOption` says ``batch``)
OPTION_KEYS = {o.manifest: name for name, o in RUN_OPTIONS.items() if o.batch and o.manifest}
#: library argument → the manifest key that sets it, for the failure messages
ARGUMENT_KEYS = {name: o.manifest for name, o in RUN_OPTIONS.items() if o.manifest}
TOP_KEYS = ("protocol", "map", "markers", "sessions", *OPTION_KEYS)
SESSION_KEYS = ("subject", "visit", "files", "reference", "markers", "map", *OPTION_KEYS)
_NAME = re.compile(r"^\w[\w .+-]*$")
_EXAMPLE = "see the study manifest example in README.md"


@dataclass(frozen=True)
class SessionSpec:
    """One session of a study: who, when, which files; ``problem`` says why it cannot run."""

    subject: str
    visit: str
    files: tuple[Path, ...]
    reference: Path | None = None
    map: Path | None = None
    line: int = 0
    problem: str = ""
    #: this session's options of ``motionlab run`` (:class:`~motionlab.pipeline.PipelineOptions`
    #: field names), replacing the study's
    options: dict[str, Any] = field(default_factory=dict)
    #: the marker map of its reference (``--markers``): the session's, else the study's
    markers: Path | None = None

    @property
    def folder(self) -> Path:
        """Output folder relative to the study's OUTDIR: ``<subject>/<visit>``."""
        return Path(self.subject) / self.visit


@dataclass(frozen=True)
class Manifest:
    """A validated study manifest (paths resolved, globs expanded, sorted)."""

    path: Path
    protocol: Path
    sessions: tuple[SessionSpec, ...]
    map: Path | None = None
    #: the study's options of ``motionlab run`` (:class:`~motionlab.pipeline.PipelineOptions`
    #: field names)
    options: dict[str, Any] = field(default_factory=dict)
    #: the study's marker map of the references (``--markers``)
    markers: Path | None = None


def _fail(path: Path, line: int | None, key: str, message: str, remedy: str) -> None:
    where = f"line {line}, key {key}" if line else f"key {key}"
    raise InputError(message, path, where, remedy)


class _ManifestLoader(LineLoader):
    """:class:`LineLoader` with room for a study of tens of thousands of sessions (about ten
    values each), still bounded against aliases that expand without end."""

    max_nodes = 1_000_000


def _read(path: Path) -> Any:
    text = read_yaml_text(
        path, "manifest", "give the study YAML file (a study over 4 MiB: split it)"
    )
    return load_yaml(text, _ManifestLoader, path, "check indentation and colons")


def _name(path: Path, entry: dict, key: str, where: str, line: int) -> str:
    value = entry.get(key)
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        _fail(
            path,
            line,
            f"{where}.{key}",
            f"is {value!r}, expected a name",
            f"give the {key}, e.g. {key}: {'S01' if key == 'subject' else 'baseline'}",
        )
    text = str(value).strip()
    if not _NAME.match(text) or text != str(value):
        _fail(
            path,
            line,
            f"{where}.{key}",
            f"{value!r} cannot name a folder",
            "use letters, digits, space, _ . + - (no slashes, not starting with a dot)",
        )
    return text


def _expand(base: Path, patterns: list[str]) -> tuple[list[Path], str]:
    """Files matching each pattern (sorted per pattern; an x-IMU3 export folder counts as a
    file, as ``motionlab run`` reads it), and the first pattern that matched none."""
    from motionlab.io.ximu3 import is_export  # the readers on first use (batch --help is quick)

    files: list[Path] = []
    for pattern in patterns:
        full = str(base / pattern)
        hits = sorted(glob.glob(full, recursive=True)) if glob.has_magic(pattern) else [full]
        hits = [h for h in hits if Path(h).is_file() or is_export(Path(h))]  # x-IMU3 folders
        if not hits:
            kind = "no file matches" if glob.has_magic(pattern) else "no such file"
            return [], f"{kind} {pattern!r}"
        files += [Path(h) for h in hits if Path(h) not in files]
    return files, ""


def _optional_file(
    base: Path, entry: dict, key: str, default: Path | None
) -> tuple[Path | None, str]:
    value = entry.get(key)
    if value is None:
        return default, ""
    file = base / str(value)
    return file, "" if file.is_file() else f"no such {key} file {str(value)!r}"


def _study_file(path: Path, base: Path, doc: dict, key: str) -> Path | None:
    """The study's file under ``key`` (``map``, ``markers``; relative to the manifest), or
    ``None`` without one; a missing file is an error naming the key's line."""
    if doc.get(key) is None:
        return None
    file = base / str(doc[key])
    if not file.is_file():
        _fail(path, doc.lines[key], key, f"no such file {doc[key]!r}", "fix the path")
    return file


def _options(path: Path, base: Path, entry: dict, where: str) -> tuple[dict[str, Any], str]:
    """The run options among ``entry``'s keys (checked; errors name the line) and a missing
    calibration folder (a problem of the session, an error at the top)."""
    out: dict[str, Any] = {}
    missing = ""
    for key, name in OPTION_KEYS.items():
        if key not in entry:
            continue
        value, line, at = entry[key], entry.lines[key], f"{where}{key}"
        kind = RUN_OPTIONS[name].kind
        if kind == "bool" and not isinstance(value, bool):
            _fail(path, line, at, f"is {value!r}, expected true or false", f"e.g. {key}: true")
        if kind == "int" and (isinstance(value, bool) or not isinstance(value, int)):
            _fail(path, line, at, f"is {value!r}, expected an integer", f"e.g. {key}: 3")
        minimum = RUN_OPTIONS[name].minimum
        if minimum is not None and value < minimum:
            _fail(path, line, at, f"is {value!r}, {RUN_OPTIONS[name].below_minimum()}",
                  f"e.g. {key}: {minimum}")  # fmt: skip
        if kind in ("text", "folder") and not (isinstance(value, str) and value.strip()):
            _fail(path, line, at, f"is {value!r}, expected a name", f"e.g. {key}: default")
        choices = RUN_OPTIONS[name].choices
        if kind == "choice" and value not in choices:
            _fail(path, line, at, f"is {value!r}", f"use one of {', '.join(choices)}")
        if name == "estimator":
            try:
                registry.get(value)
            except InputError as exc:
                _fail(path, line, at, exc.message, exc.remedy or "see the estimators' list")
        if kind == "folder":
            value = base / value
            if not value.is_dir():
                missing = f"no such calibration folder {entry[key]!r}"
        out[name] = value
    return out, missing


def load_manifest(path: str | Path) -> Manifest:
    """Load and validate a study manifest; the protocol is loaded (and so validated) too."""
    path = Path(path)
    doc = _read(path)
    base = path.parent
    if not isinstance(doc, dict):
        _fail(path, 1, "(top level)", "is not a mapping", _EXAMPLE)
    lines = doc.lines
    for key in doc:
        if key not in TOP_KEYS:
            _fail(path, lines[key], str(key), "unknown key", f"use {', '.join(TOP_KEYS)}")
    for key in ("protocol", "sessions"):
        if key not in doc:
            _fail(path, min(lines.values(), default=1), key, "missing", f"add '{key}:'; {_EXAMPLE}")
    if not isinstance(doc["protocol"], str):
        _fail(path, lines["protocol"], "protocol", "is not a path", "e.g. protocol: knee")
    local = base / doc["protocol"]
    try:
        protocol = resolve_protocol_path(local if local.is_file() else doc["protocol"])
    except InputError as exc:  # the name as the manifest gives it, with its line
        _fail(path, lines["protocol"], "protocol", f"{doc['protocol']!r}: {exc.message}",
              exc.remedy or "give a protocol file or packaged name")  # fmt: skip
    load_protocol(protocol)
    study_map, study_markers = (_study_file(path, base, doc, k) for k in ("map", "markers"))
    study_options, missing = _options(path, base, doc, "")
    if missing:
        _fail(path, lines["calibration"], "calibration", missing, "fix the path")

    entries = doc["sessions"]
    if not isinstance(entries, list) or not entries:
        _fail(path, lines["sessions"], "sessions", "needs a list of sessions", _EXAMPLE)
    sessions: list[SessionSpec] = []
    seen: dict[tuple[str, str], int] = {}
    runs: dict[tuple, tuple[str, int]] = {}  # a session's inputs and settings → its first place
    for i, entry in enumerate(entries):
        where = f"sessions[{i}]"
        if not isinstance(entry, dict):
            _fail(
                path, lines["sessions"], where, "is not a mapping", "give subject, visit and files"
            )
        line = min(entry.lines.values(), default=lines["sessions"])
        for key in entry:
            if key not in SESSION_KEYS:
                _fail(
                    path,
                    entry.lines[key],
                    f"{where}.{key}",
                    "unknown key",
                    f"use {', '.join(SESSION_KEYS)}",
                )
        subject = _name(path, entry, "subject", where, entry.lines.get("subject", line))
        visit = _name(path, entry, "visit", where, entry.lines.get("visit", line))
        if (subject, visit) in seen:
            _fail(
                path,
                line,
                where,
                f"repeats subject {subject!r} visit {visit!r}",
                f"the first is on line {seen[subject, visit]}; give each visit its own name",
            )
        seen[subject, visit] = line
        patterns = entry.get("files")
        patterns = [patterns] if isinstance(patterns, str) else patterns
        if not patterns or not all(isinstance(p, str) and p.strip() for p in patterns):
            _fail(
                path,
                entry.lines.get("files", line),
                f"{where}.files",
                "needs a file, a glob or a list of them",
                "e.g. files: raw/S01/*.txt",
            )
        files, missing = _expand(base, patterns)
        problems = [("files", missing)]
        reference, missing = _optional_file(base, entry, "reference", None)
        problems.append(("reference", missing))
        markers, missing = _optional_file(base, entry, "markers", study_markers)
        problems.append(("markers", missing))
        # the study's map is for its raw recordings: a session file already names its sensors
        own_session = len(files) == 1 and files[0].is_file() and is_session_file(files[0])
        default_map = None if own_session else study_map
        session_map, missing = _optional_file(base, entry, "map", default_map)
        problems.append(("map", missing))
        options, missing = _options(path, base, entry, f"{where}.")
        problems.append(("calibration", missing))
        problem = next(
            (
                InputError(
                    msg,
                    path,
                    f"line {entry.lines[key]}, key {where}.{key}",
                    "fix the path; the other sessions still run",
                ).line()
                for key, msg in problems
                if msg
            ),
            "",
        )
        run = (tuple(files), reference, session_map, markers, tuple(sorted(options.items())))
        if not problem and run in runs:  # the same numbers again, counted twice in the study
            first, first_line = runs[run]
            _fail(
                path,
                line,
                where,
                f"repeats the files and settings of {first} (line {first_line})",
                "list each recording once (a second run of it needs its own map, reference or "
                "option)",
            )
        runs.setdefault(run, (where, line))
        sessions.append(
            SessionSpec(
                subject,
                visit,
                tuple(files),
                reference,
                session_map,
                line,
                problem,
                options,
                markers,
            )
        )
    return Manifest(
        path=path,
        protocol=protocol,
        sessions=tuple(sessions),
        map=study_map,
        options=study_options,
        markers=study_markers,
    )


def manifest_spelling(name: str, value: str | None) -> str | None:
    """How a batch user sets library argument ``name`` (to ``value``): its manifest key
    (``map_path=map.yaml`` → ``'map: map.yaml'``); ``None`` for an argument with no key
    (:meth:`motionlab.errors.InputError.respelled`)."""
    key = ARGUMENT_KEYS.get(name)
    if key is None:
        return None
    if value in (None, "", "True"):
        return f"manifest key '{key}'"
    value = "false" if value == "False" else value.strip("'")
    return f"'{key}: {value}'"
