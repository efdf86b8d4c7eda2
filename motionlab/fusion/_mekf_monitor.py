"""Numba kernels of the MEKF's inconsistency monitor and of its causal rest detector.

Used by :func:`motionlab.fusion._mekf_kernels.forward` (see :mod:`motionlab.fusion.mekf` for the
method). Conventions: earth frame ENU, vectors in the earth frame of the filter's current
estimate; accelerometer m/s², field µT, angles rad, times s. The monitor's state is one float
work array (``N_MONITOR``) so nothing allocates per sample.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.quat_kernels import log_rotvec

# slots of the inconsistency monitor's work array (earth-frame vectors under the estimate):
# low-passed acc and horizontal field direction; sums and counts of the tilt run (acc, field)
# and of the heading run (horizontal field directions), and the runs' durations
_LA, _LM, _SA, _NA, _SM, _TA, _SH, _NH, _TH = 0, 3, 5, 8, 9, 12, 13, 15, 16
N_MONITOR = 17


@numba.njit(cache=True, inline="always")
def _rotate(
    qw: float, qx: float, qy: float, qz: float, vx: float, vy: float, vz: float
) -> tuple[float, float, float]:
    """``q ⊗ [0, v] ⊗ q*`` for a unit ``q``, as scalars (``v + 2w u×v + 2u×(u×v)``)."""
    cx = qy * vz - qz * vy
    cy = qz * vx - qx * vz
    cz = qx * vy - qy * vx
    return (
        vx + 2.0 * (qw * cx + qy * cz - qz * cy),
        vy + 2.0 * (qw * cy + qz * cx - qx * cz),
        vz + 2.0 * (qw * cz + qx * cy - qy * cx),
    )


@numba.njit(cache=True)
def monitor_clear(mon: np.ndarray) -> None:
    """Forget the monitor's history: low-passed vectors on earth-up and north, no bad run."""
    mon[:] = 0.0
    mon[_LA + 2] = 9.81
    mon[_LM + 1] = 1.0


@numba.njit(cache=True, inline="always")
def tilt_run(mon: np.ndarray) -> bool:
    """Whether the accelerometer currently contradicts the estimate (its updates are held)."""
    return mon[_NA] > 0.0


@numba.njit(cache=True, inline="always")
def in_run(mon: np.ndarray) -> bool:
    """Whether a tilt or heading run is being summed."""
    return mon[_NA] > 0.0 or mon[_NH] > 0.0


@numba.njit(cache=True)
def monitor_turn(mon: np.ndarray, angle: float) -> None:
    """Turn the monitor's earth-frame vectors about up by ``angle`` (rad), as a heading
    correction of the estimate turns them, so that a run's sums stay consistent."""
    c, s = np.cos(angle), np.sin(angle)
    for i in (_LA, _SA, _SM, _LM, _SH):
        x, y = mon[i], mon[i + 1]
        mon[i] = c * x - s * y
        mon[i + 1] = s * x + c * y


@numba.njit(cache=True)
def monitor(
    mon: np.ndarray,
    ea: tuple[float, float, float],
    em: tuple[float, float, float],
    mag_ok: bool,
    alpha: float,
    cos_tilt: float,
    cos_heading: float,
    t_tilt: float,
    t_heading: float,
    agree: float,
    dt: float,
) -> int:
    """Feed one sample to the inconsistency monitor; return the reset it calls for.

    ``ea``, ``em`` are the sample's accelerometer and field in the earth frame of the current
    estimate. A consistent filter sees ``ea`` along earth-up on average (linear acceleration
    averages out: its mean over ``T`` is ``Δv/T``) and the undisturbed field's (``mag_ok``)
    horizontal part pointing north. Both are low-passed (``alpha = dt/τ``). While one stays
    further from its reference than the angle whose cosine is ``cos_tilt`` / ``cos_heading``,
    that run's vectors are summed; a run longer than ``t_tilt`` / ``t_heading`` (s) returns
    1 (tilt) / 2 (heading) — a heading run only if its field directions agree (mean resultant
    length above ``agree``) — else 0.
    """
    for i in range(3):
        mon[_LA + i] += alpha * (ea[i] - mon[_LA + i])
    ln = np.sqrt(mon[_LA] ** 2 + mon[_LA + 1] ** 2 + mon[_LA + 2] ** 2)
    if mon[_LA + 2] < cos_tilt * ln:
        for i in range(3):
            mon[_SA + i] += ea[i]
            mon[_SM + i] += em[i]
        mon[_NA] += 1.0
        mon[_TA] += dt
        if mon[_TA] > t_tilt:
            return 1
    elif mon[_NA] > 0.0:
        for i in range(_SA, _TA + 1):
            mon[i] = 0.0
    if mag_ok:
        hn = np.sqrt(em[0] * em[0] + em[1] * em[1])
        hx, hy = em[0] / hn, em[1] / hn
        mon[_LM] += alpha * (hx - mon[_LM])
        mon[_LM + 1] += alpha * (hy - mon[_LM + 1])
        ln = np.sqrt(mon[_LM] ** 2 + mon[_LM + 1] ** 2)
        if mon[_LM + 1] < cos_heading * ln:
            mon[_SH] += hx
            mon[_SH + 1] += hy
            mon[_NH] += 1.0
            mon[_TH] += dt
            sn = np.sqrt(mon[_SH] ** 2 + mon[_SH + 1] ** 2)
            if mon[_TH] > t_heading and sn > agree * mon[_NH]:
                return 2
        elif mon[_NH] > 0.0:
            for i in range(_SH, _TH + 1):
                mon[i] = 0.0
    return 0


@numba.njit(cache=True)
def reset_correction(
    mon: np.ndarray,
    mode: int,
    use_mag: bool,
    ref_n: float,
    ref_d: float,
    norm_tol: float,
    dip_tol: float,
    corr: np.ndarray,
) -> bool:
    """Earth-frame rotation vector ``corr`` that re-aligns the estimate with the summed vectors.

    Tilt (``mode`` 1): the shortest rotation taking the mean earth-frame accelerometer direction
    to earth-up, then — when the mean field, so tilted, matches the reference norm and dip — the
    rotation about up turning its horizontal part north (norm within ``norm_tol`` relative,
    dip within ``dip_tol`` rad; TRIAD with gravity exact, as
    :func:`motionlab.fusion.attitude.triad`). Heading (``mode`` 2): the rotation about up only.
    Returns whether the heading is part of the correction.
    """
    if mode == 2:
        corr[0] = 0.0
        corr[1] = 0.0
        corr[2] = np.arctan2(mon[_SH], mon[_SH + 1])
        return True
    an = np.sqrt(mon[_SA] ** 2 + mon[_SA + 1] ** 2 + mon[_SA + 2] ** 2)
    ax, ay, az = mon[_SA] / an, mon[_SA + 1] / an, mon[_SA + 2] / an
    sn = np.sqrt(ax * ax + ay * ay)
    half = 0.5 * np.arctan2(sn, az)
    # axis a × up = (ay, −ax, 0)
    tw = np.cos(half)
    tx = np.sin(half) * ay / sn if sn > 1e-12 else 0.0
    ty = -np.sin(half) * ax / sn if sn > 1e-12 else 0.0
    hw, hz = 1.0, 0.0
    heading = False
    if use_mag and ref_n > 0.0:
        mx, my, mz = _rotate(tw, tx, ty, 0.0, mon[_SM], mon[_SM + 1], mon[_SM + 2])
        mx, my, mz = mx / mon[_NA], my / mon[_NA], mz / mon[_NA]
        mn = np.sqrt(mx * mx + my * my + mz * mz)
        if abs(mn - ref_n) < norm_tol * ref_n and abs(np.arcsin(mz / mn) - ref_d) < dip_tol:
            psi = np.arctan2(mx, my)
            hw, hz = np.cos(0.5 * psi), np.sin(0.5 * psi)
            heading = True
    # q_c = exp(ψ ẑ/2) ⊗ q_tilt, then its rotation vector
    cw, cx, cy, cz = hw * tw, hw * tx - hz * ty, hw * ty + hz * tx, hz * tw
    corr[0], corr[1], corr[2] = log_rotvec(cw, cx, cy, cz)
    return heading


@numba.njit(cache=True)
def trailing_rest(
    gyr: np.ndarray,
    acc: np.ndarray,
    w: int,
    run: int,
    gyr_thr2: float,
    acc_thr2: float,
    rest: np.ndarray,
) -> None:
    """Causal rest flags into ``rest`` (N): over the last ``w`` samples the mean square rate is
    below ``gyr_thr2`` and the accelerometer's variance below ``acc_thr2`` — for the last ``run``
    samples (or since the start) — and the newest sample's deviations from the window means are
    below the same thresholds. Running window sums, one pass."""
    n = gyr.shape[0]
    sg = np.zeros(3)
    sa = np.zeros(3)
    sg2 = 0.0
    sa2 = 0.0
    count = 0
    for k in range(n):
        for i in range(3):
            sg[i] += gyr[k, i]
            sa[i] += acc[k, i]
            sg2 += gyr[k, i] * gyr[k, i]
            sa2 += acc[k, i] * acc[k, i]
            if k >= w:
                sg[i] -= gyr[k - w, i]
                sa[i] -= acc[k - w, i]
                sg2 -= gyr[k - w, i] * gyr[k - w, i]
                sa2 -= acc[k - w, i] * acc[k - w, i]
        m = min(k + 1, w)
        var_a = sa2 / m
        dev_g = 0.0
        dev_a = 0.0
        for i in range(3):
            var_a -= (sa[i] / m) ** 2
            dev_g += (gyr[k, i] - sg[i] / m) ** 2
            dev_a += (acc[k, i] - sa[i] / m) ** 2
        count = count + 1 if sg2 / m < gyr_thr2 and var_a < acc_thr2 else 0
        rest[k] = count >= min(run, k + 1) and dev_g < gyr_thr2 and dev_a < acc_thr2
