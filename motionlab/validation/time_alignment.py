"""Time alignment of the IMU and optical clocks from angular-speed magnitudes (IMU to optical;
the IMU-to-IMU clock sync is :mod:`motionlab.clocksync`).

The clock model maps the IMU (session) clock to the reference clock::

    t_ref = offset + (1 + drift) · t_imu     (offset in s, drift a fraction; ppm = 1e6 · drift)

Method (Ricci 2015, §4.2 and §5.2): the angular-speed magnitude ``‖ω‖`` of each IMU (gyroscope)
and of its optical counterpart (angular velocity of the optical orientations,
:func:`~motionlab.rotations.angular_velocity`) is low-passed with the same zero-phase
Butterworth filter (no group delay) and put on a uniform grid at the IMU rate. A normalised
cross-correlation of the whole recordings gives a coarse offset; then, window by window, the
normalised cross-correlation peak is found near the current clock model and refined to a
sub-sample lag by a parabola through the peak and its neighbours. The window correspondences of
all sensor pairs are fitted with the linear clock model by RANSAC (Fischler & Bolles 1981,
Comm ACM 24:381; exhaustive over pairs of windows when there are few), followed by a
random-effects least-squares line on the inliers (each sensor's clock may keep an offset and a
drift of its own from the IMU-to-IMU sync: :func:`~.time_offset.clock_line`); the windows are
then re-correlated under the new model (removing the smearing of drift and the bias of the
parabola) and the fit repeated. The drift is corrected only where the recording determines it
(:func:`~.time_offset.settle_drift`), and the grade is of the clock's standard error at the ends
of the recording, where a wrong drift tells most.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.interpolate import make_interp_spline

from motionlab.dsp import butter, correlate, sosfiltfilt
from motionlab.errors import InputError
from motionlab.results import OpticalSync
from motionlab.rotations import angular_velocity
from motionlab.validation import time_offset as ta

CUTOFF_HZ = 3.0
WINDOW_S = 10.0
STEP_S = 5.0
SEARCH_S = 0.5
MIN_CORRELATION = 0.6
MIN_MOTION_RAD_S = 0.1
#: an optical rate above this many times its IMU's fastest is a marker jump (:func:`without_jumps`)
JUMP_FACTOR = 2.0
#: longest span (s) of one clock's recording the sync takes: a day
MAX_SPAN_S = 86400.0
REFINEMENTS = 2
#: a coarse lag must let the recordings overlap (valid samples on both sides, all pairs) by at
#: least this share of the most any lag gives: at a lag with little overlap a short stretch
#: correlates by chance (real trunk trials of 12-16 s locked onto ±10-14 s with 1.7 s shared,
#: where their clocks differ by about a second)
MIN_OVERLAP = 0.5
_RANSAC_PAIRS = 2000


@dataclass
class ClockModel:
    """``t_ref = offset_s + (1 + drift) · t_imu``."""

    offset_s: float = 0.0
    drift: float = 0.0

    def to_reference(self, t_imu: np.ndarray) -> np.ndarray:
        return self.offset_s + (1.0 + self.drift) * np.asarray(t_imu, dtype=float)

    def to_imu(self, t_ref: np.ndarray) -> np.ndarray:
        return (np.asarray(t_ref, dtype=float) - self.offset_s) / (1.0 + self.drift)


@dataclass
class TimeAlignment:
    """Clock model, its support, and the window correspondences behind it.

    ``window_time_s`` is the window centre on the IMU clock, ``window_lag_s`` = t_ref − t_imu
    found there, ``window_corr`` the correlation peak, ``window_pair`` the index of the sensor
    pair, ``inliers`` the RANSAC inliers. ``standard_error_s`` is the clock's standard error at
    the centre of the recording, ``ends_standard_error_s`` the larger one at its ends (what
    ``grade`` grades); ``measured_drift`` ± ``drift_se`` the drift the windows show, applied
    (``model.drift``) only when ``drift_grade`` is ``determined``
    (:func:`~motionlab.validation.time_offset.settle_drift`).
    """

    model: ClockModel
    inlier_ratio: float
    residual_rms_s: float
    coarse_lag_s: float
    window_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_lag_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_sd_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_corr: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_pair: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    inliers: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    method: str = "cross-correlation"
    standard_error_s: float = float("nan")
    grade: str = "poor"
    fallback: str = ""
    ends_standard_error_s: float = float("nan")
    measured_drift: float = float("nan")
    drift_se: float = float("nan")
    drift_grade: str = "none"

    def record(self, signal: str, sensors: list[str]) -> OpticalSync:
        """The record stored in ``results.validation.sync``: ``signal`` names the IMU side's
        signal (empty without sync), ``sensors`` the sensor of each pair index (their
        :meth:`pair_residuals` by name)."""
        residual = self.pair_residuals()
        return OpticalSync(
            method=self.method,
            time_offset_s=float(self.model.offset_s),
            drift_ppm=float(self.model.drift * 1e6),
            inlier_ratio=float(self.inlier_ratio),
            residual_rms_s=float(self.residual_rms_s),
            coarse_lag_s=float(self.coarse_lag_s),
            n_windows=int(len(self.window_time_s)),
            window_time_s=np.asarray(self.window_time_s, float),
            window_lag_s=np.asarray(self.window_lag_s, float),
            window_sd_s=np.asarray(self.window_sd_s, float),
            window_corr=np.asarray(self.window_corr, float),
            window_pair=np.asarray(self.window_pair, int),
            inliers=np.asarray(self.inliers, bool),
            standard_error_s=float(self.standard_error_s),
            ends_standard_error_s=float(self.ends_standard_error_s),
            drift_measured_ppm=float(self.measured_drift * 1e6),
            drift_se_ppm=float(self.drift_se * 1e6),
            drift_grade=self.drift_grade,
            grade=self.grade,
            fallback=self.fallback,
            signal=signal,
            sensor_residual_s={
                k: float(residual[i]) for i, k in enumerate(sensors) if i < len(residual)
            },
        )

    def pair_residuals(self) -> np.ndarray:
        """Median lag residual (s) of each sensor pair's inlier windows (NaN: none): sensors
        whose own clocks disagree show here."""
        n = int(self.window_pair.max()) + 1 if len(self.window_pair) else 0
        resid = self.window_lag_s - self.model.to_reference(self.window_time_s) + self.window_time_s
        out = np.full(n, np.nan)
        for p in range(n):
            sel = (self.window_pair == p) & self.inliers
            if sel.any():
                out[p] = np.median(resid[sel])
        return out


def no_sync() -> TimeAlignment:
    """The identity clock model, for streams already on one clock."""
    return TimeAlignment(ClockModel(), float("nan"), float("nan"), 0.0, method="none", grade="none")


# ------------------------------------------------------------------------------ signals


def _finite_rows(x: np.ndarray) -> int:
    """How many rows (samples) of ``x`` are finite in every component."""
    return int(np.isfinite(x).reshape(len(x), -1).all(axis=1).sum())


def without_jumps(omega_ref: np.ndarray, omega_imu: np.ndarray) -> np.ndarray:
    """The reference's angular velocity (N, 3 rad/s, or (N,) a signed rate) with NaN where its
    magnitude exceeds :data:`JUMP_FACTOR` times the fastest the IMU on the same body turned (its
    99.5th percentile): a rigid body cannot turn faster than the sensor on it shows, so such
    samples are a marker solution jumping (a real trunk's ``low_back`` body jumped a hundred
    times in 15 s, at up to 1000°/s, and the pooled correlation then peaked at 8.3 s where the
    clocks differ by 0.8 s); they become gaps of the signal."""
    w = np.array(omega_ref, dtype=float)
    speed = np.abs(w) if w.ndim == 1 else np.linalg.norm(w, axis=1)
    imu = np.asarray(omega_imu, dtype=float)
    imu_speed = np.abs(imu) if imu.ndim == 1 else np.linalg.norm(imu, axis=1)
    imu_speed = imu_speed[np.isfinite(imu_speed)]
    if not len(imu_speed):
        return w
    fast = speed > JUMP_FACTOR * max(float(np.percentile(imu_speed, 99.5)), MIN_MOTION_RAD_S)
    w[fast] = np.nan
    return w


def speed_signal(t: np.ndarray, omega: np.ndarray, cutoff_hz: float = CUTOFF_HZ):
    """Low-passed angular speed ``‖ω‖`` (rad/s) of samples ``omega`` (N, 3) at times ``t``; a
    1-D ``omega`` (N,) is taken as a signed scalar signal (a joint angle's rate) as it is.

    The components are put on a uniform grid at the median rate (linear interpolation), filtered
    by a zero-phase 4th-order Butterworth low-pass, and the norm is interpolated by a cubic
    spline. Returns ``(spline, valid)``: ``spline(t_query)`` and ``valid(t_query)`` (bool:
    inside ``t``, next to finite samples and not in a gap longer than 5 samples).
    """
    t = np.asarray(t, dtype=float)
    omega = np.asarray(omega, dtype=float)
    scalar = omega.ndim == 1
    omega = omega[:, None] if scalar else omega
    ok = np.isfinite(omega).all(axis=1)
    if ok.sum() < 10:
        raise InputError(
            f"only {int(ok.sum())} valid angular-velocity samples",
            where="time synchronisation",
            remedy="check the marker map and the reference file",
        )
    rate = 1.0 / np.median(np.diff(t))
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1) / rate
    k = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    good = ok[k] & ok[k - 1] & (t[k] - t[k - 1] <= 5.0 / rate)
    filled = np.column_stack([np.interp(grid, t[ok], omega[ok, i]) for i in range(omega.shape[1])])
    if len(grid) > 30 and cutoff_hz < 0.45 * rate:
        filled = sosfiltfilt(butter(4, cutoff_hz, fs=rate), filled, axis=0)
    values = filled[:, 0] if scalar else np.linalg.norm(filled, axis=1)
    spline = make_interp_spline(grid, values, k=3)

    def valid(tq: np.ndarray) -> np.ndarray:
        tq = np.asarray(tq, dtype=float)
        inside = (tq >= grid[0]) & (tq <= grid[-1])
        j = np.clip(np.rint((tq - grid[0]) * rate).astype(int), 0, len(grid) - 1)
        return inside & good[j]

    return spline, valid


# ------------------------------------------------------------------------------ correlation


def _ncc(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Pearson correlation of ``x`` (W,) with every W-long stretch of ``y`` (W + 2K,)."""
    w = len(x)
    xc = x - x.mean()
    # the direct sum scipy.signal.correlate runs for these sizes (its "auto" choice), without
    # its method choice and array-API dispatch, 0.3 ms a call
    num = np.correlate(y, xc, mode="valid")
    c1 = np.concatenate([[0.0], np.cumsum(y)])
    c2 = np.concatenate([[0.0], np.cumsum(y * y)])
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    var = np.maximum(s2 - s1 * s1 / w, 1e-300)
    return num / np.sqrt(var * np.sum(xc * xc))


def _parabola(c: np.ndarray, k: int) -> float:
    """Sub-sample offset of the peak at index ``k`` from a parabola through its neighbours."""
    if k <= 0 or k >= len(c) - 1:
        return 0.0
    den = c[k - 1] - 2.0 * c[k] + c[k + 1]
    return float(np.clip(0.5 * (c[k - 1] - c[k + 1]) / den, -0.5, 0.5)) if den < 0 else 0.0


def _grid(spans: list[tuple[float, float]], rate: float) -> np.ndarray:
    """Times (s) at ``rate`` over the union of ``spans`` (``(t0, t1)`` of one clock); an
    :class:`InputError` for a span no recording of motion has (more than
    :data:`MAX_SPAN_S`: a time column in ms or ns read as s)."""
    t0, t1 = min(a for a, _ in spans), max(b for _, b in spans)
    if not t1 - t0 <= MAX_SPAN_S:
        raise InputError(
            f"a recording spans {t1 - t0:.3g} s",
            where="time synchronisation",
            remedy="give the reference's time in seconds",
        )
    return t0 + np.arange(int((t1 - t0) * rate) + 1) / rate


def coarse_lag(
    imu: list[tuple], ref: list[tuple], rate: float, max_lag_s: float | None = None
) -> tuple[float, float]:
    """Lag ``t_ref − t_imu`` (s) maximising the overlap-normalised correlation of all pairs,
    among the lags with at least :data:`MIN_OVERLAP` of the largest overlap.

    ``imu`` and ``ref`` are lists of ``(spline, valid, t0, t1)``. Returns (lag, peak).
    """
    # each side on its own clock's grid: the clocks may be hours apart (an epoch time on one),
    # and one grid over both spans allocated the gap between them
    gx = _grid([s[2:] for s in imu], rate)
    gy = _grid([s[2:] for s in ref], rate)
    nx, ny = len(gx), len(gy)
    num = np.zeros(nx + ny - 1)
    ex = np.zeros(nx + ny - 1)
    ey = np.zeros(nx + ny - 1)
    overlap = np.zeros(nx + ny - 1)
    for (fx, vx, *_), (fy, vy, *_) in zip(imu, ref, strict=True):
        mx, my = vx(gx).astype(float), vy(gy).astype(float)
        x = np.where(mx > 0, fx(gx), 0.0)
        y = np.where(my > 0, fy(gy), 0.0)
        x = (x - x[mx > 0].mean()) * mx if mx.any() else x
        y = (y - y[my > 0].mean()) * my if my.any() else y
        num += correlate(y, x)
        ex += correlate(my, x * x)
        ey += correlate(y * y, mx)
        overlap += correlate(my, mx)
    lags = gy[0] - gx[0] + np.arange(-(nx - 1), ny) / rate
    enough = overlap >= MIN_OVERLAP * overlap.max()
    if max_lag_s is not None:
        enough &= np.abs(lags) <= max_lag_s
    with np.errstate(invalid="ignore", divide="ignore"):
        ncc = np.where(enough, num / np.sqrt(np.maximum(ex * ey, 1e-300)), -np.inf)
    k = int(np.argmax(ncc))
    finite = np.where(np.isfinite(ncc), ncc, np.nan)
    return float(lags[k] + _parabola(finite, k) / rate), float(ncc[k])


class WindowLags(NamedTuple):
    """The windows matched by :func:`window_lags`, one entry each: ``time`` (the window's centre,
    IMU clock, s), ``lag`` (``t_ref − t_imu`` there, s), ``sd`` (the lag's standard error, s),
    ``corr`` (the peak correlation) and ``pair`` (the stream pair's index)."""

    time: np.ndarray
    lag: np.ndarray
    sd: np.ndarray
    corr: np.ndarray
    pair: np.ndarray


def window_lags(
    imu: list[tuple],
    ref: list[tuple],
    model: ClockModel,
    rate: float,
    window_s: float,
    step_s: float,
    search_s: float,
    cutoff_hz: float,
) -> WindowLags:
    """Lag ``t_ref − t_imu`` at the centre of each window (IMU clock) of each pair.

    Returns the :class:`WindowLags` that matched. The standard error is the Gauss-Newton one
    of fitting ``y(t + τ) ≈ α x(t) + β``: ``σ_e² / Σ ẏ²``, inflated by ``rate / (2 cutoff)``
    for the correlation of low-passed noise. Windows without motion (IMU signal SD below 0.1 rad/s),
    with gaps, or whose peak correlation is below 0.6 or on the edge of the search are left out.
    """
    w = int(round(window_s * rate))
    k_search = max(int(np.ceil(search_s * rate)), 2)
    shifts = np.arange(-k_search, w + k_search) / rate
    rows = []
    for p, ((fx, vx, a0, a1), (fy, vy, _, _)) in enumerate(zip(imu, ref, strict=True)):
        starts = a0 + np.arange(0.0, max(a1 - a0 - window_s, 0.0) + 1e-9, step_s)
        # every window's samples at once: the splines and masks are evaluated point by point
        windows = starts[:, None] + np.arange(w) / rate
        shifted = model.to_reference(starts[:, None] + shifts)
        seen = vx(windows).all(axis=1) & vy(shifted).all(axis=1)
        dfy = None  # the reference's derivative spline, made once per pair when first needed
        for s, tx, x, y in zip(starts[seen], windows[seen], fx(windows[seen]), fy(shifted[seen]),
                               strict=True):  # fmt: skip
            if x.std() < MIN_MOTION_RAD_S:  # one correlation per window, not per sample
                continue
            c = _ncc(x, y)
            k = int(np.argmax(c))
            if c[k] < MIN_CORRELATION or k == 0 or k == len(c) - 1:
                continue
            shift = (k - k_search + _parabola(c, k)) / rate
            t_best = model.to_reference(tx + shift)
            y = fy(t_best)
            design = np.column_stack([x, np.ones(w)])
            coef = np.linalg.lstsq(design, y, rcond=None)[0]
            resid = y - design @ coef
            dfy = fy.derivative() if dfy is None else dfy
            slope = dfy(t_best)
            var = np.mean(resid**2) / max(np.sum(slope**2), 1e-300) * max(rate / (2 * cutoff_hz), 1)
            centre = s + 0.5 * (w - 1) / rate
            lag = float(model.to_reference(centre + shift)) - centre
            rows.append((centre, lag, np.sqrt(var), c[k], p))
    cols = np.array(rows, dtype=float).reshape(-1, 5)
    return WindowLags(cols[:, 0], cols[:, 1], cols[:, 2], cols[:, 3], cols[:, 4].astype(int))


def ransac_line(
    t: np.ndarray,
    y: np.ndarray,
    threshold: float,
    sd: np.ndarray | None = None,
    seed: int = 0,
) -> tuple[float, float, np.ndarray]:
    """Robust fit ``y ≈ a + b t``: the two-point model with most inliers (|residual| ≤
    ``threshold``; ties: smallest inlier residual sum), refitted on its inliers by least
    squares weighted by ``1 / sd²`` (default: unweighted)."""
    n = len(t)
    if n < 2:
        raise InputError(
            f"only {n} window(s) could be matched between the IMU and the optical data",
            where="time synchronisation",
            remedy="record some movement with both systems, or pass clock=False if they share a "
            "clock",
            argument="clock",
        )
    if n * (n - 1) // 2 <= _RANSAC_PAIRS:
        i, j = np.triu_indices(n, 1)
    else:
        rng = np.random.default_rng(seed)
        i = rng.integers(0, n, _RANSAC_PAIRS)
        j = (i + rng.integers(1, n, _RANSAC_PAIRS)) % n
    keep = np.abs(t[j] - t[i]) > 1e-9
    i, j = i[keep], j[keep]
    if len(i) == 0:  # every window at the same time: an offset only
        a = float(np.median(y))
        return a, 0.0, np.abs(y - a) <= threshold
    b = (y[j] - y[i]) / (t[j] - t[i])
    a = y[i] - b * t[i]
    res = np.abs(y[None, :] - a[:, None] - b[:, None] * t[None, :])
    inl = res <= threshold
    best = np.lexsort((np.where(inl, res, 0.0).sum(axis=1), -inl.sum(axis=1)))[0]
    inliers = inl[best]
    if inliers.sum() < 2 or np.ptp(t[inliers]) <= 0:
        return float(a[best]), float(b[best]), inliers
    w = None if sd is None else 1.0 / np.maximum(sd[inliers], 1e-9)
    b_fit, a_fit = np.polyfit(t[inliers], y[inliers], 1, w=w)
    return float(a_fit), float(b_fit), inliers


def synchronise(
    imu: list[tuple[np.ndarray, np.ndarray]],
    ref: list[tuple[np.ndarray, np.ndarray]],
    *,
    window_s: float = WINDOW_S,
    step_s: float = STEP_S,
    search_s: float = SEARCH_S,
    cutoff_hz: float = CUTOFF_HZ,
    max_lag_s: float | None = None,
    threshold_s: float | None = None,
    seed: int = 0,
    ref_is_rate: bool = False,
) -> TimeAlignment:
    """Clock model between IMU and reference from pairs of streams on the same rigid body.

    Parameters
    ----------
    imu
        Per pair ``(time (N,), ω (N, 3))``: IMU clock (s), angular velocity (rad/s) at the
        times it describes (a gyroscope at its interval centres:
        :func:`~motionlab.validation.time_offset.imu_signal`); or ``(time, x (N,))``, a
        signed scalar signal (a joint angle's rate).
    ref
        Per pair ``(time (M,), quat (M, 4))``: reference clock (s), optical orientations
        (NaN in gaps); with ``ref_is_rate`` already ``(time, ω or x)`` like ``imu``.
    window_s, step_s, search_s
        Window length, window step and the lag search half-range around the coarse estimate (s).
    cutoff_hz
        Low-pass cutoff applied to both angular velocities (Hz).
    max_lag_s
        Largest coarse offset considered (s; default: any with :data:`MIN_OVERLAP`).
    threshold_s
        RANSAC inlier threshold (s; default: two IMU samples; a wrong match is off by a
        fraction of a movement period, far more).
    """
    if not imu or len(imu) != len(ref):
        raise InputError("no IMU/optical pair to synchronise", where="time synchronisation")
    rate = float(np.median([1.0 / np.median(np.diff(t)) for t, _ in imu]))
    imu_sig, ref_sig = [], []
    for (t_i, w_i), (t_r, q) in zip(imu, ref, strict=True):
        t_i = np.asarray(t_i, float)
        imu_sig.append((*speed_signal(t_i, w_i, cutoff_hz), t_i[0], t_i[-1]))
        t_mid, omega = (np.asarray(t_r, float), q) if ref_is_rate else angular_velocity(t_r, q)
        kept = without_jumps(omega, w_i)
        if _finite_rows(kept) < 10 <= _finite_rows(omega):  # it had samples: all jumps
            raise InputError(
                "the reference's orientations turn faster than twice its IMU between almost "
                "every two frames: no movement of a body",
                where="time synchronisation",
                remedy="give the reference as unit quaternions w, x, y, z (not Euler angles) "
                "of the same bodies as the sensors",
            )
        omega = kept
        ref_sig.append((*speed_signal(t_mid, omega, cutoff_hz), t_mid[0], t_mid[-1]))
    return fit_clock(imu_sig, ref_sig, rate, window_s=window_s, step_s=step_s,
                     search_s=search_s, cutoff_hz=cutoff_hz, max_lag_s=max_lag_s,
                     threshold_s=threshold_s, seed=seed)  # fmt: skip


def fit_clock(
    imu_sig: list[tuple],
    ref_sig: list[tuple],
    rate: float,
    *,
    window_s: float = WINDOW_S,
    step_s: float = STEP_S,
    search_s: float = SEARCH_S,
    cutoff_hz: float = CUTOFF_HZ,
    max_lag_s: float | None = None,
    threshold_s: float | None = None,
    seed: int = 0,
) -> TimeAlignment:
    """The clock model from signals ``(spline, valid, t0, t1)`` (:func:`speed_signal`): coarse
    lag, window lags, RANSAC line, refined twice; the line through the inlier windows lets each
    pair's clock stray from it (:func:`~motionlab.validation.time_offset.clock_line`), and its
    drift is corrected only when the recording determines it
    (:func:`~motionlab.validation.time_offset.settle_drift`). When fewer than two windows match
    (or fewer than two agree), one global offset over the whole recordings instead
    (:func:`~motionlab.validation.time_offset.global_offset`, ``fallback`` says why; the drift
    not determined). Sets ``standard_error_s`` (of the clock at the centre of the recording),
    ``ends_standard_error_s`` (at its ends) and ``grade`` (of the latter)."""
    threshold = 2.0 / rate if threshold_s is None else threshold_s
    lag0, _ = coarse_lag(imu_sig, ref_sig, rate, max_lag_s)
    t0, t1 = min(s[2] for s in imu_sig), max(s[3] for s in imu_sig)
    centre = 0.5 * (t0 + t1)
    model = ClockModel(lag0, 0.0)
    search = search_s
    fallback = ""
    for _ in range(1 + REFINEMENTS):
        win = window_lags(imu_sig, ref_sig, model, rate, window_s, step_s, search, cutoff_hz)
        if len(win.time) < 2:
            fallback = f"only {len(win.time)} window(s) matched"
            break
        a, b, inliers = ransac_line(win.time, win.lag, threshold, win.sd, seed)
        if inliers.sum() < 2:
            fallback = f"only {int(inliers.sum())} window(s) agree"
            break
        if np.ptp(win.time[inliers]) > 0:  # the line with each pair's own clock let stray
            line = ta.clock_line(win.time[inliers], win.lag[inliers], win.sd[inliers],
                                 win.pair[inliers], centre)  # fmt: skip
            a, b = line.lag_s - line.drift * centre, line.drift
        model = ClockModel(a, b)
        search = 3.0 / rate
    if fallback:
        offset, se, peak = ta.global_offset(imu_sig, ref_sig, model.offset_s, rate, cutoff_hz)
        if not np.isfinite(peak):
            raise InputError(
                "the IMU and optical recordings could not be matched in time (no overlap "
                "with movement on both sides)",
                where="time synchronisation",
                remedy="record some movement with both systems, or pass clock=False if they "
                "share a clock",
                argument="clock",
            )
        empty = np.zeros(0)
        ends_se = ta.unmeasured_drift_se(se, t0, t1)  # no drift measured: a crystal's may be
        return TimeAlignment(
            model=ClockModel(offset, 0.0), inlier_ratio=float("nan"), residual_rms_s=float("nan"),
            coarse_lag_s=lag0, method="global cross-correlation", standard_error_s=se,
            ends_standard_error_s=ends_se, drift_grade="not determined",
            grade=ta.grade(ends_se, rate) if peak >= MIN_CORRELATION else "poor",
            fallback=f"{fallback}: one offset for the whole recording (peak correlation "
            f"{peak:.2f})",
            window_time_s=empty, window_lag_s=empty, window_sd_s=empty, window_corr=empty,
            window_pair=np.zeros(0, int), inliers=np.zeros(0, bool),
        )  # fmt: skip
    if np.ptp(win.time[inliers]) > 0:
        choice = ta.settle_drift(line, t0, t1, rate)
    else:  # every inlier window at one time: an offset only, the drift as for no window
        se = float(np.sqrt(1.0 / np.sum(1.0 / np.maximum(win.sd[inliers], 1e-9) ** 2)))
        choice = ta.ClockChoice(a, 0.0, "not determined", float("nan"), float("nan"), se,
                                ta.unmeasured_drift_se(se, t0, t1))  # fmt: skip
    model = ClockModel(choice.offset_s, choice.drift)
    resid = win.lag - (model.offset_s + model.drift * win.time)
    return TimeAlignment(
        model=model,
        inlier_ratio=float(inliers.mean()),
        residual_rms_s=float(np.sqrt(np.mean(resid[inliers] ** 2))),
        coarse_lag_s=lag0,
        window_time_s=win.time,
        window_lag_s=win.lag,
        window_sd_s=win.sd,
        window_corr=win.corr,
        window_pair=win.pair,
        inliers=inliers,
        standard_error_s=choice.centre_se_s,
        ends_standard_error_s=choice.ends_se_s,
        measured_drift=choice.measured_drift,
        drift_se=choice.drift_se,
        drift_grade=choice.drift_grade,
        grade=ta.grade(choice.ends_se_s, rate) if inliers.mean() >= 0.5 else "poor",
    )
