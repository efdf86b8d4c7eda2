"""Device clocks: unwrapping tick counters that wrap around at ``2**bits``, and the date a
vendor's start-time stamp or a Unix time gives.

Vendor files count time in integer ticks of a fixed-width register (Xsens ``SampleTimeFine``:
10 kHz ticks in 32 bits, wrapping every 4.97 days; Xsens DOT ``SampleTimeFine``: µs in
32 bits, wrapping every 71.6 min; Xsens ``PacketCounter``: one per sample in 16 bits).
Unwrapping takes every step modulo ``2**bits`` into ``[-2**(bits-1), 2**(bits-1))``: a forward
step is a sample interval or a gap of dropped samples, a negative step an out-of-order packet
(kept, for the ingest stage to repair). A gap longer than half the wrap period cannot be told
from a wrap and is read as the shorter interval.

A reader that knows its sensors share one clock (one time column for all of them in the file, or
the vendor's documented synchronisation) says so with :func:`mark_shared_clock`: clock sync then
keeps their stamps as recorded (:mod:`motionlab.clocksync.stage`; evidence per format in
docs/ingest.md, "Sensors on one clock").
"""

from __future__ import annotations

import datetime as _dt
import re
from pathlib import Path

import numpy as np

from motionlab.errors import InputError
from motionlab.session import SensorStream

#: ``SensorStream.attrs`` key saying which one clock the sensor shares with every other sensor
#: that has the same value, and what in the file shows it
SHARED_CLOCK = "vendor_clock_sync"

_DATE = re.compile(r"\s*(\d{4})[-_/.](\d{1,2})[-_/.](\d{1,2})(?!\d)")


def mark_shared_clock(streams: list[SensorStream], evidence: str) -> None:
    """Mark two or more ``streams`` as on one clock, ``attrs[SHARED_CLOCK] = evidence``: what in
    the file shows it, naming the file (``one Time column for 4 sensors in walk.csv``), so that
    sensors of two files are not taken as one clock by the same words."""
    if len(streams) > 1:
        for stream in streams:
            stream.attrs[SHARED_CLOCK] = evidence


def recording_date(stamp: object) -> str | None:
    """The calendar date (ISO ``YYYY-MM-DD``) a vendor's start-time stamp begins with: the
    DOT app's ``StartTime`` (``2021-08-20_20:21:13_839 GMT+8``), the time the x-IMU3 GUI set
    in ``Command.json`` (``2025-02-13 11:44:29``). The device's own calendar, no time zone
    applied; ``None`` when the stamp holds no real date (``Unknown``, ``2021-13-40``)."""
    m = _DATE.match(stamp) if isinstance(stamp, str) else None
    if m is None:
        return None
    try:
        return _dt.date(*(int(g) for g in m.groups())).isoformat()
    except ValueError:
        return None


def unix_date(seconds: float) -> str | None:
    """The UTC calendar date (ISO ``YYYY-MM-DD``) of a Unix time (s); ``None`` outside
    1990-2100 (a clock that was never set, or no Unix time at all)."""
    if not (np.isfinite(seconds) and 631152000.0 <= seconds < 4102444800.0):
        return None
    return _dt.datetime.fromtimestamp(float(seconds), _dt.UTC).date().isoformat()


def unwrap_counter(counter: np.ndarray, bits: int) -> np.ndarray:
    """Monotone int64 tick count from a counter that wraps at ``2**bits``.

    Parameters
    ----------
    counter
        (N,) counter values (any numeric dtype, integral values, no NaN).
    bits
        Register width: 16 for Xsens ``PacketCounter``, 32 for ``SampleTimeFine``.

    Returns
    -------
    (N,) int64 ticks, starting at ``counter[0]``.
    """
    c = np.asarray(counter)
    if c.size == 0:
        return np.zeros(0, dtype=np.int64)
    if c.dtype.kind == "f" and not np.all(np.isfinite(c)):
        raise ValueError("counter contains NaN")
    c = c.astype(np.int64)
    modulus = np.int64(1) << bits
    half = modulus >> 1
    step = (np.diff(c) + half) % modulus - half
    return c[0] + np.concatenate(([0], np.cumsum(step)))


def count_wraps(counter: np.ndarray, bits: int) -> int:
    """How many times ``counter`` wrapped around (steps back by more than half the range)."""
    c = np.asarray(counter, dtype=np.int64)
    return int(np.sum(np.diff(c) < -(np.int64(1) << (bits - 1))))


def counter_time(counter: np.ndarray, tick_hz: float, bits: int) -> np.ndarray:
    """Time in s (float64) of a wrapping tick counter: ``unwrap_counter(counter) / tick_hz``.

    The time keeps the device's origin (``counter[0] / tick_hz``); ingest re-bases it.
    """
    return unwrap_counter(counter, bits) / float(tick_hz)


def checked_counter_time(
    counter: np.ndarray,
    tick_hz: float,
    bits: int,
    path: str | Path,
    name: str,
    lines: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`counter_time` that raises :class:`InputError` naming the column and file line
    (``lines``: the file line of each value) on a missing, negative or non-integer value."""
    c = np.asarray(counter, dtype=float)
    bad = np.flatnonzero(~np.isfinite(c) | (c != np.round(c)) | (c < 0))
    if len(bad):
        k = bad[0]
        where = f"line {lines[k]}" if lines is not None else f"row {k + 1}"
        raise InputError(
            f"column '{name}': missing or non-integer tick value",
            path,
            where,
            remedy="repair the row, or export the file again",
        )
    return counter_time(c, tick_hz, bits)
