"""Quality checks of one sensor stream, stored in ``SensorStream.qc`` and shown by ``info``.

All checks run on the stream as recorded (after the clock repair, before gap filling and
resampling), in SI units. ``qc["flags"]`` holds one boolean per finding:

==========================  ===============================================================
flag                        raised when
==========================  ===============================================================
``gaps``                    an interval longer than ``gap_max`` is kept as missing data
``dropped_samples``         any sample is missing (filled or not), from the time stamps
``dropped_packets``         the packet counter (``extra["packet_counter"]``) skips values
``clock_repaired``          duplicate rows dropped or an out-of-order stamp repaired
``irregular_sampling``      jitter (std of the sample interval) above 10 % of the interval
``acc/gyr/mag_saturated``   flat tops at the range: ≥ 3 identical extreme samples in a row
``gyr_looks_like_deg_s``    ‖ω‖ above 35 rad/s (beyond a ±2000 °/s range) for ≥ 5 samples
``gyr_unit_mismatch``       the gyroscope's rotation explains how the accelerometer sees
                            gravity turn only in the other unit (°/s read as rad/s, or the
                            reverse; :func:`gyr_scale`, ``qc["gyr_scale"]``): the ingest
                            refuses the file
``gyr_unit_doubt``          the same, weaker (4–10 times better rather than ≥ 10), or only
                            on the accelerometer's axes and not once the axes are free (the
                            gyroscope's axes are not the accelerometer's?): a warning
``gyr_unit_unchecked``      a gyroscope read as °/s that the tilt cannot tell from one in
                            rad/s (:func:`gyr_unit_unchecked`: a short or still recording,
                            never above 35 °/s): a warning
``acc_looks_like_g``        ‖a‖ at rest between 0.5 and 2 (a value in g, not m/s²)
``acc_norm_implausible``    ‖a‖ at rest neither ≈ 1 g (7.8–11.8 m/s²) nor in g
``mag_norm_out_of_range``   median ‖m‖ outside 20–70 µT (Earth's field); skipped when the
                            reader had to assume the field's scale (Xsens a.u.)
``nan_spans``               any channel has samples that are not numbers
``held_samples``            ≥ 20 % of the rows repeat the previous row exactly in every
                            channel: the device sent a slower stream at a faster rate (a
                            166.67 Hz file with two rows in three repeated is ≈ 50 Hz real);
                            ``qc["held_share"]`` and ``qc["effective_rate_hz"]`` say how much
``identical_stream``        the sensor's data equal another sensor's sample for sample
                            (``qc["identical_to"]``; set by :func:`mark_identical_streams`)
``rate_assumed``            the reader had to assume the sampling rate (e.g. an Xsens export
                            without 'Update Rate'); times rest on that assumption
``mag_scale_assumed``       the magnetometer's scale was assumed (arbitrary units)
``header_rate_mismatch``    the rate from the time stamps is more than 10 % from the one the
                            file's header states (``attrs["nominal_rate_hz"]``: DOT
                            ``OutputRate``, APDM): a time column in another unit
``non_finite``              any channel holds NaN or ±inf (``qc["non_finite_share"]``: the
                            share of samples per channel)
``implausible_values``      any sample beyond what a sensor measures (``IMPLAUSIBLE``: e.g.
                            a 1e308 spike, or ±inf, which 1e308 g becomes in m/s²;
                            ``qc["implausible_share"]`` per channel)
==========================  ===============================================================
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np

from motionlab.session import SENSOR_CHANNELS, SensorStream
from motionlab.timebase import runs
from motionlab.units import STANDARD_GRAVITY

#: thresholds below which an extreme value is not a sensor range (smallest common ranges)
SATURATION_MIN = {"acc": 2 * STANDARD_GRAVITY, "gyr": 4.0, "mag": 100.0}
SATURATION_RUN = 3
GYR_MAX_PLAUSIBLE = 35.0  # rad/s: ±2000 °/s, the largest common gyroscope range
GYR_SUSTAINED = 5  # samples
MAG_RANGE_UT = (20.0, 70.0)
ACC_REST_RANGE = (7.8, 11.8)  # m/s²
#: ‖a‖ at rest outside this (and not in g) is no accelerometer on Earth in m/s²: refused
ACC_REST_REFUSE = (3.0, 50.0)  # m/s²
#: ‖a‖'s interquartile range / median over the samples the gyroscope calls still, above which
#: the accelerometer is not measuring gravity there (real recordings ≤ 0.018, simulated
#: ≤ 0.057; accelerometer and gyroscope columns swapped: 1.1-4.1): refused …
ACC_REST_SPREAD_MAX = 0.5
STILL_S = 0.5  # s: … over the runs of still samples at least this long
JITTER_LIMIT = 0.1  # relative to the nominal interval
REST_GYR = 0.2  # rad/s: below this the sensor is taken to be at rest
HELD_SHARE = 0.2  # share of rows repeating the previous one above which samples are "held"
HEADER_RATE_TOLERANCE = 0.1  # relative: time stamps and the header's stated rate disagree
#: the gyroscope's scale against the accelerometer's tilt (:func:`gyr_scale`)
SCALE_BLOCK_S = 0.25  # s: the accelerometer's direction is averaged over blocks this long
SCALE_ACC_TOL = 0.2  # samples with ‖a‖ within 20 % of its median: gravity dominates
SCALE_REFUSE = 10.0  # the other unit explains the tilt this many times better: refused
SCALE_DOUBT = 4.0  # … this many times better: a warning
SCALE_MISS_DEG = 5.0  # °: and the unit as read misses the tilt by this much per window (RMS)
#: the gyroscope's turn against the tilt the accelerometer sees: a sensor cannot tilt further
#: than it turns (real recordings: 1.0-4.1 times as far; a rad/s gyroscope read as °/s: 0.02-0.07)
SCALE_TURN_MIN = 0.25  # ∫‖ω‖dt / tilt below this: the gyroscope is far too small, refused …
SCALE_TURN_TILT_DEG = 90.0  # … when the tilt seen over the windows adds up to at least this, …
#: … or when the block pairs in which gravity turned by at least SCALE_PAIR_MOVED_DEG each (a
#: movement, not the accelerometer's noise, which adds up over a long still recording: 0.43° a
#: pair on APDM's still sensor) add up to this much (3-s excerpts of real recordings with it:
#: ``turn_ratio`` 0.58 or more as read, 0.11 or less divided by 57.3)
SCALE_TURN_MOVED_DEG = 30.0
SCALE_PAIR_MOVED_DEG = 1.0
#: rad/s explains the tilt this many times worse (squared residual) than the unit as read, or
#: worse: a gyroscope read as °/s is not one in rad/s (2- to 5-s excerpts of real recordings
#: divided by 57.3: 0.024 at the least)
SCALE_EXCLUDE = 0.01
DEG = math.pi / 180.0  # rad/s per °/s
#: magnitudes no sensor reports (per axis; m/s², rad/s, µT, 1): beyond them a value is damage,
#: not motion; the vendor's free acceleration (``extra["free_acc"]``, gravity removed) like the
#: accelerometer's
IMPLAUSIBLE = {"acc": 1e4, "gyr": 1e3, "mag": 1e5, "quat": 10.0, "free_acc": 1e4}


def damage_checked(stream: SensorStream) -> dict[str, np.ndarray]:
    """The arrays checked for values no sensor gives: the sensor channels present and the
    vendor's extras with a known range (:data:`IMPLAUSIBLE`), by name."""
    out = {ch: getattr(stream, ch) for ch in stream.channels}
    out.update({k: v for k, v in stream.extra.items() if k in IMPLAUSIBLE and v is not None})
    return out


def measurable(samples: np.ndarray, channel: str) -> np.ndarray:
    """(N,) bool: the samples (N, ...) of ``channel`` that are finite and within what a sensor
    measures (:data:`IMPLAUSIBLE`); a 1e300 spike is as unusable as a NaN."""
    a = np.asarray(samples, dtype=float).reshape(len(samples), -1)
    with np.errstate(invalid="ignore"):
        return (np.isfinite(a) & (np.abs(a) <= IMPLAUSIBLE[channel])).all(axis=1)


def saturated_samples(values: np.ndarray, minimum: float) -> int:
    """Samples in flat tops: runs of ≥ 3 identical values at an axis' extreme (≥ ``minimum``)."""
    count = 0
    for x in np.atleast_2d(values.T):
        if not len(x):
            continue
        high, low = np.fmax.reduce(x), np.fmin.reduce(x)  # NaN ignored, no copy
        if not (np.isfinite(high) and np.isfinite(low)):  # all NaN, or an infinite value
            finite = x[np.isfinite(x)]
            if not len(finite):
                continue
            high, low = finite.max(), finite.min()
        for extreme in (high, low):
            if abs(extreme) < minimum:
                continue
            start, end = runs(x == extreme).T
            length = end - start
            count += int(length[length >= SATURATION_RUN].sum())
    return count


def nan_spans(time: np.ndarray, values: np.ndarray) -> list[list[float]]:
    """``[start_s, end_s]`` of every run of samples with a NaN in any axis."""
    bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
    if not bad.any():
        return []
    start, end = runs(bad).T
    return [[float(time[a]), float(time[b - 1])] for a, b in zip(start, end, strict=True)]


def _median(x: np.ndarray) -> float:
    """``np.nanmedian`` without its copy when there is no NaN."""
    return float(np.nanmedian(x) if np.isnan(x).any() else np.median(x))


def _norm(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def dropped_packets(counter: np.ndarray) -> int:
    """Packets missing from a counter that steps by one and may wrap at 2¹⁶ or 2³²."""
    c = np.asarray(counter, dtype=np.int64)
    if len(c) < 2:
        return 0
    modulus = np.int64(1) << (16 if c.max() < 65536 else 32)
    step = np.diff(c) % modulus
    return int(np.clip(step - 1, 0, None).sum())


def held_rows(stream: SensorStream) -> int:
    """Rows (after the first) equal to the previous row in every channel, bit for bit (a row
    with a NaN never counts): samples a device held and sent again."""
    arrays = [getattr(stream, ch) for ch in SENSOR_CHANNELS if getattr(stream, ch) is not None]
    n = len(stream.time)
    if not arrays or n < 3:
        return 0
    same = np.ones(n - 1, dtype=bool)
    for a in arrays:
        a = np.asarray(a).reshape(n, -1)
        same &= np.all(a[1:] == a[:-1], axis=1)
    return int(same.sum())


def mark_identical_streams(sensors: dict[str, SensorStream]) -> dict[str, list[str]]:
    """Flag sensors whose channels are identical, sample for sample, to another sensor's (the
    same file given twice, or a channel map pointing two sensors at the same columns): sets
    ``qc["identical_to"]`` and ``qc["flags"]["identical_stream"]``; returns label → others."""
    groups: dict[str, list[str]] = {}
    for label, s in sensors.items():
        if not s.channels:
            continue
        h = hashlib.sha256(",".join(s.channels).encode())
        for ch in s.channels:
            h.update(np.ascontiguousarray(getattr(s, ch), dtype=float).tobytes())
        groups.setdefault(h.hexdigest(), []).append(label)
    out = {}
    for labels in groups.values():
        for label in labels if len(labels) > 1 else []:
            others = [k for k in labels if k != label]
            out[label] = others
            qc = sensors[label].qc
            qc["identical_to"] = others
            qc.setdefault("flags", {})["identical_stream"] = True
    return out


def _skew(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3): the matrices ``[v]×`` of the rows of ``v`` (``[v]× x = v × x``)."""
    zero = np.zeros(len(v))
    return np.stack((np.column_stack((zero, -v[:, 2], v[:, 1])),
                     np.column_stack((v[:, 2], zero, -v[:, 0])),
                     np.column_stack((-v[:, 1], v[:, 0], zero))), axis=1)  # fmt: skip


def gyr_scale(time: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> dict[str, Any] | None:
    """The scale of the gyroscope that best explains how the accelerometer sees gravity turn.

    A sensor that moves slowly sees gravity (the direction ``u = a/‖a‖``) turn in its frame as
    ``du/dt = −ω × u = u × ω``. A gyroscope read in the wrong unit gives ``ω/s`` (``s = π/180``:
    °/s read as rad/s; ``s = 180/π``: rad/s read as °/s), so
    ``u(t) − u(0) = s ∫ u × ω_read dt + β × ∫ u dt`` (``β``: the bias, rad/s), linear in
    ``(s, β)``. Samples whose ‖a‖ is within :data:`SCALE_ACC_TOL` of its median are integrated
    (gaps up to 0.1 s bridged); the relation is averaged over :data:`SCALE_BLOCK_S` blocks (a
    low-pass) and differenced between neighbouring blocks free of faster movement, and fitted by
    least squares. Its residual with ``s`` held at 1, π/180, 180/π and 0 (``β`` refitted) says
    how well each unit explains the tilt. The same fit with a free 3×3 map ``M`` in place of
    ``s·I`` gives a scale that does not assume the two sensors' axes agree (the middle singular
    value of ``M``): a column map that gives the accelerometer's axes in another order turns
    the first scale towards 0, not this one.

    Returns ``scale`` (the best ``s``: 1 for a gyroscope in the unit it was read in),
    ``axes_free_scale``, ``miss_deg`` (RMS residual per block pair, °, with ``s`` at
    ``as_read`` 1, ``deg_s`` π/180, ``rad_s`` 180/π, ``none`` 0), ``deg_s_fit`` and
    ``rad_s_fit`` (how many times smaller the squared residual is in that unit than as read),
    ``tilt_deg`` (the turn of gravity seen, summed over the block pairs, °), ``turn_ratio``
    (the gyroscope's turn ``∫‖ω‖dt`` over the same spans, as read, per unit of that tilt: at
    least about 1 for a gyroscope in its unit, as a sensor cannot tilt further than it turns),
    ``moving_tilt_deg`` (the tilt of the block pairs in which gravity turned by at least
    :data:`SCALE_PAIR_MOVED_DEG`, a movement rather than the accelerometer's noise) and
    ``windows`` (block pairs used); ``None`` with fewer than 4 pairs. A sensor that barely
    tilts gives fits near 1 both ways: no evidence. Linear acceleration (a swinging limb) makes
    ``scale`` noisy, not near π/180.
    """
    t = np.asarray(time, dtype=float)
    a = np.asarray(acc, dtype=float).reshape(len(t), 3)
    w = np.asarray(gyr, dtype=float).reshape(len(t), 3)
    n = len(t)
    dt = np.diff(t)
    nominal = float(np.median(dt)) if n >= 8 else 0.0
    if not nominal > 0:
        return None
    norm = _norm(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = a / norm[:, None]
        slow = np.abs(norm / _median(norm) - 1.0) < SCALE_ACC_TOL
    good = slow & np.isfinite(u).all(axis=1) & measurable(w, "gyr")
    bridge = max(1.5 * nominal, min(0.1, 5.0 * nominal))  # s: a dropped sample or two
    ok = good[1:] & good[:-1] & (dt > 0) & (dt <= bridge)
    u = np.where(good[:, None], u, 0.0)
    um = np.where(ok[:, None], 0.5 * (u[1:] + u[:-1]), 0.0) * dt[:, None]
    wm = np.where(ok[:, None], 0.5 * (w[1:] + w[:-1]), 0.0)
    turn = _norm(wm) * dt  # rad per interval
    m = max(2, round(SCALE_BLOCK_S / nominal))
    k = n // m
    if k < 5:
        return None

    def blocks(x: np.ndarray) -> np.ndarray:
        return x[: k * m].reshape(k, m, -1)

    # block j holds samples j·m … j·m+m-1 and the intervals that start there; the pair (j, j+1)
    # spans its intervals j·m … j·m+2m-2
    bad = blocks(np.append(~ok, True)).any(axis=(1, 2))
    use = ~(bad[:-1] | bad[1:])
    y = np.diff(blocks(u).mean(axis=1), axis=0)[use]
    if len(y) < 4:
        return None

    # per pair, ∫ x dt from block j's mean time to block j+1's = the difference of the block
    # means of the running integral: a triangle over the intervals of both blocks; x = u ω_jᵀ
    # (row-major, for the map M) and u (for the bias), per interval, already × dt
    x = np.column_stack(((um[:, :, None] * wm[:, None, :]).reshape(n - 1, 9), um))
    xb = blocks(np.vstack((x, np.zeros((1, 12)))))
    rise = np.arange(1, m + 1) / m
    pair = (np.einsum("kmc,m->kc", xb[:-1], rise) + np.einsum("kmc,m->kc", xb[1:], 1 - rise))[use]
    tb = blocks(np.append(turn, 0.0)[:, None])[:, :, 0]
    turned = float((tb[:-1] @ rise + tb[1:] @ (1 - rise))[use].sum())  # over the same spans
    # u × (M ω) = [u]× M ω: linear in the 9 entries of M (row-major, index 3·row + column)
    uw = pair[:, :9].reshape(-1, 3, 3)
    c9 = np.stack([_skew(uw[:, :, j]) for j in range(3)], axis=3).reshape(-1, 3, 9)
    bias = -_skew(pair[:, 9:])  # β × v = −[v]× β
    yy = float(np.einsum("ki,ki->", y, y))

    def fit(design: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.einsum("kij,kil->jl", design, design), np.einsum("kij,ki->j", design, y)

    normal, rhs = fit(np.concatenate((c9[:, :, [0, 4, 8]].sum(axis=2)[:, :, None], bias), axis=2))

    def rss(s: float) -> float:
        """Squared residual with the scale held at ``s`` and the bias refitted."""
        r = rhs[1:] - s * normal[1:, 0]
        beta = np.linalg.lstsq(normal[1:, 1:], r, rcond=1e-12)[0]
        return max(yy - 2.0 * s * rhs[0] + s * s * normal[0, 0] - float(r @ beta), 1e-300)

    best = float(np.linalg.lstsq(normal, rhs, rcond=1e-12)[0][0])
    free = np.linalg.lstsq(*fit(np.concatenate((c9, bias), axis=2)), rcond=1e-12)[0]
    units = {"as_read": 1.0, "deg_s": DEG, "rad_s": 1.0 / DEG, "none": 0.0}
    miss = {key: math.degrees(math.sqrt(rss(s) / len(y))) for key, s in units.items()}
    tilts = _norm(y)
    moved = tilts >= math.radians(SCALE_PAIR_MOVED_DEG)
    return {
        "scale": best,
        "axes_free_scale": float(np.linalg.svd(free[:9].reshape(3, 3), compute_uv=False)[1]),
        "deg_s_fit": (miss["as_read"] / miss["deg_s"]) ** 2,
        "rad_s_fit": (miss["as_read"] / miss["rad_s"]) ** 2,
        "miss_deg": miss,
        "tilt_deg": math.degrees(float(tilts.sum())),
        "turn_ratio": turned / max(float(tilts.sum()), 1e-12),
        "moving_tilt_deg": math.degrees(float(tilts[moved].sum())),
        "windows": len(y),
    }


def gyr_unit_finding(found: dict[str, Any] | None) -> str:
    """The verdict on :func:`gyr_scale`'s ``found``: ``"deg_s"`` (a °/s gyroscope read as
    rad/s: refused), ``"rad_s"`` (rad/s read as °/s: refused), ``"deg_s?"`` / ``"rad_s?"``
    (a doubt: warned), ``"axes?"`` (the other unit fits on the accelerometer's axes, but not
    once the axes are free: the two sensors' axes differ, warned) or ``""``.

    A verdict needs the other unit to explain the tilt :data:`SCALE_REFUSE`
    (:data:`SCALE_DOUBT`) times better than the unit as read and, to refuse, the axes-free
    scale on the same side of the geometric middle (√(π/180) ≈ 0.13, or √(180/π) ≈ 7.6). For
    °/s, the unit as read must also miss the tilt by at least :data:`SCALE_MISS_DEG` per block
    pair (RMS): a still sensor whose bias drifts by 1°/s over 5 minutes is explained 4.5 times
    better by π/180 (it claims less), but misses by 0.1°. Before that, a gyroscope that turned
    far less than the accelerometer saw gravity tilt (``turn_ratio`` under
    :data:`SCALE_TURN_MIN` over :data:`SCALE_TURN_TILT_DEG` of tilt, or over
    :data:`SCALE_TURN_MOVED_DEG` of it in block pairs that moved) is ``"rad_s"``: a sensor
    cannot tilt further than it turns, and the fit alone missed most such gyroscopes (a moving
    limb's acceleration leaves every unit a large residual: 53 of 76 real sensors divided by
    57.3 passed it, ``bench/gyr_units.py``)."""
    if not found:
        return ""
    if _turns_too_little(found):
        return "rad_s"
    fit, unit = max((found["deg_s_fit"], "deg_s"), (found["rad_s_fit"], "rad_s"))
    if fit < SCALE_DOUBT or (unit == "deg_s" and found["miss_deg"]["as_read"] < SCALE_MISS_DEG):
        return ""
    free = found["axes_free_scale"]
    agrees = free < math.sqrt(DEG) if unit == "deg_s" else free > 1.0 / math.sqrt(DEG)
    if not agrees:
        return "axes?"
    return unit if fit >= SCALE_REFUSE else f"{unit}?"


def _turns_too_little(found: dict[str, Any]) -> bool:
    """The gyroscope turned less than :data:`SCALE_TURN_MIN` times as far as the accelerometer
    saw gravity tilt, over at least :data:`SCALE_TURN_TILT_DEG` of tilt or
    :data:`SCALE_TURN_MOVED_DEG` of it in block pairs that moved: a 3-s excerpt's tilt rarely
    adds up to 90°, and noise, which adds up over a long still recording, is not counted there
    (``turn_ratio`` and ``moving_tilt_deg`` are missing from checks stored before they
    existed)."""
    ratio = found.get("turn_ratio", np.inf)
    enough = (found["tilt_deg"] >= SCALE_TURN_TILT_DEG
              or found.get("moving_tilt_deg", 0.0) >= SCALE_TURN_MOVED_DEG)  # fmt: skip
    return enough and ratio < SCALE_TURN_MIN


def sustained_peak(w: np.ndarray) -> float:
    """The largest value ``w`` (N,) reaches for :data:`GYR_SUSTAINED` samples in a row (NaN
    ignored; 0 when it has fewer samples): a peak that one damaged sample does not make."""
    if len(w) < GYR_SUSTAINED:
        return 0.0
    lows = np.lib.stride_tricks.sliding_window_view(w, GYR_SUSTAINED).min(axis=1)
    lows = lows[np.isfinite(lows)]
    return float(lows.max()) if len(lows) else 0.0


def gyr_unit_unchecked(found: dict[str, Any] | None, peak: float) -> bool:
    """Whether a gyroscope read as °/s, which :func:`gyr_unit_finding` found nothing wrong
    with (``found``: :func:`gyr_scale`'s, or ``None``), could as well be in rad/s, and it would
    matter. Its rate as read (``peak``, rad/s: :func:`sustained_peak` of ‖ω‖) stays at or
    below 35 °/s, which a gyroscope in rad/s of a ±2000 °/s range read as °/s gives, and the
    accelerometer's tilt does not exclude rad/s (:data:`SCALE_EXCLUDE`) or could not be
    compared (too few slow stretches: a short or vigorous recording), so nothing in the
    recording tells the two units apart: a short recording (its slow tilt does not add up to
    :data:`SCALE_TURN_MOVED_DEG`), a still one, or one turning only about the vertical. Unless
    the sensor is at rest in either unit (``peak`` at most :data:`REST_GYR` in rad/s were the
    values rad/s: 0.2 °/s as read; a gyroscope that reads zeros): its unit then changes nothing
    (real 3-s excerpts at rest turned 1.6° in the median, at most 14.5°)."""
    if gyr_unit_finding(found) or peak > GYR_MAX_PLAUSIBLE * DEG or peak <= REST_GYR * DEG:
        return False
    return found is None or found["rad_s_fit"] > SCALE_EXCLUDE


def _still(rest: np.ndarray | None, t: np.ndarray) -> np.ndarray | None:
    """The samples of ``rest`` (the gyroscope below :data:`REST_GYR`) in runs of at least
    :data:`STILL_S`: a sensor held still, not a limb's rate passing through zero (a running
    shank's stance, where ‖a‖ still carries the impact)."""
    if rest is None or len(t) < 2:
        return None
    still = np.zeros(len(rest), bool)
    for a, b in runs(rest):
        if t[b - 1] - t[a] >= STILL_S:
            still[a:b] = True
    return still


def acc_unit_problem(stream: SensorStream) -> tuple[str, str] | None:
    """``(what, remedy)`` for one line when the accelerometer's ‖a‖ at rest (``qc
    ["acc_rest_norm"]``) cannot be gravity in m/s²: in g (0.5-2) or outside
    :data:`ACC_REST_REFUSE` (a g value read as m/s² scaled again, mg, …); the ingest refuses
    it. ``None`` otherwise (between that and :data:`ACC_REST_RANGE` :func:`doubts` warns)."""
    flags = stream.qc.get("flags", {})
    g = stream.qc.get("acc_rest_norm", float("nan"))
    read = stream.source_units.get("acc", "m/s^2")
    if g == 0.0:  # zeros: a channel off or not recorded, whatever its unit
        return ("|a| at rest is 0: the accelerometer reads zeros, it was off or not recorded",
                "record with the accelerometer on, or export its channel again")  # fmt: skip
    if flags.get("acc_looks_like_g") and read != "g":
        return (f"|a| at rest is {g:.2f} m/s² (read as {read}), where 1 g is 9.81: the "
                "accelerometer is in g",
                "check the export's accelerometer unit (for a file read by a column "
                "map, acc: {unit: g} says it; a vendor's export: export it again)")  # fmt: skip
    beyond = np.isfinite(g) and not ACC_REST_REFUSE[0] <= g <= ACC_REST_REFUSE[1]
    lo, hi = (STANDARD_GRAVITY * v for v in ACC_REST_RANGE)
    steady = stream.qc.get("acc_rest_spread", 0.0) <= ACC_REST_SPREAD_MAX  # not swapped
    if read == "g" and lo <= g <= hi and steady:  # 9.81 m/s² read as g: 96 "m/s²"
        return (f"|a| at rest is {g:.3g} m/s² (read as g), 9.81 times gravity: the "
                "accelerometer is in m/s², read as g",
                "check the export's accelerometer unit (for a file read by a column "
                "map, acc: {unit: m/s^2} says it; a vendor's export: export it again)")  # fmt: skip
    if (flags.get("acc_looks_like_g") or beyond) and read == "g":
        return (f"|a| at rest is {g:.3g} m/s² (read as g), not ≈ 9.81: the accelerometer does "
                "not measure gravity — are its columns another channel's (the gyroscope's)?",
                "check the export's columns and units")  # fmt: skip
    if beyond:
        return (f"|a| at rest is {g:.3g} m/s² (read as {read}), not ≈ 9.81: a wrong unit or "
                "scale",
                "check the export's accelerometer unit (for a file read by a column "
                "map, acc: {unit: m/s^2} or g says it; a vendor's export: export it "
                "again)")  # fmt: skip
    return None


def swapped_problem(stream: SensorStream) -> tuple[str, str] | None:
    """``(what, remedy)`` when the accelerometer's ‖a‖ varies where the gyroscope reads the
    sensor still (``qc["acc_rest_spread"]`` above :data:`ACC_REST_SPREAD_MAX`): the two
    channels swapped (the ingest refuses it, after the units' checks, whose findings say
    more); else ``None``."""
    spread = stream.qc.get("acc_rest_spread", 0.0)
    if spread <= ACC_REST_SPREAD_MAX:
        return None
    return (f"|a| varies by {100 * spread:.0f} % (interquartile range) where the gyroscope "
            "reads the sensor still: the accelerometer does not measure gravity there — are "
            "the accelerometer and gyroscope columns swapped?",
            "check the export's columns (a column map names them as acc: {columns: [...]} "
            "and gyr: {columns: [...]})")  # fmt: skip


def gyr_unit_problem(stream: SensorStream) -> tuple[str, str] | None:
    """What :func:`gyr_unit_finding` found in ``stream.qc["gyr_scale"]`` as ``(what, remedy)``
    for one line (the ingest refuses ``deg_s``/``rad_s`` with it, ``doubts`` warns the rest), or
    ``None``."""
    found = stream.qc.get("gyr_scale")
    finding = gyr_unit_finding(found)
    if not finding:
        return None
    read = stream.source_units.get("gyr", "rad/s")
    miss, free = found["miss_deg"], found["axes_free_scale"]
    window = f"{2 * SCALE_BLOCK_S:g} s"
    if finding == "axes?":
        return (f"the gyroscope (read as {read}) does not turn with the tilt the accelerometer "
                f"sees (missed by {miss['as_read']:.0f}° per {window}, RMS; best scale "
                f"{found['scale']:.3g} on the same axes, {free:.3g} with the axes free): its "
                "unit, or axes that are not the accelerometer's?",
                "check the export's gyroscope unit and that its x, y, z are the "
                "accelerometer's")  # fmt: skip
    unit = finding.rstrip("?")
    other = {"deg_s": "°/s", "rad_s": "rad/s"}[unit]
    how = f"{1 / free:.3g}× more" if unit == "deg_s" else f"{free:.3g}× less"
    if unit == "rad_s" and _turns_too_little(found):
        how = f"{1 / max(found['turn_ratio'], 1e-9):.3g}× less"
    says = {"deg_s": "deg/s", "rad_s": "rad/s"}[unit]
    misses = (f"it misses the tilt by {miss['as_read']:.0f}° per {window} (RMS), by "
              f"{miss[unit]:.1f}° scaled by 57.3")  # fmt: skip
    if _unit_is(read, unit):  # read in the unit the scale points to: scaled twice, not mislabelled
        return (f"the gyroscope (read as {read}) turns {how} than the tilt the accelerometer "
                f"sees, and 57.3× is the step between rad/s and °/s: {misses}: were its values "
                "converted between °/s and rad/s twice, or not at all?",
                f"check the gyroscope's values against its unit ({read})")  # fmt: skip
    return (f"the gyroscope (read as {read}) turns {how} than the tilt the accelerometer sees "
            f"(a gyroscope in {other} read as {read.replace('deg/s', '°/s')} turns 57.3×): it "
            f"misses the tilt by {miss['as_read']:.0f}° per {window} (RMS), by "
            f"{miss[unit]:.1f}° in {other}: is it in {other}?",
            f"check the export's gyroscope unit (for a file read by a column map, "
            f"gyr: {{unit: {says}}} says it; a vendor's export: export it again)")  # fmt: skip


def unchecked_line(stream: SensorStream) -> str:
    """The warning of ``qc["flags"]["gyr_unit_unchecked"]`` (:func:`gyr_unit_unchecked`): the
    file (``qc["gyr_unit_source"]``, set by the ingest), why the recording cannot tell, the
    remedy."""
    qc = stream.qc
    found = qc.get("gyr_scale")
    peak = math.degrees(qc.get("gyr_sustained_peak_rad_s", 0.0))
    where = qc.get("gyr_unit_source") or "the recording"
    if found is None:
        why = "too few slow stretches to compare with the accelerometer's tilt"
    else:
        why = (f"the accelerometer saw gravity tilt by {found['tilt_deg']:.0f}° in its slow "
               "stretches, too little to compare")  # fmt: skip
    return (f"{where}: the gyroscope's unit cannot be checked in {qc.get('duration_s', 0.0):.3g} "
            f"s: read as {stream.source_units.get('gyr', '°/s')}, it never turns faster than "
            f"{peak:.3g} °/s, as rad/s values read as °/s (57.3× too small) could, and {why} — "
            "check the export's gyroscope unit")  # fmt: skip


def _unit_is(read: str, unit: str) -> bool:
    """Whether the gyroscope unit ``read`` (as a reader or column map wrote it) is ``unit``
    (``deg_s`` or ``rad_s``)."""
    degrees = read.strip().lower().replace("°", "deg") in ("deg/s", "dps", "deg s^-1")
    return degrees == (unit == "deg_s")


def check_stream(stream: SensorStream, gap_max: float) -> dict[str, Any]:
    """Rate, jitter, saturation, unit plausibility and NaN spans of ``stream`` (see module)."""
    t = np.asarray(stream.time, dtype=float)
    dt = np.diff(t)
    nominal = float(np.median(dt)) if len(dt) else float("nan")
    regular = dt[dt <= 1.5 * nominal] if len(dt) else dt
    jitter = float(np.std(regular)) if len(regular) else float("nan")
    qc: dict[str, Any] = {
        "rate_hz": 1.0 / nominal if nominal > 0 else float("nan"),
        "jitter_ms": 1e3 * jitter,
        "n_samples_recorded": int(len(t)),
        "duration_s": float(t[-1] - t[0]) if len(t) else 0.0,
        "gap_max_s": float(gap_max),
    }
    flags = {"irregular_sampling": bool(jitter > JITTER_LIMIT * nominal)}
    stated = stream.attrs.get("nominal_rate_hz")
    if stated and np.isfinite(qc["rate_hz"]):  # a time column read in the wrong unit
        qc["header_rate_hz"] = float(stated)
        off = abs(qc["rate_hz"] / float(stated) - 1.0) > HEADER_RATE_TOLERANCE
        flags["header_rate_mismatch"] = bool(off)

    qc["saturated_samples"] = {}
    spans: dict[str, list] = {}
    for ch in SENSOR_CHANNELS:
        a = getattr(stream, ch)
        if a is None:
            continue
        if ch in SATURATION_MIN:
            n = saturated_samples(a, SATURATION_MIN[ch])
            qc["saturated_samples"][ch] = n
            flags[f"{ch}_saturated"] = n > 0
        s = nan_spans(t, a)
        if s:
            spans[ch] = s
    qc["nan_spans"] = spans
    flags["nan_spans"] = bool(spans)
    qc["non_finite_share"], qc["implausible_share"] = {}, {}
    for ch, a in damage_checked(stream).items():
        if not len(a):
            continue
        a = np.asarray(a, dtype=float).reshape(len(a), -1)
        finite = np.isfinite(a)
        bad = ~finite.all(axis=1)
        if bad.any():
            qc["non_finite_share"][ch] = float(bad.mean())
        with np.errstate(invalid="ignore"):
            wild = (np.isinf(a) | (finite & (np.abs(a) > IMPLAUSIBLE[ch]))).any(axis=1)
        if wild.any():
            qc["implausible_share"][ch] = float(wild.mean())
    flags["non_finite"] = bool(qc["non_finite_share"])
    flags["implausible_values"] = bool(qc["implausible_share"])

    rest = None
    if stream.gyr is not None:
        w = _norm(stream.gyr)
        qc["gyr_max_rad_s"] = float(np.nanmax(w))
        start, end = runs(w > GYR_MAX_PLAUSIBLE).T
        flags["gyr_looks_like_deg_s"] = bool(np.any(end - start >= GYR_SUSTAINED))
        rest = w < REST_GYR
        scale = gyr_scale(t, stream.acc, stream.gyr) if stream.acc is not None else None
        if scale is not None:
            qc["gyr_scale"] = scale
            finding = gyr_unit_finding(scale)
            flags["gyr_unit_mismatch"] = finding in ("deg_s", "rad_s")
            flags["gyr_unit_doubt"] = finding.endswith("?")
        if stream.acc is not None and _unit_is(stream.source_units.get("gyr", "rad/s"), "deg_s"):
            qc["gyr_sustained_peak_rad_s"] = peak = sustained_peak(w)
            flags["gyr_unit_unchecked"] = gyr_unit_unchecked(scale, peak)
    if stream.acc is not None:  # the norm at rest of rows a sensor can give: 1e308 is damage
        a = np.where(measurable(stream.acc, "acc"), _norm(stream.acc), np.nan)
        use = rest if rest is not None and rest.sum() >= 10 else np.isfinite(a)
        g = _median(a[use]) if use.any() else float("nan")
        qc["acc_rest_norm"] = g
        still = _still(rest, t)
        if still is not None and np.isfinite(a[still]).sum() >= 10 and g > 0:
            q1, q3 = np.nanpercentile(a[still], [25, 75])
            qc["acc_rest_spread"] = float((q3 - q1) / g)
        flags["acc_looks_like_g"] = bool(0.5 <= g <= 2.0)
        flags["acc_norm_implausible"] = not (
            flags["acc_looks_like_g"] or ACC_REST_RANGE[0] <= g <= ACC_REST_RANGE[1]
        )
    if stream.mag is not None:
        m = _median(_norm(stream.mag))
        qc["mag_norm_ut"] = m
        if not stream.attrs.get("mag_scale_assumed"):
            flags["mag_norm_out_of_range"] = not (MAG_RANGE_UT[0] <= m <= MAG_RANGE_UT[1])
    held = held_rows(stream)
    share = held / max(len(t) - 1, 1)
    qc["held_samples"] = held
    qc["held_share"] = share
    qc["effective_rate_hz"] = qc["rate_hz"] * (1.0 - share)
    flags["held_samples"] = share >= HELD_SHARE
    flags["rate_assumed"] = bool(stream.attrs.get("rate_assumed"))
    flags["mag_scale_assumed"] = bool(stream.attrs.get("mag_scale_assumed"))
    counter = stream.extra.get("packet_counter")
    if counter is not None:
        qc["dropped_packets"] = dropped_packets(counter)
        flags["dropped_packets"] = qc["dropped_packets"] > 0
    qc["flags"] = flags
    return qc


def doubts(stream: SensorStream) -> list[str]:
    """One line per finding of :func:`check_stream` (``stream.qc``) that suggests a wrong unit
    or damaged values in the file, and per repair the reader made of a damaged file (a
    truncated last line dropped): what ``motionlab ingest`` prints as warnings. Empty for a
    plausible recording; the flags stay in ``qc`` for ``motionlab info`` either way."""
    qc, flags, units = stream.qc, stream.qc.get("flags", {}), stream.source_units
    out = []
    g = qc.get("acc_rest_norm", float("nan"))
    read_as = f"read as {units['acc']}" if "acc" in units else "in m/s²"
    if flags.get("acc_looks_like_g"):
        out.append(f"|a| at rest is {g:.2f} m/s² ({read_as}), 1 g is 9.81: is the accelerometer "
                   "in g? — check the export's accelerometer unit")  # fmt: skip
    elif flags.get("acc_norm_implausible"):
        out.append(f"|a| at rest is {g:.3g} m/s² ({read_as}), not ≈ 9.81: a wrong unit or "
                   "scale? — check the export's accelerometer unit")  # fmt: skip
    if flags.get("gyr_looks_like_deg_s"):
        read_as = f"read as {units['gyr']}" if "gyr" in units else "in rad/s"
        peak = qc["gyr_max_rad_s"]
        out.append(f"|ω| reaches {peak:.3g} rad/s ({read_as}), beyond a ±2000 °/s gyroscope: "
                   "is it in °/s? — check the export's gyroscope unit")  # fmt: skip
    problem = gyr_unit_problem(stream)
    if problem:
        out.append(" — ".join(problem))
    if flags.get("gyr_unit_unchecked"):
        out.append(unchecked_line(stream))
    if flags.get("implausible_values"):
        share = ", ".join(f"{ch} {100 * v:.3g} %" for ch, v in qc["implausible_share"].items())
        out.append(f"values beyond what a sensor measures (1e308, ±inf) in {share} of the rows: "
                   "damaged? — check the file, or export it again")  # fmt: skip
    if qc.get("quat_dropped"):  # the ingest's check of the norms (motionlab.ingest)
        left = "no channel left" if not stream.channels else f"kept: {', '.join(stream.channels)}"
        out.append(f"orientation dropped: {qc['quat_dropped']}; {left} — check the file, or "
                   "export it again")  # fmt: skip
    elif qc.get("quat_invalid_samples"):
        out.append(f"{qc['quat_invalid_samples']} orientations with a norm far from 1 set "
                   "missing — check the file, or export it again")  # fmt: skip
    if flags.get("header_rate_mismatch"):
        out.append(f"the time stamps give {qc['rate_hz']:.4g} Hz, the file's header says "
                   f"{qc['header_rate_hz']:g} Hz: is the time column in another unit? — check "
                   "the export's time column")  # fmt: skip
    if qc.get("nan_time_dropped"):  # the ingest's clock repair (motionlab.timebase)
        out.append(f"{qc['nan_time_dropped']} rows without a time stamp (NaN) dropped — check "
                   "the file's time column")  # fmt: skip
    out += [n for n in stream.attrs.get("notes", []) if "truncated" in n]
    return out
