"""Detectors shared by the estimators: rest, magnetic disturbance, magnetometer usability.

Inputs are (N, 3) sensor-frame arrays in SI units (gyr rad/s, acc m/s², mag µT) sampled at
``rate`` Hz. Magnetic disturbance is judged by the field norm and the dip angle against a
reference estimated from the undisturbed part of the recording (Ricci 2015, thesis eqs. 4.3–4.5;
Roetenberg et al. 2005): ``dip = asin(−(up·m)/|m|)`` with ``up`` the earth-up direction in the
sensor frame (positive downward field, northern hemisphere). Estimators drop (gate) the
magnetometer on flagged samples, so the heading is carried by the gyroscope and stays consistent;
when the magnetometer is unusable over most of a recording they run in 6-D
(:func:`mag_usable`).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.ndimage import label, uniform_filter1d

from motionlab import rotations as rot


def _window(seconds: float, rate: float) -> int:
    return max(1, int(round(seconds * rate)))


def _dilate(mask: np.ndarray, size: int) -> np.ndarray:
    """Binary dilation by a centred window of odd ``size`` in O(N) (moving average > 0)."""
    return uniform_filter1d(mask.astype(np.float32), size, mode="nearest") > 1e-3 / size


def _erode(mask: np.ndarray, size: int) -> np.ndarray:
    """Binary erosion by a centred window of odd ``size`` in O(N) (moving average = 1)."""
    return uniform_filter1d(mask.astype(np.float32), size, mode="nearest") > 1.0 - 1e-3 / size


def acc_quiet(
    acc: np.ndarray, rate: float, acc_threshold: float = 0.5, window: float = 0.5
) -> np.ndarray:
    """Samples (N,) bool whose accelerometer's moving-RMS deviation from its moving mean (both
    over ``window`` s) is below ``acc_threshold`` (m/s²): the accelerometer's half of
    :func:`rest_mask`."""
    w = _window(window, rate)
    acc_t = np.ascontiguousarray(acc.T)
    acc_dev = acc_t - uniform_filter1d(acc_t, w, axis=1, mode="nearest")
    acc_ms = uniform_filter1d(np.einsum("ij,ij->j", acc_dev, acc_dev), w, mode="nearest")
    return acc_ms < acc_threshold**2


def rest_mask(
    gyr: np.ndarray,
    acc: np.ndarray | None,
    rate: float,
    gyr_threshold: float = np.deg2rad(2.0),
    acc_threshold: float = 0.5,
    window: float = 0.5,
    min_duration: float = 1.5,
    acc_still: np.ndarray | None = None,
) -> np.ndarray:
    """Samples (N,) bool where the sensor is at rest.

    Rest means the moving-RMS (over ``window`` s) of the angular rate is below ``gyr_threshold``
    (rad/s) and of the accelerometer's deviation from its moving mean below ``acc_threshold``
    (m/s²), for at least ``min_duration`` s. ``acc_still``: :func:`acc_quiet` of ``acc`` with
    the same threshold and window, when the caller has it (it is then not recomputed, and
    ``acc`` may be None).
    """
    w = _window(window, rate)
    gyr_ms = uniform_filter1d(np.einsum("ij,ij->i", gyr, gyr), w, mode="nearest")
    if acc_still is None:
        acc_still = acc_quiet(acc, rate, acc_threshold, window)
    still = (gyr_ms < gyr_threshold**2) & acc_still
    run = _window(min_duration, rate) | 1
    if run > 1 and len(still) >= run:
        still = _dilate(_erode(still, run), run)  # opening: drop shorter still runs
    return still


def steady_mask(
    gyr: np.ndarray,
    rate: float,
    rest: np.ndarray | None = None,
    sway: float = np.deg2rad(0.2),
    smooth: float = 0.25,
    window: float = 1.0,
    min_duration: float = 0.5,
) -> np.ndarray:
    """Samples (N,) bool of ``rest`` (N, bool; default all) where the angular rate is steady:
    its moving mean over ``smooth`` s varies by less than ``sway`` (rad/s, RMS over the three
    axes) within the centred ``window`` s around the sample, both taken over the rest's own
    samples only (the movement next to a short rest does not count), for at least
    ``min_duration`` s (a sway levelling off for a moment is not steady).

    A gyroscope's bias is constant and its noise averages out within ``smooth``; a sensor on a
    person sitting or standing "still" sways and drifts at fractions of a degree per second,
    slower than that and with no constant rate to take for a bias. On the shared BROAD trials
    (an IMU set down) the rests vary by 0.014–0.025°/s (medians to 90th percentiles); on
    people seated (the shared trunk recordings) the upper and lower back vary by 0.26–0.70°/s
    (medians) while the wheelchair's sensor varies by 0.04–0.10°/s; the real RING rig's rests
    (about 1 s, next to its movement) are steady over 0.6–1.2 s of each. The default 0.2°/s
    lies between them; the rest's bias update of :func:`motionlab.fusion.mekf.run_smoother`
    uses only steady samples.
    """
    gyr = np.asarray(gyr, dtype=float)
    inside = np.ones(len(gyr), bool) if rest is None else np.asarray(rest, bool)
    w = inside.astype(float)

    def mean(x: np.ndarray, size: int) -> np.ndarray:  # moving mean over the rest's samples
        count = np.maximum(uniform_filter1d(w, size, mode="constant"), 1e-12)
        total = uniform_filter1d(x * (w[:, None] if x.ndim == 2 else w), size, axis=0,
                                 mode="constant")  # fmt: skip
        return total / (count[:, None] if x.ndim == 2 else count)

    g = mean(gyr, _window(smooth, rate))
    dev = g - mean(g, _window(window, rate))
    steady = inside & (mean(np.einsum("ij,ij->i", dev, dev), _window(window, rate)) < sway**2)
    run = _window(min_duration, rate) | 1
    if run > 1 and len(steady) >= run:
        steady = _dilate(_erode(steady, run), run) & inside  # opening: drop shorter runs
    return steady


def field_norm_dip(
    mag: np.ndarray, acc: np.ndarray, q: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Field norm (µT) and dip angle (rad, positive downward) per sample.

    The up direction comes from the orientation ``q`` (sensor → ENU) when given, otherwise from
    the accelerometer (exact at rest, disturbed by linear acceleration).
    """
    norm = np.linalg.norm(mag, axis=1)
    if q is not None:
        up = rot.rotate(rot.conj(q), np.array([0.0, 0.0, 1.0]))
    else:
        up = acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-12)
    sin_dip = -np.sum(up * mag, axis=1) / np.maximum(norm, 1e-12)
    return norm, np.arcsin(np.clip(sin_dip, -1.0, 1.0))


def field_reference(
    mag: np.ndarray,
    acc: np.ndarray,
    q: np.ndarray | None = None,
    norm_tol: float = 4.0,
    dip_tol: float = np.deg2rad(6.0),
) -> tuple[float, float]:
    """Reference field norm (µT) and dip (rad) of the undisturbed field.

    The mode of the norm (histogram with ``norm_tol`` bins), then the median norm and dip of the
    samples consistent with it (within ``norm_tol`` and ``dip_tol`` of the dip median), and
    restricted to samples with accelerometer norm within 1 m/s² of g when q is not given.
    """
    step = max(1, len(mag) // 5000)  # a few thousand samples fix the reference well enough
    mag, acc = mag[::step], acc[::step]
    q = None if q is None else q[::step]
    norm, dip = field_norm_dip(mag, acc, q)
    keep = np.isfinite(norm) & np.isfinite(dip)
    if q is None:
        calm = np.abs(np.linalg.norm(acc, axis=1) - 9.81) < 1.0
        if calm.sum() > 0.1 * keep.sum():
            keep &= calm
    if not keep.any():
        return float("nan"), float("nan")
    n, d = norm[keep], dip[keep]
    lo, hi = n.min(), n.max()
    bins = max(1, int(np.ceil((hi - lo) / norm_tol)))
    counts, edges = np.histogram(n, bins=bins, range=(lo, hi + 1e-9))
    peak = int(np.argmax(counts))
    ref_norm = 0.5 * (edges[peak] + edges[peak + 1])
    for _ in range(3):
        sel = np.abs(n - ref_norm) < norm_tol
        ref_dip = float(np.median(d[sel]))
        sel &= np.abs(d - ref_dip) < dip_tol
        if sel.any():
            ref_norm = float(np.median(n[sel]))
            ref_dip = float(np.median(d[sel]))
    return float(ref_norm), float(ref_dip)


def mag_disturbance(
    mag: np.ndarray,
    acc: np.ndarray,
    q: np.ndarray | None,
    rate: float,
    norm_tol: float = 4.0,
    dip_tol: float = np.deg2rad(6.0),
    smooth: float = 0.2,
    hold: float = 0.5,
    reference: tuple[float, float] | None = None,
) -> np.ndarray:
    """Samples (N,) bool where the magnetic field is disturbed.

    A sample is disturbed when its field norm differs from the reference by more than
    ``norm_tol`` (µT) or, when the orientation ``q`` is given, its dip by more than ``dip_tol``
    (rad); without ``q`` the dip is not tested, because the accelerometer's up direction is
    unreliable during motion (estimators test it in their loop with their own orientation,
    :func:`nb_field_disturbed`). Both are averaged over
    ``smooth`` s; flags are extended by ``hold`` s on both sides so short clean gaps inside a
    disturbance are not trusted. ``reference`` is ``(norm, dip)``; by default
    :func:`field_reference`.
    """
    ref_norm, ref_dip = reference or field_reference(mag, acc, q, norm_tol, dip_tol)
    w = _window(smooth, rate)
    if q is None:
        norm = uniform_filter1d(np.sqrt(np.einsum("ij,ij->i", mag, mag)), w, mode="nearest")
        bad = ~(np.abs(norm - ref_norm) <= norm_tol)
    else:
        norm, dip = field_norm_dip(mag, acc, q)
        norm = uniform_filter1d(norm, w, mode="nearest")
        dip = uniform_filter1d(dip, w, mode="nearest")
        bad = ~((np.abs(norm - ref_norm) <= norm_tol) & (np.abs(dip - ref_dip) <= dip_tol))
    size = 2 * _window(hold, rate) + 1
    if size > 1 and bad.any():
        closed = _erode(_dilate(bad, size), size)  # fill clean gaps shorter than the window
        bad = _dilate(closed, size)
    return bad


def mag_usable(disturbed: np.ndarray, min_fraction: float = 0.2) -> bool:
    """Whether enough of the recording (``min_fraction``) has an undisturbed field for 9-D use."""
    return bool(len(disturbed)) and float(np.mean(~disturbed)) >= min_fraction


@numba.njit(cache=True, inline="always")
def nb_field_disturbed(
    qw: float,
    qx: float,
    qy: float,
    qz: float,
    mx: float,
    my: float,
    mz: float,
    ref_norm: float,
    ref_dip: float,
    norm_tol: float,
    dip_tol: float,
) -> bool:
    """In-loop check of one sample against the reference, with the filter's current ``q``."""
    n = np.sqrt(mx * mx + my * my + mz * mz)
    if n < 1e-12:
        return True
    # earth-frame z of the field: third row of R(q) times m
    ez = 2.0 * (qx * qz - qw * qy) * mx + 2.0 * (qy * qz + qw * qx) * my
    ez += (1.0 - 2.0 * (qx * qx + qy * qy)) * mz
    s = -ez / n
    s = min(1.0, max(-1.0, s))
    return abs(n - ref_norm) > norm_tol or abs(np.arcsin(s) - ref_dip) > dip_tol


def _wrapped(angle: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped to (−π, π]."""
    return np.arctan2(np.sin(angle), np.cos(angle))


def field_gate(
    field: np.ndarray,
    rate: float,
    norm_tol: float = 0.1,
    dip_tol: float = np.deg2rad(10.0),
    hysteresis: float = 0.5,
    smooth: float = 0.2,
    hold: float = 0.5,
    heading_tol: float = np.deg2rad(90.0),
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Offline magnetometer gate from the recording's own field: ``(gate, dev, norm, dip)``.

    Scale-free, so a field in arbitrary units works as well as one in µT. ``field`` (N, 3) is
    the magnetometer in the earth frame (ENU) of an orientation estimate (its inclination is
    what matters, e.g. a 6-D smoother's), sampled at ``rate`` Hz. Each sample's field norm and
    dip (rad, ``asin(m_up/|m|)``: negative for a downward field) are compared with the
    recording's robust reference — the median of both over the samples consistent with it,
    iterated from the overall median. A sample is gated (``gate`` True: do not use its field)
    when its deviation, averaged over ``smooth`` s, exceeds ``hysteresis`` × the tolerance
    (``norm_tol`` relative to the reference norm, ``dip_tol`` rad) within a run that crosses the
    full tolerance somewhere (hysteresis thresholding), then extended by ``hold`` s on both
    sides. A sample whose field heading (``atan2(m_east, m_north)``; gyroscope-carried, so
    nearly constant for a homogeneous field) is more than ``heading_tol`` rad from its
    recording median is also gated. ``dev`` (N) is the smoothed deviation in units of the
    tolerance (the larger of norm and dip). The reference norm is in the unit of ``field``.
    Disturbance by norm and dip as in Roetenberg et al. (IEEE TBME 52(3), 2005) and VQF
    (Laidig & Seel 2023), which rejects a field whose norm or dip departs from its learnt
    reference.
    """
    field = np.asarray(field, dtype=float)
    norm = np.sqrt(np.einsum("ij,ij->i", field, field))
    with np.errstate(invalid="ignore", divide="ignore"):
        dip = np.arcsin(np.clip(field[:, 2] / norm, -1.0, 1.0))
    psi = np.arctan2(field[:, 0], field[:, 1])
    good = np.isfinite(norm) & np.isfinite(dip) & (norm > 0)
    if not good.any():
        return np.ones(len(field), dtype=bool), np.full(len(field), np.inf), np.nan, np.nan
    ref_n, ref_d = float(np.median(norm[good])), float(np.median(dip[good]))
    for _ in range(3):
        sel = good & (np.abs(norm / ref_n - 1.0) < norm_tol) & (np.abs(dip - ref_d) < dip_tol)
        if not sel.any():
            break
        ref_n, ref_d = float(np.median(norm[sel])), float(np.median(dip[sel]))
    w = _window(smooth, rate)
    dev_n = np.where(good, np.abs(norm / ref_n - 1.0) / norm_tol, np.inf)
    dev_d = np.where(good, np.abs(dip - ref_d) / dip_tol, np.inf)
    dev = np.maximum(
        uniform_filter1d(np.nan_to_num(dev_n, posinf=1e6), w, mode="nearest"),
        uniform_filter1d(np.nan_to_num(dev_d, posinf=1e6), w, mode="nearest"),
    )
    ok = good & (dev <= 1.0)
    if ok.any():
        mean = np.arctan2(np.sin(psi[ok]).mean(), np.cos(psi[ok]).mean())
        mid = mean + np.median(_wrapped(psi[ok] - mean))
        off = np.abs(_wrapped(np.where(good, psi, 0.0) - mid))
        dev = np.maximum(dev, uniform_filter1d(off, w, mode="nearest") / heading_tol)
    low = dev > hysteresis
    runs, count = label(low)
    strong = np.unique(runs[dev > 1.0])
    bad = np.isin(runs, strong[strong > 0]) if count else low
    size = 2 * _window(hold, rate) + 1
    if size > 1 and bad.any():
        bad = _dilate(bad, size)
    return bad | ~good, dev, ref_n, ref_d
