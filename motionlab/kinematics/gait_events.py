"""Gait events per side from the shank gyroscope, with a confidence per event, and strides kept or
rejected with the reason.

Input: the shank's sagittal angular velocity ``ω_z`` (rad/s, about the shank segment's z axis,
positive when the lower end swings forward, both sides) and, for turns, the vertical (earth z)
angular velocity of the shank or pelvis. Low-passed at 6 Hz (2nd-order Butterworth, zero phase).

- **Mid-swing**: the large positive peaks of ``ω_z`` (Aminian et al. 2002, J Biomech 35:689;
  Salarian et al. 2004, IEEE TBME 51:1434), at least half the median of the larger peaks and
  1 rad/s, 0.6 s apart.
- **Initial contact** (IC): the positive-to-negative zero crossing after mid-swing, where the
  shank stops swinging forward and turns over the planted foot (Behboodi et al. 2015, IEEE EMBC
  5529; as in :func:`motionlab.kinematics.cycles.gait_events`), linearly interpolated between
  samples. Trojaniello et al. (2014, J NeuroEng Rehabil 11:152) take the same crossing region for
  pathological gait; the impact dip (Aminian's IC) is not used because soft landings lack it.
- **Final contact** (FC, toe-off): the midpoint between the last local minimum of ``ω_z``
  before mid-swing (Aminian 2002; Salarian 2004's toe-off) and the first upward zero crossing
  of ``ω_z`` after it. The minimum is located on the signal low-passed at 15 Hz within ±40 ms of
  the 6 Hz one and refined by a parabola through its three samples (it is skewed: a slow fall,
  a steep rise; the 6 Hz filter alone moved it 5-12 ms earlier). Toe-off lies on that steep
  rise: the minimum is the shank's fastest backward rotation while the foot still pushes, the
  zero crossing is the shank already swinging forward with the foot off the floor. The minimum
  alone precedes toe-off: by 33-37 ms against the force plates on a real walk (Vicon
  ``walking2``, tibia clusters as a virtual gyroscope, ``bench/gait_real.py``), 40-60 ms against
  the kinematic (Zeni) toe-off, and the zero crossing follows it by 56-65 ms; the midpoint was
  the best of six features tried on that walk (minimum, zero crossing, midpoint, steepest rise,
  half the minimum's value, first peak of the vertical acceleration): +9/+16 ms against the
  two force-plate toe-offs, −14..+8 ms (median −3) against four Zeni toe-offs. Chosen on that
  walk (n = 2 + 4 events), it was then tested on the simulator as independent data
  (``bench/gait.py``). Without a zero crossing before mid-swing (``ω_z`` never negative), FC is
  the minimum itself. Published shank toe-off errors for comparison: mean differences up to
  75 ms (Catalfamo et al. 2010, Sensors 10:5683), 3.8 ± 28.7 ms (Greene et al. 2012, J Appl
  Biomech 28:349).

Data gaps (lost packets: Bluetooth IMUs such as the Xsens DOT or x-IMU3 drop runs of samples;
ingest keeps a gap longer than ``--gap-max`` as a jump of the time stamps, fills a shorter one
linearly and lists it in ``qc["filled_spans_s"]``; a short run of NaN may remain): the signal
is put on its regular time base first (the instants inside a jump added, every missing sample
interpolated linearly), so that the filters run in time, not across a jump as if its two sides
were neighbours. A gap up to :data:`BRIDGE_S` long (from the recorded sample before to the one
after) is bridged. Cut over the simulator's heel strikes and toe-offs and filled linearly
(typical sensors, 3 seeds, both legs, 5 positions of the gap, about 1000 cuts per length and
event, at 50, 60 and 100 Hz), a gap of 0.1 s moved IC by at most 9.8 ms (the detector's own
bound ``spatiotemporal.IC_ERROR_S`` is 10 ms; 14.7 ms at 0.11 s, 33 ms at 0.14 s), FC by 5 ms
in the median and 22 ms at the 95th percentile (its minimum may move to a neighbouring sample
with a gap of 0.04 s already). A longer gap (its samples, filled or missing) is no data: no
swing peak is taken within :data:`GAP_MARGIN_S` of it, an event only when the samples it is
found from lie that far clear of it (IC: from its swing peak to the zero crossing; FC: from the
minimum to the swing peak; beyond 0.04 s from a 0.3-s gap an IC moved by at most 1.9 ms, at
0.02 s by up to 8.3 ms, 100 Hz), and a stride that holds such a gap is rejected (``data gap``,
below). Before, a 0.18-s gap over a left heel strike of a simulated walk put that contact
0.13 s late and its step-time asymmetry read 4.3 % for a true 0.4 %
(``tests/test_gait_clocks.py``).

Confidence (0-1) of an event: how typical its stride's swing peak and the event's own feature
(the slope of ``ω_z`` at IC, the depth of the minimum at FC) are, each ``exp(-|ln(x / median)|)``
(1 for the median, 0.5 for half or twice it), multiplied.

Strides (IC to the next IC of the same side) are rejected, with the first reason that applies:
``data gap`` (a gap longer than :data:`BRIDGE_S` inside the stride: an event or part of its
movement is missing), ``duration`` (outside 0.6-2.5 s or more than 25 % from the median
stride), ``final contact`` (not exactly one FC inside), ``start/stop`` (a swing peak of the
stride or its neighbours below 80 % of the median: gait initiation, termination, a pause),
``turn`` (the heading changed by more than 20° over the stride), ``low confidence`` (an event
below 0.5). The thresholds are this module's constants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from motionlab.dsp import butter, find_peaks, sosfiltfilt
from motionlab.fusion.timegrid import gap_grid
from motionlab.timebase import find_gaps, joined_spans, nominal_interval, runs

LOWPASS_HZ = 6.0
FC_REFINE_HZ = 15.0
FC_REFINE_S = 0.04
SWING_MIN_RAD_S = 1.0
SWING_FRACTION = 0.5
MIN_STRIDE_S, MAX_STRIDE_S = 0.6, 2.5
STRIDE_TOLERANCE = 0.25
STEADY_FRACTION = 0.8
TURN_DEG = 20.0
MIN_CONFIDENCE = 0.5
#: the longest gap (s, from the recorded sample before to the one after) bridged by linear
#: interpolation as if the samples were there (module docstring: IC within 10 ms)
BRIDGE_S = 0.1
#: how far (s) the samples an event is found from must lie from a longer gap (module docstring)
GAP_MARGIN_S = 0.04
#: the reason of a stride rejected for a gap inside it
GAP_REASON = "data gap"


@dataclass
class SideEvents:
    """Events of one side: times (s) and confidences (0-1), the swing peaks (s, rad/s), and the
    gaps longer than :data:`BRIDGE_S` (``(G, 2)`` ``[start_s, end_s]``: no event is placed near
    them, a stride holding one is rejected)."""

    ic: np.ndarray
    ic_confidence: np.ndarray
    fc: np.ndarray
    fc_confidence: np.ndarray
    swing: np.ndarray
    swing_height: np.ndarray
    gaps: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass
class Strides:
    """Strides of one side: IC, FC inside, next IC (s), kept or the reason why not."""

    side: str
    ic: np.ndarray
    fc: np.ndarray
    next_ic: np.ndarray
    kept: np.ndarray
    reason: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.ic)


def _typical(x: np.ndarray, median: float) -> np.ndarray:
    x = np.maximum(np.asarray(x, dtype=float), 1e-9)
    return np.exp(-np.abs(np.log(x / max(median, 1e-9))))


def lowpass(x: np.ndarray, rate: float, cutoff: float = LOWPASS_HZ) -> np.ndarray:
    """Zero-phase 2nd-order Butterworth low-pass (cutoff in Hz, at most 0.4 × ``rate``)."""
    sos = butter(2, min(cutoff, 0.4 * rate), fs=rate)
    return sosfiltfilt(sos, x)


def data_gaps(
    time: np.ndarray, omega_z: np.ndarray, filled: np.ndarray | None = None
) -> np.ndarray:
    """``(G, 2)`` ``[start_s, end_s]`` of the gaps longer than :data:`BRIDGE_S`: the jumps of
    ``time`` (s) beyond 1.5 sampling intervals, the runs of non-finite ``omega_z`` (from the
    finite sample before to the one after) and the spans ingest ``filled`` (``(F, 2)``, s, on
    ``time``'s clock), those that touch joined."""
    t = np.asarray(time, dtype=float)
    if len(t) < 2:
        return np.zeros((0, 2))
    jump = find_gaps(t)
    spans = [np.column_stack((t[jump], t[jump + 1]))]
    bad = runs(~np.isfinite(np.asarray(omega_z, dtype=float)))
    spans.append(np.column_stack((t[np.maximum(bad[:, 0] - 1, 0)],
                                  t[np.minimum(bad[:, 1], len(t) - 1)])))  # fmt: skip
    if filled is not None:
        spans.append(np.asarray(filled, dtype=float).reshape(-1, 2))
    joined = joined_spans(np.vstack(spans))
    return joined[joined[:, 1] - joined[:, 0] > BRIDGE_S * (1 + 1e-9)]


def _regular(time: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``time`` with the instants missing inside each jump added
    (:func:`motionlab.fusion.timegrid.gap_grid`), ``x`` NaN there; unchanged without a jump."""
    grid = gap_grid(time, 1.0 / nominal_interval(time))
    if grid is None:
        return time, x
    out = np.full(len(grid.time), np.nan)
    out[grid.index] = x
    return grid.time, out


def _clear(a: float, b: float, gaps: np.ndarray) -> bool:
    """The span ``[a, b]`` (s) lies :data:`GAP_MARGIN_S` clear of every one of ``gaps``."""
    return not np.any((gaps[:, 0] < b + GAP_MARGIN_S) & (gaps[:, 1] > a - GAP_MARGIN_S))


def detect(time: np.ndarray, omega_z: np.ndarray, filled: np.ndarray | None = None) -> SideEvents:
    """IC and FC of one side from its shank's ``ω_z`` (rad/s) at ``time`` (s, sampled at one
    rate, with gaps: a jump of the stamps, NaN, or the spans ``filled`` by ingest, ``(F, 2)``
    ``[start_s, end_s]``); no event from a gap longer than :data:`BRIDGE_S` (module
    docstring)."""
    time = np.asarray(time, dtype=float)
    empty = np.zeros(0)
    omega_z = np.asarray(omega_z, dtype=float)
    ok = np.isfinite(omega_z)
    if len(time) < 2 or ok.sum() < 3:
        return SideEvents(empty, empty, empty, empty, empty, empty)
    gaps = data_gaps(time, omega_z, filled)
    time, omega_z = _regular(time, omega_z)
    ok = np.isfinite(omega_z)
    rate = 1.0 / float(np.median(np.diff(time)))
    if len(time) < int(2 * MIN_STRIDE_S * rate) + 3:
        return SideEvents(empty, empty, empty, empty, empty, empty, gaps)
    idx = np.arange(len(time))
    raw = np.interp(idx, idx[ok], omega_z[ok])
    w = lowpass(raw, rate)
    fine = lowpass(raw, rate, FC_REFINE_HZ)
    half = max(1, int(round(FC_REFINE_S * rate)))
    cand, props = find_peaks(w, height=SWING_MIN_RAD_S, distance=int(MIN_STRIDE_S * rate))
    heights = props["peak_heights"]
    measured = np.array([_clear(t, t, gaps) for t in time[cand]], dtype=bool)
    cand, heights = cand[measured], heights[measured]  # a peak in a gap is the interpolation's
    if len(cand) == 0:
        return SideEvents(empty, empty, empty, empty, empty, empty, gaps)
    top = np.sort(heights)[-max(1, len(cand) // 2) :]
    keep = heights >= SWING_FRACTION * np.median(top)
    swing, heights = cand[keep], heights[keep]
    stride = np.median(np.diff(swing)) if len(swing) > 1 else MAX_STRIDE_S * rate / 2
    reach = int(0.4 * min(stride, MAX_STRIDE_S * rate))
    minima = np.flatnonzero((w[1:-1] < w[:-2]) & (w[1:-1] <= w[2:])) + 1
    down = np.flatnonzero((w[:-1] >= 0) & (w[1:] < 0))
    ic, ic_slope, ic_peak, fc, fc_depth, fc_peak = [], [], [], [], [], []
    for p, h in zip(swing, heights, strict=True):
        after = down[(down > p) & (down <= p + reach)]
        if len(after) and _clear(time[p], time[after[0] + 1], gaps):
            k = after[0]
            frac = w[k] / (w[k] - w[k + 1])
            ic.append(time[k] + frac * (time[k + 1] - time[k]))
            ic_slope.append((w[k] - w[k + 1]) * rate)
            ic_peak.append(h)
        before = minima[(minima < p) & (minima >= p - reach)]
        if len(before):
            k0 = before[-1]
            lo, hi = max(1, k0 - half), min(len(w) - 2, k0 + half)
            k = lo + int(np.argmin(fine[lo : hi + 1]))
            den = fine[k - 1] - 2 * fine[k] + fine[k + 1]
            shift = 0.5 * (fine[k - 1] - fine[k + 1]) / den if den > 0 else 0.0
            t_min = time[k] + np.clip(shift, -0.5, 0.5) * (time[k + 1] - time[k - 1]) / 2
            if _clear(min(time[k - 1], time[k0]), time[p], gaps):
                fc.append(_toe_off(time, w, k0, p, t_min))
                fc_depth.append(h - w[k0])
                fc_peak.append(h)
    med_h = float(np.median(heights))
    ic_c = _typical(np.array(ic_slope), float(np.median(ic_slope)) if ic_slope else 1.0)
    fc_c = _typical(np.array(fc_depth), float(np.median(fc_depth)) if fc_depth else 1.0)
    return SideEvents(
        ic=np.array(ic),
        ic_confidence=ic_c * _typical(np.array(ic_peak), med_h),
        fc=np.array(fc),
        fc_confidence=fc_c * _typical(np.array(fc_peak), med_h),
        swing=time[swing],
        swing_height=heights,
        gaps=gaps,
    )


def _toe_off(time: np.ndarray, w: np.ndarray, k0: int, peak: int, t_min: float) -> float:
    """Final contact between the minimum of ``ω_z`` (sample ``k0``, refined time ``t_min``) and
    the swing peak (sample ``peak``): the midpoint of ``t_min`` and the first upward zero
    crossing of the 6 Hz ``ω_z`` after it; ``t_min`` itself when ``ω_z`` does not cross zero
    there (a shank that never turns backward)."""
    up = np.flatnonzero((w[k0:peak] < 0) & (w[k0 + 1 : peak + 1] >= 0))
    if w[k0] >= 0 or len(up) == 0:
        return float(t_min)
    k = k0 + int(up[0])
    zc = time[k] + w[k] / (w[k] - w[k + 1]) * (time[k + 1] - time[k])
    return float(0.5 * (t_min + zc))


def heading_change(time: np.ndarray, yaw_rate: np.ndarray, t0: float, t1: float,
                   ordered: bool = False) -> float:  # fmt: skip
    """Heading change (deg) between ``t0`` and ``t1`` from the vertical angular velocity (rad/s).

    ``ordered``: ``time`` is known to be non-decreasing, so the samples between are found by
    bisection (a stride's cost then does not grow with the recording's length); same result.
    """
    if ordered:
        if not t0 <= t1:
            return 0.0
        a, b = np.searchsorted(time, t0, side="left"), np.searchsorted(time, t1, side="right")
        if b - a < 2:
            return 0.0
        y, t = np.ascontiguousarray(yaw_rate[a:b]), np.ascontiguousarray(time[a:b])
        return float(np.degrees(np.trapezoid(y, t)))
    m = (time >= t0) & (time <= t1)
    if m.sum() < 2:
        return 0.0
    return float(np.degrees(np.trapezoid(yaw_rate[m], time[m])))


def strides(
    side: str,
    ev: SideEvents,
    yaw: tuple[np.ndarray, np.ndarray] | None = None,
    span: tuple[float, float] | None = None,
) -> Strides:
    """Strides of one side, kept or rejected (module docstring); ``yaw`` ``(time, rad/s)`` for
    turns; ``span`` ``(t0, t1)`` keeps strides inside a task."""
    ic = ev.ic if span is None else ev.ic[(ev.ic >= span[0]) & (ev.ic <= span[1])]
    a, b = ic[:-1], ic[1:]
    out = Strides(side, a, np.full(len(a), np.nan), b, np.zeros(len(a), bool), [])
    if len(a) == 0:
        return out
    med = float(np.median(b - a))
    med_h = float(np.median(ev.swing_height)) if len(ev.swing_height) else 1.0
    conf = {t: c for t, c in zip(ev.ic, ev.ic_confidence, strict=True)}
    ordered = yaw is not None and bool(np.all(np.diff(yaw[0]) >= 0))
    for k, (t0, t1) in enumerate(zip(a, b, strict=True)):
        inside = (ev.fc > t0) & (ev.fc < t1)
        near = (ev.swing > t0 - 0.6 * med) & (ev.swing < t1 + 0.6 * med)
        reason = ""
        if np.any((ev.gaps[:, 0] < t1) & (ev.gaps[:, 1] > t0)):
            reason = GAP_REASON
        elif not (MIN_STRIDE_S <= t1 - t0 <= MAX_STRIDE_S) or abs(t1 - t0 - med) > (
            STRIDE_TOLERANCE * med
        ):
            reason = "duration"
        elif inside.sum() != 1:
            reason = "final contact"
        elif near.any() and ev.swing_height[near].min() < STEADY_FRACTION * med_h:
            reason = "start/stop"
        elif yaw is not None and abs(heading_change(*yaw, t0, t1, ordered)) > TURN_DEG:
            reason = "turn"
        else:
            out.fc[k] = ev.fc[inside][0]
            c = min(conf.get(t0, 0.0), conf.get(t1, 0.0), float(ev.fc_confidence[inside][0]))
            if c < MIN_CONFIDENCE:
                reason = "low confidence"
        if inside.sum() == 1:
            out.fc[k] = ev.fc[inside][0]
        out.kept[k] = reason == ""
        out.reason.append(reason or "kept")
    return out
