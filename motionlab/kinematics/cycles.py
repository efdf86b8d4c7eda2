"""Repetitions, gait cycles and cycle normalisation (0-100 %).

Conventions: the first array dimension is time; ``rate`` is the sampling rate in Hz of a regular
time base; angles in degrees (the unit of the angle tables), angular velocities in rad/s. Event
and boundary positions are sample indices.

- :func:`find_repetitions`: the repetitions of a movement in one angle curve. The movement is
  the excursion away from the posture the block starts in; each prominent peak of that excursion
  is one repetition, which starts where the curve leaves, and ends where it returns to, the
  trough level on either side (within 5 % of the excursion).
- :func:`gait_events`: heel strikes and toe-offs from the shank's sagittal angular velocity
  (segment z, positive when the shank's lower end swings forward): mid-swing is the large
  positive peak (Aminian et al. 2002, J Biomech 35:689; Salarian et al. 2004, IEEE TBME
  51:1434); toe-off the last local minimum before it (ibid.); heel strike (initial contact)
  the positive-to-negative zero crossing after it, where the shank stops swinging forward and
  starts to turn over the planted foot (the shank-gyroscope gait phase detection of Behboodi
  et al., IEEE EMBC 2015:5529, doi:10.1109/EMBC.2015.7319644, as described in Phys Ther 2019
  99:739, doi:10.1093/ptj/pzz040, Fig. 3). The first local minimum after mid-swing (Aminian's
  heel strike) is the impact dip on recordings that have one; without it (soft landings, the
  simulator) it falls in the loading response, about 0.1 s and 8° of knee flexion late.
- :func:`normalise`: each cycle resampled to 101 points, 0-100 %; :func:`mean_sd` across cycles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab.dsp import butter, find_peaks, sosfiltfilt

CURVE_POINTS = 101
RETURN_FRACTION = 0.05
EVENT_LOWPASS_HZ = 6.0
SWING_PEAK_FRACTION = 0.5
SWING_PEAK_MIN_RAD_S = 1.0
MIN_STRIDE_S = 0.6
MAX_STRIDE_S = 2.5


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


def _local_minima(y: np.ndarray) -> np.ndarray:
    return np.flatnonzero((y[1:-1] < y[:-2]) & (y[1:-1] <= y[2:])) + 1


def gait_events(omega_z: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Heel-strike and toe-off indices from the shank's sagittal angular velocity (rad/s).

    ``omega_z`` is the angular velocity about the shank segment's z axis (positive: the lower
    end swings forward, both sides). Low-passed at 6 Hz; mid-swing peaks must reach half the
    median of the largest peaks and 1 rad/s, at least 0.6 s apart. The heel strike is the
    sample nearest the first positive-to-negative zero crossing after a mid-swing peak, the
    toe-off the last local minimum before it, each within 40 % of a stride of the peak.
    """
    w = _filled(omega_z)
    if len(w) < int(2 * MIN_STRIDE_S * rate) or not np.isfinite(w).all():
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    sos = butter(2, min(EVENT_LOWPASS_HZ, 0.4 * rate), fs=rate)
    w = sosfiltfilt(sos, w)
    cand, props = find_peaks(w, height=SWING_PEAK_MIN_RAD_S, distance=int(MIN_STRIDE_S * rate))
    if len(cand) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    top = np.sort(props["peak_heights"])[-max(1, len(cand) // 2) :]
    swing = cand[props["peak_heights"] >= SWING_PEAK_FRACTION * np.median(top)]
    stride = np.median(np.diff(swing)) if len(swing) > 1 else MAX_STRIDE_S * rate / 2
    stride = min(stride, MAX_STRIDE_S * rate)
    reach = int(0.4 * stride)
    minima = _local_minima(w)
    down = np.flatnonzero((w[:-1] >= 0) & (w[1:] < 0))  # crossing between down[i] and down[i]+1
    down = down + (w[down] > -w[down + 1])  # the sample nearer zero
    hs, to = [], []
    for p in swing:
        after = down[(down > p) & (down <= p + reach)]
        before = minima[(minima < p) & (minima >= p - reach)]
        if len(after):
            hs.append(after[0])
        if len(before):
            to.append(before[-1])
    return np.unique(hs).astype(int), np.unique(to).astype(int)


def strides(heel_strikes: np.ndarray, toe_offs: np.ndarray, rate: float) -> Cycles:
    """Strides from consecutive heel strikes, each with its toe-off (``peak``).

    A stride is kept when it lasts 0.6-2.5 s and holds exactly one toe-off.
    """
    start, peak, end = [], [], []
    for a, b in zip(heel_strikes[:-1], heel_strikes[1:], strict=True):
        inside = toe_offs[(toe_offs > a) & (toe_offs < b)]
        if MIN_STRIDE_S * rate <= b - a <= MAX_STRIDE_S * rate and len(inside) == 1:
            start.append(a)
            peak.append(inside[0])
            end.append(b)
    if not start:
        return Cycles.empty()
    return Cycles(np.array(start), np.array(peak), np.array(end))


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
