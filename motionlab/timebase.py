"""Clocks: repair of time stamps, gaps, short-gap filling and resampling onto a regular clock.

Conventions: time in s (float64); a stream's per-sample arrays (``acc``, ``gyr``, ``mag``,
``quat``, ``extra/*``) share the first dimension with ``time``. The nominal interval is the
median of the sample intervals; an interval longer than 1.5 × nominal is a **gap**, reported as
``[start_s, end_s]`` = the stamps of the samples either side of it.

Policy (see ``docs``/the ingest command's help):

- exact duplicate rows (same stamp, same values) are dropped; the same stamp with different
  values is refused;
- a single out-of-order stamp is repaired when unambiguous: two swapped rows are put back in
  order, or one stamp that is out of line with both neighbours is re-stamped to their midpoint;
  more than one backward step is refused, naming the first data row;
- gaps up to ``gap_max`` s are filled on the stream's own clock (vectors linearly, quaternions by
  SLERP, other channels by holding the previous value); longer gaps are **left as they are**
  (no invented rows: the time array jumps) and listed in ``qc["gaps"]``;
- ``resample`` puts a stream on the clock ``t = k / rate`` (k integer, the same instants for
  every stream), within the stream's own span; instants inside a long gap are NaN. Vector
  channels are low-pass filtered (zero-phase Butterworth, order 4, cut-off 0.4 × the new rate)
  before down-sampling, so that the result is not aliased.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from motionlab import rotations
from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.session import SENSOR_CHANNELS, SensorStream

GAP_FACTOR = 1.5  # an interval longer than this many nominal intervals is a gap
#: longest run of non-finite samples (s, from the finite sample before to the one after) the
#: fusion bridges by holding the last finite sample (:mod:`motionlab.fusion.stage`); a longer
#: run in the accelerometer or gyroscope is dropped at ingest (:func:`drop_nan_runs`)
NAN_BRIDGE_MAX_S = 0.1


def runs(mask: np.ndarray) -> np.ndarray:
    """(W, 2) int start (inclusive) and stop (exclusive) indices of the runs of True in a 1-D
    ``mask``."""
    edges = np.diff(np.concatenate(([0], np.asarray(mask).astype(np.int8), [0])))
    return np.column_stack((np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def joined_spans(spans: np.ndarray) -> np.ndarray:
    """``(K, 2)`` ``[start, end]`` spans (any order, any unit) with those that overlap or touch
    joined into one, sorted by start."""
    out: list[list[float]] = []
    for a, b in sorted(map(tuple, np.asarray(spans, dtype=float).reshape(-1, 2))):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return np.array(out, dtype=float).reshape(-1, 2)


def per_sample_arrays(stream: SensorStream) -> dict[str, np.ndarray]:
    """Every per-sample array of a stream: channels by name, extras as ``extra/<name>``."""
    out = {ch: getattr(stream, ch) for ch in SENSOR_CHANNELS if getattr(stream, ch) is not None}
    out.update({f"extra/{k}": v for k, v in stream.extra.items()})
    return out


def with_arrays(stream: SensorStream, time: np.ndarray, arrays: dict[str, np.ndarray]):
    """A copy of ``stream`` with a new time array and per-sample arrays."""
    channels = {k: v for k, v in arrays.items() if not k.startswith("extra/")}
    extra = {k[6:]: v for k, v in arrays.items() if k.startswith("extra/")}
    return dataclasses.replace(stream, time=time, **channels, extra=extra)


def take(stream: SensorStream, index: np.ndarray) -> SensorStream:
    """The rows ``index`` of a stream (a copy)."""
    arrays = {k: np.asarray(v)[index] for k, v in per_sample_arrays(stream).items()}
    return with_arrays(stream, np.asarray(stream.time, dtype=float)[index], arrays)


def nominal_interval(time: np.ndarray) -> float:
    """Median sample interval (s)."""
    return float(np.median(np.diff(time))) if len(time) > 1 else float("nan")


def _rows_equal(a: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Whether rows i and j of ``a`` are identical (NaN equals NaN)."""
    x, y = np.asarray(a)[i], np.asarray(a)[j]
    same = x == y
    if x.dtype.kind == "f":
        same |= np.isnan(x) & np.isnan(y)
    return same.reshape(len(i), -1).all(axis=1)


def repair_clock(
    stream: SensorStream, path: str | Path | None = None
) -> tuple[SensorStream, dict[str, int]]:
    """Drop rows without a stamp and exact duplicates; repair one out-of-order stamp.

    Returns the repaired stream and counts ``nan_time_dropped``, ``duplicates_dropped``,
    ``reordered`` and ``restamped``. Raises :class:`InputError` (naming the data row, 1-based,
    as read) for a repeated stamp with different values or more than one backward step.
    """
    report = {"nan_time_dropped": 0, "duplicates_dropped": 0, "reordered": 0, "restamped": 0}
    t = np.asarray(stream.time, dtype=float)
    rows = np.arange(len(t))  # original data row of every sample
    finite = np.isfinite(t)
    if not finite.all():
        report["nan_time_dropped"] = int((~finite).sum())
        rows = rows[finite]
    where = f"sensor {stream.label}"
    if len(rows) < 2:
        raise InputError(
            f"only {len(rows)} time-stamped samples", path, where, "export the file again"
        )

    d = np.diff(t[rows])
    same = np.flatnonzero(d == 0)
    if len(same):
        arrays = per_sample_arrays(stream)
        dup = np.ones(len(same), dtype=bool)
        for a in arrays.values():
            dup &= _rows_equal(a, rows[same], rows[same + 1])
        if not dup.all():
            k = rows[same[~dup][0] + 1]
            raise InputError(
                f"time stamp {t[k]:.6g} s repeats with different values",
                path,
                f"{where}, data row {k + 1}",
                "the device clock is faulty there; cut the recording or fix the row",
            )
        report["duplicates_dropped"] = len(same)
        rows = np.delete(rows, same + 1)

    tt = t[rows]
    back = np.flatnonzero(np.diff(tt) < 0)
    if len(back) > 1:
        raise InputError(
            f"time goes backwards at {len(back)} places",
            path,
            f"{where}, data row {rows[back[0] + 1] + 1}",
            "the stamps are out of order; export the file again or sort it by time",
        )
    if len(back) == 1:
        k = int(back[0])
        swapped = rows.copy()
        swapped[[k, k + 1]] = swapped[[k + 1, k]]
        if np.all(np.diff(t[swapped]) > 0):
            rows = swapped
            report["reordered"] = 1
        else:
            fixed = _restamp(tt, k)
            if fixed is None:
                raise InputError(
                    "time goes backwards and no single stamp explains it",
                    path,
                    f"{where}, data row {rows[k + 1] + 1}",
                    "cut the recording at that row or export it again",
                )
            report["restamped"] = 1
            out = take(stream, rows)
            out.time = fixed
            return out, report
    if len(rows) == len(t) and not report["reordered"]:
        return stream, report
    return take(stream, rows), report


def _restamp(t: np.ndarray, k: int) -> np.ndarray | None:
    """Re-stamp sample k or k+1 (the one out of line with both neighbours) to their midpoint."""
    for j in (k, k + 1):
        if 0 < j < len(t) - 1 and t[j - 1] < t[j + 1]:
            trial = t.copy()
            trial[j] = 0.5 * (t[j - 1] + t[j + 1])
            if np.all(np.diff(trial) > 0):
                return trial
    return None


def find_gaps(time: np.ndarray, dt: float | None = None) -> np.ndarray:
    """Indices i whose interval ``time[i+1] - time[i]`` exceeds 1.5 × the nominal interval."""
    dt = nominal_interval(time) if dt is None else dt
    return np.flatnonzero(np.diff(time) > GAP_FACTOR * dt)


def long_nan_runs(
    time: np.ndarray, channels: list[np.ndarray], longer_than: float
) -> list[tuple[int, int]]:
    """``[start, stop)`` of every run of samples non-finite in any of ``channels`` (N, ...)
    lasting more than ``longer_than`` s from the finite sample before to the one after (the
    recording's first or last stamp for a run at either end), as a time gap is measured."""
    t = np.asarray(time, dtype=float)
    bad = np.zeros(len(t), dtype=bool)
    for a in channels:
        bad |= ~np.isfinite(np.asarray(a, dtype=float).reshape(len(t), -1)).all(axis=1)
    return [
        (int(a), int(b))
        for a, b in runs(bad)
        if t[min(b, len(t) - 1)] - t[max(a - 1, 0)] > longer_than * (1 + 1e-9)
    ]


def drop_nan_runs(
    stream: SensorStream, longer_than: float = NAN_BRIDGE_MAX_S, path: str | Path | None = None
) -> tuple[SensorStream, list[list[float]]]:
    """``stream`` without its runs of samples whose accelerometer or gyroscope (the
    orientation for a stream with neither) is not a number in any axis, where a run lasts more
    than ``longer_than`` s (:func:`long_nan_runs`), and the ``[first_s, last_s]`` dropped.

    Vendors write such rows for lost packets (an Xsens export leaves their fields empty): the
    rows dropped leave the time gap lost packets leave, which the gap filling, the fusion, the
    headings and the joint angles then treat as one. Shorter runs stay for the fusion to bridge.
    A stream left with fewer than two samples is an :class:`InputError`.
    """
    fused = {k: getattr(stream, k) for k in ("acc", "gyr") if getattr(stream, k) is not None}
    if not fused and stream.quat is not None:
        fused = {"quat": stream.quat}
    channels = list(fused.values())
    t = np.asarray(stream.time, dtype=float)
    long = long_nan_runs(t, channels, longer_than) if channels else []
    if not long:
        return stream, []
    keep = np.ones(len(t), dtype=bool)
    for a, b in long:
        keep[a:b] = False
    if keep.sum() < 2:
        raise InputError(
            f"{'/'.join(fused)} not a number in {int((~keep).sum())} of its {len(t)} samples: "
            "nothing to fuse",
            path,
            f"sensor {stream.label}",
            "export the recording again, or leave the sensor out of it",
        )
    return take(stream, np.flatnonzero(keep)), [[float(t[a]), float(t[b - 1])] for a, b in long]


def interpolate_rows(
    t: np.ndarray, arrays: dict[str, np.ndarray], t_new: np.ndarray
) -> dict[str, np.ndarray]:
    """All per-sample arrays at the instants ``t_new`` (inside ``[t[0], t[-1]]``).

    Float arrays linearly, ``quat`` by SLERP (:func:`motionlab.rotations.slerp`), others
    (bool, int, str) by holding the previous sample. An instant equal to a stamp returns that
    sample exactly.
    """
    n = len(t)
    i = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, max(n - 2, 0))
    j = np.minimum(i + 1, n - 1)
    span = t[j] - t[i]
    frac = np.where(span > 0, (t_new - t[i]) / np.where(span > 0, span, 1.0), 0.0)
    at_i, at_j = frac <= 0.0, frac >= 1.0
    out = {}
    for name, a in arrays.items():
        a = np.asarray(a)
        if name == "quat":
            v = rotations.slerp(a[i], a[j], frac)
        elif a.dtype.kind == "f":
            f = frac.reshape((-1,) + (1,) * (a.ndim - 1))
            v = a[i] + f * (a[j] - a[i])
        else:
            out[name] = np.where(at_j.reshape((-1,) + (1,) * (a.ndim - 1)), a[j], a[i])
            continue
        sel = (-1,) + (1,) * (a.ndim - 1)
        v = np.where(at_i.reshape(sel), a[i], np.where(at_j.reshape(sel), a[j], v))
        out[name] = v
    return out


def fill_short_gaps(
    stream: SensorStream, gap_max: float, dt: float | None = None
) -> tuple[SensorStream, dict[str, Any]]:
    """Fill every gap up to ``gap_max`` s with samples at the nominal rate (``dt`` s: the
    stream's median interval unless given, e.g. measured before NaN rows were dropped).

    Returns the filled stream and ``gaps`` (long gaps kept, ``[start_s, end_s]``),
    ``gaps_filled``, ``samples_filled``, ``dropped_samples`` (missing samples over all gaps,
    from the nominal interval) and ``filled_spans_s`` (the filled gaps, ``[start_s, end_s]``:
    the recorded stamps either side; the fusion treats them as the gaps they are).
    """
    t = np.asarray(stream.time, dtype=float)
    dt = nominal_interval(t) if dt is None else float(dt)
    gaps = find_gaps(t, dt)
    span = t[gaps + 1] - t[gaps]
    missing = np.maximum(np.round(span / dt).astype(np.int64) - 1, 1)
    short = span <= gap_max * (1 + 1e-9)
    report = {
        "gaps": [[float(t[g]), float(t[g + 1])] for g in gaps[~short]],
        "gaps_filled": int(short.sum()),
        "samples_filled": int(missing[short].sum()),
        "dropped_samples": int(missing.sum()),
        "filled_spans_s": [[float(t[g]), float(t[g + 1])] for g in gaps[short]],
    }
    if not short.any():
        return stream, report
    at = np.repeat(gaps[short], missing[short])
    k = np.arange(len(at)) - np.repeat(np.cumsum(missing[short]) - missing[short],
                                       missing[short]) + 1  # fmt: skip
    t_new = t[at] + k * (span[short] / (missing[short] + 1)).repeat(missing[short])
    arrays = per_sample_arrays(stream)
    new = interpolate_rows(t, arrays, t_new)
    merged = {name: _insert_rows(a, at + 1, new[name]) for name, a in arrays.items()}
    return with_arrays(stream, _insert_rows(t, at + 1, t_new), merged), report


def _insert_rows(a: np.ndarray, before: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``np.insert(a, before, rows, axis=0)`` for ascending ``before``, by block copies (one
    per gap, not one mask over every sample)."""
    a, rows = np.asarray(a), np.asarray(rows).astype(np.asarray(a).dtype, copy=False)
    at, first, count = np.unique(before, return_index=True, return_counts=True)
    pieces, prev = [], 0
    for i, f, c in zip(at.tolist(), first.tolist(), count.tolist(), strict=True):
        pieces += [a[prev:i], rows[f : f + c]]
        prev = i
    return np.concatenate([*pieces, a[prev:]])


def interp_columns(t_new: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Each column of ``x`` (sampled at ``t``) linearly interpolated at ``t_new`` from its
    finite samples (across NaN spans; a column with fewer than two is NaN)."""
    out = np.full((len(t_new), x.shape[1]), np.nan)
    for k in range(x.shape[1]):
        ok = np.isfinite(x[:, k]) & np.isfinite(t)
        if ok.sum() >= 2:
            out[:, k] = np.interp(t_new, t[ok], x[ok, k])
    return out


def regular_grid(t0: float, t1: float, rate: float) -> np.ndarray:
    """Instants ``k / rate`` (k integer) inside ``[t0, t1]``: the same clock for every stream."""
    k0, k1 = int(np.ceil(t0 * rate - 1e-9)), int(np.floor(t1 * rate + 1e-9))
    return np.arange(k0, k1 + 1) / rate


def _lowpass(t: np.ndarray, a: np.ndarray, rate: float, segments: list[slice]) -> np.ndarray:
    """Zero-phase Butterworth low-pass at 0.4 × ``rate`` on each NaN-free gapless segment."""
    fs = 1.0 / nominal_interval(t)
    sos = butter(4, 0.4 * rate, fs=fs)
    out = np.array(a, dtype=float, copy=True)
    for seg in segments:
        block = out[seg]
        if len(block) > 30 and np.isfinite(block).all():
            out[seg] = sosfiltfilt(sos, block, axis=0)
    return out


def resample(stream: SensorStream, rate: float) -> SensorStream:
    """``stream`` on the clock ``k / rate``; NaN inside gaps (see the module notes)."""
    t = np.asarray(stream.time, dtype=float)
    grid = regular_grid(t[0], t[-1], rate)
    gaps = find_gaps(t)
    arrays = per_sample_arrays(stream)
    if rate < 0.9 / nominal_interval(t):
        bounds = np.concatenate([[0], gaps + 1, [len(t)]])
        segs = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        for name, a in arrays.items():
            if name != "quat" and np.asarray(a).dtype.kind == "f":
                arrays[name] = _lowpass(t, a, rate, segs)
    out = interpolate_rows(t, arrays, grid)
    if len(gaps):
        # grid instants strictly between the samples either side of a gap
        lo = np.searchsorted(grid, t[gaps], side="right")
        hi = np.searchsorted(grid, t[gaps + 1], side="left")
        delta = np.zeros(len(grid) + 1, dtype=np.int64)
        np.add.at(delta, lo, 1)
        np.add.at(delta, hi, -1)
        inside = np.cumsum(delta[:-1]) > 0
        for v in out.values():
            if v.dtype.kind == "f":
                v[inside] = np.nan
    res = with_arrays(stream, grid, out)
    res.attrs = {**stream.attrs, "resampled_to_hz": float(rate)}
    return res
