"""The heel-strike clock lag of any two sensors (:func:`impact_clock`).

A timing signal independent of the joint centre: the heel strikes. Every heel strike
shakes the whole body at one instant, and every leg and pelvis sensor rocks on its soft tissue
for a few tens of milliseconds after it (10-16 Hz ringing; on real recordings also a sharp spike
at the shank, weaker above). The envelope of each sensor's rocking — the gyroscope integrated to
an angle, band-passed to ``IMPACT_BAND_HZ`` (zero phase), its norm low-passed — is then a pulse
train common to all sensors, and the lag that maximises the correlation of two sensors'
envelopes (within ``±max_offset_s``, refined between samples) is their clock offset, for any two
sensors, not only neighbours. The angle rather than the rate: the envelope of a rate is the
angle's times the ringing frequency plus the envelope's own slope, so two sensors ringing at 10
and 15 Hz gave lags 2.8 ms apart (tests/test_clock_impacts.py); the angle's envelope does not
depend on the frequency. The lag is searched over the recording's middle ``IMPACT_SEARCH_S``
(all of a recording up to 2 min); block lags (``BLOCK_S`` blocks with transients, from the
middle outwards, each within ``IMPACT_BLOCK_SEARCH_S`` of the line through the blocks timed so
far, so that a long recording's drift is followed) give the drift and, from their scatter, the
standard error. The lag is refused when the transients are too few, correlate poorly, or
recur so regularly that a lag one step away fits as well (``IMPACT_MARGIN``). **Assumption:**
the transient reaches every sensor at the same instant. In the body it travels up the leg at
tens of metres per second, and the pelvis may see it a few milliseconds after the shank (a
bias of that size on pelvis pairs, not modelled). On the simulator, where it arrives at once,
the lags still carry errors that their block scatter does not show: with tissue that also
rocks with the segment's acceleration (``soft_tissue="motion"``, bench/real_world.py seeds 0-9)
pelvis–thigh and thigh–thigh ≤ 1 ms, every pair with a shank median 0.4-0.9 ms but up to
3-5 ms (the shank's own resonance, driven at its own phase of the stride, adds to its
envelope); with ringing after heel strikes only (bench/gait.py seeds 0-4) ≤ 2.1 ms. Where each
sensor rings in its own way after the strike, as the ``skin`` preset's legs do since they ring as
a real walk's (a shock after the sensor's own leg's strike and a wobble after every strike,
docs/simulator.md), the envelopes' shapes differ and so do their peaks: the lags of sensors on
one clock are up to 13 ms for pelvis-thigh pairs and 8 ms for the knees, or refused
(``bench/leg_ringing.py``); on own clocks, a pelvis's lags against the legs +8 to +36 ms on 9
of 10 walks. On the real one-clock walk nine of its ten pairs are refused and the tenth,
pelvis–shank_l, is 36.6 ms off (the network's knee check then corrects nothing). The
accelerometer is left out: its band carries the segment's own movement, which biased the
simulated lags by 6-18 ms; its 20-45 Hz band, where the skin's shock rises, timed the
simulated pairs to 2-2.5 ms RMS but took both real one-clock knees 63-77 ms off (a real thigh
rings at the end of the swing, before the strike: docs/simulator.md, "The legs ring after heel
strikes").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize_scalar

from motionlab.clocknet import IMPACTS
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
from motionlab.dsp import sosfiltfilt
from motionlab.qc import measurable
from motionlab.results import ClockFit
from motionlab.session import SensorStream

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
# the whole lag is searched over this much of the recording's middle (s): two crystal clocks'
# drift (150 ppm, three times the prior's SD) moves the lag by 18 ms over it; over a 1-h walk
# 66 ppm moved it by 240 ms, which smeared the correlation peak into its neighbours'
IMPACT_SEARCH_S = 120.0
#: the status of a pair whose shared recording is too short for the method to run
TOO_SHORT = "not enough shared recording"
#: the status of a lag refused because a lag one step away fits about as well
REGULAR_STEPS = "not reliable: steps as regular as the clock search"


@dataclass
class Envelope:
    """High-frequency energy envelope of one sensor on a uniform grid: time (s), envelope
    (dimensionless, see :func:`envelope`; zero where the samples are not real) and its cubic
    spline."""

    time: np.ndarray
    values: np.ndarray
    spline: CubicSpline


def envelope(stream: SensorStream) -> Envelope:
    """‖θ_band‖ low-passed at ``IMPACT_ENVELOPE_HZ`` (rad): the gyroscope integrated to a
    rotation angle θ and band-passed to ``IMPACT_BAND_HZ`` (zero phase, so that no sensor's
    envelope is delayed; the integration's drift is far below the band), gaps bridged linearly
    and the envelope zero within ``SETTLE_S`` of them (see the module docstring: why the angle
    and not the rate, why not the accelerometer)."""
    grid, gyr, valid = on_grid(stream, stream.gyr, measurable(stream.gyr, "gyr"))
    dt = 1.0 / stream.rate_hz
    high = min(IMPACT_BAND_HZ[1], 0.4 / dt)
    if high <= 1.2 * IMPACT_BAND_HZ[0]:  # sampled too slowly to see the transients
        return Envelope(grid, np.zeros(len(grid)), CubicSpline(grid, np.zeros(len(grid))))
    sos = butter_sos(IMPACT_ORDER, (IMPACT_BAND_HZ[0], high), 1.0 / dt, "bandpass")
    band = sosfiltfilt(sos, np.cumsum(gyr, axis=0) * dt, axis=0)  # angle (rad), band
    low = butter_sos(4, IMPACT_ENVELOPE_HZ, 1.0 / dt)
    env = np.where(valid, sosfiltfilt(low, np.linalg.norm(band, axis=1)), 0.0)
    return Envelope(grid, env, CubicSpline(grid, env))


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
    values = spline(t[None, :] + lags[:, None])  # every grid lag in one call
    r = np.array([_correlation(x, row) for row in values])
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
    envelope_of: Callable[[SensorStream], Envelope] | None = None,
) -> ClockFit:
    """Offset and drift of ``sensor``'s clock against ``reference``'s from the transients
    both see at every heel strike (see the module docstring); any two sensors of the body.

    The lag that maximises the correlation of the two high-frequency energy envelopes
    (:func:`envelope`) over the middle ``IMPACT_SEARCH_S`` of the recording, then the lag of
    each ``BLOCK_S`` block with shared transients (within ``IMPACT_BLOCK_SEARCH_S`` of the line
    through the blocks nearer the middle), and a line through the block lags with a prior on
    the drift whose scatter gives the standard errors. ``residual`` is 1 − that middle's
    correlation coefficient; the status is ``"applied"`` only when
    the fit is reliable and differs from zero. ``envelope_of``: how a stream's
    :class:`Envelope` is had (default :func:`envelope`; the stage computes it once per sensor,
    :class:`~motionlab.clocksync.common.PerStream`).
    """
    name = (reference.label, sensor.label)
    t_mid = float(np.mean(reference.time[[0, -1]]))

    def refused(status: str, moving_s: float = 0.0) -> ClockFit:
        return ClockFit(*name, 0.0, 0.0, t_mid, np.inf, np.inf, np.nan, moving_s, status,
                        IMPACTS)  # fmt: skip

    if min(finite_samples(reference), finite_samples(sensor)) < MIN_SAMPLES:
        return refused("no usable accelerometer and gyroscope samples")
    a, b = (envelope_of or envelope)(reference), (envelope_of or envelope)(sensor)
    inside = (a.time - max_offset_s >= b.time[0]) & (a.time + max_offset_s <= b.time[-1])
    t_mid = float(0.5 * (a.time[0] + a.time[-1]))
    if inside.sum() < 3 * BLOCK_S / (a.time[1] - a.time[0]):
        return refused(f"{TOO_SHORT} ({3 * BLOCK_S:.0f} s needed)")
    t, x = a.time[inside], a.values[inside]
    dt = float(t[1] - t[0])
    # blocks of the recording in which the reference's envelope has transients: fewer than
    # three and no lag is searched (the lags below need three)
    active = x > IMPACT_ACTIVE * np.median(x[x > 0]) if np.any(x > 0) else np.zeros(len(x), bool)
    active_s = float(active.sum() * dt)
    n_blocks = int(len(t) * dt // BLOCK_S)
    blocks = [block for block in np.array_split(np.arange(len(t)), max(n_blocks, 1))
              if active[block].sum() * dt >= IMPACT_MIN_ACTIVE_S]  # fmt: skip
    too_few = "not reliable: too few heel strikes (or other shared transients)"
    if len(blocks) < 3:
        return refused(too_few, active_s)
    lags = np.arange(-max_offset_s, max_offset_s + 1e-12, dt)
    mid = np.abs(t - t_mid) <= 0.5 * IMPACT_SEARCH_S  # all of a recording up to 2 min
    tm, xm = t[mid], x[mid]
    r = np.array([_correlation(xm, np.interp(tm + c, b.time, b.values)) for c in lags])
    i = int(np.argmax(r))
    others = np.abs(lags - lags[i]) > IMPACT_PEAK_WIDTH_S
    second = float(r[others].max()) if others.any() else -1.0
    lag, corr, _ = _best_lag(tm, xm, b.spline, lags[max(i - 1, 0) : i + 2])
    rows, offsets = [], []
    search = np.arange(-IMPACT_BLOCK_SEARCH_S, IMPACT_BLOCK_SEARCH_S + 1e-12, dt)
    # from the middle outwards, each block searched about the line through the blocks timed so
    # far, so that the drift of a long recording is followed block by block
    for block in sorted(blocks, key=lambda k: abs(float(t[k].mean()) - t_mid)):
        centre = float(t[block].mean()) - t_mid
        expected = (
            lag
            if len(offsets) < 2
            else float(np.polyval(np.polyfit(np.array(rows)[:, 1], offsets, 1), centre))
        )
        c, r_block, ok = _best_lag(t[block], x[block], b.spline, expected + search)
        if ok and r_block >= IMPACT_MIN_CORRELATION:
            rows.append([1.0, centre])
            offsets.append(c)
    if len(offsets) < 3:
        return refused(too_few, active_s)
    order = np.argsort(np.array(rows)[:, 1])
    rows, offsets = [rows[k] for k in order], [offsets[k] for k in order]
    clock, offset_se, drift_se = _line(np.array(rows), np.array(offsets))
    ends = np.array([rows[0][1] - 0.5 * BLOCK_S, rows[-1][1] + 0.5 * BLOCK_S])  # - t_mid
    worst_se = float(np.hypot(offset_se, drift_se * 0.5 * (ends[1] - ends[0])))
    c_ends = np.abs(clock[0] + clock[1] * ends)
    if worst_se > IMPACT_MAX_SE_S:
        status = "not reliable: the heel-strike transients disagree between blocks"
    elif corr - second < IMPACT_MARGIN:
        status = (
            f"{REGULAR_STEPS} (correlation {corr:.3f} at the best lag, {second:.3f} at another)"
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
    return line_with_prior(x, y, np.ones(len(y)), s2)
