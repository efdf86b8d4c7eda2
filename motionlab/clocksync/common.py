"""What both clock-sync methods share: the search range, the block length, the drift prior,
a sensor's signals on a uniform grid with its gap mask, and the line through block offsets."""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from motionlab.dsp import butter
from motionlab.qc import measurable
from motionlab.session import SensorStream

MAX_OFFSET_S = 0.5  # search range of the offset (s)
MIN_CORRECTION_S = 0.001  # smaller clock differences are left alone (s)
BLOCK_S = 8.0  # movement time per block whose offset checks the fit (s)
DRIFT_PRIOR = 50e-6  # prior standard deviation of one clock's drift against another's
MIN_SAMPLES = 100  # finite accelerometer and gyroscope samples a sensor needs
SETTLE_S = 0.3  # samples this close to a gap are left out (s)


def butter_sos(
    order: int, hz: float | tuple[float, float], fs: float, btype: str = "lowpass"
) -> np.ndarray:
    """``motionlab.dsp.butter(order, hz, fs, btype)``, designed once per set of
    arguments (a design took milliseconds, and every sensor and pair asked for it); a copy."""
    return _butter(order, hz, fs, btype).copy()


@lru_cache(maxsize=32)
def _butter(order: int, hz: float | tuple[float, float], fs: float, btype: str) -> np.ndarray:
    return butter(order, hz, fs, btype)


class PerStream:
    """``compute(stream)`` once per stream object: a sensor's signals are prepared once for all
    the pairs it is in (a corrected stream is a new object, and is prepared anew)."""

    def __init__(self, compute: Callable[[SensorStream], Any]) -> None:
        self.compute = compute
        self._done: dict[int, tuple[SensorStream, Any]] = {}  # id: (the stream, its result)

    def __call__(self, stream: SensorStream) -> Any:
        hit = self._done.get(id(stream))
        if hit is None or hit[0] is not stream:
            hit = self._done[id(stream)] = (stream, self.compute(stream))
        return hit[1]


def finite_samples(s: SensorStream) -> int:
    """Samples with a measurable accelerometer and gyroscope reading (0 without either)."""
    if s.acc is None or s.gyr is None:
        return 0
    return int(np.sum(measurable(s.acc, "acc") & measurable(s.gyr, "gyr")))


def on_grid(
    stream: SensorStream, raw: np.ndarray, ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``raw`` (N, K) of ``stream`` at its samples ``ok`` interpolated linearly onto a uniform
    grid at the stream's rate from its first stamp: the grid (s), the values (M, K), and which
    grid samples are real (a sample ``ok`` within 0.75 of a period, and no gap within
    ``SETTLE_S``: a low-pass filter's settling time)."""
    t = np.asarray(stream.time, float)
    dt = 1.0 / stream.rate_hz
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    t_ok = t[ok]
    values = np.column_stack([np.interp(grid, t_ok, raw[ok, k]) for k in range(raw.shape[1])])
    k = np.clip(np.searchsorted(t_ok, grid), 1, len(t_ok) - 1)
    real = np.minimum(grid - t_ok[k - 1], t_ok[k] - grid) <= 0.75 * dt
    valid = np.convolve(~real, np.ones(2 * int(SETTLE_S / dt) + 1), mode="same") == 0
    return grid, values, valid


def line_with_prior(
    x: np.ndarray, y: np.ndarray, w: np.ndarray, scale: float
) -> tuple[np.ndarray, float, float]:
    """Offset (s) and drift through block offsets ``y`` (s) at rows ``x`` = [1, t − t_mid]
    with weights ``w`` divided by ``scale``, drift prior 0 ± ``DRIFT_PRIOR`` (two crystal
    clocks); and their standard errors."""
    info = x.T @ (w[:, None] * x) / scale + np.diag([0.0, DRIFT_PRIOR**-2])
    cov = np.linalg.inv(info)
    clock = cov @ (x.T @ (w * y)) / scale
    return clock, float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))
