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
- **How sure.** :func:`clock_line` (the line through the windows of all sensor pairs, each
  sensor's clock let stray from it as the IMU-to-IMU sync left it), :func:`settle_drift`
  (whether the recording determines the drift; one it does not is not corrected) and
  :func:`grade` (``good``/``fair``/``poor``: the clock's standard error at the ends of the
  recording against the IMU sample interval).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from motionlab.clocksync.common import DRIFT_PRIOR
from motionlab.results import OpticalSync
from motionlab.rotations import angular_velocity

GYRO_SAMPLING = ("interval", "point")
SYNC_SOURCES = ("gyroscope", "orientation")
#: standard errors (in IMU sample intervals) up to which a sync is graded good / fair
GOOD_SAMPLES, FAIR_SAMPLES = 0.1, 0.5
#: a drift is corrected when the windows show it at this many standard errors or more (or know it
#: to :data:`GOOD_SAMPLES` over half the recording): :func:`settle_drift`
DRIFT_MIN_Z = 3.0
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


class ClockLine(NamedTuple):
    """The clock line through the window lags (:func:`clock_line`): ``lag_s`` the lag
    ``t_ref − t_imu`` (s) at ``centre`` (s, IMU clock), ``drift`` (s/s), ``cov`` the (2, 2)
    covariance of the two; ``level_lag_s`` the lag with the drift held at 0, its variance
    ``level_var`` (s²) and the time ``level_time`` (s) it is the lag at (the windows' weighted
    centre)."""

    lag_s: float
    drift: float
    cov: np.ndarray
    centre: float
    level_lag_s: float
    level_var: float
    level_time: float


def _pair_sums(z: np.ndarray, y: np.ndarray, w: np.ndarray, pair: np.ndarray) -> tuple:
    """Per pair: ``Σ w z zᵀ`` (P, 2, 2), ``Σ w z y`` (P, 2), ``Σ w y²`` (P,)."""
    ids = np.unique(pair)
    m = np.array([(z[pair == p].T * w[pair == p]) @ z[pair == p] for p in ids])
    g = np.array([(z[pair == p].T * w[pair == p]) @ y[pair == p] for p in ids])
    q = np.array([float(np.sum(w[pair == p] * y[pair == p] ** 2)) for p in ids])
    return m, g, q


def _restricted(m: np.ndarray, g: np.ndarray, q: np.ndarray, n: int, tau2: np.ndarray) -> tuple:
    """For each row of ``tau2`` (G, 2), the spreads' variances relative to the windows' scale:
    ``(−2 log L_REML (G,) without constants, A (G, 2, 2), B (G, 2))``, where
    ``V = scale (diag(sd²) + Z T Zᵀ)``, ``T = diag(tau2)``, ``A = Σ Zᵀ V⁻¹ Z`` and
    ``B = Σ Zᵀ V⁻¹ y`` over the pairs. Per pair by the Woodbury identity and the determinant
    lemma (2 × 2 only): ``Zᵀ V⁻¹ Z = M (I + T M)⁻¹``, ``Zᵀ V⁻¹ y = (I + M T)⁻¹ g``,
    ``|V| ∝ |I + T M|``; the scale is profiled out (at least 1)."""
    tm = tau2[:, None, :, None] * m[None]  # T M: row i of M times tau2_i
    inv = np.linalg.inv(np.eye(2) + tm)  # (G, P, 2, 2)
    a = np.einsum("pij,gpjk->gik", m, inv)
    b = np.einsum("gpji,pj->gi", inv, g)  # (I + M T)⁻¹ = ((I + T M)⁻¹)ᵀ
    logdet = np.linalg.slogdet(np.eye(2) + tm)[1].sum(axis=1)
    quad = q.sum() - np.einsum("pi,gpij,gpj->g", g, inv, tau2[:, None, :] * g[None])
    rss = quad - np.einsum("gi,gi->g", b, np.linalg.solve(a, b[..., None])[..., 0])
    dof = max(n - 2, 1)
    scale = np.maximum(rss / dof, 1.0)
    sign, log_a = np.linalg.slogdet(a)
    value = np.where(sign > 0, dof * np.log(scale) + logdet + rss / scale + log_a, np.inf)
    return value, a / scale[:, None, None], b / scale[:, None]


#: the spreads of the sensors' own clocks about the line that :func:`clock_line` weighs: none,
#: or offsets of 10 µs to 0.1 s and drifts of 0.1 to 1000 ppm (relative to the windows' scale),
#: eight steps a decade
SPREAD_S = np.concatenate([[0.0], np.logspace(-5.0, -1.0, 33)])
SPREAD_DRIFT = np.concatenate([[0.0], np.logspace(-7.0, -3.0, 33)])


def clock_line(
    t: np.ndarray, lag: np.ndarray, sd: np.ndarray, pair: np.ndarray, centre: float
) -> ClockLine:
    """The line ``lag ≈ a + b (t − centre)`` through the window lags of all sensor pairs, each
    sensor's own clock allowed to stray from it.

    The pairs' IMUs are on one clock only as well as the IMU-to-IMU sync put them there: each
    sensor keeps a residual offset and drift (a simulated harsh walk's, after the sync: −85 to
    +27 ppm against the cameras, where the session's clock is +17). One line through all the
    windows weighted by their own precision alone follows the best-correlating sensor's clock
    and stated the drift to a few ppm. Here each pair's clock is the line plus an offset and a
    drift of its own, drawn with standard deviations (a spread of offsets and one of drifts), and
    the windows' variances are ``scale · sd²`` (``scale`` ≥ 1, profiled). How far the sensors'
    clocks stray is weighed by its restricted likelihood (REML, Patterson & Thompson 1971,
    Biometrika 58:545) over a grid of spreads (:data:`SPREAD_S` × :data:`SPREAD_DRIFT`, equally
    likely a priori), and the line is the generalised least-squares one averaged over them with
    those weights, its covariance the average one plus the spread of the lines (a few sensors
    cannot tell a spread of offsets from one of drifts: two pairs of a harsh walk, 17 ms and
    88 ppm apart, fitted +96 ± 10 ppm under the likeliest spread alone, where the session's
    clock is +17). A drift the pairs disagree about is known only as well as their mean. With
    one pair the spreads cannot be told from the line and are 0."""
    t, lag, sd = (np.asarray(v, dtype=float) for v in (t, lag, sd))
    pair = np.asarray(pair)
    z = np.column_stack([np.ones_like(t), t - centre])
    w = 1.0 / np.maximum(sd, 1e-9) ** 2
    m, g, q = _pair_sums(z, lag, w, pair)
    if len(m) < 2:
        tau2 = np.zeros((1, 2))
    else:
        su, sv = np.meshgrid(SPREAD_S, SPREAD_DRIFT, indexing="ij")
        tau2 = np.column_stack([su.ravel() ** 2, sv.ravel() ** 2])
    value, a, b = _restricted(m, g, q, len(t), tau2)
    weight = np.exp(-0.5 * (value - value.min()))
    weight /= weight.sum()
    covs = np.linalg.inv(a)
    lines = np.einsum("gij,gj->gi", covs, b)
    line = weight @ lines
    dev = lines - line
    cov = np.einsum("g,gij->ij", weight, covs) + np.einsum("g,gi,gj->ij", weight, dev, dev)
    level, level_var = b[:, 0] / a[:, 0, 0], 1.0 / a[:, 0, 0]  # the drift held at 0
    level_lag = float(weight @ level)
    return ClockLine(
        lag_s=float(line[0]), drift=float(line[1]), cov=cov, centre=float(centre),
        level_lag_s=level_lag, level_var=float(weight @ (level_var + (level - level_lag) ** 2)),
        level_time=float(centre + weight @ (a[:, 0, 1] / a[:, 0, 0])),
    )  # fmt: skip


class ClockChoice(NamedTuple):
    """What :func:`settle_drift` keeps of a :class:`ClockLine`: ``offset_s`` (the lag at IMU time
    0, s) and ``drift`` (s/s, 0 when not determined), ``drift_grade`` (``determined`` or ``not
    determined``), the drift the windows show and its standard error (s/s), and the clock's
    standard error (s) at the recording's centre and the larger one at its ends."""

    offset_s: float
    drift: float
    drift_grade: str
    measured_drift: float
    drift_se: float
    centre_se_s: float
    ends_se_s: float


def settle_drift(line: ClockLine, t0: float, t1: float, rate_hz: float) -> ClockChoice:
    """Whether the recording (IMU clock ``t0``…``t1``, s) determines the drift of ``line``, and
    the clock it gives.

    The drift is ``determined`` when the windows show it at :data:`DRIFT_MIN_Z` standard errors
    or more (a drift is there), or know it so well that its standard error moves the recording's
    ends by no more than a good sync's error (:data:`GOOD_SAMPLES` of a sample). Else it is
    ``not determined`` and not corrected: the clock is the lag with the drift held at 0
    (``ClockLine.level_lag_s``), and its standard error at a time ``t`` includes the drift it
    may leave there, ``(t − t_w)² E[b²]`` (``t_w`` where that lag was measured; ``E[b²]`` of
    the drift the windows show, ``b ± se_b``, combined with the drift two crystal clocks may
    have a priori, 0 ± ``DRIFT_PRIOR``, :mod:`motionlab.clocksync.common`). The grade
    (:func:`grade`) is of the larger of the two ends."""
    se_b = float(np.sqrt(line.cov[1, 1]))
    half = 0.5 * (t1 - t0)
    determined = abs(line.drift) >= DRIFT_MIN_Z * se_b or se_b * half * rate_hz <= GOOD_SAMPLES
    if determined:

        def se(t: float) -> float:
            v = np.array([1.0, t - line.centre])
            return float(np.sqrt(v @ line.cov @ v))

        offset, drift = line.lag_s - line.drift * line.centre, line.drift
    else:
        # the drift left in: the windows' b ± se_b and the prior 0 ± DRIFT_PRIOR combined
        var_b = 1.0 / (se_b**-2 + DRIFT_PRIOR**-2)
        left2 = (line.drift * var_b / se_b**2) ** 2 + var_b

        def se(t: float) -> float:
            return float(np.sqrt(line.level_var + (t - line.level_time) ** 2 * left2))

        offset, drift = line.level_lag_s, 0.0
    return ClockChoice(
        offset_s=float(offset), drift=float(drift),
        drift_grade="determined" if determined else "not determined",
        measured_drift=line.drift, drift_se=se_b, centre_se_s=se(line.centre),
        ends_se_s=max(se(t0), se(t1)),
    )  # fmt: skip


def unmeasured_drift_se(standard_error_s: float, t0: float, t1: float) -> float:
    """The clock's standard error (s) at the ends of a recording (IMU clock ``t0``…``t1``, s) when
    no drift was measured (one offset for all of it, ``standard_error_s``): the drift two
    crystal clocks may have, ``DRIFT_PRIOR`` (:mod:`motionlab.clocksync.common`), over half the
    recording, added in quadrature."""
    return float(np.hypot(standard_error_s, DRIFT_PRIOR * 0.5 * (t1 - t0)))


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
    """Notes on a sync record (``results.validation.sync``): its fallback, a drift the windows
    did not determine, a poor grade."""
    out = []
    if sync.fallback:
        out.append(f"time sync: {sync.fallback}")
    elif sync.drift_grade == "not determined":
        out.append(
            f"time sync: the camera clock's drift is {sync.drift_words()}: the windows do not "
            "tell it from none (less than three standard errors; the sensors' own clocks "
            "scatter, or the windows are too few or too close together); the clock's standard "
            f"error at the ends of the recording is {sync.ends_standard_error_s * 1e3:.1f} ms"
        )
    if sync.grade == "poor":
        ends = sync.ends_standard_error_s  # None: a file written before the ends were graded
        se = (sync.standard_error_s if ends is None else ends) * 1e3
        out.append(
            f"time sync is poor (standard error {se:.1f} ms): the errors may come from the "
            "clocks, not the sensors; record more movement seen by both systems"
        )
    return out
