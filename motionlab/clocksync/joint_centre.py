"""The joint-centre clock fit of two sensors on neighbouring segments (:func:`estimate_clock`).

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
biases with a prior of 0 ± 1 m/s², see :meth:`Pair._with_prior`). ``f`` and ``ω`` are first
low-passed at ``INPUT_LP_HZ`` against soft-tissue wobble; on a real-like walk the shank's own
motion reaches past it (the knee's terminal-swing reversal), which leaves 0.37-0.43 ms of
thigh-shank clock error on clean simulated sensors (knee protocol, seeds 4-6 and 8); a 10 Hz
low-pass gave 0.05-0.09 ms there (seeds 4, 8) but let a typical sensor's 10-16 Hz wobble
through (0.30-0.46 ms instead of 0.15-0.37). The
clock is then refitted from the offsets of 8 s blocks of movement: a weighted line with a prior
on the drift, whose scatter gives honest standard errors (see :meth:`Pair.clock_from_blocks`).

A correction is applied only when the fit is reliable: standard error ≤ ``MAX_SE_S`` over the
recording, and the joint-centre model fits (RMS residual ≤ ``MAX_RESIDUAL_M_S2``; a sensor
rocking on soft tissue with the segment's acceleration breaks the model and biased the offset
by 20–30 ms on simulated walks, with a residual five times the usual).

**The spine** (``spine=True``: sensors among pelvis, lumbar and thorax, timed by
:func:`motionlab.clocksync.stage.synchronise` without heel strikes). A trunk recording is often
short (10–20 s of movement: a seated rest and one block of trunk movement), under the three
``BLOCK_S`` blocks the standard error needs: a movement shorter than three blocks is cut into
``SPINE_BLOCKS`` blocks, none shorter than ``SPINE_BLOCK_MIN_S`` (on the simulated seated
sessions, seeds 0-9, three blocks let two wrong offsets through with small standard errors:
8.4 → 27.7 ms and 20.3 → 46 ms off; five blocks apply on three seeds, each closer to the truth
than no correction, and refuse or keep the rest). And the spine bends along its length: no
single centre joins the two sensors, so the model's residual is larger than at a hinge or a
ball joint while a seated trunk's offset is not biased by it (no heel strikes drive the soft
tissue): on the five real trials of the trunk data set (x-IMU3 sensors whose timestamps the
vendor's software synchronised) the residual was 0.12–0.27 m/s², and the offsets it applies on
four of them (+14.2, +13.1, +17.8, +11.4 ms, ± 1.1–4.7 ms) agree within 1–8 ms with each
sensor's lag behind its own OptiTrack body (+16, +14, +10, +18 ms; docs/kinematics.md); the
residual limit there is ``SPINE_MAX_RESIDUAL_M_S2``. The simulator's lumbar joint is one
centre (residual 0.01 m/s²).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares

from motionlab.clocksync._kernels import pair_residual_rows, pair_residuals
from motionlab.clocksync.common import (
    BLOCK_S,
    MAX_OFFSET_S,
    MIN_CORRECTION_S,
    MIN_SAMPLES,
    butter_sos,
    finite_samples,
    line_with_prior,
    on_grid,
)
from motionlab.dsp import filtfilt_at, padlen, sosfilt_zi, sosfiltfilt
from motionlab.minpack import lm
from motionlab.qc import measurable
from motionlab.results import ClockFit
from motionlab.session import SensorStream

GRID_STEP_S = 0.01  # coarse grid over the offset (s)
LEVERS_GRID_STEP_S = 0.04  # grid of the second search, levers refitted at each offset (s)
LEVERS_MAX_NFEV = 20  # evaluations per refit there: on a real walk (residual 0.8-1 m/s², soft
# tissue) an unbounded refit took 3.5-9 s per pair over the grid, bounded 0.5-0.7 s
# the second search's fit replaces the first only with a residual this much smaller: out of the
# wrong valley it fell 0.24 → 0.04 and 0.26 → 0.03 m/s²; where soft tissue spoils the model
# everywhere (0.33 m/s²) another valley of about the same cost lay 66 ms from the truth
VALLEY_RATIO = 0.7
MAX_SE_S = 0.010  # largest standard error of c(t) for a correction to be applied (s)
# largest RMS residual (low-passed, m/s²) for a correction: 0.009-0.026 on the simulated clinical
# protocols; 0.09-0.13 where acceleration-driven soft tissue biased the offset by 20-30 ms
MAX_RESIDUAL_M_S2 = 0.05
# the spine (see the module notes): the residual limit (the five real trials of the trunk data
# set: 0.12-0.27 m/s²), and a short movement's blocks: how many, the shortest (s)
SPINE_MAX_RESIDUAL_M_S2 = 0.3
SPINE_BLOCKS = 5
SPINE_BLOCK_MIN_S = 2.0
MOVING_RAD_S = 0.35  # a segment moves above this angular rate (rad/s, 20 °/s)
MIN_MOVING_S = 5.0  # shared movement needed (s)
LOWPASS_HZ = 6.0  # zero-phase low-pass of the residuals (Hz)
INPUT_LP_HZ = 8.0  # zero-phase low-pass of f and ω (order INPUT_ORDER): soft-tissue wobble
INPUT_ORDER = 8  # at 10–20 Hz would otherwise reach ω̇ × r by tens of m/s²
BIAS_PRIOR_M_S2 = 1.0  # prior standard deviation of each accelerometer bias (m/s²), see Pair
# residuals are computed this close to the samples used only (s): the impulse response of the
# LOWPASS_HZ low-pass falls below 1e-18 of its peak within 3 s (at any rate)
MARGIN_S = 3.0
BODY = 12  # parameters besides the clock: two lever arms and two accelerometer biases
# the levers, biases and clock are searched for on at most this much shared movement (s), in
# BLOCK_S blocks spread evenly over the recording, then refined on all of it from there: the
# searches over a whole recording took more iterations the longer it was (docs/performance.md)
FIT_MOVING_S = 240.0
#: the status of a fit refused for its residual alone
POOR_FIT = "not reliable: the shared joint centre fits poorly"
# the offset's grid search and first fit take this much contiguous movement at the recording's
# middle (s), where a drift of 50 ppm moves the offset by 1 ms: on blocks spread over a 30-min
# walk, two clocks drifting 44 ppm apart (80 ms over it) smeared the grid's zero-drift costs and
# the fit ended 86 ms off the truth (its residual refused it, and with it every correction)
SEARCH_MOVING_S = 40.0


@dataclass
class Signals:
    """One sensor on a uniform grid: time (s), ``[f, ω, ω̇]`` (N, 9), their cubic spline, and
    which samples are real (no gap within the low-pass filter's settling time)."""

    time: np.ndarray
    values: np.ndarray
    spline: CubicSpline
    valid: np.ndarray


def signals(stream: SensorStream) -> Signals:
    """``stream``'s accelerometer and gyroscope on its uniform grid, low-passed at
    ``INPUT_LP_HZ`` (zero phase), with ω̇ (:class:`Signals`)."""
    ok = measurable(stream.acc, "acc") & measurable(stream.gyr, "gyr")
    grid, values, valid = on_grid(stream, np.hstack([stream.acc, stream.gyr]), ok)
    dt = 1.0 / stream.rate_hz
    values = sosfiltfilt(butter_sos(INPUT_ORDER, INPUT_LP_HZ, 1.0 / dt), values, axis=0)
    # ω̇ from the spline, not np.gradient, whose central difference is 1.6 % low at 5 Hz: on the
    # simulated walk's shank that was 0.15-0.2 ms of the offset's error (clean, seeds 4 and 8)
    values = np.hstack([values, CubicSpline(grid, values[:, 3:], axis=0)(grid, 1)])
    return Signals(grid, values, CubicSpline(grid, values, axis=0), valid)


def estimate_clock(
    reference: SensorStream,
    sensor: SensorStream,
    max_offset_s: float = MAX_OFFSET_S,
    signals_of: Callable[[SensorStream], Signals] | None = None,
    spine: bool = False,
) -> ClockFit:
    """Offset and drift of ``sensor``'s clock against ``reference``'s (see the module docstring).

    Both streams need ``acc`` (m/s²) and ``gyr`` (rad/s) and must sit on the two sides of one
    joint. The status is ``"applied"`` only when the fit is reliable and differs from zero
    (:func:`motionlab.clocksync.stage.synchronise` applies only those). ``signals_of``: how a
    stream's :class:`Signals` are had (default :func:`signals`; the stage computes them once
    per sensor, :class:`~motionlab.clocksync.common.PerStream`). ``spine``: sensors among
    pelvis, lumbar and thorax (a short movement in ``SPINE_BLOCKS`` blocks, the residual limit
    ``SPINE_MAX_RESIDUAL_M_S2``; module notes).
    """
    name = (reference.label, sensor.label)
    if min(finite_samples(reference), finite_samples(sensor)) < MIN_SAMPLES:
        return ClockFit(*name, 0.0, 0.0, float(np.mean(reference.time[[0, -1]])), np.inf, np.inf,
                        np.nan, 0.0, "no usable accelerometer and gyroscope samples")  # fmt: skip
    a, b = (signals_of or signals)(reference), (signals_of or signals)(sensor)
    inside = (a.time - max_offset_s >= b.time[0]) & (a.time + max_offset_s <= b.time[-1])
    t_mid = float(0.5 * (a.time[0] + a.time[-1]))
    if inside.sum() < 2 * MIN_MOVING_S / (a.time[1] - a.time[0]):
        # needed: the shared movement twice over, plus the offset's search at either end
        shared_s = min(a.time[-1], b.time[-1]) - max(a.time[0], b.time[0])
        return ClockFit(*name, 0.0, 0.0, t_mid, np.inf, np.inf, np.nan, 0.0,
                        f"not enough shared recording ({max(shared_s, 0.0):.0f} s; "
                        f"{2 * (MIN_MOVING_S + max_offset_s):.0f} s needed)")  # fmt: skip
    span = slice(np.argmax(inside), len(inside) - np.argmax(inside[::-1]))
    t, ref = a.time[span], a.values[span]
    dt = float(t[1] - t[0])
    sos = butter_sos(4, LOWPASS_HZ, 1.0 / dt)
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
    pair = Pair(t, ref, b.spline, t_mid, sos, use[::stride])
    if spine and moving_s < 3 * BLOCK_S:  # a short trunk recording: in shorter blocks
        covered = len(pair.use) * float(np.median(np.diff(t[pair.use])))  # as blocks() counts
        block = covered / SPINE_BLOCKS * (1.0 - 1e-9)
        pair = replace(pair, block_s=max(block, SPINE_BLOCK_MIN_S))
    searching = pair.middle(SEARCH_MOVING_S)  # the offset at the middle, the drift aside
    fitting = pair.spread(FIT_MOVING_S)  # the levers, biases and clock over the recording
    limit = SPINE_MAX_RESIDUAL_M_S2 if spine else MAX_RESIDUAL_M_S2
    chain = [searching, *_widening(pair, fitting, searching)]
    fit = _fit_from(chain, _grid_offset(searching, max_offset_s))
    if _rms(pair, fit) > limit:  # perhaps the valley of the zero offset's levers: search again
        again = _fit_from(chain, _levers_grid_offset(searching, max_offset_s))
        fit = again if _rms(pair, again) < VALLEY_RATIO * _rms(pair, fit) else fit
    half = 0.5 * (t[use[-1]] - t[use[0]])
    fit[-2:], offset_se, drift_se = pair.clock_from_blocks(fit)
    worst_se = float(np.hypot(offset_se, drift_se * half))
    c_ends = np.abs(fit[-2] + fit[-1] * (t[use[[0, -1]]] - t_mid))
    rms = _rms(pair, fit)
    if worst_se > MAX_SE_S:
        status = "not reliable: too little shared movement"
    elif rms > limit:
        status = f"{POOR_FIT} (residual {rms:.2f} m/s²: soft tissue or a loose sensor)"
    elif abs(fit[-2]) > max_offset_s - GRID_STEP_S:
        status = f"not reliable: offset at the edge of the ±{max_offset_s:g} s search"
    elif c_ends.max() <= max(MIN_CORRECTION_S, 2.0 * worst_se):
        status = "consistent with one clock"
    else:
        status = "applied"
    return ClockFit(*name, float(fit[-2]), float(fit[-1]), t_mid, offset_se, drift_se, rms,
                    moving_s, status)  # fmt: skip


@dataclass
class Pair:
    """Residuals LP(‖f₁ + b₁ + K₁ r₁‖ − ‖f₂ + b₂ + K₂ r₂‖) at reference times ``t[use]`` (s),
    LP the zero-phase low-pass ``sos``, and their Jacobian in the parameters ``[r₁, r₂ (m), b₁,
    b₂ (accelerometer biases, m/s²), c₀ (s), c₁]``; sensor 2 is read at ``t + c(t)``. The biases
    are fitted because an uncalibrated 0.1 m/s² projects onto the changing gravity direction in
    step with the movement, and so would pull the offset.

    The residuals are computed over the spans of the samples ``use`` and ``MARGIN_S`` either
    side only (:attr:`parts`), not over the stretches between them that are farther from every
    used sample: the low-pass's response to what lies further away is below floating-point
    resolution, so the residuals are those of the whole recording at a fraction of the cost."""

    t: np.ndarray
    ref: np.ndarray  # (N, 9) [f, ω, ω̇] of the reference at t
    spline: CubicSpline
    t_mid: float
    sos: np.ndarray
    use: np.ndarray
    block_s: float = BLOCK_S  # movement per block (s): :meth:`blocks`

    def __post_init__(self) -> None:
        sos = self.sos
        self._zi = sosfilt_zi(sos)  # what sosfiltfilt computes on every call
        self._edge = padlen(sos)  # sosfiltfilt's default padding
        self.parts = _parts(self.use, int(round(MARGIN_S / float(self.t[1] - self.t[0]))),
                            len(self.t))  # fmt: skip

    def residuals(self, p: np.ndarray, jacobian: bool = False, columns: int = 14) -> np.ndarray:
        """The residuals (K) at ``p``, or with ``jacobian`` their Jacobian (K, ``columns``: in
        the first ``columns`` parameters)."""
        p = np.asarray(p, float)
        out = np.empty((columns if jacobian else 1, len(self.use)))
        for lo, hi, at, use in self.parts:
            res, jac = self._unfiltered(p, 14 if jacobian else 0, lo, hi)
            self._filter(jac[:columns] if jacobian else res[None], use, out[:, at])
        return out.T if jacobian else out[0]

    def offset_residuals(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residuals (K) at ``p`` and their derivative in the offset ``c₀`` (K)."""
        p = np.asarray(p, float)
        out = np.empty((2, len(self.use)))
        for lo, hi, at, use in self.parts:
            res, dc = self._unfiltered(p, 1, lo, hi)
            self._filter(np.vstack([res, dc]), use, out[:, at])
        return out[0], out[1]

    def _unfiltered(self, p: np.ndarray, rows: int, lo: int, hi: int) -> tuple[np.ndarray, ...]:
        """The residuals on ``t[lo:hi]`` before the low-pass, and ``rows`` of their derivatives
        (none, 1: in ``c₀``, 14: in every parameter; :func:`._kernels.pair_residuals`)."""
        res = np.empty(hi - lo)
        jac = np.empty((max(rows, 1), hi - lo if rows else 0))
        sp = self.spline
        pair_residuals(self.t[lo:hi], self.t_mid, sp.x, sp.c, self.ref[lo:hi], p, res, jac)
        return res, jac

    def _filter(self, x: np.ndarray, use: np.ndarray, out: np.ndarray) -> None:
        """``sosfiltfilt(sos, x, axis=-1)[:, use]`` into ``out``, by scipy's own steps with the
        steady state computed once per pair (:func:`motionlab.dsp.filtfilt_at`)."""
        filtered = np.empty((x.shape[0], len(use)))
        filtfilt_at(x, self.sos, self._zi, self._edge, use, filtered)
        out[:] = filtered

    def _with_prior(self, p: np.ndarray, jacobian: bool = False, columns: int = 14) -> np.ndarray:
        """:meth:`residuals` and the biases' prior rows ``b / BIAS_PRIOR_M_S2`` (0 ± 1 m/s²);
        with ``jacobian`` the Jacobian in the first ``columns`` parameters.

        Without them the fit has a second valley at biases of ~10⁸ m/s², where ‖f + b + K r‖
        is the projection of the joint-centre acceleration on a fixed axis of each sensor: both
        sensors' projections on the knee's flexion axis agree, so it nearly fits, but it times
        the clock poorly. On the knee protocol's simulated walk (clean sensors, seeds 5 and 6)
        the search fell into it (residual 0.076 m/s², offsets 1.6-1.7 ms off) once the knee
        template had a real-like terminal swing; a real accelerometer's bias is < 1 m/s².
        """
        if not jacobian:
            return np.concatenate((self.residuals(p), p[6:12] / BIAS_PRIOR_M_S2))
        prior = np.zeros((6, len(p)))
        prior[:, 6:12] = np.eye(6) / BIAS_PRIOR_M_S2
        return np.vstack([self.residuals(p, True, columns), prior[:, :columns]])

    def cost(self, p: np.ndarray) -> float:
        """Sum of the squared residuals at ``p``."""
        return float(np.sum(self.residuals(p) ** 2))

    def costs(self, ps: np.ndarray, lanes: int = 8) -> np.ndarray:
        """:meth:`cost` at each row of ``ps`` (G, 14), the same numbers: every row's residuals
        in one pass over the samples (:func:`._kernels.pair_residual_rows`, the reference's
        side once for rows that share its lever and bias), ``lanes`` rows low-passed together
        (:func:`motionlab.dsp.filtfilt_at`)."""
        ps = np.ascontiguousarray(ps, dtype=float)
        own = np.r_[0:3, 6:9]  # the parameters of the reference's side
        same_body = np.r_[False, (ps[1:, own] == ps[:-1, own]).all(axis=1)]
        res = np.empty((len(ps), len(self.use)))
        sp = self.spline
        for lo, hi, at, use in self.parts:
            rows = np.empty((len(ps), hi - lo))
            pair_residual_rows(self.t[lo:hi], self.t_mid, sp.x, sp.c, self.ref[lo:hi], ps,
                               same_body, rows)  # fmt: skip
            for first in range(0, len(ps), lanes):
                self._filter(rows[first : first + lanes], use, res[first : first + lanes, at])
        return np.sum(res**2, axis=1)

    def body(self, c0: float, max_nfev: int | None = None) -> np.ndarray:
        """r₁, r₂ (m), b₁, b₂ (m/s²) for the offset ``c0`` (s) and no drift, in at most
        ``max_nfev`` evaluations (default MINPACK's)."""
        fixed = np.array([c0, 0.0])
        sol = lm(
            lambda q: self._with_prior(np.concatenate((q, fixed))),
            np.zeros(BODY),
            lambda q: self._with_prior(np.concatenate((q, fixed)), True, BODY),
            x_scale=0.1,
            max_nfev=max_nfev,
        )
        return sol.x

    def solve(self, p0: np.ndarray) -> np.ndarray:
        """All parameters, from ``p0``."""
        return lm(
            self._with_prior,
            p0,
            lambda p: self._with_prior(p, jacobian=True),
            x_scale=np.r_[np.full(BODY, 0.1), 0.01, 1e-4],
        ).x

    def blocks(self) -> list[np.ndarray]:
        """The used samples in runs of ``block_s`` of movement (none when under three)."""
        dt = float(np.median(np.diff(self.t[self.use])))  # spacing of the fitted samples
        n_blocks = int(len(self.use) * dt // self.block_s)
        return np.array_split(self.use, n_blocks) if n_blocks >= 3 else []

    def spread(self, moving_s: float) -> Pair:
        """The pair on at most ``moving_s`` of its movement: whole :meth:`blocks` spread evenly
        over the recording (itself when it moves less)."""
        blocks = self.blocks()
        keep = int(moving_s // self.block_s)
        if len(blocks) <= keep:
            return self
        chosen = np.unique(np.round(np.linspace(0, len(blocks) - 1, keep)).astype(int))
        return replace(self, use=np.concatenate([blocks[i] for i in chosen]))

    def middle(self, moving_s: float) -> Pair:
        """The pair on ``moving_s`` of contiguous movement at the middle of the recording:
        whole :meth:`blocks` around the middle one (itself when it moves less)."""
        blocks = self.blocks()
        keep = max(3, int(moving_s // self.block_s))
        if len(blocks) <= keep:
            return self
        first = (len(blocks) - keep) // 2
        return replace(self, use=np.concatenate(blocks[first : first + keep]))

    def clock_from_blocks(self, p: np.ndarray) -> tuple[np.ndarray, float, float]:
        """c₀ (s), c₁ and their standard errors from offsets fitted block by block (the moving
        samples in runs of ``block_s``; levers and biases of ``p`` held).

        A line through the block offsets, weighted by each block's information and scaled by
        its scatter (χ²/dof when above 1, so that the model's errors, which the residuals'
        statistics understate, show), with a prior on the drift (0 ± ``DRIFT_PRIOR``: two
        crystal clocks): where the movement sits in two clusters whose offsets carry different
        model errors, an unrestrained line turned a few milliseconds into hundreds of ppm.
        Fewer than three blocks: infinite errors.
        """
        dt = float(np.median(np.diff(self.t[self.use])))  # spacing of the fitted samples
        blocks = self.blocks()
        if not blocks:
            return p[-2:], np.inf, np.inf
        rows, offsets, weights = [], [], []
        correlation = max(1.0, 0.5 / (LOWPASS_HZ * dt))  # samples per independent residual
        for block in blocks:
            part = replace(self, use=block)
            centre = self.t[block].mean() - self.t_mid
            sol = _offset_fit(part, p[:BODY], p[-2:-1] + p[-1] * centre)
            s2 = float(np.mean(sol.fun**2)) * correlation
            rows.append([1.0, centre])
            offsets.append(sol.x[0])
            weights.append(float(sol.jac[:, 0] @ sol.jac[:, 0]) / max(s2, 1e-30))
        x, w, y = np.array(rows), np.array(weights), np.array(offsets)
        line = np.linalg.solve(x.T @ (w[:, None] * x), x.T @ (w * y))
        chi2 = float(w @ (y - x @ line) ** 2) / (len(y) - 2)
        return line_with_prior(x, y, w, max(1.0, chi2))


def _rms(pair: Pair, p: np.ndarray) -> float:
    """RMS residual (m/s², low-passed) of the parameters ``p`` over all of ``pair``."""
    return float(np.sqrt(pair.cost(p) / len(pair.use)))


def _grid_offset(searching: Pair, max_offset_s: float) -> float:
    """The offset (s) of least cost on a ``GRID_STEP_S`` grid, the levers and biases fitted at
    a zero offset (one fit: cheap, and right where the clocks start within tens of ms)."""
    body = searching.body(0.0)
    grid = np.arange(-max_offset_s, max_offset_s + 1e-12, GRID_STEP_S)
    return float(grid[int(np.argmin(searching.costs(np.column_stack([
        np.tile(body, (len(grid), 1)), grid, np.zeros(len(grid))]))))])  # fmt: skip


def _levers_grid_offset(searching: Pair, max_offset_s: float) -> float:
    """The offset (s) of least cost with the levers and biases refitted at every offset of a
    ``LEVERS_GRID_STEP_S`` grid, then on the ``GRID_STEP_S`` grid about it with the best
    one's: levers fitted at a zero offset take up part of a large one, and the zero offset's
    valley then wins the plain grid (a pair 57 ms apart: residual 0.31 m/s² at 0 ms against
    1.08 at 60 ms; refitted, 0.16 at 60 ms and 0.31 at 0)."""
    coarse = np.arange(-max_offset_s, max_offset_s + 1e-12, LEVERS_GRID_STEP_S)
    # each from zero (started from its neighbour's, the levers of a wrong offset carried on
    # and a shank 150 ms off was not found), in a bounded number of evaluations
    bodies = [searching.body(c, LEVERS_MAX_NFEV) for c in coarse]
    costs = [searching.cost(np.r_[b, c, 0.0]) for b, c in zip(bodies, coarse, strict=True)]
    best = int(np.argmin(costs))
    grid = coarse[best] + np.arange(-LEVERS_GRID_STEP_S, LEVERS_GRID_STEP_S + 1e-12, GRID_STEP_S)
    lanes = np.column_stack([np.tile(bodies[best], (len(grid), 1)), grid, np.zeros(len(grid))])
    return float(grid[int(np.argmin(searching.costs(lanes)))])


def _fit_from(chain: list[Pair], c0: float) -> np.ndarray:
    """All parameters fitted from the offset ``c0`` (s) on the first pair of ``chain``, then
    refitted on each of the others from the last fit (:func:`_widening`)."""
    first = chain[0]
    fit = first.solve(np.r_[first.body(c0), c0, 0.0])
    for wider in chain[1:]:
        fit = wider.solve(fit)
    return fit


def _widening(pair: Pair, fitting: Pair, searching: Pair) -> list[Pair]:
    """The pairs the clock is refitted on after the search on ``searching`` (the middle's
    ``SEARCH_MOVING_S``), each holding more samples than the last: contiguous movement around
    the middle, twice as much each time below ``FIT_MOVING_S``, then ``fitting`` (blocks spread
    over the recording) and ``pair`` (all of it). Each extrapolates the last fit's drift only
    about twice as far: from the middle 40 s straight to blocks over 300 s, a drift of 350 ppm
    misjudged on the 40 s ended in another valley."""
    out: list[Pair] = []
    last, moving_s = len(searching.use), SEARCH_MOVING_S
    candidates = []
    while (moving_s := 2.0 * moving_s) < FIT_MOVING_S:
        candidates.append(pair.middle(moving_s))
    for wider in (*candidates, fitting, pair):
        if len(wider.use) > last:
            out.append(wider)
            last = len(wider.use)
    return out


def _parts(use: np.ndarray, margin: int, n: int) -> list[tuple[int, int, slice, np.ndarray]]:
    """The spans of ``t`` (``n`` samples) over which the residuals at ``use`` (sorted indices)
    are computed: runs of used samples less than ``2 margin`` apart, each widened by
    ``margin`` either side (within ``0, n``). Per span: ``lo``, ``hi``, the slice of ``use``
    it holds, and those samples' indices from ``lo``."""
    use = np.asarray(use, np.int64)
    breaks = np.flatnonzero(np.diff(use) > 2 * margin) + 1
    parts = []
    for first, end in zip(np.r_[0, breaks], np.r_[breaks, len(use)], strict=True):
        lo, hi = max(0, int(use[first]) - margin), min(n, int(use[end - 1]) + margin + 1)
        parts.append((lo, hi, slice(int(first), int(end)), use[first:end] - lo))
    return parts


def _offset_fit(pair: Pair, body: np.ndarray, c_start: np.ndarray):
    """``least_squares`` of the offset ``c₀`` alone (levers and biases ``body`` held, no drift)
    with its analytic derivative; the residuals and the derivative come from one evaluation,
    kept for the Jacobian call that follows at the same point."""
    last: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def at(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = float(c[0])
        if key not in last:
            last.clear()
            last[key] = pair.offset_residuals(np.concatenate((body, c, (0.0,))))
        return last[key]

    return least_squares(lambda c: at(c)[0], c_start, jac=lambda c: at(c)[1][:, None], x_scale=0.01)


def centre(values: np.ndarray, r: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Specific force at the joint centre f + b + ω̇ × r + ω × (ω × r) (N, 3), rows [f, ω, ω̇]."""
    f, w, a = values[:, :3], values[:, 3:6], values[:, 6:]
    return f + bias + np.cross(a, r) + np.cross(w, np.cross(w, r))


def joint_centre_forces(
    reference: SensorStream, sensor: SensorStream
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Specific force at the shared joint centre seen by each sensor, in its own frame.

    ``(time s, f_J reference (N, 3), f_J sensor (N, 3))`` on the reference's uniform grid, from
    the lever arms and accelerometer biases fitted as for the clock (:class:`Pair`; the clocks
    taken as one: clock sync first). ``None`` when the two share too little movement. Rotated
    into the earth frame the two vectors are one (Seel et al. 2012), which ties their headings
    (:func:`motionlab.segments.heading.centre_anchors`).
    """
    if min(finite_samples(reference), finite_samples(sensor)) < MIN_SAMPLES:
        return None
    a, b = signals(reference), signals(sensor)
    inside = (a.time >= b.time[0]) & (a.time <= b.time[-1])
    t, ref = a.time[inside], a.values[inside]
    if len(t) < 10:
        return None
    dt = float(t[1] - t[0])
    sos = butter_sos(4, LOWPASS_HZ, 1.0 / dt)
    other = b.spline(t)
    rates = np.hypot(np.linalg.norm(ref[:, 3:6], axis=1), np.linalg.norm(other[:, 3:6], axis=1))
    use = np.flatnonzero(sosfiltfilt(sos, rates) > MOVING_RAD_S)
    if len(use) * dt < MIN_MOVING_S:
        return None
    stride = max(1, int(0.25 / (LOWPASS_HZ * dt)))
    p = Pair(t, ref, b.spline, float(t.mean()), sos, use[::stride]).body(0.0)
    return t, centre(ref, p[:3], p[6:9]), centre(other, p[3:6], p[9:12])
