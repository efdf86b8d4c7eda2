"""To's quaternion linear Kalman filter with a vector-attitude pseudo-measurement (``kf``).

State: the orientation quaternion ``q`` (sensor → ENU earth, scalar first) as a 4-vector.

- prediction (To 2012, thesis eqs. (188)–(191)): ``q⁻ = A q`` with ``A = I + ½ Ω(ω) Δt`` and
  ``Ω(ω) q = q ⊗ [0, ω]`` (body-frame rates), re-normalised; ``P⁻ = A P Aᵀ + Q``;
- measurement (Table 6-1, corrected): the observation quaternion ``q_obs`` of the accelerometer
  and magnetometer — the printed eq. (199) ``q_obs = H z`` is dimensionally wrong, the notes'
  correction is a Gauss–Newton/QUEST/TRIAD quaternion. Here ``q_obs`` starts from the TRIAD
  solution nearest to ``q⁻`` (gravity exact, field sets the heading) and takes Gauss–Newton steps
  (To eq. (206); reduced-order form of Liu 2010, eq. (55)) on the weighted residuals of both
  vectors, weights = inverse variances; the field reference is ``[0, cos δ, −sin δ]`` with the dip
  ``δ`` of the undisturbed data. With ``H = I₄`` the update is the linear KF (eqs. (66)–(69)):
  ``K = P⁻ (P⁻ + R)⁻¹``, ``q = q⁻ + K (q_obs − q⁻)``, ``P = (I − K) P⁻``, then re-normalised.

Noise models (defaults; ``paper_noise=True`` uses To's eqs. (197)–(198) instead):
``Q = ¼ σ_g² Δt (I − q qᵀ)`` (gyroscope white noise through ``½ q ⊗ [0, δω]``) and
``R = ¼ Ψ diag(σ_t², σ_t², σ_h²) Ψᵀ``, ``Ψ`` the 4×3 map of a small earth-frame rotation
``δθ`` to ``½ [0, δθ] ⊗ q``: tilt noise ``σ_t`` from the accelerometer (inflated by the deviation of
``|acc|`` from g and by the rotation rate, gated beyond ``acc_gate``), heading noise ``σ_h`` from
the magnetometer. On samples with a disturbed field (:mod:`motionlab.fusion.detect`) or without a
magnetometer ``q_obs`` corrects the tilt only and ``σ_h`` is effectively infinite, so the heading
is carried by the gyroscope; the update's turn about earth-up, which the covariance's
tilt-heading terms still make, is dropped there (:func:`~motionlab.fusion._common.keep_heading`).
After each step ``P`` is projected onto the tangent space of the unit
sphere at ``q``. The KF has no bias state; on detected rest the gyroscope's mean is taken as its
bias (low-pass with time constant ``rest_bias_tau``) and subtracted from then on.

Defaults were tuned on the 8 BROAD trials in ``../shared``, which are also the reported test set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion import _kalman_common as kc
from motionlab.fusion._kalman_common import KalmanCommon
from motionlab.fusion.registry import FusionResult, param, register
from motionlab.rotations import make_continuous

#: To 2012, eq. (197) as printed (not symmetric); see :func:`paper_process_noise`
TO_Q = np.array(
    [
        [0.12, -0.06, 0.0, -0.06],
        [-0.06, 0.12, -0.06, 0.0],
        [0.0, -0.06, 0.12, -0.06],
        [-0.06, -0.06, -0.06, 0.12],
    ]
)


#: largest Gauss–Newton step |p| (a rotation of 2·atan(|p|) ≈ 11°)
MAX_STEP = 0.1


@dataclass
class KalmanParams(KalmanCommon):
    """Tunables of To's quaternion Kalman filter."""

    gn_iterations: int = param(2, "1", "Gauss–Newton steps of the observation quaternion")
    mag_weight: float = param(
        0.1, "1", "Gauss–Newton weight of the field direction relative to gravity's"
    )
    rest_bias_tau: float = param(1.0, "s", "time constant of the gyro-bias average at rest")
    paper_noise: bool = param(False, "", "use To's printed Q, R, P0 (eqs. 197–198) instead")


def paper_process_noise() -> np.ndarray:
    """To's ``Q`` (eq. (197)) symmetrised and clipped to the nearest positive semidefinite matrix
    (the printed matrix is neither symmetric nor, symmetrised, positive semidefinite)."""
    q = 0.5 * (TO_Q + TO_Q.T)
    val, vec = np.linalg.eigh(q)
    return (vec * np.clip(val, 0.0, None)) @ vec.T


@numba.njit(cache=True, inline="always")
def _psi_col(q: np.ndarray, j: int, out: np.ndarray) -> None:
    """Column ``j`` of Ψ(q): ``[0, e_j] ⊗ q`` (orthonormal columns, all orthogonal to q)."""
    if j == 0:
        out[0], out[1], out[2], out[3] = -q[1], q[0], -q[3], q[2]
    elif j == 1:
        out[0], out[1], out[2], out[3] = -q[2], q[3], q[0], -q[1]
    else:
        out[0], out[1], out[2], out[3] = -q[3], -q[2], q[1], q[0]


@numba.njit(cache=True)
def _gn_step(
    q: np.ndarray,
    r: np.ndarray,
    ax: float,
    ay: float,
    az: float,
    mx: float,
    my: float,
    mz: float,
    w_m: float,
    cos_dip: float,
    sin_dip: float,
) -> None:
    """One reduced-order Gauss–Newton step on ``q`` in place (Liu eq. (55), To eq. (206)).

    Residuals ``ŷ − R(q)ᵀ ref`` of the unit accelerometer (ref up, weight 1) and magnetometer
    (ref ``[0, cos δ, −sin δ]``, weight ``w_m``); with ``X_p = 2[y]×`` the normal equations are
    ``Σ w 4(I − y yᵀ) p = Σ w 2 ŷ × y`` and ``q ← normalise(q ⊗ [1, p])``.
    """
    cm.rot_matrix(q, r)
    n00 = n11 = n22 = 1e-9
    n01 = n02 = n12 = 0.0
    g0 = g1 = g2 = 0.0
    for v in range(2):
        if v == 0:
            yx, yy, yz = r[2, 0], r[2, 1], r[2, 2]
            ox, oy, oz, w = ax, ay, az, 1.0
        else:
            yx = r[1, 0] * cos_dip - r[2, 0] * sin_dip
            yy = r[1, 1] * cos_dip - r[2, 1] * sin_dip
            yz = r[1, 2] * cos_dip - r[2, 2] * sin_dip
            ox, oy, oz, w = mx, my, mz, w_m
        n00 += 4.0 * w * (1.0 - yx * yx)
        n11 += 4.0 * w * (1.0 - yy * yy)
        n22 += 4.0 * w * (1.0 - yz * yz)
        n01 -= 4.0 * w * yx * yy
        n02 -= 4.0 * w * yx * yz
        n12 -= 4.0 * w * yy * yz
        g0 += 2.0 * w * (oy * yz - oz * yy)
        g1 += 2.0 * w * (oz * yx - ox * yz)
        g2 += 2.0 * w * (ox * yy - oy * yx)
    p0, p1, p2 = cm.solve_sym3(n00, n01, n02, n11, n12, n22, g0, g1, g2)
    pn = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    if pn > MAX_STEP:
        # a step beyond the linearisation's reach: shorten it
        p0, p1, p2 = p0 * MAX_STEP / pn, p1 * MAX_STEP / pn, p2 * MAX_STEP / pn
    w0 = q[0] - q[1] * p0 - q[2] * p1 - q[3] * p2
    x0 = q[1] + q[0] * p0 + q[2] * p2 - q[3] * p1
    y0 = q[2] + q[0] * p1 - q[1] * p2 + q[3] * p0
    z0 = q[3] + q[0] * p2 + q[1] * p1 - q[2] * p0
    q[0], q[1], q[2], q[3] = w0, x0, y0, z0
    cm.normalize(q)


@numba.njit(cache=True)
def _observation(
    qp: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray,
    k: int,
    use_m: bool,
    w_m: float,
    cos_dip: float,
    sin_dip: float,
    iters: int,
    qo: np.ndarray,
    r: np.ndarray,
) -> None:
    """Observation quaternion ``qo`` nearest to the prediction ``qp``.

    TRIAD about ``qp`` (shortest tilt rotation that makes the measured up vertical, then the
    heading rotation that points the horizontal field north), refined by Gauss–Newton steps
    when the magnetometer is used; without it the heading of ``qp`` is kept.
    """
    an = np.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
    ax, ay, az = acc[k, 0] / an, acc[k, 1] / an, acc[k, 2] / an
    for i in range(4):
        qo[i] = qp[i]
    cm.rot_matrix(qo, r)
    ex = r[0, 0] * ax + r[0, 1] * ay + r[0, 2] * az
    ey = r[1, 0] * ax + r[1, 1] * ay + r[1, 2] * az
    ez = r[2, 0] * ax + r[2, 1] * ay + r[2, 2] * az
    # half-way quaternion of the arc e → up: [1 + e·up, e × up]
    tw, tx, ty = 1.0 + ez, ey, -ex
    if tw < 1e-9:
        tw, tx, ty = 0.0, 1.0, 0.0
    tn = np.sqrt(tw * tw + tx * tx + ty * ty)
    tw, tx, ty = tw / tn, tx / tn, ty / tn
    w0 = tw * qo[0] - tx * qo[1] - ty * qo[2]
    x0 = tw * qo[1] + tx * qo[0] + ty * qo[3]
    y0 = tw * qo[2] - tx * qo[3] + ty * qo[0]
    z0 = tw * qo[3] + tx * qo[2] - ty * qo[1]
    qo[0], qo[1], qo[2], qo[3] = w0, x0, y0, z0
    cm.normalize(qo)
    if not use_m:
        return
    cm.rot_matrix(qo, r)
    hx = r[0, 0] * mag[k, 0] + r[0, 1] * mag[k, 1] + r[0, 2] * mag[k, 2]
    hy = r[1, 0] * mag[k, 0] + r[1, 1] * mag[k, 1] + r[1, 2] * mag[k, 2]
    cm.mul_exp_left(0.0, 0.0, np.arctan2(hx, hy), qo)
    mn = np.sqrt(mag[k, 0] ** 2 + mag[k, 1] ** 2 + mag[k, 2] ** 2)
    mx, my, mz = mag[k, 0] / mn, mag[k, 1] / mn, mag[k, 2] / mn
    for _ in range(iters):
        _gn_step(qo, r, ax, ay, az, mx, my, mz, w_m, cos_dip, sin_dip)


@numba.njit(cache=True)
def _kernel(rec: tuple, own: tuple, q_paper: np.ndarray, out: tuple) -> None:
    """The quaternion KF over the recording ``rec``
    (:func:`~motionlab.fusion._kalman_common.recording`) with ``own`` = (Gauss–Newton iterations,
    magnetometer weight, rest-bias time constant s, To's process noise ``q_paper`` or not), into
    the preallocated ``out`` = (quat, bias, dist)."""
    gyr, acc, mag, use_mag, pre, rest, dt, q0, prm = rec
    iters, w_m, bias_tau, paper = own
    quat, bias, dist = out
    n = gyr.shape[0]
    q = q0.copy()
    qo = np.empty(4)
    qn = np.empty(4)
    prior = np.empty(4)
    col = np.empty(4)
    r = np.empty((3, 3))
    p = np.empty((4, 4))
    s = np.empty((4, 4))
    kt = np.empty((4, 4))
    tmp = np.empty((4, 4))
    low = np.empty((4, 4))
    b = np.zeros(3)
    var_g = 0.25 * prm[kc.GYR_NOISE] ** 2 * dt
    var_h_mag = prm[kc.MAG_NOISE] ** 2 / dt
    cos_dip, sin_dip = np.cos(prm[kc.REF_DIP]), np.sin(prm[kc.REF_DIP])
    a_bias = min(1.0, dt / bias_tau)
    # P0 = I (To) or ¼ σ_att² (I − q qᵀ): attitude std σ_att, quaternion error ½ δθ
    v0 = 0.25 * prm[kc.ATT_INIT] ** 2
    for i in range(4):
        for j in range(4):
            e = 1.0 if i == j else 0.0
            p[i, j] = e if paper else v0 * (e - q[i] * q[j])
    for k in range(n):
        if rest[k]:
            for i in range(3):
                b[i] += a_bias * (gyr[k, i] - b[i])
        wx, wy, wz = gyr[k, 0] - b[0], gyr[k, 1] - b[1], gyr[k, 2] - b[2]
        if k > 0:
            # q⁻ = (I + ½ Ω Δt) q, eqs. (190)–(191); A is stored in s
            h = 0.5 * dt
            s[0, 0], s[0, 1], s[0, 2], s[0, 3] = 1.0, -h * wx, -h * wy, -h * wz
            s[1, 0], s[1, 1], s[1, 2], s[1, 3] = h * wx, 1.0, h * wz, -h * wy
            s[2, 0], s[2, 1], s[2, 2], s[2, 3] = h * wy, -h * wz, 1.0, h * wx
            s[3, 0], s[3, 1], s[3, 2], s[3, 3] = h * wz, h * wy, -h * wx, 1.0
            for i in range(4):
                qn[i] = s[i, 0] * q[0] + s[i, 1] * q[1] + s[i, 2] * q[2] + s[i, 3] * q[3]
            for i in range(4):
                for j in range(4):
                    tmp[i, j] = s[i, 0] * p[0, j] + s[i, 1] * p[1, j] + s[i, 2] * p[2, j]
                    tmp[i, j] += s[i, 3] * p[3, j]
            for i in range(4):
                for j in range(4):
                    p[i, j] = tmp[i, 0] * s[j, 0] + tmp[i, 1] * s[j, 1] + tmp[i, 2] * s[j, 2]
                    p[i, j] += tmp[i, 3] * s[j, 3]
            for i in range(4):
                q[i] = qn[i]
            cm.normalize(q)
            for i in range(4):
                for j in range(4):
                    e = 1.0 if i == j else 0.0
                    p[i, j] += q_paper[i, j] if paper else var_g * (e - q[i] * q[j])
        dist[k] = True
        use_m = False
        if use_mag:
            use_m = kc.mag_ok(q, mag, k, pre, prm)
            dist[k] = not use_m
        rate = np.sqrt(wx * wx + wy * wy + wz * wz)
        var_t = kc.acc_variance(
            acc, k, rate, prm[kc.GRAVITY], prm[kc.ACC_NOISE], prm[kc.ACC_NORM_GAIN],
            prm[kc.ACC_RATE_GAIN], prm[kc.ACC_GATE], dt,
        )  # fmt: skip
        if var_t > 0.0:
            var_t *= kc.startup_scale(prm, k, dt)
            var_h = var_h_mag * kc.startup_scale(prm, k, dt) if use_m else 1e2
            _observation(q, acc, mag, k, use_m, w_m, cos_dip, sin_dip, iters, qo, r)
            if qo[0] * q[0] + qo[1] * q[1] + qo[2] * q[2] + qo[3] * q[3] < 0.0:
                for i in range(4):
                    qo[i] = -qo[i]
            # S = P⁻ + R; R's unit radial part keeps S well conditioned (P⁻ has none, so the
            # radial gain stays zero)
            for i in range(4):
                for j in range(4):
                    e = 1.0 if i == j else 0.0
                    s[i, j] = p[i, j] + (1e-3 * e if paper else q[i] * q[j])
            if not paper:
                for c in range(3):
                    _psi_col(q, c, col)
                    v = 0.25 * (var_h if c == 2 else var_t)
                    for i in range(4):
                        for j in range(4):
                            s[i, j] += v * col[i] * col[j]
            # Kᵀ = S⁻¹ P⁻ ; q += K (q_obs − q⁻) ; P = P⁻ − K P⁻
            for i in range(4):
                for j in range(4):
                    kt[i, j] = p[i, j]
            cm.chol_solve(s, 4, low, kt, 4)
            for i in range(4):
                d = 0.0
                for j in range(4):
                    d += kt[j, i] * (qo[j] - q[j])
                qn[i] = q[i] + d
            for i in range(4):
                for j in range(4):
                    acc_ij = p[i, j]
                    for m in range(4):
                        acc_ij -= kt[m, i] * p[m, j]
                    tmp[i, j] = acc_ij
            for i in range(4):
                prior[i] = q[i]
                q[i] = qn[i]
                for j in range(4):
                    p[i, j] = 0.5 * (tmp[i, j] + tmp[j, i])
            cm.normalize(q)
            if not use_m:  # nothing measured the heading
                cm.keep_heading(prior, q)
        if not paper:
            _project(p, q, tmp)
        for i in range(4):
            quat[k, i] = q[i]
        for i in range(3):
            bias[k, i] = b[i]


@numba.njit(cache=True)
def _project(p: np.ndarray, q: np.ndarray, tmp: np.ndarray) -> None:
    """``P ← Π P Π`` with ``Π = I − q qᵀ`` (covariance on the tangent space of the sphere)."""
    for i in range(4):
        for j in range(4):
            acc = p[i, j]
            for m in range(4):
                acc -= q[i] * q[m] * p[m, j]
            tmp[i, j] = acc
    for i in range(4):
        for j in range(4):
            acc = tmp[i, j]
            for m in range(4):
                acc -= tmp[i, m] * q[m] * q[j]
            p[i, j] = acc


@register("kf", KalmanParams, "To's quaternion linear KF, Gauss-Newton observation quaternion")
def run(
    gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None, rate: float, params: KalmanParams
) -> FusionResult:
    """Quaternion Kalman filter of To (2012), Table 6-1 corrected; see the module docstring."""
    prep = kc.prepare(gyr, acc, mag, rate, params)
    n = len(gyr)
    quat = np.empty((n, 4))
    bias = np.empty((n, 3))
    dist = np.empty(n, dtype=np.bool_)
    own = (
        int(params.gn_iterations), float(params.mag_weight), float(params.rest_bias_tau),
        bool(params.paper_noise),
    )  # fmt: skip
    rec = kc.recording(gyr, acc, rate, prep, params)
    _kernel(rec, own, paper_process_noise(), (quat, bias, dist))
    return FusionResult(
        make_continuous(quat), "kf", {}, gyro_bias=bias, rest=prep.rest,
        mag_disturbed=dist if prep.use_mag else None, extra={"mag_used": prep.use_mag},
    )  # fmt: skip
