"""Repetitions and cycle normalisation (0-100 %).

Conventions: the first array dimension is time; ``rate`` is the sampling rate in Hz of a regular
time base; angles in degrees (the unit of the angle tables), angular velocities in rad/s. Event
and boundary positions are sample indices.

- :func:`find_repetitions`: the repetitions of a movement in one angle curve. The movement is
  the excursion away from the posture the block starts in; each prominent peak of that excursion
  is one repetition, which starts where the curve leaves, and ends where it returns to, the
  trough level on either side (within 5 % of the excursion).
- Gait cycles (strides) are not found here: :mod:`.gait_events` and
  :mod:`.session_strides`.
- :func:`normalise`: each cycle resampled to 101 points, 0-100 %; :func:`mean_sd` across cycles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab.dsp import find_peaks

CURVE_POINTS = 101
RETURN_FRACTION = 0.05


@dataclass
class Cycles:
    """Repetitions or cycles of one block: index arrays of equal length.

    ``start[i] < peak[i] < end[i]``; for gait, ``peak`` is the toe-off of the stride that starts
    with the heel strike ``start[i]`` and ends with the next one ``end[i]``.
    """

    start: np.ndarray
    peak: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return len(self.start)

    @classmethod
    def empty(cls) -> Cycles:
        e = np.zeros(0, dtype=int)
        return cls(e, e.copy(), e.copy())


def _filled(x: np.ndarray) -> np.ndarray:
    """``x`` with NaN samples linearly interpolated (ends held)."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    if ok.all() or not ok.any():
        return x
    idx = np.arange(len(x))
    return np.interp(idx, idx[ok], x[ok])


def find_repetitions(
    angle: np.ndarray,
    rate: float,
    min_prominence: float = 5.0,
    prominence_fraction: float = 0.4,
    min_period_s: float = 0.5,
) -> Cycles:
    """Repetitions of a movement in one angle curve (degrees), see the module docstring.

    A peak counts when its prominence is at least ``min_prominence`` (deg) and
    ``prominence_fraction`` × the block's range; peaks closer than ``min_period_s`` are merged.
    """
    x = _filled(angle)
    if len(x) < 3 or not np.isfinite(x).all():
        return Cycles.empty()
    base = float(np.median(x[: max(1, int(0.5 * rate))]))
    sign = 1.0 if np.max(x) - base >= base - np.min(x) else -1.0
    y = sign * x
    prominence = max(min_prominence, prominence_fraction * float(np.ptp(y)))
    peaks, _ = find_peaks(y, prominence=prominence, distance=max(1, int(min_period_s * rate)))
    if len(peaks) == 0:
        return Cycles.empty()
    edges = np.r_[0, peaks, len(y) - 1]
    start, end = [], []
    for i, p in enumerate(peaks):
        left = y[edges[i] : p + 1]
        lo = left.min()
        near = np.flatnonzero(left <= lo + RETURN_FRACTION * (y[p] - lo))
        start.append(edges[i] + near[-1])
        right = y[p : edges[i + 2] + 1]
        lo = right.min()
        near = np.flatnonzero(right <= lo + RETURN_FRACTION * (y[p] - lo))
        end.append(p + near[0])
    return Cycles(np.array(start), peaks.astype(int), np.array(end))


def normalise(values: np.ndarray, cycles: Cycles, points: int = CURVE_POINTS) -> np.ndarray:
    """(K, points) array: ``values`` over each cycle ``start..end`` resampled to 0-100 %."""
    values = np.asarray(values, dtype=float)
    out = np.empty((len(cycles), points))
    pct = np.linspace(0.0, 1.0, points)
    for k, (a, b) in enumerate(zip(cycles.start, cycles.end, strict=True)):
        seg = values[a : b + 1]
        out[k] = np.interp(pct * (b - a), np.arange(b - a + 1), seg)
    return out


def mean_sd(curves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and sample SD (ddof 1; 0 for one cycle) across cycles of a (K, P) array."""
    curves = np.asarray(curves, dtype=float)
    if len(curves) == 0:
        nan = np.full(curves.shape[1] if curves.ndim == 2 else CURVE_POINTS, np.nan)
        return nan, nan.copy()
    sd = curves.std(axis=0, ddof=1) if len(curves) > 1 else np.zeros(curves.shape[1])
    return curves.mean(axis=0), sd
