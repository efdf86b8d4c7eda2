"""IMU-to-IMU clock synchronisation from the joint centres the segments share and the heel strikes.

Sensors that record on their own clocks (no radio synchronisation: consumer IMUs, loggers started
one by one, Xsens DOT without its sync) disagree by tens of milliseconds in offset and 10–50 ppm in
rate. 10 ms at a knee's 300 °/s in gait is 3° of flexion, so the clocks must agree to about a
millisecond before two sensors make a joint angle.

Two segments joined at a joint share the joint centre, and the centre's acceleration seen from
either sensor has the same magnitude at every instant (Seel, Schauer & Raisch 2012, IEEE CCA,
joint position estimation):

    ‖f₁ + K(ω₁, ω̇₁) r₁‖ = ‖f₂ + K(ω₂, ω̇₂) r₂‖,    K(ω, ω̇) r = ω̇ × r + ω × (ω × r),

with ``f`` the specific force (accelerometer, m/s²), ``ω`` the angular rate (rad/s) and ``r`` the
vector from the sensor to the joint centre in the sensor frame (m). When sensor 2's clock reads
``t + c(t)`` at sensor 1's time ``t``, with ``c(t) = c₀ + c₁ (t − t_mid)`` (offset s, drift), the
equality holds only for the right ``c``. ``r₁``, ``r₂``, both accelerometer biases, ``c₀`` and
``c₁`` minimise the squared differences (low-passed) over the samples where a segment moves
(MINPACK Levenberg–Marquardt with the analytic Jacobian, started from a grid over ``c₀``; the
biases with a prior of 0 ± 1 m/s², see :meth:`_Pair._with_prior`). ``f`` and ``ω`` are first
low-passed at ``INPUT_LP_HZ`` against soft-tissue wobble; on a real-like walk the shank's own
motion reaches past it (the knee's terminal-swing reversal), which leaves 0.37-0.43 ms of
thigh-shank clock error on clean simulated sensors (knee protocol, seeds 4-6 and 8); a 10 Hz
low-pass gave 0.05-0.09 ms there (seeds 4, 8) but let a typical sensor's 10-16 Hz wobble
through (0.30-0.46 ms instead of 0.15-0.37). The
clock is then refitted from the offsets of 8 s blocks of movement: a weighted line with a prior
on the drift, whose scatter gives honest standard errors (see :meth:`_Pair.clock_from_blocks`).

A second, independent timing signal: the heel strikes (:func:`impact_clock`). Every heel strike
shakes the whole body at one instant, and every leg and pelvis sensor rocks on its soft tissue
for a few tens of milliseconds after it (10-16 Hz ringing; on real recordings also a sharp spike
at the shank, weaker above). The envelope of each sensor's rocking — the gyroscope integrated to
an angle, band-passed to ``IMPACT_BAND_HZ`` (zero phase), its norm low-passed — is then a pulse
train common to all sensors, and the lag that maximises the correlation of two sensors'
envelopes (within ``±max_offset_s``, refined between samples) is their clock offset, for any two
sensors, not only neighbours. The angle rather than the rate: the envelope of a rate is the
angle's times the ringing frequency plus the envelope's own slope, so two sensors ringing at 10
and 15 Hz gave lags 2.8 ms apart (tests/test_clock_impacts.py); the angle's envelope does not
depend on the frequency. Block lags (``BLOCK_S`` blocks with transients, each within
``IMPACT_BLOCK_SEARCH_S`` of the whole recording's lag) give the drift and, from their scatter,
the standard error. The lag is refused when the transients are too few, correlate poorly, or
recur so regularly that a lag one step away fits as well (``IMPACT_MARGIN``). **Assumption:**
the transient reaches every sensor at the same instant. In the body it travels up the leg at
tens of metres per second, and the pelvis may see it a few milliseconds after the shank (a
bias of that size on pelvis pairs, not modelled). On the simulator, where it arrives at once,
the lags still carry errors that their block scatter does not show: with tissue that also
rocks with the segment's acceleration (``soft_tissue="motion"``, bench/real_world.py seeds 0-9)
pelvis–thigh and thigh–thigh ≤ 1 ms, every pair with a shank median 0.4-0.9 ms but up to
3-5 ms (the shank's own resonance, driven at its own phase of the stride, adds to its
envelope); with ringing after heel strikes only (bench/gait.py seeds 0-4) ≤ 2.1 ms. The
accelerometer is left out: its band carries the segment's own movement, which biased the
simulated lags by 6-18 ms.

Which pairs: the protocol's joints, then anatomical neighbours (pelvis–thigh, thorax–upper arm,
pelvis–lumbar–thorax, …) so that every sensor reaches one reference sensor (pelvis, else thorax,
else the first segment) through a tree. The impact lag is tried on the tree's pairs first.

*Without heel strikes* (no reliable impact lag: arm, elbow, lumbar and the clinical tasks, whose
timing is as before) each sensor is put on its parent's corrected clock by the joint-centre fit
(:func:`choose` keeps it).

*With heel strikes* every sensor's clock is solved at once on the root's
(:mod:`motionlab.clocknet`): the impact lags of every pair of sensors and the joint-centre fits
of every pair of neighbours, all on the recorded clocks, in one weighted least squares with a
floor under each standard error, a prior on each sensor's own delay of its transient envelope,
and the measurements that break the loops set aside one at a time (data snooping). Why not the
per-pair choice it replaced (joint centre when both agree, else the impact lag): on simulated
walks the joint-centre fits of pelvis–thigh were 7-68 ms off with claimed standard errors of
0.1 ms, the knee's 0.1-6 ms, and the impact lags of one shank can all be shifted together by its
own tissue resonance (bench/gait.py seed 1 asymmetric: all four of shank_r's by 7.3 ms, its knee
joint centre 1.1 ms off), so a per-pair rule picked a wrong answer either way. A shift shared by
all of one sensor's impact lags cancels around every loop of impact lags: only that sensor's
joint-centre fit shows it, and where the two disagree the data cannot tell which is wrong; the
solution then weighs them by their priors (``ENVELOPE_SD_S``, ``HIP_CENTRE_FLOOR_S``,
:data:`motionlab.clocknet.CENTRE_FLOOR_S`) and the sensor's line says that they disagree.
Seed 1 asymmetric: shank_r 5.2 ms off instead of 7.9 ms, the other sensors within 0.9 ms. Each
network :class:`ClockFit` is against the root sensor (``method`` ``network``) and says in
``other`` what timed the sensor, what was set aside and what disagrees; it is applied when the
correction at the recording's ends exceeds ``MIN_CORRECTION_S`` and its own standard error. A
sensor that no reliable measurement ties to the others follows its tree parent's clock.

A correction is applied only when it is reliable (joint centre: standard error ≤ ``MAX_SE_S``
over the recording, and the joint-centre model fits: RMS residual ≤ ``MAX_RESIDUAL_M_S2``; a
sensor rocking on soft tissue with the segment's acceleration breaks the model and biased the
offset by 20–30 ms on simulated walks, with a residual five times the usual; impacts: standard
error ≤ ``IMPACT_MAX_SE_S``) and differs from zero (by more than twice that and
``MIN_CORRECTION_S``); otherwise the sensor keeps its clock and the reason is recorded. Segments
that never move together carry no timing information (a still pelvis under a bending trunk), and
there the timing does not matter either. The bench (``bench/joint_angles.py``) reports the
accuracy reached per pair.
"""

from __future__ import annotations

from collections import deque
from dataclasses import asdict, dataclass, replace

import numba
import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares, minimize_scalar
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfiltfilt

from motionlab.clocknet import CENTRE_FLOOR_S, IMPACTS, NETWORK, solve_network
from motionlab.protocol import Protocol
from motionlab.qc import measurable
from motionlab.results import ClockFit, ClockSync
from motionlab.segments import sensor_for_segment
from motionlab.session import SensorStream, Session

MAX_OFFSET_S = 0.5  # search range of the offset (s)
GRID_STEP_S = 0.01  # coarse grid over the offset (s)
MAX_SE_S = 0.010  # largest standard error of c(t) for a correction to be applied (s)
# largest RMS residual (low-passed, m/s²) for a correction: 0.009-0.026 on the simulated clinical
# protocols; 0.09-0.13 where acceleration-driven soft tissue biased the offset by 20-30 ms
MAX_RESIDUAL_M_S2 = 0.05
MIN_CORRECTION_S = 0.001  # smaller clock differences are left alone (s)
MOVING_RAD_S = 0.35  # a segment moves above this angular rate (rad/s, 20 °/s)
MIN_MOVING_S = 5.0  # shared movement needed (s)
LOWPASS_HZ = 6.0  # zero-phase low-pass of the residuals (Hz)
INPUT_LP_HZ = 8.0  # zero-phase low-pass of f and ω (order INPUT_ORDER): soft-tissue wobble
INPUT_ORDER = 8  # at 10–20 Hz would otherwise reach ω̇ × r by tens of m/s²
BIAS_PRIOR_M_S2 = 1.0  # prior standard deviation of each accelerometer bias (m/s²), see _Pair
BLOCK_S = 8.0  # movement time per block whose offset checks the fit (s)
# a block's residuals are computed over its span and this much either side (s): the impulse
# response of the LOWPASS_HZ low-pass falls below 1e-18 of its peak within 3 s (at any rate)
BLOCK_MARGIN_S = 3.0
DRIFT_PRIOR = 50e-6  # prior standard deviation of one clock's drift against another's
MIN_SAMPLES = 100  # finite accelerometer and gyroscope samples a sensor needs
SETTLE_S = 0.3  # samples this close to a gap are left out (s)
BODY = 12  # parameters besides the clock: two lever arms and two accelerometer biases
IMPACT_BAND_HZ = (7.0, 40.0)  # band of the heel-strike transients (upper ≤ 0.4 × rate) (Hz)
IMPACT_ORDER = 8  # Butterworth order of the band-pass (flat over the 10-16 Hz of tissue ringing)
IMPACT_ENVELOPE_HZ = 8.0  # zero-phase low-pass of the energy envelope (Hz)
IMPACT_ACTIVE = 2.0  # a transient: the envelope above this many times its median
IMPACT_MIN_ACTIVE_S = 0.5  # transient time a block needs (s)
IMPACT_BLOCK_SEARCH_S = 0.05  # a block's lag is searched this close to the whole one's (s)
IMPACT_MIN_CORRELATION = 0.5  # correlation coefficient of the envelopes a lag needs
IMPACT_MAX_SE_S = 0.002  # largest standard error of c(t) for an impact lag to be used (s)
IMPACT_PEAK_WIDTH_S = 0.15  # other correlation peaks lie farther than this from the best (s)
IMPACT_MARGIN = 0.02  # the best correlation must beat every other peak's by this much
IMPACT_FLOOR_S = 2e-4  # smallest scatter of block lags assumed (s)
# allowance for the errors of an impact lag that its block scatter does not show (medians
# 0.2-0.9 ms on simulated walks, see above): within it plus twice the standard errors, the
# joint-centre fit is kept; 3 ms let pelvis-thigh fits 3.4 ms off through on bench/gait.py seed 0
IMPACT_BIAS_S = 0.0015

# The network solve's priors (motionlab.clocknet). Tuned on simulated walks, bench/gait.py seeds 5-9
# (both variants) and bench/real_world.py walk seeds 10-14, for the smallest worst-case clock error
# left on shank_r-shank_l, the knees and the hips (a 3 ms knee floor gave smaller medians but a
# larger worst case; a 2 ms hip floor, or 1 ms for the pelvis's and thighs' envelope delays, let
# wrong joint centres through: 5-8 ms); reported on seeds 0-4 and 0-9 (bench/clock_network.py).
# The standard deviation of a sensor's own delay of its heel-strike envelope (s) by segment kind:
# the shank's own tissue resonance shifted all of its impact lags by up to 7 ms, the other
# sensors' by ≤ 0.7 ms (the others: motionlab.clocknet.ENVELOPE_BIAS_S, 0.5 ms)
ENVELOPE_SD_S = {"shank": 0.0015, "foot": 0.0015}
# and the floor of a joint-centre fit's offset error (s): its model error locked to the stride,
# 0.1-6 ms at the knee, up to 31 ms at the hip on simulated walks (claimed errors ≈ 0.05 ms);
# elsewhere motionlab.clocknet.CENTRE_FLOOR_S (2 ms)
HIP_CENTRE_FLOOR_S = 0.005

# Anatomical neighbours by segment kind (a joint centre between them), proximal first.
NEIGHBOURS = (
    ("pelvis", "thigh"),
    ("thigh", "shank"),
    ("shank", "foot"),
    ("pelvis", "lumbar"),
    ("lumbar", "thorax"),
    ("pelvis", "thorax"),
    ("thorax", "upperarm"),
    ("upperarm", "forearm"),
    ("forearm", "hand"),
    ("thorax", "head"),
)
ROOTS = ("pelvis", "thorax")


@dataclass
class _Signals:
    """One sensor on a uniform grid: time (s), ``[f, ω, ω̇]`` (N, 9), their cubic spline, and
    which samples are real (no gap within the low-pass filter's settling time)."""

    time: np.ndarray
    values: np.ndarray
    spline: CubicSpline
    valid: np.ndarray


def _signals(stream: SensorStream) -> _Signals:
    t = np.asarray(stream.time, float)
    dt = 1.0 / stream.rate_hz
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    ok = measurable(stream.acc, "acc") & measurable(stream.gyr, "gyr")
    t_ok = t[ok]
    raw = np.hstack([stream.acc[ok], stream.gyr[ok]])
    on_grid = np.column_stack([np.interp(grid, t_ok, raw[:, k]) for k in range(6)])
    on_grid = sosfiltfilt(
        butter(INPUT_ORDER, INPUT_LP_HZ, fs=1.0 / dt, output="sos"), on_grid, axis=0
    )
    # ω̇ from the spline, not np.gradient, whose central difference is 1.6 % low at 5 Hz: on the
    # simulated walk's shank that was 0.15-0.2 ms of the offset's error (clean, seeds 4 and 8)
    values = np.hstack([on_grid, CubicSpline(grid, on_grid[:, 3:], axis=0)(grid, 1)])
    k = np.clip(np.searchsorted(t_ok, grid), 1, len(t_ok) - 1)
    real = np.minimum(grid - t_ok[k - 1], t_ok[k] - grid) <= 0.75 * dt
    valid = np.convolve(~real, np.ones(2 * int(SETTLE_S / dt) + 1), mode="same") == 0
    return _Signals(grid, values, CubicSpline(grid, values, axis=0), valid)


def estimate_clock(
    reference: SensorStream,
    sensor: SensorStream,
    max_offset_s: float = MAX_OFFSET_S,
) -> ClockFit:
    """Offset and drift of ``sensor``'s clock against ``reference``'s (see the module docstring).

    Both streams need ``acc`` (m/s²) and ``gyr`` (rad/s) and must sit on the two sides of one
    joint. The status is ``"applied"`` only when the fit is reliable and differs from zero
    (:func:`synchronise` applies only those).
    """
    name = (reference.label, sensor.label)
    if min(_finite_samples(reference), _finite_samples(sensor)) < MIN_SAMPLES:
        return ClockFit(*name, 0.0, 0.0, float(np.mean(reference.time[[0, -1]])), np.inf, np.inf,
                        np.nan, 0.0, "no usable accelerometer and gyroscope samples")  # fmt: skip
    a, b = _signals(reference), _signals(sensor)
    inside = (a.time - max_offset_s >= b.time[0]) & (a.time + max_offset_s <= b.time[-1])
    t_mid = float(0.5 * (a.time[0] + a.time[-1]))
    if inside.sum() < 2 * MIN_MOVING_S / (a.time[1] - a.time[0]):
        return ClockFit(*name, 0.0, 0.0, t_mid, np.inf, np.inf, np.nan, 0.0,
                        "not enough shared recording")  # fmt: skip
    span = slice(np.argmax(inside), len(inside) - np.argmax(inside[::-1]))
    t, ref = a.time[span], a.values[span]
    dt = float(t[1] - t[0])
    sos = butter(4, LOWPASS_HZ, fs=1.0 / dt, output="sos")
    rates = np.hypot(
        np.linalg.norm(ref[:, 3:6], axis=1), np.linalg.norm(b.spline(t)[:, 3:6], axis=1)
    )
    moving = np.convolve(sosfiltfilt(sos, rates) > MOVING_RAD_S, np.ones(int(0.5 / dt) | 1),
                         mode="same") > 0  # fmt: skip
    b_valid = np.interp(t, b.time, b.valid.astype(float)) > 0.99
    use = np.flatnonzero(moving & a.valid[span] & b_valid)
    moving_s = len(use) * dt
    if moving_s < MIN_MOVING_S:
        return ClockFit(*name, 0.0, 0.0, t_mid, np.inf, np.inf, np.nan, moving_s,
                        "not enough shared movement")  # fmt: skip
    # the low-passed residuals change little within a quarter of the filter's period
    stride = max(1, int(0.25 / (LOWPASS_HZ * dt)))
    pair = _Pair(t, ref, b.spline, t_mid, sos, use[::stride])
    body = pair.body(0.0)
    grid = np.arange(-max_offset_s, max_offset_s + 1e-12, GRID_STEP_S)
    c0 = float(grid[int(np.argmin([pair.cost(np.r_[body, c, 0.0]) for c in grid]))])
    fit = pair.solve(np.r_[pair.body(c0), c0, 0.0])
    half = 0.5 * (t[use[-1]] - t[use[0]])
    fit[-2:], offset_se, drift_se = pair.clock_from_blocks(fit)
    worst_se = float(np.hypot(offset_se, drift_se * half))
    c_ends = np.abs(fit[-2] + fit[-1] * (t[use[[0, -1]]] - t_mid))
    rms = float(np.sqrt(pair.cost(fit) / len(pair.use)))
    if worst_se > MAX_SE_S:
        status = "not reliable: too little shared movement"
    elif rms > MAX_RESIDUAL_M_S2:
        status = (
            f"not reliable: the shared joint centre fits poorly (residual {rms:.2f} m/s²: soft "
            "tissue or a loose sensor)"
        )
    elif abs(fit[-2]) > max_offset_s - GRID_STEP_S:
        status = f"not reliable: offset at the edge of the ±{max_offset_s:g} s search"
    elif c_ends.max() <= max(MIN_CORRECTION_S, 2.0 * worst_se):
        status = "consistent with one clock"
    else:
        status = "applied"
    return ClockFit(*name, float(fit[-2]), float(fit[-1]), t_mid, offset_se, drift_se, rms,
                    moving_s, status)  # fmt: skip


def joint_centre_forces(
    reference: SensorStream, sensor: SensorStream
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Specific force at the shared joint centre seen by each sensor, in its own frame.

    ``(time s, f_J reference (N, 3), f_J sensor (N, 3))`` on the reference's uniform grid, from
    the lever arms and accelerometer biases fitted as for the clock (the clocks taken as one;
    :func:`synchronise` first). ``None`` when the two share too little movement. Rotated into
    the earth frame the two vectors are one (Seel et al. 2012), which ties their headings.
    """
    if min(_finite_samples(reference), _finite_samples(sensor)) < MIN_SAMPLES:
        return None
    a, b = _signals(reference), _signals(sensor)
    inside = (a.time >= b.time[0]) & (a.time <= b.time[-1])
    t, ref = a.time[inside], a.values[inside]
    if len(t) < 10:
        return None
    dt = float(t[1] - t[0])
    sos = butter(4, LOWPASS_HZ, fs=1.0 / dt, output="sos")
    other = b.spline(t)
    rates = np.hypot(np.linalg.norm(ref[:, 3:6], axis=1), np.linalg.norm(other[:, 3:6], axis=1))
    use = np.flatnonzero(sosfiltfilt(sos, rates) > MOVING_RAD_S)
    if len(use) * dt < MIN_MOVING_S:
        return None
    stride = max(1, int(0.25 / (LOWPASS_HZ * dt)))
    p = _Pair(t, ref, b.spline, float(t.mean()), sos, use[::stride]).body(0.0)
    return t, _centre(ref, p[:3], p[6:9]), _centre(other, p[3:6], p[9:12])


@dataclass
class _Pair:
    """Residuals LP(‖f₁ + b₁ + K₁ r₁‖ − ‖f₂ + b₂ + K₂ r₂‖) at reference times ``t[use]`` (s),
    LP the zero-phase low-pass ``sos``, and their Jacobian in the parameters ``[r₁, r₂ (m), b₁,
    b₂ (accelerometer biases, m/s²), c₀ (s), c₁]``; sensor 2 is read at ``t + c(t)``. The biases
    are fitted because an uncalibrated 0.1 m/s² projects onto the changing gravity direction in
    step with the movement, and so would pull the offset."""

    t: np.ndarray
    ref: np.ndarray  # (N, 9) [f, ω, ω̇] of the reference at t
    spline: CubicSpline
    t_mid: float
    sos: np.ndarray
    use: np.ndarray

    def __post_init__(self) -> None:
        self._zi = sosfilt_zi(self.sos)  # what sosfiltfilt computes on every call

    def _filtered(self, x: np.ndarray) -> np.ndarray:
        """``sosfiltfilt(sos, x, axis=-1)[..., use]``, by scipy's own steps (odd extension of
        3 × taps, ``sosfilt`` forward and backward from the steady state of the edge values)
        with the steady state computed once per pair."""
        sos = self.sos
        taps = 2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
        edge = 3 * taps
        ext = np.concatenate(
            (
                2 * x[..., :1] - x[..., edge:0:-1],
                x,
                2 * x[..., -1:] - x[..., -2 : -(edge + 2) : -1],
            ),
            axis=-1,
        )
        zi = self._zi.reshape((len(sos),) + (1,) * (x.ndim - 1) + (2,))
        y, _ = sosfilt(sos, ext, zi=zi * ext[..., :1])
        y, _ = sosfilt(sos, y[..., ::-1], zi=zi * y[..., -1:])
        return y[..., ::-1][..., edge:-edge][..., self.use]

    def residuals(self, p: np.ndarray, jacobian: bool = False) -> np.ndarray:
        res = np.empty(len(self.t))
        jac = np.empty((len(p), len(self.t) if jacobian else 0))  # one row per parameter
        sp = self.spline
        _pair_residuals(self.t, self.t_mid, sp.x, sp.c, self.ref, np.asarray(p, float), res, jac)
        return self._filtered(jac).T if jacobian else self._filtered(res)

    def _with_prior(self, p: np.ndarray, jacobian: bool = False) -> np.ndarray:
        """:meth:`residuals` and the biases' prior rows ``b / BIAS_PRIOR_M_S2`` (0 ± 1 m/s²).

        Without them the fit has a second valley at biases of ~10⁸ m/s², where ‖f + b + K r‖
        is the projection of the joint-centre acceleration on a fixed axis of each sensor: both
        sensors' projections on the knee's flexion axis agree, so it nearly fits, but it times
        the clock poorly. On the knee protocol's simulated walk (clean sensors, seeds 5 and 6)
        the search fell into it (residual 0.076 m/s², offsets 1.6-1.7 ms off) once the knee
        template had a real-like terminal swing; a real accelerometer's bias is < 1 m/s².
        """
        if not jacobian:
            return np.r_[self.residuals(p), p[6:12] / BIAS_PRIOR_M_S2]
        prior = np.zeros((6, len(p)))
        prior[:, 6:12] = np.eye(6) / BIAS_PRIOR_M_S2
        return np.vstack([self.residuals(p, jacobian=True), prior])

    def window(self, use: np.ndarray, margin: int) -> _Pair:
        """The pair on the samples ``use`` (indices into ``t``, sorted), computed over their
        span and ``margin`` samples either side only: the low-pass's response to what lies
        further away is below floating-point resolution (:data:`BLOCK_MARGIN_S`), so the
        residuals are those of the whole recording at a fraction of the cost."""
        lo, hi = max(0, int(use[0]) - margin), min(len(self.t), int(use[-1]) + margin + 1)
        return replace(self, t=self.t[lo:hi], ref=self.ref[lo:hi], use=use - lo)

    def cost(self, p: np.ndarray) -> float:
        return float(np.sum(self.residuals(p) ** 2))

    def body(self, c0: float) -> np.ndarray:
        """r₁, r₂ (m), b₁, b₂ (m/s²) for the offset ``c0`` (s) and no drift."""
        fixed = np.array([c0, 0.0])
        sol = least_squares(
            lambda q: self._with_prior(np.r_[q, fixed]),
            np.zeros(BODY),
            jac=lambda q: self._with_prior(np.r_[q, fixed], jacobian=True)[:, :BODY],
            x_scale=0.1,
            method="lm",
        )
        return sol.x

    def solve(self, p0: np.ndarray) -> np.ndarray:
        """All parameters, from ``p0``."""
        return least_squares(
            self._with_prior,
            p0,
            jac=lambda p: self._with_prior(p, jacobian=True),
            x_scale=np.r_[np.full(BODY, 0.1), 0.01, 1e-4],
            method="lm",
        ).x

    def clock_from_blocks(self, p: np.ndarray) -> tuple[np.ndarray, float, float]:
        """c₀ (s), c₁ and their standard errors from offsets fitted block by block (the moving
        samples in runs of ``BLOCK_S``; levers and biases of ``p`` held).

        A line through the block offsets, weighted by each block's information and scaled by
        its scatter (χ²/dof when above 1, so that the model's errors, which the residuals'
        statistics understate, show), with a prior on the drift (0 ± ``DRIFT_PRIOR``: two
        crystal clocks): where the movement sits in two clusters whose offsets carry different
        model errors, an unrestrained line turned a few milliseconds into hundreds of ppm.
        Fewer than three blocks: infinite errors.
        """
        dt = float(np.median(np.diff(self.t[self.use])))  # spacing of the fitted samples
        n_blocks = int(len(self.use) * dt // BLOCK_S)
        if n_blocks < 3:
            return p[-2:], np.inf, np.inf
        rows, offsets, weights = [], [], []
        correlation = max(1.0, 0.5 / (LOWPASS_HZ * dt))  # samples per independent residual
        margin = int(round(BLOCK_MARGIN_S / float(self.t[1] - self.t[0])))
        for block in np.array_split(self.use, n_blocks):
            part = self.window(block, margin)
            centre = self.t[block].mean() - self.t_mid
            sol = least_squares(
                lambda c, part=part: part.residuals(np.r_[p[:BODY], c, 0.0]),
                p[-2:-1] + p[-1] * centre,
                x_scale=0.01,
            )
            s2 = float(np.mean(sol.fun**2)) * correlation
            rows.append([1.0, centre])
            offsets.append(sol.x[0])
            weights.append(float(sol.jac[:, 0] @ sol.jac[:, 0]) / max(s2, 1e-30))
        x, w, y = np.array(rows), np.array(weights), np.array(offsets)
        line = np.linalg.solve(x.T @ (w[:, None] * x), x.T @ (w * y))
        chi2 = float(w @ (y - x @ line) ** 2) / (len(y) - 2)
        return _line_with_prior(x, y, w, max(1.0, chi2))


def _centre(values: np.ndarray, r: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Specific force at the joint centre f + b + ω̇ × r + ω × (ω × r) (N, 3), rows [f, ω, ω̇]."""
    f, w, a = values[:, :3], values[:, 3:6], values[:, 6:]
    return f + bias + np.cross(a, r) + np.cross(w, np.cross(w, r))


@numba.njit(cache=True, inline="always")
def _cross3(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@numba.njit(cache=True)
def _pair_residuals(
    t: np.ndarray,
    t_mid: float,
    knots: np.ndarray,
    coef: np.ndarray,
    ref: np.ndarray,
    p: np.ndarray,
    res: np.ndarray,
    jac: np.ndarray,
) -> None:
    """The unfiltered residuals of :class:`_Pair` into ``res`` (N) and, when ``jac`` has
    columns, their Jacobian (14, N: one row per parameter) in ``p = [r₁, r₂, b₁, b₂, c₀, c₁]``.

    Sensor 2 is the cubic spline (``knots`` (M+1), ``coef`` (4, M, 9) as
    :class:`scipy.interpolate.CubicSpline`'s, extrapolated past the ends) of ``[f, ω, ω̇]``
    read at ``t + c₀ + c₁ (t − t_mid)``; the reference's rows ``ref`` (N, 9) are at ``t``.
    Residual ``‖f_J1‖ − ‖f_J2‖`` with ``f_J = f + b + ω̇ × r + ω × (ω × r)``; its gradient
    in a lever ``r`` is ``±(f_J × ω̇ + ω × (ω × f_J)) / ‖f_J‖``, in a bias ``±f_J / ‖f_J‖``, and
    in the clock ``−f_J2 · ḟ_J2 / ‖f_J2‖`` (times ``t − t_mid`` for the drift), ``ḟ_J2`` from
    the spline's derivative.
    """
    m = coef.shape[1]
    v = np.empty(9)
    d = np.empty(9)
    with_jac = jac.shape[1] > 0
    i = 0
    if len(t):  # start the walk below from the first sample's interval (a block's window)
        i = min(max(np.searchsorted(knots, t[0] + p[12] + p[13] * (t[0] - t_mid)) - 1, 0), m - 1)
    for k in range(len(t)):
        x = t[k] + (p[12] + p[13] * (t[k] - t_mid))
        # the spline's interval: knots[i] <= x < knots[i + 1], the first and last extended
        # (times increase, so it moves forward from the previous sample's)
        while i > 0 and x < knots[i]:
            i -= 1
        while i < m - 1 and x >= knots[i + 1]:
            i += 1
        s = x - knots[i]
        for j in range(9):
            v[j] = ((coef[0, i, j] * s + coef[1, i, j]) * s + coef[2, i, j]) * s + coef[3, i, j]
            if with_jac:
                d[j] = (3.0 * coef[0, i, j] * s + 2.0 * coef[1, i, j]) * s + coef[2, i, j]
        # reference: f_J1
        w0, w1, w2 = ref[k, 3], ref[k, 4], ref[k, 5]
        a0, a1, a2 = ref[k, 6], ref[k, 7], ref[k, 8]
        u0, u1, u2 = _cross3(w0, w1, w2, p[0], p[1], p[2])
        c0, c1, c2 = _cross3(a0, a1, a2, p[0], p[1], p[2])
        e0, e1, e2 = _cross3(w0, w1, w2, u0, u1, u2)
        f0 = ref[k, 0] + p[6] + c0 + e0
        f1 = ref[k, 1] + p[7] + c1 + e1
        f2 = ref[k, 2] + p[8] + c2 + e2
        n1 = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        # sensor 2: f_J2
        x0, x1, x2 = v[3], v[4], v[5]
        y0, y1, y2 = v[6], v[7], v[8]
        u0, u1, u2 = _cross3(x0, x1, x2, p[3], p[4], p[5])
        c0, c1, c2 = _cross3(y0, y1, y2, p[3], p[4], p[5])
        e0, e1, e2 = _cross3(x0, x1, x2, u0, u1, u2)
        g0 = v[0] + p[9] + c0 + e0
        g1 = v[1] + p[10] + c1 + e1
        g2 = v[2] + p[11] + c2 + e2
        n2 = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        res[k] = n1 - n2
        if not with_jac:
            continue
        c0, c1, c2 = _cross3(f0, f1, f2, a0, a1, a2)
        u0, u1, u2 = _cross3(w0, w1, w2, f0, f1, f2)
        e0, e1, e2 = _cross3(w0, w1, w2, u0, u1, u2)
        jac[0, k], jac[1, k], jac[2, k] = (c0 + e0) / n1, (c1 + e1) / n1, (c2 + e2) / n1
        c0, c1, c2 = _cross3(g0, g1, g2, y0, y1, y2)
        u0, u1, u2 = _cross3(x0, x1, x2, g0, g1, g2)
        e0, e1, e2 = _cross3(x0, x1, x2, u0, u1, u2)
        jac[3, k], jac[4, k], jac[5, k] = -(c0 + e0) / n2, -(c1 + e1) / n2, -(c2 + e2) / n2
        jac[6, k], jac[7, k], jac[8, k] = f0 / n1, f1 / n1, f2 / n1
        jac[9, k], jac[10, k], jac[11, k] = -g0 / n2, -g1 / n2, -g2 / n2
        # d/dt of f_J2 = ḟ + ω̈ × r + ω̇ × (ω × r) + ω × (ω̇ × r)
        u0, u1, u2 = _cross3(x0, x1, x2, p[3], p[4], p[5])  # ω × r
        h0, h1, h2 = _cross3(d[3], d[4], d[5], u0, u1, u2)
        c0, c1, c2 = _cross3(d[6], d[7], d[8], p[3], p[4], p[5])
        u0, u1, u2 = _cross3(d[3], d[4], d[5], p[3], p[4], p[5])  # ω̇ × r
        e0, e1, e2 = _cross3(x0, x1, x2, u0, u1, u2)
        q0 = d[0] + c0 + h0 + e0
        q1 = d[1] + c1 + h1 + e1
        q2 = d[2] + c2 + h2 + e2
        dc = -(g0 * q0 + g1 * q1 + g2 * q2) / n2
        jac[12, k] = dc
        jac[13, k] = dc * (t[k] - t_mid)


def _edges(session: Session, protocol: Protocol) -> list[tuple[str, str]]:
    """(proximal, distal) segment pairs with usable sensors that share a joint centre: the
    protocol's joints, then anatomical neighbours."""
    present = [s for s in protocol.segments if _usable(session, s)]
    edges = [(j.proximal, j.distal) for j in protocol.joints.values()]
    for p in present:
        for d in present:
            if _neighbours(p, d) and (p, d) not in edges:
                edges.append((p, d))
    return [(p, d) for p, d in edges if p in present and d in present]


def sync_tree(session: Session, protocol: Protocol) -> list[tuple[str, str]]:
    """(reference segment, segment) pairs in breadth-first order from the root segment."""
    present = [s for s in protocol.segments if _usable(session, s)]
    edges = _edges(session, protocol)
    root = next((s for r in ROOTS for s in present if s == r), present[0] if present else None)
    order, seen, todo = [], {root}, deque([root])
    while todo:
        node = todo.popleft()
        for p, d in edges:
            other = d if p == node else p if d == node else None
            if other is not None and other not in seen:
                seen.add(other)
                order.append((node, other))
                todo.append(other)
    return order


def _usable(session: Session, segment: str) -> bool:
    label = sensor_for_segment(session, segment)
    return label is not None and _finite_samples(session.sensors[label]) >= MIN_SAMPLES


def _finite_samples(s: SensorStream) -> int:
    """Samples with a measurable accelerometer and gyroscope reading (0 without either)."""
    if s.acc is None or s.gyr is None:
        return 0
    return int(np.sum(measurable(s.acc, "acc") & measurable(s.gyr, "gyr")))


def _centre_floor(a: str, b: str) -> float:
    """Floor (s) of the joint-centre fit's offset error between segments ``a`` and ``b``."""
    kinds = {_kind_side(a)[0], _kind_side(b)[0]}
    return HIP_CENTRE_FLOOR_S if kinds == {"pelvis", "thigh"} else CENTRE_FLOOR_S


def _kind_side(segment: str) -> tuple[str, str]:
    return (segment[:-2], segment[-1]) if segment[-2:] in ("_l", "_r") else (segment, "")


def _neighbours(a: str, b: str) -> bool:
    (ka, sa), (kb, sb) = _kind_side(a), _kind_side(b)
    return (ka, kb) in NEIGHBOURS and (not sa or not sb or sa == sb)


def synchronise(
    session: Session, protocol: Protocol, max_offset_s: float = MAX_OFFSET_S
) -> list[ClockFit]:
    """Put the protocol's sensors on one clock, in place (see the module docstring).

    Each corrected stream's ``time`` is replaced and ``attrs["clock_sync"]`` records the fit (so
    the recorded stamps can be restored); ``session.results.clock_sync`` holds every fit.

    With heel strikes (a reliable impact lag between any two sensors) every sensor's clock is
    solved at once on the root sensor's (:func:`motionlab.clocknet.solve_network`) from the
    impact lags of all pairs and the joint-centre fits of all neighbours, measurements that
    break the loops set aside; each fit then has ``method`` ``network`` and says in ``other``
    what timed it. Without (arm, elbow, lumbar, clinical tasks) the sync tree as before: each
    sensor against its reference's corrected clock by the joint centre.
    """
    unsynchronise(session)
    tree = sync_tree(session, protocol)
    label = {seg: sensor_for_segment(session, seg) for pair in tree for seg in pair}
    segments = list(dict.fromkeys(seg for pair in tree for seg in pair))

    def lag(a: str, b: str) -> ClockFit:
        return impact_clock(session.sensors[label[a]], session.sensors[label[b]], max_offset_s)

    impacts = {(a, b): lag(a, b) for a, b in tree}
    if any(_reliable(f) for f in impacts.values()):  # heel strikes: every pair, all at once
        pairs = [(a, b) for i, a in enumerate(segments) for b in segments[i + 1 :]]
        impacts = {p: impacts[p] if p in impacts else lag(*p) for p in pairs}  # in this order
        fits = _synchronise_network(session, protocol, tree, label, impacts, max_offset_s)
    else:
        fits = _synchronise_tree(session, tree, label, impacts, max_offset_s)
    session.results.clock_sync = ClockSync({f.sensor: f for f in fits})
    return fits


def _synchronise_tree(
    session: Session, tree, label, impacts, max_offset_s: float
) -> list[ClockFit]:
    """Each sensor against its reference's corrected clock, down the sync tree, by the joint
    centre (``impacts``: the tree pairs' refused impact lags, kept in ``other``). A sensor whose own
    fit is not reliable but whose reference was corrected gets the reference's correction: its
    recorded timing relative to its neighbour is kept (a thigh moved while its shank stayed
    would misalign the knee by the thigh's whole correction)."""
    fits = []
    moved: dict[str, ClockFit] = {}  # label: the correction its stamps got
    for ref_seg, seg in tree:
        ref, lab = label[ref_seg], label[seg]
        stream = session.sensors[lab]
        # the pair's impact lag was measured on the raw clocks; none is reliable (no heel strikes)
        fit = choose(estimate_clock(session.sensors[ref], stream, max_offset_s),
                     impacts[(ref_seg, seg)])  # fmt: skip
        fits.append(fit)
        # the fit is against the reference's corrected clock: "consistent with one clock" means
        # the sensor already agrees with it; an unreliable fit tells nothing, so the sensor keeps
        # its recorded timing relative to its reference and follows the reference's correction
        use = fit if fit.status == "applied" else None
        if fit.status.startswith("not reliable"):
            use = moved.get(ref)
        if use is not None:
            _apply(session, lab, use)
            moved[lab] = use
    return fits


def _apply(session: Session, label: str, fit: ClockFit) -> None:
    stream = session.sensors[label]
    attrs = dict(stream.attrs, clock_sync=asdict(fit))
    session.sensors[label] = replace(stream, time=fit.corrected_time(stream.time), attrs=attrs)


def _synchronise_network(
    session: Session, protocol: Protocol, tree, label, impacts, max_offset_s: float
) -> list[ClockFit]:
    """Every sensor's clock at once from all pairwise measurements on the raw clocks
    (:func:`motionlab.clocknet.solve_network`). A sensor that no reliable measurement ties to
    the root follows its reference's clock (its recorded timing against it is kept)."""
    edges = [(a, b) for a, b in _edges(session, protocol) if a in label and b in label]
    centres = {
        (a, b): estimate_clock(session.sensors[label[a]], session.sensors[label[b]], max_offset_s)
        for a, b in edges
    }
    pool = [f for f in [*impacts.values(), *centres.values()] if _reliable(f)]
    envelope = {lab: ENVELOPE_SD_S[_kind_side(seg)[0]] for seg, lab in label.items()
                if _kind_side(seg)[0] in ENVELOPE_SD_S}  # fmt: skip
    floor = {frozenset((label[a], label[b])): _centre_floor(a, b) for a, b in edges}
    root = label[tree[0][0]]
    t0 = float(np.mean(session.sensors[root].time[[0, -1]]))
    span = float(np.ptp(session.sensors[root].time))
    clocks: dict[str, tuple] = {root: (None, "")}  # label: (NetworkClock or None, follows)
    clocks.update({k: (v, "") for k, v in solve_network(pool, root, t0, envelope, floor).items()})
    for ref_seg, seg in tree:  # not tied to the root: the reference's clock (tree order)
        if label[seg] not in clocks:
            clocks[label[seg]] = (clocks[label[ref_seg]][0], label[ref_seg])
    fits = []
    for _, seg in tree:
        lab = label[seg]
        clock, follows = clocks[lab]
        fit = _network_fit(root, lab, clock, follows, t0, span)
        fits.append(fit)
        if fit.status == "applied" or (follows and clock is not None):
            _apply(session, lab, replace(fit, status="applied") if follows else fit)
    return fits


def _network_fit(root: str, lab: str, clock, follows: str, t0: float, span: float) -> ClockFit:
    """The :class:`ClockFit` of one sensor's network solution (``method`` ``network``) on the
    root's clock; ``follows``: the sensor whose clock it takes when nothing ties it; ``t0``
    and ``span`` the root's mid-time and duration (s)."""
    if follows:
        why = ("not reliable: no reliable heel-strike lag or joint-centre fit ties it to the "
               f"others; follows {follows}'s clock")  # fmt: skip
        if clock is None:
            return ClockFit(root, lab, 0.0, 0.0, t0, np.inf, np.inf, np.nan, 0.0, why, NETWORK)
        return ClockFit(root, lab, clock.offset_s, clock.drift, clock.t_mid_s, clock.offset_se_s,
                        clock.drift_se, np.nan, 0.0, why, NETWORK)  # fmt: skip
    # a correction smaller than its standard error is not applied; not twice it, as for one
    # pair: the priors' share of the error (a shank's 1.3 ms) would leave real 2-3 ms offsets
    # uncorrected (gait seed 0: shank_r 1.9 ms off)
    worst = float(np.hypot(clock.offset_se_s, clock.drift_se * span / 2))
    ends = np.abs(clock.offset_s) + np.abs(clock.drift) * span / 2
    status = "applied" if ends > max(MIN_CORRECTION_S, worst) else "consistent with one clock"
    return ClockFit(root, lab, clock.offset_s, clock.drift, clock.t_mid_s, clock.offset_se_s,
                    clock.drift_se, np.nan, 0.0, status, NETWORK, clock.summary())  # fmt: skip


def _reliable(fit: ClockFit) -> bool:
    return fit.status in ("applied", "consistent with one clock")


def choose(centre: ClockFit, impacts: ClockFit) -> ClockFit:
    """The fit :func:`synchronise` uses for one pair, with the other's answer in ``other``.

    The joint-centre fit when the impact lag is not reliable (no heel strikes: the arm, lumbar
    and clinical tasks) or when both are reliable and agree (their offsets within twice their
    combined standard error plus ``IMPACT_BIAS_S``: the joint centre is the more precise);
    the impact lag when it is reliable and the joint-centre fit is not or disagrees (its
    model error locked to the stride gave 7-68 ms wrong offsets with standard errors of
    0.1 ms on simulated walks).
    """
    if not _reliable(impacts):
        return replace(centre, other=_summary(impacts))
    gap = abs(centre.offset_s - impacts.offset_s)
    allowed = 2.0 * np.hypot(centre.offset_se_s, impacts.offset_se_s) + IMPACT_BIAS_S
    if _reliable(centre) and gap <= allowed:
        return replace(centre, other=_summary(impacts))
    why = "not reliable" if not _reliable(centre) else f"{1e3 * gap:.1f} ms away"
    return replace(impacts, other=f"{_summary(centre)} ({why})")


def _summary(fit: ClockFit) -> str:
    """``impacts: +12.3 ms ± 0.4 ms, applied`` (or the status alone when no offset)."""
    if not np.isfinite(fit.offset_se_s):
        return f"{fit.method}: {fit.status}"
    return (f"{fit.method}: {1e3 * fit.offset_s:+.1f} ± {1e3 * fit.offset_se_s:.1f} ms, "
            f"{fit.status}")  # fmt: skip


def unsynchronise(session: Session) -> None:
    """Restore every sensor's recorded stamps (undo :func:`synchronise`), in place."""
    for label, stream in list(session.sensors.items()):
        if "clock_sync" in stream.attrs:
            fit = ClockFit(**stream.attrs["clock_sync"])
            attrs = {k: v for k, v in stream.attrs.items() if k != "clock_sync"}
            session.sensors[label] = replace(
                stream, time=fit.recorded_time(stream.time), attrs=attrs
            )
    session.results.clock_sync = None


def describe(fit: ClockFit) -> str:
    """One line: ``shank_r vs thigh_r (impacts): +12.3 ms, drift −21 ppm (± 0.4 ms, 9 ppm) —
    applied; joint centre: ...`` (the other method's answer last); for a network fit
    ``shank_r on pelvis's clock (every pair at once): ... — applied; timed by heel strikes with
    ...; set aside: ...`` (what timed it, what was set aside and why)."""
    head = f"{fit.sensor} vs {fit.reference} ({fit.method}):"
    if fit.method == NETWORK:
        head = f"{fit.sensor} on {fit.reference}'s clock (every pair at once):"
    other = f"; {fit.other}" if fit.other else ""
    if not np.isfinite(fit.offset_se_s):
        return f"{head} {fit.status} ({fit.moving_s:.0f} s of shared movement){other}"
    return (
        f"{head} {1e3 * fit.offset_s:+.1f} ms, drift {1e6 * fit.drift:+.0f} ppm "
        f"(± {1e3 * fit.offset_se_s:.1f} ms, {1e6 * fit.drift_se:.0f} ppm) — {fit.status}" + other
    )


# --- the impact lag ---------------------------------------------------------------------------


@dataclass
class _Envelope:
    """High-frequency energy envelope of one sensor on a uniform grid: time (s), envelope
    (dimensionless, see :func:`_envelope`), its cubic spline, and which samples are real."""

    time: np.ndarray
    values: np.ndarray
    spline: CubicSpline
    valid: np.ndarray


def _envelope(stream: SensorStream) -> _Envelope:
    """‖θ_band‖ low-passed at ``IMPACT_ENVELOPE_HZ`` (rad): the gyroscope integrated to a
    rotation angle θ and band-passed to ``IMPACT_BAND_HZ`` (zero phase, so that no sensor's
    envelope is delayed; the integration's drift is far below the band), gaps bridged linearly
    and the envelope zero within ``SETTLE_S`` of them (see the module docstring: why the angle
    and not the rate, why not the accelerometer)."""
    t = np.asarray(stream.time, float)
    dt = 1.0 / stream.rate_hz
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    ok = measurable(stream.gyr, "gyr")
    t_ok = t[ok]
    on_grid = np.column_stack([np.interp(grid, t_ok, stream.gyr[ok, k]) for k in range(3)])
    high = min(IMPACT_BAND_HZ[1], 0.4 / dt)
    if high <= 1.2 * IMPACT_BAND_HZ[0]:  # sampled too slowly to see the transients
        return _Envelope(grid, np.zeros(len(grid)), CubicSpline(grid, np.zeros(len(grid))),
                         np.zeros(len(grid), bool))  # fmt: skip
    sos = butter(IMPACT_ORDER, (IMPACT_BAND_HZ[0], high), "bandpass", fs=1.0 / dt, output="sos")
    band = sosfiltfilt(sos, np.cumsum(on_grid, axis=0) * dt, axis=0)  # angle (rad), band
    k = np.clip(np.searchsorted(t_ok, grid), 1, len(t_ok) - 1)
    real = np.minimum(grid - t_ok[k - 1], t_ok[k] - grid) <= 0.75 * dt
    valid = np.convolve(~real, np.ones(2 * int(SETTLE_S / dt) + 1), mode="same") == 0
    low = butter(4, IMPACT_ENVELOPE_HZ, fs=1.0 / dt, output="sos")
    env = np.where(valid, sosfiltfilt(low, np.linalg.norm(band, axis=1)), 0.0)
    return _Envelope(grid, env, CubicSpline(grid, env), valid)


def _correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Correlation coefficient of two series (0 when either is constant). The sums by
    ``einsum``, not BLAS: a threaded BLAS spent milliseconds per call on a busy machine."""
    x, y = x - x.mean(), y - y.mean()
    norm = float(np.sqrt(np.einsum("i,i->", x, x) * np.einsum("i,i->", y, y)))
    return float(np.einsum("i,i->", x, y)) / norm if norm > 0 else 0.0


def _best_lag(t: np.ndarray, x: np.ndarray, spline: CubicSpline, lags: np.ndarray) -> tuple[
        float, float, bool]:  # fmt: skip
    """The lag (s) in ``lags`` (uniform, s) that maximises the correlation of ``x`` at ``t``
    with ``spline`` at ``t + lag``, refined between grid lags by a bounded scalar search;
    its correlation coefficient; whether the maximum is inside the range (not at an end)."""
    r = np.array([_correlation(x, spline(t + c)) for c in lags])
    i = int(np.argmax(r))
    inside = 0 < i < len(lags) - 1
    if not inside:
        return float(lags[i]), float(r[i]), False
    step = float(lags[1] - lags[0])
    sol = minimize_scalar(lambda c: -_correlation(x, spline(t + c)),
                          bounds=(lags[i] - step, lags[i] + step), method="bounded",
                          options={"xatol": 1e-5})  # fmt: skip
    return float(sol.x), float(-sol.fun), True


def impact_clock(
    reference: SensorStream,
    sensor: SensorStream,
    max_offset_s: float = MAX_OFFSET_S,
) -> ClockFit:
    """Offset and drift of ``sensor``'s clock against ``reference``'s from the transients
    both see at every heel strike (see the module docstring); any two sensors of the body.

    The lag that maximises the correlation of the two high-frequency energy envelopes
    (:func:`_envelope`) over the whole recording, then the lag of each ``BLOCK_S`` block with
    shared transients (within ``IMPACT_BLOCK_SEARCH_S`` of it), and a line through the block
    lags with a prior on the drift whose scatter gives the standard errors. ``residual`` is
    1 − the whole recording's correlation coefficient; the status is ``"applied"`` only when
    the fit is reliable and differs from zero.
    """
    name = (reference.label, sensor.label)
    t_mid = float(np.mean(reference.time[[0, -1]]))

    def refused(status: str, moving_s: float = 0.0) -> ClockFit:
        return ClockFit(*name, 0.0, 0.0, t_mid, np.inf, np.inf, np.nan, moving_s, status,
                        IMPACTS)  # fmt: skip

    if min(_finite_samples(reference), _finite_samples(sensor)) < MIN_SAMPLES:
        return refused("no usable accelerometer and gyroscope samples")
    a, b = _envelope(reference), _envelope(sensor)
    inside = (a.time - max_offset_s >= b.time[0]) & (a.time + max_offset_s <= b.time[-1])
    t_mid = float(0.5 * (a.time[0] + a.time[-1]))
    if inside.sum() < 3 * BLOCK_S / (a.time[1] - a.time[0]):
        return refused("not enough shared recording")
    t, x = a.time[inside], a.values[inside]
    dt = float(t[1] - t[0])
    lags = np.arange(-max_offset_s, max_offset_s + 1e-12, dt)
    r = np.array([_correlation(x, np.interp(t + c, b.time, b.values)) for c in lags])
    i = int(np.argmax(r))
    others = np.abs(lags - lags[i]) > IMPACT_PEAK_WIDTH_S
    second = float(r[others].max()) if others.any() else -1.0
    lag, corr, _ = _best_lag(t, x, b.spline, lags[max(i - 1, 0) : i + 2])
    # blocks of the recording in which the reference's envelope has transients
    active = x > IMPACT_ACTIVE * np.median(x[x > 0]) if np.any(x > 0) else np.zeros(len(x), bool)
    n_blocks = int(len(t) * dt // BLOCK_S)
    rows, offsets = [], []
    search = np.arange(-IMPACT_BLOCK_SEARCH_S, IMPACT_BLOCK_SEARCH_S + 1e-12, dt)
    for block in np.array_split(np.arange(len(t)), max(n_blocks, 1)):
        if active[block].sum() * dt < IMPACT_MIN_ACTIVE_S:
            continue
        c, r_block, ok = _best_lag(t[block], x[block], b.spline, lag + search)
        if ok and r_block >= IMPACT_MIN_CORRELATION:
            rows.append([1.0, float(t[block].mean()) - t_mid])
            offsets.append(c)
    active_s = float(active.sum() * dt)
    if len(offsets) < 3:
        return refused("not reliable: too few heel strikes (or other shared transients)",
                       active_s)  # fmt: skip
    clock, offset_se, drift_se = _line(np.array(rows), np.array(offsets))
    ends = np.array([rows[0][1] - 0.5 * BLOCK_S, rows[-1][1] + 0.5 * BLOCK_S])  # - t_mid
    worst_se = float(np.hypot(offset_se, drift_se * 0.5 * (ends[1] - ends[0])))
    c_ends = np.abs(clock[0] + clock[1] * ends)
    if worst_se > IMPACT_MAX_SE_S:
        status = "not reliable: the heel-strike transients disagree between blocks"
    elif corr - second < IMPACT_MARGIN:
        status = (
            f"not reliable: steps as regular as the clock search (correlation {corr:.3f} at "
            f"the best lag, {second:.3f} at another)"
        )
    elif corr < IMPACT_MIN_CORRELATION:
        status = f"not reliable: the transients correlate poorly ({corr:.2f})"
    elif abs(clock[0]) > max_offset_s - IMPACT_BLOCK_SEARCH_S:
        status = f"not reliable: offset at the edge of the ±{max_offset_s:g} s search"
    elif c_ends.max() <= max(MIN_CORRECTION_S, 2.0 * worst_se):
        status = "consistent with one clock"
    else:
        status = "applied"
    return ClockFit(*name, float(clock[0]), float(clock[1]), t_mid, offset_se, drift_se,
                    1.0 - corr, active_s, status, IMPACTS)  # fmt: skip


def _line(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Offset (s) and drift of block lags ``y`` (s) at rows ``x`` = [1, t − t_mid], equal
    weights scaled by their scatter (at least ``IMPACT_FLOOR_S``), with the drift prior."""
    fit = np.linalg.lstsq(x, y, rcond=None)[0]
    dof = max(len(y) - 2, 1)
    s2 = max(float(np.sum((y - x @ fit) ** 2)) / dof, IMPACT_FLOOR_S**2)
    return _line_with_prior(x, y, np.ones(len(y)), s2)


def _line_with_prior(
    x: np.ndarray, y: np.ndarray, w: np.ndarray, scale: float
) -> tuple[np.ndarray, float, float]:
    """Offset (s) and drift through block offsets ``y`` (s) at rows ``x`` = [1, t − t_mid]
    with weights ``w`` divided by ``scale``, drift prior 0 ± ``DRIFT_PRIOR`` (two crystal
    clocks); and their standard errors."""
    info = x.T @ (w[:, None] * x) / scale + np.diag([0.0, DRIFT_PRIOR**-2])
    cov = np.linalg.inv(info)
    clock = cov @ (x.T @ (w * y)) / scale
    return clock, float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))
