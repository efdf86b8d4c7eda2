"""Generic delimited text, read through a small column map (YAML, passed as ``options``).

For any export no dedicated reader knows. :func:`sniff` is always False: this reader is used
only when the options say ``format: generic`` (``motionlab ingest --map map.yaml``).

Column map schema (every key optional unless marked *required*)::

    format: generic
    delimiter: ";"        # "\\t", ";", ",", " " or "whitespace" (runs of blanks); else detected
    decimal: ","          # "." or ","; a decimal comma is detected if absent (non-comma delimiter)
    comment: ["#", "//"]  # prefixes of comment lines, skipped anywhere (default "#" and "//")
    skip_rows: 2          # lines to skip before the header (default 0)
    header_rows: 2        # 0 (no header), 1 (default) or 2; with two rows a column is named
                          #   "<row 1> <row 2>", row 1 carried right over empty cells
    rate_hz: 100          # nominal rate, used only when there is no time column; without it
                          #   the rate is read from a comment line before the header:
                          #   "# sampling frequency: 40", "// fs=100", "# rate: 100 Hz"
    time:                 # or just  time: "t"  (a column in seconds)
      column: t           # name or 0-based index
      unit: ms            # s, ms, us, or ticks (then tick_hz, and wrap_bits if it wraps)
      tick_hz: 10000
      wrap_bits: 32
    sensors:              # *required* (or one sensor's keys at the top level, see below)
      - label: thigh      # *required* with several sensors; default: the file name
        serial: "00B421AF"
        vendor: "Acme"
        acc: {columns: [ax, ay, az], unit: g}        # unit *required*: g, m/s^2, mg …
        gyr: {columns: [4, 5, 6], unit: deg/s}       # deg/s, rad/s …
        mag: {columns: [mx, my, mz], unit: uT}       # uT, gauss, nT … or a.u. (below)
        quat: {columns: [qw, qx, qy, qz], order: wxyz}   # order wxyz (default) or xyzw;
                                                      # inverse: true if it maps earth → sensor
      - label: shank
        gyr: {columns: ["shank gyr_x", "shank gyr_y", "shank gyr_z"], unit: rad/s}

Without a time column the time is row / rate (s), the first row at 0; ``attrs["time_source"]``
says where the rate came from (``rate_hz 40.0`` or ``comment line 1: 40.0 Hz``). Several sensors
of one file share its time base, so they are on one clock
(:func:`motionlab.io.clock.mark_shared_clock`).

Magnetometer in arbitrary units (``unit: a.u.``, e.g. raw counts, or a field normalised to 1):
only the direction is known. Inside motionlab the field is in µT (fusion's disturbance tolerances
are in µT), so each sensor's field is scaled by one constant that makes its median norm
``field_ut`` (a key of the ``mag`` entry; default 50 µT, a typical mid-latitude field). The
direction is kept exactly; ``source_units["mag"]`` is ``"a.u."``, ``attrs["mag_scale_assumed"]``
is set (so the QC does not judge the norm) with the factor in ``attrs["mag_scale_ut_per_au"]``,
and a note says so.

A single sensor may be described at the top level instead (``label``, ``acc``, ``gyr`` …
beside ``delimiter``). Quaternions must map sensor → ENU earth (``inverse: true`` conjugates).
A key that is unknown, missing or of the wrong type raises :class:`InputError` naming it
(``key sensors[1].gyr.unit``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from motionlab import rotations
from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.clock import checked_counter_time, mark_shared_clock
from motionlab.io.delimited import (
    COMMENT_PREFIXES,
    DELIMITERS,
    Table,
    first_content_line,
    parse_table,
    read_lines,
)
from motionlab.session import SensorStream
from motionlab.units import to_si

FORMAT = "generic"

_TOP_KEYS = {"format", "delimiter", "decimal", "comment", "skip_rows", "header_rows", "rate_hz",
             "time", "sensors"}  # fmt: skip
_SENSOR_KEYS = {"label", "serial", "vendor", "acc", "gyr", "mag", "quat"}
_CHANNEL_KEYS = {"columns", "unit", "order", "inverse", "field_ut"}
_TIME_KEYS = {"column", "unit", "tick_hz", "wrap_bits"}
_QUANTITY = {"acc": "acc", "gyr": "gyr", "mag": "mag"}
ARBITRARY_UNITS = ("a.u.", "au", "a.u", "arbitrary")
DEFAULT_FIELD_UT = 50.0  # µT: the assumed field norm of a magnetometer in arbitrary units
#: a rate in a comment line: "# sampling frequency: 40", "// fs=100", "# rate: 100 Hz"
_RATE_LINE = re.compile(
    r"(?:sampling|sample)?[ _-]?(?:frequency|freq|rate|fs)\s*(?:\(\s*hz\s*\)|\[\s*hz\s*\])?"
    r"\s*[:=]\s*([0-9]+(?:\.[0-9]*)?(?:e[+-]?[0-9]+)?)\s*(?:hz)?\s*$",
    re.IGNORECASE,
)


def sniff(path: Path, head: bytes) -> bool:
    """Never: the generic reader needs a column map (``format: generic``)."""
    return False


class _Map:
    """Validating accessor for the column map: every error names the key."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, message: str, remedy: str) -> InputError:
        return InputError(message, self.path, f"column map key {key}", remedy)

    def check_keys(self, d: Any, allowed: set[str], key: str) -> dict:
        if not isinstance(d, dict):
            raise self.fail(key, "must be a mapping", "see the schema in the generic reader docs")
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise self.fail(
                f"{key}.{unknown[0]}" if key else unknown[0],
                "unknown key",
                f"allowed keys: {', '.join(sorted(allowed))}",
            )
        return d

    def number(self, d: dict, name: str, key: str, positive: bool = True) -> float | None:
        if d.get(name) is None:
            return None
        v = d[name]
        if isinstance(v, bool) or not isinstance(v, int | float) or (positive and v <= 0):
            raise self.fail(key, f"must be a positive number, not {v!r}", "give a number")
        return float(v)


def _column(m: _Map, table: Table, ref: Any, key: str) -> int:
    if isinstance(ref, bool) or not isinstance(ref, int | str):
        raise m.fail(key, f"column {ref!r} is neither a name nor an index", "give a name or index")
    if isinstance(ref, int):
        if not 0 <= ref < len(table.names):
            raise m.fail(
                key, f"column index {ref} out of range", f"the file has {len(table.names)} columns"
            )
        return ref
    if ref in table.names:
        return table.names.index(ref)
    folded = [n.lower() for n in table.names]
    if folded.count(ref.lower()) == 1:
        return folded.index(ref.lower())
    raise m.fail(key, f"no column '{ref}'", f"columns are {', '.join(table.names)}")


def _channel(m: _Map, table: Table, spec: Any, name: str, key: str) -> tuple[np.ndarray, str]:
    spec = m.check_keys(spec, _CHANNEL_KEYS, key)
    n = 4 if name == "quat" else 3
    cols = spec.get("columns")
    if not isinstance(cols, list) or len(cols) != n:
        raise m.fail(f"{key}.columns", f"needs a list of {n} columns", "e.g. [ax, ay, az]")
    idx = [_column(m, table, c, f"{key}.columns[{k}]") for k, c in enumerate(cols)]
    values = table.data[:, idx]
    for k, j in enumerate(idx):
        if not np.isfinite(values[:, k]).any():
            raise InputError(
                f"channel {name}: column '{table.names[j]}' has no values (all empty, NaN or ±inf)",
                table.path,
                f"column '{table.names[j]}'",
                remedy="check the column map, or leave the channel out",
            )
    if name == "quat":
        order = spec.get("order", "wxyz")
        if order not in ("wxyz", "xyzw"):
            raise m.fail(f"{key}.order", f"'{order}' is not wxyz or xyzw", "give wxyz or xyzw")
        q = values if order == "wxyz" else values[:, [3, 0, 1, 2]]
        q = rotations.normalize(q)
        if spec.get("inverse", False):
            q = rotations.conj(q)
        return rotations.make_continuous(q), order
    if "order" in spec or "inverse" in spec:
        raise m.fail(f"{key}.order", "only quaternions take 'order'/'inverse'", "remove it")
    unit = spec.get("unit")
    if not isinstance(unit, str):
        raise m.fail(f"{key}.unit", "missing unit", f"give the unit of {name}, e.g. deg/s or g")
    arbitrary = unit.strip().lower() in ARBITRARY_UNITS
    if "field_ut" in spec and not (name == "mag" and arbitrary):
        raise m.fail(f"{key}.field_ut", "only a magnetometer in a.u. takes it", "remove it")
    if arbitrary:
        if name != "mag":
            raise m.fail(f"{key}.unit", f"{name} cannot be in a.u.", "give its physical unit")
        m.number(spec, "field_ut", f"{key}.field_ut")
        return values.astype(float), "a.u."
    try:
        return to_si(values, unit, _QUANTITY[name]), unit
    except InputError as exc:
        raise m.fail(f"{key}.unit", exc.message, exc.remedy or "") from None


def rate_from_comments(lines: list[str], prefixes: list[str]) -> tuple[float, int] | None:
    """The rate (Hz) written in a comment line among ``lines``, and its 1-based line number.

    Recognised: ``# sampling frequency: 40``, ``// fs=100``, ``# rate: 100 Hz``,
    ``# sample rate (Hz): 50`` (case-insensitive); the first such line wins.
    """
    for i, line in enumerate(lines):
        s = line.strip()
        prefix = next((p for p in prefixes if s.startswith(p)), None)
        if prefix is None:
            continue
        match = _RATE_LINE.fullmatch(s[len(prefix) :].strip())
        if match and float(match.group(1)) > 0:
            return float(match.group(1)), i + 1
    return None


def _time(m: _Map, table: Table, opts: dict, comments: list[str]) -> tuple[np.ndarray, dict]:
    spec = opts.get("time")
    if spec is None:
        rate = m.number(opts, "rate_hz", "rate_hz")
        source = f"rate_hz {rate}"
        if rate is None:
            found = rate_from_comments(table.preamble, comments)
            if found is None:
                raise m.fail(
                    "time",
                    "no time column, no rate_hz and no rate in a comment line",
                    "give 'time' or 'rate_hz' in the column map",
                )
            rate, line = found
            source = f"comment line {line}: {rate} Hz"
        return np.arange(len(table.data)) / rate, {"time_source": source}
    if isinstance(spec, str | int) and not isinstance(spec, bool):
        spec = {"column": spec}
    spec = m.check_keys(spec, _TIME_KEYS, "time")
    if "column" not in spec:
        raise m.fail("time.column", "missing", "name the time column")
    j = _column(m, table, spec["column"], "time.column")
    unit = spec.get("unit", "s")
    attrs = {"time_source": table.names[j]}
    if unit == "ticks":
        tick_hz = m.number(spec, "tick_hz", "time.tick_hz")
        if tick_hz is None:
            raise m.fail("time.tick_hz", "missing for unit ticks", "give the tick rate in Hz")
        bits = spec.get("wrap_bits", 62)  # 62: no wrap within int64 ticks
        if isinstance(bits, bool) or not isinstance(bits, int) or not 2 <= bits <= 62:
            raise m.fail("time.wrap_bits", f"{bits!r} is not a bit width", "e.g. 16 or 32")
        t = checked_counter_time(
            table.data[:, j], tick_hz, bits, table.path, table.names[j], table.lines
        )
        return t, attrs
    values = table.data[:, j]
    bad = np.flatnonzero(np.isnan(values))
    if len(bad):
        raise InputError(
            f"time column '{table.names[j]}' is empty",
            table.path,
            f"line {table.lines[bad[0]]}",
            remedy="repair or delete the line",
        )
    try:
        return to_si(values, unit, "time"), attrs
    except InputError as exc:
        raise m.fail("time.unit", exc.message, exc.remedy or "") from None


def _comments(m: _Map, opts: dict) -> list[str]:
    comment = opts.get("comment", list(COMMENT_PREFIXES))
    comment = [comment] if isinstance(comment, str) else comment
    if not isinstance(comment, list) or not all(isinstance(c, str) and c for c in comment):
        raise m.fail("comment", "must be a list of line prefixes", 'e.g. ["#", "//"]')
    return comment


def _scale_arbitrary(values: np.ndarray, spec: dict) -> tuple[np.ndarray, dict[str, Any]]:
    """A field in a.u. scaled to a median norm of ``field_ut`` µT; the attributes saying so."""
    field_ut = float(spec.get("field_ut", DEFAULT_FIELD_UT))
    norm = np.linalg.norm(values, axis=1)
    median = float(np.nanmedian(norm)) if np.isfinite(norm).any() else 0.0
    scale = field_ut / median if median > 0 else 1.0
    attrs = {"mag_scale_assumed": True, "mag_field_ut": field_ut, "mag_scale_ut_per_au": scale}
    return values * scale, attrs


def _table(m: _Map, path: Path, opts: dict) -> Table:
    lines = read_lines(path)
    delimiter = opts.get("delimiter")
    if delimiter is not None and delimiter not in (*DELIMITERS, "whitespace"):
        raise m.fail(
            "delimiter", f"{delimiter!r} is not supported", "use \\t ; , space or whitespace"
        )
    decimal = opts.get("decimal")
    if decimal is not None and decimal not in (".", ","):
        raise m.fail("decimal", f"{decimal!r} is not '.' or ','", "give '.' or ','")
    comment = _comments(m, opts)
    skip = opts.get("skip_rows", 0)
    header_rows = opts.get("header_rows", 1)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise m.fail("skip_rows", f"{skip!r} is not a line count", "give 0 or more")
    if header_rows not in (0, 1, 2) or isinstance(header_rows, bool):
        raise m.fail("header_rows", f"{header_rows!r} is not 0, 1 or 2", "give 0, 1 or 2")
    header = first_content_line(lines, skip, comment)
    return parse_table(
        path,
        lines,
        header,
        header_rows=header_rows,
        delimiter=delimiter,
        decimal=decimal,
        comments=comment,
    )


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read a delimited text file described by the column map ``options`` (module docs)."""
    path = Path(path)
    m = _Map(path)
    opts = dict(options or {})
    if "sensors" in opts:
        m.check_keys(opts, _TOP_KEYS, "")
        sensors = opts["sensors"]
        if not isinstance(sensors, list) or not sensors:
            raise m.fail("sensors", "must be a non-empty list", "list one entry per sensor")
    else:
        m.check_keys(opts, _TOP_KEYS | _SENSOR_KEYS, "")
        sensors = [{k: opts[k] for k in _SENSOR_KEYS if k in opts}]
    table = _table(m, path, opts)
    time, time_attrs = _time(m, table, opts, _comments(m, opts))
    streams = []
    for i, spec in enumerate(sensors):
        key = f"sensors[{i}]" if "sensors" in opts else ""
        spec = m.check_keys(spec, _SENSOR_KEYS, key)
        label = spec.get("label")
        if label is None and len(sensors) > 1:
            raise m.fail(f"{key}.label", "missing", "give each sensor a label")
        s = SensorStream(
            label=str(label or path.stem),
            time=time.copy(),
            serial=str(spec.get("serial", "")),
            vendor=str(spec.get("vendor", "")),
        )
        notes = list(table.notes)
        mag_attrs: dict[str, Any] = {}
        for name in ("acc", "gyr", "mag", "quat"):
            if name in spec:
                sub = f"{key}.{name}" if key else name
                values, unit = _channel(m, table, spec[name], name, sub)
                if unit == "a.u.":
                    values, mag_attrs = _scale_arbitrary(values, spec[name])
                    notes.append(
                        f"mag in a.u.: scaled by {mag_attrs['mag_scale_ut_per_au']:.4g} µT/a.u. "
                        f"to an assumed median field of {mag_attrs['mag_field_ut']:g} µT "
                        "(direction only)"
                    )
                setattr(s, name, values)
                s.source_units[name] = "1" if name == "quat" else unit
        if not s.channels:
            raise m.fail(key or "acc", "no channel", "map at least one of acc, gyr, mag, quat")
        s.attrs = {**time_attrs, **mag_attrs, "notes": notes}
        streams.append(s)
    base = f"one time base ({time_attrs['time_source']})"
    mark_shared_clock(streams, f"{base} for {len(streams)} sensors in {path.name}")
    labels = [s.label for s in streams]
    if len(set(labels)) != len(labels):
        raise m.fail("sensors", "labels repeat", "give every sensor its own label")
    return Recording(sensors=streams, metadata={"source": str(path)}, format=FORMAT)
