"""The IMU-to-reference time offset on real recordings: gyroscope timing, signals, one global
offset when windows fail, and how sure it is (helpers of :mod:`.time_alignment`).

- **Gyroscope timing.** A MEMS gyroscope sample is the mean rate over the interval that ends at
  its time stamp (the sensor integrates or low-passes between reads), not the rate at the stamp:
  correlating it at its stamps against an optical angular velocity (which lives at the midpoints
  of its frames) puts the lag half an IMU sample away from the lag that aligns the orientations.
  :func:`gyro_times` moves each sample to the centre of its interval unless the stream says it is
  point-sampled (``attrs["gyr_sampling"] == "point"``, as the simulator's default stream does).
  The fusion filters integrate sample ``k`` over the interval ending at ``k``
  (:mod:`motionlab.fusion`), which is exact for interval averages, so the orientation being
  validated and the interval-centred gyroscope agree in time.
- **Signals from both sides.** :func:`imu_signal` gives the IMU's angular velocity from its
  gyroscope (``source="gyroscope"``) or from differences of the orientation being validated
  (``"orientation"``; the same operator as the optical side, so no sampling model is needed).
- **One global offset.** When no window can be matched (movement too slow or too short for
  10 s windows, gaps), :func:`global_offset` correlates the whole recordings at sub-sample lags
  around the coarse estimate and gives one offset (no drift) with its standard error.
- **How sure.** :func:`offset_standard_error` (the clock fit's standard error at the centre of
  the recording) and :func:`grade` (``good``/``fair``/``poor`` against the IMU sample interval).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.results import OpticalSync
from motionlab.rotations import angular_velocity

GYRO_SAMPLING = ("interval", "point")
SYNC_SOURCES = ("gyroscope", "orientation")
#: standard errors (in IMU sample intervals) up to which a sync is graded good / fair
GOOD_SAMPLES, FAIR_SAMPLES = 0.1, 0.5
GLOBAL_STEP_SAMPLES = 0.05
GLOBAL_SEARCH_SAMPLES = 3.0


def gyro_sampling(attrs: dict[str, Any]) -> str:
    """``attrs["gyr_sampling"]`` (``interval`` or ``point``); without it ``interval`` (real
    sensors), except for a simulated stream (``attrs["simulated"]``), which predates the
    option and so was point-sampled."""
    default = "point" if attrs.get("simulated") else "interval"
    value = str(attrs.get("gyr_sampling", default))
    return value if value in GYRO_SAMPLING else default


def gyro_times(time: np.ndarray, sampling: str = "interval") -> np.ndarray:
    """Times (s) at which gyroscope samples stamped ``time`` describe the motion: the centres of
    the intervals ending at the stamps (``interval``; the first sample's interval is the median
    one) or the stamps themselves (``point``)."""
    t = np.asarray(time, dtype=float)
    if sampling == "point" or len(t) < 2:
        return t
    dt = np.diff(t)
    return t - 0.5 * np.concatenate([[np.median(dt)], dt])


def imu_signal(
    time: np.ndarray,
    gyr: np.ndarray | None,
    quat: np.ndarray | None,
    source: str = "gyroscope",
    sampling: str = "interval",
) -> tuple[np.ndarray, np.ndarray]:
    """``(time, ω (N, 3) rad/s)`` of one IMU for the sync: its gyroscope at
    :func:`gyro_times`, or (``source="orientation"``, or without a gyroscope) the angular
    velocity of ``quat`` at the midpoints of its samples."""
    if source == "gyroscope" and gyr is not None:
        return gyro_times(time, sampling), np.asarray(gyr, dtype=float)
    if quat is None:
        raise ValueError("no gyroscope and no orientation to synchronise on")
    return angular_velocity(time, quat)


def offset_standard_error(t: np.ndarray, sd: np.ndarray, resid: np.ndarray, centre: float) -> float:
    """Standard error (s) of ``a + b·centre`` for the weighted line fit of lags on window times
    (weights ``1/sd²``), scaled up by the reduced χ² of the residuals when it exceeds 1. One
    window: its own ``sd``."""
    t, sd, resid = (np.asarray(v, dtype=float) for v in (t, sd, resid))
    if len(t) == 0:
        return float("nan")
    w = 1.0 / np.maximum(sd, 1e-9) ** 2
    if len(t) < 3 or np.ptp(t) <= 0:
        return float(np.sqrt(1.0 / w.sum()) * max(1.0, float(np.sqrt(np.mean(resid**2 * w)))))
    x = np.column_stack([np.ones_like(t), t])
    cov = np.linalg.inv(x.T @ (w[:, None] * x))
    chi2 = float(np.sum(w * resid**2) / (len(t) - 2))
    v = np.array([1.0, centre])
    return float(np.sqrt(v @ cov @ v * max(chi2, 1.0)))


def grade(standard_error_s: float, rate_hz: float) -> str:
    """``good`` (standard error ≤ 0.1 IMU sample), ``fair`` (≤ 0.5 sample) or ``poor``."""
    if not np.isfinite(standard_error_s):
        return "poor"
    samples = standard_error_s * rate_hz
    return "good" if samples <= GOOD_SAMPLES else "fair" if samples <= FAIR_SAMPLES else "poor"


def global_offset(
    imu: list[tuple], ref: list[tuple], lag0: float, rate: float, cutoff_hz: float
) -> tuple[float, float, float]:
    """One offset ``t_ref − t_imu`` (s) for the whole recordings, near the coarse ``lag0``.

    ``imu``/``ref`` are ``(spline, valid, t0, t1)`` per pair
    (:func:`.time_alignment.speed_signal`). The pooled Pearson correlation over every pair's
    overlap (both signals valid) is evaluated at lags ``lag0 ± 3`` IMU samples in steps of
    0.05 sample, the peak refined by a parabola.
    Returns ``(offset_s, standard_error_s, peak correlation)``; the standard error is the
    Gauss-Newton one of fitting ``y(t + τ) ≈ α x(t) + β`` (as for a window), inflated by
    ``rate / (2 cutoff)`` for low-passed noise.
    """
    step = GLOBAL_STEP_SAMPLES / rate
    lags = lag0 + np.arange(-GLOBAL_SEARCH_SAMPLES / rate, GLOBAL_SEARCH_SAMPLES / rate + step / 2,
                            step)  # fmt: skip
    grids = [t0 + np.arange(int(np.floor((t1 - t0) * rate)) + 1) / rate for *_, t0, t1 in imu]
    corr = np.full(len(lags), -np.inf)
    for i, lag in enumerate(lags):
        xs, ys = [], []
        for (fx, vx, *_), (fy, vy, *_), g in zip(imu, ref, grids, strict=True):
            ok = vx(g) & vy(g + lag)
            if ok.sum() > 10:
                xs.append(fx(g[ok]))
                ys.append(fy(g[ok] + lag))
        if xs:
            x, y = np.concatenate(xs), np.concatenate(ys)
            if x.std() > 0 and y.std() > 0:
                corr[i] = float(np.corrcoef(x, y)[0, 1])
    if not np.isfinite(corr).any():
        return float(lag0), float("nan"), float("nan")
    k = int(np.argmax(corr))
    frac = 0.0
    if 0 < k < len(corr) - 1 and np.isfinite(corr[k - 1 : k + 2]).all():
        den = corr[k - 1] - 2.0 * corr[k] + corr[k + 1]
        frac = float(np.clip(0.5 * (corr[k - 1] - corr[k + 1]) / den, -0.5, 0.5)) if den < 0 else 0
    lag = float(lags[k] + frac * step)
    # standard error from the residual of the linear fit at the best lag
    num, den_sum, n = 0.0, 0.0, 0
    for (fx, vx, *_), (fy, vy, *_), g in zip(imu, ref, grids, strict=True):
        ok = vx(g) & vy(g + lag)
        if ok.sum() <= 10:
            continue
        x, y = fx(g[ok]), fy(g[ok] + lag)
        design = np.column_stack([x, np.ones_like(x)])
        resid = y - design @ np.linalg.lstsq(design, y, rcond=None)[0]
        num += float(np.sum(resid**2))
        den_sum += float(np.sum(fy.derivative()(g[ok] + lag) ** 2))
        n += int(ok.sum())
    se = float("nan")
    if n and den_sum > 0:
        se = float(np.sqrt(num / n / den_sum * max(rate / (2 * cutoff_hz), 1.0)))
    return lag, se, float(corr[k])


def sync_notes(sync: OpticalSync) -> list[str]:
    """Notes on a sync record (``results.validation.sync``): its fallback, a poor grade."""
    out = []
    if sync.fallback:
        out.append(f"time sync: {sync.fallback}")
    if sync.grade == "poor":
        se = sync.standard_error_s * 1e3
        out.append(
            f"time sync is poor (standard error {se:.1f} ms): the errors may come from the "
            "clocks, not the sensors; record more movement seen by both systems"
        )
    return out
