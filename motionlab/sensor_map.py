"""The sensor map (`ingest --map map.yaml`): where each sensor sits, and who was measured.

Schema (every block optional)::

    subject:                 # free metadata, stored in the session's metadata["subject"]
      id: P017
      height_m: 1.78
    session:                 # free metadata, stored in metadata["session"]
      date: 2024-05-02
      protocol: knee
    sensors:                 # keyed by the serial (device id) or the label the reader reports
      00B421ED: {segment: shank, side: right}
      00B421AF: {segment: thigh, side: r, label: thigh_r}
    reader:                  # options given to every reader (motionlab.io.read_any), e.g.
      format: generic        #   force a reader, or the generic reader's column map
      rate_hz: 100

``side`` is normalised to ``l``/``r`` (``left``, ``L``, ``right`` … accepted; omit it for midline
segments); ``label`` renames the sensor in the session (default: the reader's label). Keys are read
as text exactly as written, so ``00123456`` stays a serial and is not read as a number. Keys,
labels and segments are at most 100 characters, without control characters. The numbers under
``reader:`` are checked here, where their line is known: ``mag_field_ut`` and a magnetometer's
``field_ut`` 1-10000 µT, ``rate_hz`` and ``time.tick_hz`` positive. Every error names the key and
its line.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from motionlab.errors import InputError, shorten
from motionlab.yamlsafe import (
    LineMap,
    TextKeyLineLoader,
    did_you_mean,
    e_notation,
    finite,
    load_yaml,
    read_yaml_text,
    text_problem,
)

TOP_KEYS = ("subject", "session", "sensors", "reader")
SENSOR_KEYS = ("segment", "side", "label")
_SIDES = {"l": "l", "left": "l", "r": "r", "right": "r", "": ""}


@dataclass
class SensorPlacement:
    """Where one sensor sits: the map key that named it, its segment, side and new label."""

    key: str
    segment: str = ""
    side: str = ""
    label: str = ""
    line: int | None = None


@dataclass
class SensorMap:
    """A validated sensor map."""

    sensors: dict[str, SensorPlacement] = field(default_factory=dict)
    subject: dict[str, Any] = field(default_factory=dict)
    session: dict[str, Any] = field(default_factory=dict)
    reader: dict[str, Any] = field(default_factory=dict)
    path: Path | None = None

    def fail(self, key: str, message: str, remedy: str, line: int | None = None) -> InputError:
        """An :class:`InputError` naming ``key`` (and its line) in this map."""
        place = f"line {line}, key {key}" if line else f"key {key}"
        return InputError(message, self.path, place, remedy)


def _jsonable(value: Any) -> Any:
    """YAML dates become ISO strings so that metadata can be stored as JSON."""
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    if isinstance(value, _dt.date | _dt.datetime):
        return value.isoformat()
    return value


def normalise_side(value: Any) -> str | None:
    """``'Right'`` → ``'r'``, ``'left'`` → ``'l'``, ``None``/``''`` → ``''``; None if unknown."""
    if value is None:
        return ""
    return _SIDES.get(str(value).strip().lower())


#: every key a reader takes from ``reader:``: the generic reader's column map
#: (:mod:`motionlab.io.generic`, top and single-sensor keys), Xsens/x-IMU3 ``mag_field_ut``
READER_KEYS = ("format", "delimiter", "decimal", "comment", "skip_rows", "header_rows",
               "rate_hz", "time", "sensors", "label", "serial", "vendor", "acc", "gyr", "mag",
               "quat", "mag_field_ut")  # fmt: skip
#: the subject's lengths the analysis uses (m) and the range a person's can have
LENGTHS_M = {"height_m": (0.5, 2.5), "thigh_m": (0.1, 1.0), "shank_m": (0.1, 1.0)}
#: µT: the range of ``field_ut`` / ``mag_field_ut``, the size of the local field a magnetometer
#: in arbitrary units is scaled to (the earth's is 25-65 µT; a magnetometer's full scale is at
#: most a few thousand): a negative one flipped the field, 1e308 made it inf
FIELD_UT = (1.0, 10000.0)
#: Hz: the largest nominal rate (``rate_hz``) and tick rate (``time.tick_hz``) of a column map
MAX_RATE_HZ = 1e5
MAX_TICK_HZ = 1e12
#: the most characters of a sensor's key, label or segment (it names a group of the session
#: file and a sensor in the report) and of the subject's id or name and the session's date
#: (the report's headings)
MAX_NAME_CHARS = 100


def _check_lengths(smap: SensorMap, subject: LineMap) -> None:
    """Refuse a subject length that is not a number in metres (``height_m: 178`` in cm, or
    ``tall``): the gait analysis would leave it out without a word."""
    for key, (low, high) in LENGTHS_M.items():
        value = subject.get(key)
        if value is None:
            continue
        where, line = f"subject.{key}", getattr(subject, "lines", {}).get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise smap.fail(where, f"{shorten(value)!r} is not a number", "give metres, "
                            "e.g. 1.78", line)  # fmt: skip
        value = finite(value)  # 10**400 is no float: it raised OverflowError
        if value is None:
            raise smap.fail(where, f"{shorten(repr(subject[key]))} is not a finite number",
                            "give metres, e.g. 1.78", line)  # fmt: skip
        if not low <= value <= high:
            hint = f"{value / 100:g} m if that is in cm" if value > 10 else f"{low:g}-{high:g} m"
            raise smap.fail(where, f"{value:g} is not a length in metres a person has",
                            f"give metres ({hint})", line)  # fmt: skip


def _number(
    smap: SensorMap,
    m: Any,
    key: str,
    where: str,
    span: tuple[float, float],
    unit: str,
    what: str,
    note: str = "",
) -> None:
    """Refuse ``m[key]`` (if given) unless it is a number from ``span[0]`` (excluded when 0) to
    ``span[1]`` in ``unit``: the readers take it as it is (``float(10**400)``, ``'strong'``
    raised; a negative field flipped the magnetometer)."""
    if not isinstance(m, dict) or m.get(key) is None:
        return
    value, line = m[key], getattr(m, "lines", {}).get(key)
    low, high = span
    within = f"above 0 and at most {high:.12g}" if low == 0 else f"from {low:g} to {high:.12g}"
    remedy = f"give {what} {within} {unit}{note}"
    if e := e_notation(value):
        raise smap.fail(where, e[0], e[1], line)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise smap.fail(where, f"{shorten(repr(value))} is not a number", remedy, line)
    x = finite(value)
    if x is None:
        raise smap.fail(where, f"{shorten(repr(value))} is not a finite number", remedy, line)
    if not (low < x if low == 0 else low <= x) or x > high:
        raise smap.fail(where, f"is {x:g} {unit}", remedy, line)


def _check_reader(smap: SensorMap, reader: LineMap) -> None:
    """The numbers of ``reader:`` (the readers' options, the generic reader's column map): each
    in its range (:func:`_number`), where the map names its line."""
    field = ("the local field's size", " (the earth's: 25-65 µT)")
    _number(smap, reader, "mag_field_ut", "reader.mag_field_ut", FIELD_UT, "µT", *field)
    _number(smap, reader, "rate_hz", "reader.rate_hz", (0.0, MAX_RATE_HZ), "Hz", "the rate")
    time = reader.get("time")
    _number(smap, time, "tick_hz", "reader.time.tick_hz", (0.0, MAX_TICK_HZ), "Hz", "the rate")
    for key, remedy in (("skip_rows", "give 0 or more"), ("header_rows", "give 0, 1 or 2")):
        value = reader.get(key)
        count = not isinstance(value, bool) and isinstance(value, int) and value >= 0
        if value is not None and not (count and (key == "skip_rows" or value <= 2)):
            raise smap.fail(f"reader.{key}", f"{shorten(repr(value))} is not a line count",
                            remedy, reader.lines.get(key))  # fmt: skip
    sensors = reader.get("sensors")
    specs = [("reader", reader)] + [
        (f"reader.sensors[{i}]", spec)
        for i, spec in enumerate(sensors if isinstance(sensors, list) else [])
    ]
    for where, spec in specs:
        mag = spec.get("mag") if isinstance(spec, dict) else None
        _number(smap, mag, "field_ut", f"{where}.mag.field_ut", FIELD_UT, "µT", *field)


def _check_name(smap: SensorMap, value: str, what: str, where: str, line: int | None) -> None:
    """Refuse a key, label or segment (``what``) with a control character or more than
    :data:`MAX_NAME_CHARS` characters."""
    problem = text_problem(value, MAX_NAME_CHARS)
    if problem:
        raise smap.fail(where, f"{what} {shorten(repr(value))} {problem}",
                        "shorten it" if "long" in problem else "remove it", line)  # fmt: skip


def load_sensor_map(path: str | Path) -> SensorMap:
    """Read and validate a sensor map; :class:`InputError` names the offending key and line. A
    relative path into the repository's ``protocols/`` that does not exist here is the installed
    copy (:func:`motionlab.protocol.packaged_copy`: the help's example maps)."""
    from motionlab.protocol import packaged_copy

    path = packaged_copy(path) or Path(path)
    smap = SensorMap(path=path)
    text = read_yaml_text(path, "sensor map", "give a YAML sensor map (see the README)")
    doc = load_yaml(text, TextKeyLineLoader, path, "check indentation")
    if doc is None:
        return smap
    if not isinstance(doc, dict):
        raise smap.fail("(top level)", "is not a mapping", "start with 'sensors:'", 1)
    lines = doc.lines
    for key, value in doc.items():
        if key not in TOP_KEYS:
            raise smap.fail(key, "unknown key", did_you_mean(key, TOP_KEYS), lines[key])
        if value is not None and not isinstance(value, dict):
            raise smap.fail(key, "is not a mapping", "give 'name: value' lines", lines[key])
    _check_lengths(smap, doc.get("subject") or LineMap())
    for part, key in (("subject", "id"), ("subject", "name"), ("session", "date")):
        value = (doc.get(part) or {}).get(key)
        if isinstance(value, str):
            line = doc[part].lines.get(key)
            _check_name(smap, value, key, f"{part}.{key}", line)
    smap.subject = _jsonable(dict(doc.get("subject") or {}))
    smap.session = _jsonable(dict(doc.get("session") or {}))
    reader = doc.get("reader") or LineMap()
    for k in reader:  # a reader ignores what it does not take: a typo was silently no option
        if k not in READER_KEYS:
            raise smap.fail(f"reader.{k}", "unknown key", did_you_mean(k, READER_KEYS),
                            getattr(reader, "lines", {}).get(k))  # fmt: skip
    _check_reader(smap, reader)
    smap.reader = _jsonable(dict(reader))
    sensors = doc.get("sensors") or LineMap()
    seen_labels: dict[str, str] = {}
    seen_segments: dict[str, str] = {}  # protocol segment name (shank + r: shank_r) → key
    for key, spec in sensors.items():
        line = sensors.lines.get(key)
        where = f"sensors.{shorten(key)}"
        _check_name(smap, key, "key", where, line)
        if spec is None:
            spec = {}
        if not isinstance(spec, dict):
            raise smap.fail(where, "is not a mapping", "write {segment: shank, side: r}", line)
        for k in spec:
            if k not in SENSOR_KEYS:
                raise smap.fail(f"{where}.{k}", "unknown key", did_you_mean(k, SENSOR_KEYS), line)
        for k in ("segment", "label"):
            if not isinstance(spec.get(k, ""), str):
                raise smap.fail(
                    f"{where}.{k}", f"is not text: {shorten(repr(spec[k]))}", "quote it", line
                )
        raw_side = spec.get("side")
        side = normalise_side(raw_side) if raw_side is None or isinstance(raw_side, str) else None
        if side is None:
            raise smap.fail(
                f"{where}.side",
                f"side {shorten(repr(raw_side))} is not left or right",
                "write l or r",
                line,
            )
        label = spec.get("label", "").strip()
        if "/" in label or label in (".", "..") or not label.isprintable():  # "a\nb": 2 lines
            raise smap.fail(f"{where}.label", f"label {shorten(repr(label))} cannot name a sensor",
                            "use letters, digits and _", line)  # fmt: skip
        _check_name(smap, label, "label", f"{where}.label", line)
        if label:
            if label in seen_labels:
                raise smap.fail(f"{where}.label", f"label {label!r} is also used by "
                                f"sensors.{seen_labels[label]}", "give each sensor its own label",
                                line)  # fmt: skip
            seen_labels[label] = key
        segment = spec.get("segment", "").strip()
        _check_name(smap, segment, "segment", f"{where}.segment", line)
        # two sensors on one segment: the analysis would take one of them and say nothing
        placed = f"{segment}_{side}" if side and not segment.endswith(f"_{side}") else segment
        if placed and placed in seen_segments:
            raise smap.fail(f"{where}.segment", f"segment {placed} is also given to "
                            f"sensors.{seen_segments[placed]}",
                            "give each sensor its own segment (check the sides)", line)  # fmt: skip
        seen_segments[placed] = key
        smap.sensors[key] = SensorPlacement(
            key=key, segment=segment, side=side, label=label, line=line
        )
    return smap


def unmatched_place(entry: dict[str, Any]) -> str:
    """``"line 8, chair"``: where a key the ingest kept in ``metadata["map_unmatched"]`` (it named
    no sensor) stands in the map and what segment it maps."""
    line = f"line {entry['line']}" if entry.get("line") else ""
    return ", ".join(x for x in (line, entry.get("segment") or "") if x)
