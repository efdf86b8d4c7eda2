"""Liu's quaternion EKF with the angular rate in the state, extended by gyro-bias states (``ekf``).

State ``x = [q; ω; b]``: orientation ``q`` (sensor → ENU earth, scalar first, 4 elements), body
angular rate ``ω`` (rad/s) and gyroscope bias ``b`` (rad/s). Liu (2010, thesis §5.2) uses the
7-state ``[q; ω]`` with the gyroscope as a *measurement* of ``ω``; here the gyroscope measures
``ω + b`` and ``b`` follows a random walk (``bias_rw = 0`` and ``bias_init = 0`` give Liu's filter).

- process (eq. (71), constant-rate model): ``q_k = d(q_{k−1}, ω_k)``, ``d(q, ω) = q + ½Δt q ⊗ ω``
  (eq. (30)), ``ω_k = ω_{k−1} + w`` with the rate increment ``w`` (angular-acceleration noise)
  applied before the integration, so gyroscope sample k acts on the interval ending at k as in
  strapdown integration (eq. (71) read literally makes the estimate lag one sample); the
  transition Jacobian is Liu's (App. C, corrected): ``∂d/∂q = I + ½Δt Ω(ω)``,
  ``∂d/∂ω = ½Δt Ξ(q)``, with ``w`` entering through ``G = [½Δt Ξ(q); I; 0]``;
- measurements (eq. (72), Table 6): the gyroscope (``H = [0 I I]``), the unit accelerometer
  against ``R(q)ᵀ up`` and the horizontal field direction against ``R(q)ᵀ north`` with the
  Jacobian of ``q* ⊗ a ⊗ q`` (App. A, closed form in the notes). The field enters as its
  horizontal part seen through the prediction (:func:`~motionlab.fusion._kalman_common.
  horizontal_north`), so only the heading is informed by it. On detected rest a zero-rate
  pseudo-measurement ``ω = 0`` makes the bias observable directly;
- marker reference vectors (Liu Tables 3 and 6, :mod:`motionlab.fusion.markers`): a body-fixed
  unit vector ``a`` measured in the earth frame is predicted as ``R(q) a`` (``q ⊗ a ⊗ q*``) with
  the Jacobian of that form (the notes' closed form: App. A with ``q*``, vector part negated) and
  the vector's own noise variance per component; with them the gyroscope enters as the interval
  mean (:func:`~motionlab.fusion.markers.interval_rates`) and the bias starts from the
  registration's estimate;
- the accelerometer carries no heading: where nothing else measured it (no field, no markers at
  the sample) its updates' turn about earth-up is dropped (:func:`~motionlab.fusion._common.
  keep_heading`; through the covariance's tilt-heading terms a start in movement had turned the
  6-D heading by up to 190°);
- every measurement component is a scalar update (diagonal ``R``), linearised at the prediction;
  ``q`` is normalised after the prediction and the update (as Liu does) and the covariance is
  projected onto the tangent space of the unit sphere.

The accelerometer noise grows with the deviation of ``|acc|`` from g and with the rotation rate
(gated beyond ``acc_gate``); the magnetometer is dropped on samples flagged by
:mod:`motionlab.fusion.detect` or whose dip, seen through the estimate, is off the reference.
Defaults were tuned on the 8 BROAD trials in ``../shared``, which are also the reported test set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

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

NX = 10


@dataclass
class EkfParams(KalmanCommon):
    """Tunables of the quaternion EKF with rate and bias states."""

    rate_rw: float = param(50.0, "rad/s²/√Hz", "angular-acceleration noise density (rate state)")
    bias_rw: float = param(1e-4, "rad/s/√s", "gyroscope bias random walk")
    bias_init: float = param(0.02, "rad/s", "initial bias standard deviation")
    rest_noise: float = param(0.005, "rad/s", "noise of the zero-rate pseudo-measurement at rest")


@numba.njit(cache=True, inline="always")
def _jacobian(q: np.ndarray, ax: float, ay: float, az: float, row: int, h: np.ndarray) -> None:
    """Row ``row`` of ``∂(q* ⊗ a ⊗ q)/∂q`` into ``h[0:4]`` (Liu App. A, closed form).

    ``∂u/∂q0 = 2 q0 a − 2 v × a`` and ``∂u/∂v = −2 a vᵀ + 2 (v·a) I + 2 v aᵀ + 2 q0 [a]×``.
    """
    q0, vx, vy, vz = q[0], q[1], q[2], q[3]
    a = (ax, ay, az)
    v = (vx, vy, vz)
    cross = (vy * az - vz * ay, vz * ax - vx * az, vx * ay - vy * ax)
    va = vx * ax + vy * ay + vz * az
    h[0] = 2.0 * q0 * a[row] - 2.0 * cross[row]
    # skew [a]× row ``row``
    if row == 0:
        sk = (0.0, -az, ay)
    elif row == 1:
        sk = (az, 0.0, -ax)
    else:
        sk = (-ay, ax, 0.0)
    for j in range(3):
        h[1 + j] = -2.0 * a[row] * v[j] + 2.0 * v[row] * a[j] + 2.0 * q0 * sk[j]
    h[1 + row] += 2.0 * va


@numba.njit(cache=True)
def _update(
    p: np.ndarray,
    dx: np.ndarray,
    h: np.ndarray,
    innov: float,
    var: float,
    ph: np.ndarray,
    nfree: int,
) -> None:
    """Scalar Kalman update with row ``h`` (dense, NX); ``innov`` is ``z − h(x⁻)``.

    Only the first ``nfree`` states are corrected; the others are *considered* (Schmidt): no
    gain, their own covariance block unchanged, their cross-covariances updated.
    """
    s = var
    for i in range(NX):
        acc = 0.0
        for j in range(NX):
            acc += p[i, j] * h[j]
        ph[i] = acc
        s += h[i] * acc
    r = innov
    for i in range(NX):
        r -= h[i] * dx[i]
    for i in range(nfree):
        dx[i] += ph[i] / s * r
    for i in range(NX):
        for j in range(NX):
            if i < nfree or j < nfree:
                p[i, j] -= ph[i] * ph[j] / s


@numba.njit(cache=True)
def _kernel(rec: tuple, own: tuple, markers: tuple, out: tuple) -> None:
    """The EKF over the recording ``rec`` (:func:`~motionlab.fusion._kalman_common.recording`)
    with its own parameters ``own`` = (rate_rw, bias_rw, bias_init, rest_noise) and the marker
    reference vectors (:func:`~motionlab.fusion._kalman_common.run_with_markers`), into the
    preallocated outputs ``out`` = (quat, bias, dist, used)."""
    gyr, acc, mag, use_mag, pre, rest, dt, q0, prm = rec
    rate_rw, bias_rw, bias_init, rest_noise = own
    ref_body, ref_earth, ref_var, bias0 = markers
    quat, bias, dist, used = out
    n = gyr.shape[0]
    x = np.zeros(NX)
    p = np.zeros((NX, NX))
    f = np.zeros((NX, NX))
    tmp = np.empty((NX, NX))
    g = np.zeros(NX)
    hrow = np.zeros(NX)
    ph = np.empty(NX)
    dx = np.empty(NX)
    r = np.empty((3, 3))
    north = np.empty(3)
    qc = np.empty(4)
    prior = np.empty(4)
    q = x[0:4]
    for i in range(4):
        q[i] = q0[i]
    for i in range(3):
        x[7 + i] = bias0[i]
        x[4 + i] = gyr[0, i] - bias0[i]
    v0 = 0.25 * prm[kc.ATT_INIT] ** 2
    for i in range(4):
        for j in range(4):
            p[i, j] = v0 * ((1.0 if i == j else 0.0) - q[i] * q[j])
    for i in range(3):
        p[4 + i, 4 + i] = 1.0
        p[7 + i, 7 + i] = bias_init**2
    var_w = rate_rw**2 * dt
    var_b = bias_rw**2 * dt
    var_gyr = prm[kc.GYR_NOISE] ** 2 / dt
    var_mag = prm[kc.MAG_NOISE] ** 2 / dt
    hdt = 0.5 * dt
    for k in range(n):
        if k > 0:
            wx, wy, wz = x[4], x[5], x[6]
            # F = [[I + ½Δt Ω(ω), ½Δt Ξ(q), 0], [0, I, 0], [0, 0, I]]
            for i in range(NX):
                for j in range(NX):
                    f[i, j] = 1.0 if i == j else 0.0
            f[0, 1], f[0, 2], f[0, 3] = -hdt * wx, -hdt * wy, -hdt * wz
            f[1, 0], f[1, 2], f[1, 3] = hdt * wx, hdt * wz, -hdt * wy
            f[2, 0], f[2, 1], f[2, 3] = hdt * wy, -hdt * wz, hdt * wx
            f[3, 0], f[3, 1], f[3, 2] = hdt * wz, hdt * wy, -hdt * wx
            # Ξ(q): columns q ⊗ i, q ⊗ j, q ⊗ k
            f[0, 4], f[0, 5], f[0, 6] = -hdt * q[1], -hdt * q[2], -hdt * q[3]
            f[1, 4], f[1, 5], f[1, 6] = hdt * q[0], -hdt * q[3], hdt * q[2]
            f[2, 4], f[2, 5], f[2, 6] = hdt * q[3], hdt * q[0], -hdt * q[1]
            f[3, 4], f[3, 5], f[3, 6] = -hdt * q[2], hdt * q[1], hdt * q[0]
            for i in range(4):
                g[i] = f[i, 0] * q[0] + f[i, 1] * q[1] + f[i, 2] * q[2] + f[i, 3] * q[3]
            for i in range(4):
                q[i] = g[i]
            cm.normalize(q)
            # F P Fᵀ: F differs from I only in rows 0–3 (columns 0–6)
            for i in range(4):
                for j in range(NX):
                    acc_ij = 0.0
                    for m in range(7):
                        acc_ij += f[i, m] * p[m, j]
                    tmp[i, j] = acc_ij
            for i in range(4):
                for j in range(NX):
                    p[i, j] = tmp[i, j]
            for i in range(NX):
                for j in range(4):
                    acc_ij = 0.0
                    for m in range(7):
                        acc_ij += p[i, m] * f[j, m]
                    tmp[i, j] = acc_ij
            for i in range(NX):
                for j in range(4):
                    p[i, j] = tmp[i, j]
                    p[j, i] = tmp[i, j]
            # Q = var_w G Gᵀ per rate axis, G_c = [½Δt Ξ(q)_c; e_c; 0]
            for c in range(3):
                for i in range(NX):
                    g[i] = 0.0
                for i in range(4):
                    g[i] = f[i, 4 + c]
                g[4 + c] = 1.0
                for i in range(7):
                    for j in range(7):
                        p[i, j] += var_w * g[i] * g[j]
                p[7 + c, 7 + c] += var_b
        for i in range(NX):
            dx[i] = 0.0
        # the bias is held (considered, not estimated) while the start-up phase converges
        nfree = 7 if kc.startup_scale(prm, k, dt) < 1.0 else NX
        # gyroscope: z = ω + b
        for c in range(3):
            for i in range(NX):
                hrow[i] = 0.0
            hrow[4 + c] = 1.0
            hrow[7 + c] = 1.0
            _update(p, dx, hrow, gyr[k, c] - x[4 + c] - x[7 + c], var_gyr, ph, nfree)
        if rest[k]:
            for c in range(3):
                for i in range(NX):
                    hrow[i] = 0.0
                hrow[4 + c] = 1.0
                _update(p, dx, hrow, -x[4 + c], rest_noise**2, ph, nfree)
        for i in range(NX):
            hrow[i] = 0.0
        rate = np.sqrt(x[4] ** 2 + x[5] ** 2 + x[6] ** 2)
        var_a = kc.acc_variance(
            acc, k, rate, prm[kc.GRAVITY], prm[kc.ACC_NOISE], prm[kc.ACC_NORM_GAIN],
            prm[kc.ACC_RATE_GAIN], prm[kc.ACC_GATE], dt,
        )  # fmt: skip
        cm.rot_matrix(q, r)
        scale = kc.startup_scale(prm, k, dt)
        var_a *= scale
        used[k] = 0
        for i in range(4):
            prior[i] = q[i] + dx[i]  # the update without the accelerometer, for the heading
        if var_a > 0.0:
            used[k] += USED_ACC
            an = np.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
            for c in range(3):
                _jacobian(q, 0.0, 0.0, 1.0, c, hrow)
                _update(p, dx, hrow, acc[k, c] / an - r[2, c], var_a, ph, nfree)
        dist[k] = True
        if use_mag:
            ok = kc.mag_ok(q, mag, k, pre, prm)
            if ok and kc.horizontal_north(r, mag, k, north):
                dist[k] = False
                used[k] += USED_MAG
                for c in range(3):
                    _jacobian(q, 0.0, 1.0, 0.0, c, hrow)
                    _update(p, dx, hrow, north[c] - r[1, c], var_mag * scale, ph, nfree)
        qc[0], qc[1], qc[2], qc[3] = q[0], -q[1], -q[2], -q[3]
        var_att = 4.0 / 3.0 * (p[0, 0] + p[1, 1] + p[2, 2] + p[3, 3])
        jump = marker_jump(r, ref_body, ref_earth, ref_var, k, var_att)
        if jump > 0.0:  # the markers disagree beyond the covariance: widen the attitude
            for i in range(4):
                for m in range(4):
                    p[i, m] += 0.25 * jump * ((1.0 if i == m else 0.0) - q[i] * q[m])
        for j in range(ref_body.shape[0]):
            if not np.isfinite(ref_earth[k, j, 0]):
                continue
            used[k] |= USED_MARKERS
            ax, ay, az = ref_body[j, 0], ref_body[j, 1], ref_body[j, 2]
            for c in range(3):
                # ∂(q ⊗ a ⊗ q*)/∂q: App. A at q* with the vector part negated
                _jacobian(qc, ax, ay, az, c, hrow)
                for i in range(1, 4):
                    hrow[i] = -hrow[i]
                pred = r[c, 0] * ax + r[c, 1] * ay + r[c, 2] * az
                _update(p, dx, hrow, ref_earth[k, j, c] - pred, ref_var[j], ph, nfree)
        if not used[k] & (USED_MAG | USED_MARKERS):  # nothing measured the heading
            for i in range(4):
                qc[i] = q[i] + dx[i]
            cm.normalize(qc)
            cm.normalize(prior)
            cm.keep_heading(prior, qc)  # the accelerometer's turn about up dropped
            for i in range(4):
                dx[i] = qc[i] - q[i]
        for i in range(NX):
            x[i] += dx[i]
        cm.normalize(q)
        _project(p, q, tmp)
        for i in range(4):
            quat[k, i] = q[i]
        for i in range(3):
            bias[k, i] = x[7 + i]


@numba.njit(cache=True)
def _project(p: np.ndarray, q: np.ndarray, tmp: np.ndarray) -> None:
    """``P ← T P Tᵀ`` with ``T = blkdiag(I − q qᵀ, I)`` (no variance along the unit norm)."""
    for i in range(NX):
        for j in range(NX):
            acc = p[i, j]
            if i < 4:
                for m in range(4):
                    acc -= q[i] * q[m] * p[m, j]
            tmp[i, j] = acc
    for i in range(NX):
        for j in range(NX):
            acc = tmp[i, j]
            if j < 4:
                for m in range(4):
                    acc -= tmp[i, m] * q[m] * q[j]
            p[i, j] = acc


#: Liu's quaternion EKF (2010, §5.2) with bias states, registered as ``ekf``
run = kc.register_filter(
    "ekf", EkfParams, "Liu's quaternion EKF with rate (and gyro-bias) states", _kernel,
    ("rate_rw", "bias_rw", "bias_init", "rest_noise"),
)  # fmt: skip
