"""Quaternion unscented Kalman filter with gyro-bias states (``ukf``), after Kraft (2003).

State: orientation ``q`` (sensor → ENU earth, scalar first) and gyroscope bias ``b`` (rad/s);
the covariance ``P`` (6×6) lives in the error space ``[δθ; δb]`` with the attitude error a
rotation vector in the body frame, ``q_true = q ⊗ exp(δθ)``. The gyroscope drives the process.

- sigma points (Kraft 2003, eqs. (33)–(35); Liu 2010 thesis eqs. (83)–(87), errata corrected):
  the columns ``s_i`` of the Cholesky factor of ``n (P + Q)`` (process noise folded in), 2n
  points ``q ⊗ exp(±s_i,θ)``, ``b ± s_i,b`` with equal weights 1/(2n), so their covariance is
  exactly ``P + Q`` (Kraft's printed scale √(2n) doubles it);
- process: each point turns by its own bias-corrected rate, ``χ ← χ ⊗ exp((ω_k − χ_b) Δt)``;
- mean: the intrinsic (Karcher) mean by Pennec's gradient descent (Liu eqs. (89)–(92)):
  ``e_i = log(q̄* ⊗ χ_i)``, ``q̄ ← q̄ ⊗ exp(mean e_i)`` until ``|mean e_i| < 1e-10`` rad,
  started from the propagated previous estimate; ``P⁻ = mean of [e_i; b_i − b̄][·]ᵀ``;
- update (eqs. (100)–(105)): predicted measurements ``Z_i`` of the propagated points: the unit
  accelerometer ``R(χ)ᵀ up``, the horizontal field direction ``R(χ)ᵀ north`` (the field's
  horizontal part seen through the prior mean, heading only) and, on detected rest, the
  gyroscope as a measurement of the bias (zero rate); ``K = P_xz P_zz⁻¹``, the correction is
  applied multiplicatively ``q = q̄ ⊗ exp(K_θ ν)``, ``b = b̄ + K_b ν`` (eq. (106) corrected) and
  ``P = P⁻ − K P_zxᵀ − P_xz Kᵀ + K P_zz Kᵀ`` (valid for any gain; eq. (107) has no ``H`` in a UKF);
  where no field and no marker measured the heading, the update's turn about earth-up is dropped
  (:func:`~motionlab.fusion._common.keep_heading`: gravity carries no heading).

Marker reference vectors (Liu Table 3, :mod:`motionlab.fusion.markers`) add the predicted
earth-frame directions ``R(χ) a`` of the body-fixed marker pairs to ``Z_i`` with their own noise;
with them the gyroscope enters as the interval mean
(:func:`~motionlab.fusion.markers.interval_rates`), the bias starts from the registration's
estimate, and a jump beyond the covariance (:func:`~motionlab.fusion.markers.marker_jump`) widens
the attitude block of ``P⁻`` (sigma points redrawn) before the update.

During the start-up phase the bias is *considered*, not estimated (zero gain), so a wrong
initial attitude is not absorbed by the bias. Accelerometer noise grows with linear acceleration
and rotation rate; disturbed magnetometer samples are dropped (:mod:`motionlab.fusion.detect`).
Defaults were tuned on the 8 BROAD trials in ``../shared``, which are also the reported test set.

References: E. Kraft, "A quaternion-based unscented Kalman filter for orientation tracking",
Proc. 6th Int. Conf. Information Fusion, 2003, doi:10.1109/ICIF.2003.177425.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from motionlab.errors import InputError
from motionlab.fusion import _common as cm
from motionlab.fusion import _kalman_common as kc
from motionlab.fusion._kalman_common import KalmanCommon
from motionlab.fusion.markers import (
    USED_ACC,
    USED_MAG,
    USED_MARKERS,
    marker_jump,
)
from motionlab.fusion.registry import param

NX = 6
NS = 2 * NX
MEAN_TOL = 1e-10
MEAN_ITERATIONS = 20


@dataclass
class UkfParams(KalmanCommon):
    """Tunables of the quaternion UKF."""

    bias_rw: float = param(1e-4, "rad/s/√s", "gyroscope bias random walk")
    bias_init: float = param(0.02, "rad/s", "initial bias standard deviation")
    rest_noise: float = param(0.005, "rad/s", "gyroscope noise of the bias measurement at rest")


@numba.njit(cache=True, inline="always")
def _log_rel(qa: np.ndarray, qb: np.ndarray, out: np.ndarray, j: int) -> None:
    """``out[j] ← log(qa* ⊗ qb)`` as a rotation vector (rad), shortest of ±."""
    w, x, y, z = cm.conj_mul_shortest(qa, qb)
    out[j, 0], out[j, 1], out[j, 2] = cm.log_rotvec(w, x, y, z)


@numba.njit(cache=True)
def _intrinsic_mean(chi: np.ndarray, qbar: np.ndarray, err: np.ndarray) -> int:
    """Intrinsic mean of the unit quaternions ``chi`` (M×4) into ``qbar`` (start value in place).

    ``err`` (M×3) receives the final rotation-vector deviations ``log(q̄* ⊗ χ_i)``. Returns the
    number of iterations.
    """
    m = chi.shape[0]
    for it in range(MEAN_ITERATIONS):
        ex = ey = ez = 0.0
        for i in range(m):
            _log_rel(qbar, chi[i], err, i)
            ex += err[i, 0]
            ey += err[i, 1]
            ez += err[i, 2]
        ex, ey, ez = ex / m, ey / m, ez / m
        cm.mul_exp_right(qbar, ex, ey, ez, qbar)
        cm.normalize(qbar)
        if ex * ex + ey * ey + ez * ez < MEAN_TOL**2:
            for i in range(m):
                _log_rel(qbar, chi[i], err, i)
            return it + 1
    for i in range(m):
        _log_rel(qbar, chi[i], err, i)
    return MEAN_ITERATIONS


def intrinsic_mean(quats: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
    """Intrinsic (Karcher) mean of unit quaternions (M, 4), sign-insensitive.

    Pennec's gradient descent as used for the UKF's sigma points (Liu 2010, eqs. (89)–(92));
    it starts from ``start`` (default the first quaternion), which must lie within 90° of all.
    """
    chi = np.ascontiguousarray(quats, dtype=float)
    if chi.ndim != 2 or chi.shape[1] != 4 or len(chi) == 0:
        raise InputError(f"quaternions have shape {chi.shape}, expected (M, 4) with M ≥ 1")
    chi = chi / np.linalg.norm(chi, axis=1, keepdims=True)
    qbar = (chi[0] if start is None else np.asarray(start, dtype=float)).copy()
    qbar /= np.linalg.norm(qbar)
    _intrinsic_mean(chi, qbar, np.empty((len(chi), 3)))
    return qbar if qbar[0] >= 0 else -qbar


@numba.njit(cache=True)
def _kernel(rec: tuple, own: tuple, markers: tuple, out: tuple) -> None:
    """The UKF, arguments as the EKF's (``ekf._kernel``) but ``own`` = (bias_rw, bias_init,
    rest_noise): it has no rate state."""
    gyr, acc, mag, use_mag, pre, rest, dt, q0, prm = rec
    bias_rw, bias_init, rest_noise = own
    ref_body, ref_earth, ref_var, bias0 = markers
    quat, bias, dist, used = out
    n = gyr.shape[0]
    nz = 9 + 3 * ref_body.shape[0]
    q = q0.copy()
    b = bias0.copy()
    p = np.zeros((NX, NX))
    a = np.empty((NX, NX))
    low = np.empty((NX, NX))
    chi = np.empty((NS, 4))
    chib = np.empty((NS, 3))
    dev = np.empty((NS, NX))
    err = np.empty((NS, 3))
    zs = np.empty((NS, nz))
    zbar = np.empty(nz)
    z = np.empty(nz)
    rvar = np.empty(nz)
    pzz = np.empty((nz, nz))
    pxz = np.empty((NX, nz))
    kt = np.empty((nz, NX))
    lowz = np.empty((nz, nz))
    dx = np.empty(NX)
    prior = np.empty(4)
    r = np.empty((3, 3))
    north = np.empty(3)
    for i in range(3):
        p[i, i] = prm[kc.ATT_INIT] ** 2
        p[3 + i, 3 + i] = bias_init**2
    var_g = prm[kc.GYR_NOISE] ** 2 * dt
    var_b = bias_rw**2 * dt
    var_mag = prm[kc.MAG_NOISE] ** 2 / dt
    w = 1.0 / NS
    for k in range(n):
        # sigma points of N(x, P + Q) (Q only between samples), propagated by the gyroscope
        for i in range(NX):
            for j in range(NX):
                a[i, j] = NX * p[i, j]
            if k > 0:
                a[i, i] += NX * (var_g if i < 3 else var_b)
        cm.cholesky(a, NX, low)
        for s in range(NS):
            c = s % NX
            sign = 1.0 if s < NX else -1.0
            cm.mul_exp_right(q, sign * low[0, c], sign * low[1, c], sign * low[2, c], chi[s])
            for i in range(3):
                chib[s, i] = b[i] + sign * low[3 + i, c]
            if k > 0:
                cm.mul_exp_right(
                    chi[s], (gyr[k, 0] - chib[s, 0]) * dt, (gyr[k, 1] - chib[s, 1]) * dt,
                    (gyr[k, 2] - chib[s, 2]) * dt, chi[s],
                )  # fmt: skip
        if k > 0:
            cm.mul_exp_right(
                q, (gyr[k, 0] - b[0]) * dt, (gyr[k, 1] - b[1]) * dt, (gyr[k, 2] - b[2]) * dt, q
            )
        _intrinsic_mean(chi, q, err)
        for i in range(3):
            b[i] = 0.0
            for s in range(NS):
                b[i] += w * chib[s, i]
        for s in range(NS):
            for i in range(3):
                dev[s, i] = err[s, i]
                dev[s, 3 + i] = chib[s, i] - b[i]
        for i in range(NX):
            for j in range(NX):
                acc_ij = 0.0
                for s in range(NS):
                    acc_ij += dev[s, i] * dev[s, j]
                p[i, j] = w * acc_ij
        if ref_body.shape[0] > 0:
            cm.rot_matrix(q, r)
            jump = marker_jump(
                r, ref_body, ref_earth, ref_var, k, (p[0, 0] + p[1, 1] + p[2, 2]) / 3
            )
            if jump > 0.0:  # the markers disagree beyond P⁻: widen it and redraw the points
                for i in range(3):
                    p[i, i] += jump
                _redraw(q, b, p, a, low, chi, chib, dev)
        # measurements present at this sample: acc (3), horizontal field (3), markers, rest (3)
        used[k] = 0
        m = 0
        scale = kc.startup_scale(prm, k, dt)
        wx, wy, wz = gyr[k, 0] - b[0], gyr[k, 1] - b[1], gyr[k, 2] - b[2]
        var_a = kc.acc_variance(
            acc, k, np.sqrt(wx * wx + wy * wy + wz * wz), prm[kc.GRAVITY], prm[kc.ACC_NOISE],
            prm[kc.ACC_NORM_GAIN], prm[kc.ACC_RATE_GAIN], prm[kc.ACC_GATE], dt,
        )  # fmt: skip
        if var_a > 0.0:
            an = np.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
            for s in range(NS):
                cm.rot_matrix(chi[s], r)
                for i in range(3):
                    zs[s, i] = r[2, i]
            for i in range(3):
                z[i] = acc[k, i] / an
                rvar[i] = var_a * scale
            m = 3
            used[k] += USED_ACC
        dist[k] = True
        if use_mag:
            ok = kc.mag_ok(q, mag, k, pre, prm)
            cm.rot_matrix(q, r)
            if ok and kc.horizontal_north(r, mag, k, north):
                dist[k] = False
                for s in range(NS):
                    cm.rot_matrix(chi[s], r)
                    for i in range(3):
                        zs[s, m + i] = r[1, i]
                for i in range(3):
                    z[m + i] = north[i]
                    rvar[m + i] = var_mag * scale
                m += 3
                used[k] += USED_MAG
        for j in range(ref_body.shape[0]):
            if not np.isfinite(ref_earth[k, j, 0]):
                continue
            for s in range(NS):
                cm.rot_matrix(chi[s], r)
                for i in range(3):
                    zs[s, m + i] = (
                        r[i, 0] * ref_body[j, 0]
                        + r[i, 1] * ref_body[j, 1]
                        + r[i, 2] * ref_body[j, 2]
                    )
            for i in range(3):
                z[m + i] = ref_earth[k, j, i]
                rvar[m + i] = ref_var[j]
            m += 3
            used[k] |= USED_MARKERS
        if rest[k]:
            for s in range(NS):
                for i in range(3):
                    zs[s, m + i] = chib[s, i]
            for i in range(3):
                z[m + i] = gyr[k, i]
                rvar[m + i] = rest_noise**2
            m += 3
        if m > 0:
            for i in range(4):
                prior[i] = q[i]
            _correct(q, b, p, dev, zs, z, rvar, m, scale < 1.0, zbar, pzz, pxz, kt, lowz, dx)
            if not used[k] & (USED_MAG | USED_MARKERS):  # nothing measured the heading
                cm.keep_heading(prior, q)
        for i in range(4):
            quat[k, i] = q[i]
        for i in range(3):
            bias[k, i] = b[i]


@numba.njit(cache=True)
def _redraw(
    q: np.ndarray,
    b: np.ndarray,
    p: np.ndarray,
    a: np.ndarray,
    low: np.ndarray,
    chi: np.ndarray,
    chib: np.ndarray,
    dev: np.ndarray,
) -> None:
    """Sigma points ``chi``, ``chib`` and deviations ``dev`` of N([q; b], P), in place."""
    for i in range(NX):
        for j in range(NX):
            a[i, j] = NX * p[i, j]
    cm.cholesky(a, NX, low)
    for s in range(NS):
        c = s % NX
        sign = 1.0 if s < NX else -1.0
        cm.mul_exp_right(q, sign * low[0, c], sign * low[1, c], sign * low[2, c], chi[s])
        for i in range(NX):
            dev[s, i] = sign * low[i, c]
        for i in range(3):
            chib[s, i] = b[i] + sign * low[3 + i, c]


@numba.njit(cache=True)
def _correct(
    q: np.ndarray,
    b: np.ndarray,
    p: np.ndarray,
    dev: np.ndarray,
    zs: np.ndarray,
    z: np.ndarray,
    rvar: np.ndarray,
    m: int,
    hold_bias: bool,
    zbar: np.ndarray,
    pzz: np.ndarray,
    pxz: np.ndarray,
    kt: np.ndarray,
    lowz: np.ndarray,
    dx: np.ndarray,
) -> None:
    """UKF measurement update of ``q``, ``b``, ``P`` in place with the first ``m`` rows."""
    w = 1.0 / NS
    for i in range(m):
        zbar[i] = 0.0
        for s in range(NS):
            zbar[i] += w * zs[s, i]
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for s in range(NS):
                acc += (zs[s, i] - zbar[i]) * (zs[s, j] - zbar[j])
            pzz[i, j] = w * acc
        pzz[i, i] += rvar[i]
        for j in range(NX):
            acc = 0.0
            for s in range(NS):
                acc += dev[s, j] * (zs[s, i] - zbar[i])
            pxz[j, i] = w * acc
            kt[i, j] = pxz[j, i]
    # Kᵀ = P_zz⁻¹ P_xzᵀ
    cm.chol_solve(pzz, m, lowz, kt, NX)
    if hold_bias:
        for i in range(m):
            for j in range(3, NX):
                kt[i, j] = 0.0
    for j in range(NX):
        acc = 0.0
        for i in range(m):
            acc += kt[i, j] * (z[i] - zbar[i])
        dx[j] = acc
    cm.mul_exp_right(q, dx[0], dx[1], dx[2], q)
    cm.normalize(q)
    for i in range(3):
        b[i] += dx[3 + i]
    # P ← P − K P_xzᵀ − P_xz Kᵀ + K P_zz Kᵀ
    for i in range(NX):
        for j in range(i, NX):
            acc = p[i, j]
            for t in range(m):
                acc -= kt[t, i] * pxz[j, t] + pxz[i, t] * kt[t, j]
                st = 0.0
                for u in range(m):
                    st += pzz[t, u] * kt[u, j]
                acc += kt[t, i] * st
            p[i, j] = acc
            p[j, i] = acc


#: the quaternion UKF with bias states, registered as ``ukf``
run = kc.register_filter(
    "ukf", UkfParams, "Quaternion UKF (Kraft) with intrinsic mean and gyro-bias states", _kernel,
    ("bias_rw", "bias_init", "rest_noise"),
)  # fmt: skip
