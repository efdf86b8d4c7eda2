"""Numba kernels of the multiplicative EKF (see :mod:`motionlab.fusion.mekf`): the online filter's
per-sample loop and the covariance updates that the smoother's multi-rate kernels
(:mod:`motionlab.fusion._mekf_blocks`) share with it.

Conventions: quaternions scalar first, sensor → ENU earth; gyroscope rad/s, accelerometer m/s²,
magnetometer µT. The error state (``N_ERR`` = 9) is ``[δθ, δb, δa]``: ``δθ`` (rad) a small
rotation in the **earth** frame, ``q_true = exp(δθ/2) ⊗ q``; ``δb`` (rad/s) the gyroscope-bias
error, ``b_true = b + δb``; ``δa`` (m/s², sensor frame) the accelerometer-bias error,
``a_true = a + δa``. With an earth-frame attitude error the transition matrix is
``F = [[I, −R dt, 0], [0, I, 0], [0, 0, I]]`` (``R`` = rotation matrix of ``q``). The
accelerometer's horizontal earth-frame rows see ``δθ_x, δθ_y`` and ``R δa / g`` (general scalar
rows, :func:`_row_update`); the magnetometer's heading and the rest and reset updates see one
component each (:func:`_scalar_update`). Nothing in the loop allocates. The per-sample loop's
offline options (a fixed reference field with per-sample weights, stored covariances, the gaps'
process noise) were the smoother's before it became multi-rate; ``tests/test_mekf_blocks.py``
checks the multi-rate pass with blocks of one sample against this loop.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion import _mekf_monitor as mon_k
from motionlab.fusion.registry import KernelParams

#: the float parameter vector of :func:`forward`, packed from :class:`~.mekf.MekfParams`; the
#: last three are the offline magnetometer gate: fixed reference norm (≤ 0: learn it online) and
#: dip, and whether an undisturbed field may call for a heading reset
PRM = KernelParams(
    "gyr_noise", "bias_rw", "acc_noise", "acc_rest_noise", "rest_noise", "gravity",
    "mag_noise", "mag_rest_noise", "mag_norm_tol", "mag_dip_tol", "mag_ref_tau",
    "mag_new_field_time", "att_init", "reset_tilt", "reset_heading", "reset_time",
    "reset_heading_time", "reset_tau", "reset_noise", "reset_agree", "mag_new_field_min",
    "mag_fixed_norm", "mag_fixed_dip", "mag_heading_reset", "acc_bias_rw",
)  # fmt: skip
GYR_NOISE, BIAS_RW, ACC_NOISE, ACC_REST_NOISE, REST_NOISE, GRAVITY = range(6)
MAG_NOISE, MAG_REST_NOISE, MAG_NORM_TOL, MAG_DIP_TOL, MAG_REF_TAU = range(6, 11)
MAG_NEW_FIELD_TIME, ATT_INIT, RESET_TILT, RESET_HEADING, RESET_TIME = range(11, 16)
RESET_HEADING_TIME, RESET_TAU, RESET_NOISE, RESET_AGREE, MAG_NEW_FIELD_MIN = range(16, 21)
MAG_FIXED_NORM, MAG_FIXED_DIP, MAG_HEADING_RESET, ACC_BIAS_RW = range(21, 25)

#: dimension of the error state ``[δθ, δb, δa]``
N_ERR = 9
#: floats of a stored covariance (its upper triangle)
N_PACKED = N_ERR * (N_ERR + 1) // 2


@numba.njit(cache=True, inline="always")
def _inject(q: np.ndarray, b: np.ndarray, a: np.ndarray, dx: np.ndarray) -> None:
    """Move the error state ``dx`` into the estimate, ``q ← exp(δθ/2) ⊗ q`` (normalised),
    ``b ← b + δb`` and ``a ← a + δa``, and clear it."""
    cm.mul_exp_left(dx[0], dx[1], dx[2], q)
    cm.normalize(q)
    for i in range(3):
        b[i] += dx[3 + i]
        a[i] += dx[6 + i]
    for i in range(N_ERR):
        dx[i] = 0.0


@numba.njit(cache=True)
def _predict(
    p: np.ndarray, r: np.ndarray, dt: float, qa: float, qb: float, qc: float, t: np.ndarray
) -> None:
    """Covariance prediction ``P ← F P Fᵀ + Q`` with ``F = [[I, G, 0], [0, I, 0], [0, 0, I]]``,
    ``G = −R dt``; ``Q = diag(qa I, qb I, qc I)``. ``t`` is a 3×6 work array."""
    # new cross blocks: P_ab + G P_bb and P_ac + G P_bc; then P_aa += G P_abᵀ + (P_ab + G P_bb) Gᵀ
    for i in range(3):
        for j in range(6):
            acc = p[i, 3 + j]
            for m in range(3):
                acc -= r[i, m] * dt * p[3 + m, 3 + j]
            t[i, j] = acc
    for i in range(3):
        for j in range(i, 3):
            acc = p[i, j]
            for m in range(3):
                acc -= r[i, m] * dt * p[j, 3 + m] + t[i, m] * r[j, m] * dt
            p[i, j] = acc
            p[j, i] = acc
    for i in range(3):
        for j in range(6):
            p[i, 3 + j] = t[i, j]
            p[3 + j, i] = t[i, j]
        p[i, i] += qa
        p[3 + i, 3 + i] += qb
        p[6 + i, 6 + i] += qc


@numba.njit(cache=True, inline="always")
def _gain_update(
    p: np.ndarray, dx: np.ndarray, ph: np.ndarray, s: float, innov: float, k: np.ndarray
) -> None:
    """The Kalman update of one scalar measurement from ``ph = P hᵀ``, ``s = h P hᵀ + var`` and
    the innovation: ``K = ph / s``, ``dx ← dx + K innov``, ``P ← P − K phᵀ`` (upper triangle
    computed and mirrored, so ``P`` stays exactly symmetric)."""
    n = N_ERR
    for i in range(n):
        k[i] = ph[i] / s
        dx[i] += k[i] * innov
    for i in range(n):
        for m in range(i, n):
            v = p[i, m] - k[i] * ph[m]
            p[i, m] = v
            p[m, i] = v


@numba.njit(cache=True)
def _scalar_update(
    p: np.ndarray,
    dx: np.ndarray,
    j: int,
    innov: float,
    var: float,
    heading_only: bool,
    k: np.ndarray,
    ph: np.ndarray,
) -> None:
    """Kalman update with a scalar measurement of error component ``j`` (``H = e_j``).

    ``innov`` is the residual at the prior error (``z − H dx``). With ``heading_only`` the gain
    of the inclination components (``δθ_x, δθ_y``) and of the accelerometer bias (which would
    move the inclination at the next sample) is forced to zero and the covariance is updated in
    Joseph form, which stays valid for that suboptimal gain: with ``ph = P e_j`` and
    ``s = P_jj + var``, ``(I − K e_jᵀ) P (I − K e_jᵀ)ᵀ + var K Kᵀ = P − K phᵀ − ph Kᵀ + s K Kᵀ``.
    ``P`` is symmetric and stays exactly so.
    """
    n = N_ERR
    for i in range(n):
        ph[i] = p[i, j]
    s = ph[j] + var
    if not heading_only:
        _gain_update(p, dx, ph, s, innov, k)
        return
    for i in range(n):
        k[i] = ph[i] / s
    k[0] = 0.0
    k[1] = 0.0
    for i in range(6, n):
        k[i] = 0.0
    for i in range(n):
        dx[i] += k[i] * innov
    for i in range(n):
        for m in range(i, n):
            v = p[i, m] - k[i] * ph[m] - ph[i] * k[m] + s * k[i] * k[m]
            p[i, m] = v
            p[m, i] = v


@numba.njit(cache=True)
def _row_update(
    p: np.ndarray,
    dx: np.ndarray,
    h: np.ndarray,
    z: float,
    var: float,
    k: np.ndarray,
    ph: np.ndarray,
) -> None:
    """Kalman update with a scalar measurement ``z = h · x + v``, ``v ~ N(0, var)``, of the
    error state (``h`` a general row, N_ERR); ``k`` and ``ph`` are work arrays.

    ``dx ← dx + K (z − h dx)``, ``K = P h / (hᵀ P h + var)``, ``P ← P − K (P h)ᵀ``.
    """
    n = N_ERR
    for i in range(n):
        acc = 0.0
        for m in range(n):
            acc += p[i, m] * h[m]
        ph[i] = acc
    s = var
    innov = z
    for i in range(n):
        s += h[i] * ph[i]
        innov -= h[i] * dx[i]
    _gain_update(p, dx, ph, s, innov, k)


@numba.njit(cache=True)
def _axis_update(
    p: np.ndarray,
    dx: np.ndarray,
    j: int,
    c: float,
    z: float,
    var: float,
    k: np.ndarray,
    ph: np.ndarray,
) -> None:
    """:func:`_row_update` for the row ``h = c e_j`` (one error component, scaled by ``c``)."""
    n = N_ERR
    for i in range(n):
        ph[i] = c * p[i, j]
    _gain_update(p, dx, ph, var + c * ph[j], z - c * dx[j], k)


@numba.njit(cache=True, inline="always")
def _pack_upper(p: np.ndarray, out: np.ndarray) -> None:
    """The upper triangle of the symmetric ``p`` (N_ERR²), row by row, into ``out`` (N_PACKED)."""
    c = 0
    for i in range(N_ERR):
        for m in range(i, N_ERR):
            out[c] = p[i, m]
            c += 1


@numba.njit(cache=True, inline="always")
def _inflate(p: np.ndarray, mode: int, att_init: float) -> None:
    """A reset's process noise: ``att_init²`` on the attitude variances (all three for an
    attitude reset, mode 1; the heading's for a heading reset, mode 2; none for mode 0)."""
    if mode != 0:
        first = 0 if mode == 1 else 2
        for i in range(first, 3):
            p[i, i] += att_init**2


@numba.njit(cache=True)
def forward(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray,
    use_mag: bool,
    rest: np.ndarray,
    steady: np.ndarray,
    dt: float,
    q0: np.ndarray,
    p0: np.ndarray,
    prm: np.ndarray,
    quat: np.ndarray,
    bias: np.ndarray,
    acc_bias: np.ndarray,
    mag_dist: np.ndarray,
    reset: np.ndarray,
) -> None:
    """Run the error-state EKF over all samples, writing into the preallocated outputs.

    ``quat`` (N×4), ``bias`` (N×3, rad/s), ``acc_bias`` (N×3, m/s², sensor frame), ``mag_dist``
    (N) receive the posterior estimates, ``reset`` (N, int8) the samples where the attitude was
    re-initialised (1: attitude, 2: heading only; 0: none). The biases start at zero, the error
    covariance at ``p0`` (9×9, symmetric); the covariance stays exactly symmetric.

    A reset found at sample k is applied at k+1 as process noise plus a measurement: the
    attitude covariance is inflated by ``ATT_INIT²`` in the prior (so that a backward pass
    decouples the samples before the reset, whose estimates were inconsistent), then the
    vector-attitude correction is measured with standard deviation ``RESET_NOISE``.

    The field's reference (norm, dip) is learnt online (the smoother's passes,
    :mod:`._mekf_blocks`, fix it instead).

    ``rest`` (N) flags the samples at rest (the accelerometer and magnetometer at their rest
    noise); the gyroscope measures the bias where ``steady`` (N) is set too.
    """
    n = gyr.shape[0]
    q = q0.copy()
    b = np.zeros(3)
    a = np.zeros(3)
    p = p0.copy()
    r = np.empty((3, 3))
    t = np.empty((3, 6))
    dx = np.zeros(N_ERR)
    kvec = np.empty(N_ERR)
    row = np.empty(N_ERR)
    h = np.zeros(N_ERR)
    mon = np.empty(mon_k.N_MONITOR)
    corr = np.zeros(3)
    mon_k.monitor_clear(mon)
    alpha = min(1.0, dt / prm[RESET_TAU])
    cos_tilt = np.cos(prm[RESET_TILT])
    cos_heading = np.cos(prm[RESET_HEADING])
    mx, my, mz = 0.0, 0.0, 0.0
    qa = prm[GYR_NOISE] ** 2 * dt
    qb = prm[BIAS_RW] ** 2 * dt
    qc = prm[ACC_BIAS_RW] ** 2 * dt
    g = prm[GRAVITY]
    a_ref = dt / prm[MAG_REF_TAU]
    ref_n = -1.0
    ref_d = 0.0
    cand_n = 0.0
    cand_d = 0.0
    cand_t = 0.0
    ref_age = 0.0
    mode = 0
    with_heading = False
    heading_reset = prm[MAG_HEADING_RESET] > 0.0
    for k in range(n):
        wx = gyr[k, 0] - b[0]
        wy = gyr[k, 1] - b[1]
        wz = gyr[k, 2] - b[2]
        if k > 0:
            cm.mul_exp_right(q, wx * dt, wy * dt, wz * dt, q)
            cm.normalize(q)
            cm.rot_matrix(q, r)
            _predict(p, r, dt, qa, qb, qc, t)
        for i in range(N_ERR):
            dx[i] = 0.0
        reset[k] = mode
        _inflate(p, mode, prm[ATT_INIT])
        if mode != 0:
            var = prm[RESET_NOISE] ** 2
            if mode == 1:
                _scalar_update(p, dx, 0, corr[0], var, False, kvec, row)
                _scalar_update(p, dx, 1, corr[1] - dx[1], var, False, kvec, row)
                if with_heading:
                    _scalar_update(p, dx, 2, corr[2] - dx[2], var, False, kvec, row)
            else:
                _scalar_update(p, dx, 2, corr[2], var, True, kvec, row)
            _inject(q, b, a, dx)
            mon_k.monitor_clear(mon)
            mode = 0
        if rest[k] and steady[k]:
            var = prm[REST_NOISE] ** 2
            for i in range(3):
                _scalar_update(p, dx, 3 + i, gyr[k, i] - b[i] - dx[3 + i], var, False, kvec, row)
        cm.rot_matrix(q, r)
        # earth-frame bias-corrected acc over g, linear in acc (not normalised by |acc|):
        # zero-mean linear acceleration then averages out instead of being weighted by its own
        # magnitude
        cx, cy, cz = acc[k, 0] - a[0], acc[k, 1] - a[1], acc[k, 2] - a[2]
        ax = r[0, 0] * cx + r[0, 1] * cy + r[0, 2] * cz
        ay = r[1, 0] * cx + r[1, 1] * cy + r[1, 2] * cz
        az = r[2, 0] * cx + r[2, 1] * cy + r[2, 2] * cz
        var = (prm[ACC_REST_NOISE] if rest[k] else prm[ACC_NOISE]) ** 2
        # residual e_z × δθ = (−δθ_y, δθ_x), plus R δa / g at rest: two scalar rows, gated
        # while inconsistent. In motion the bias columns are left out (see the module docstring
        # of mekf: a limb's linear acceleration is correlated with its orientation and would
        # be taken for a bias); the vertical row is not used (it would tie δa to |acc| − g,
        # i.e. to scale errors and the local gravity)
        if not mon_k.tilt_run(mon):
            if rest[k]:
                h[0], h[1], h[2] = 0.0, -1.0, 0.0
                for i in range(3):
                    h[6 + i] = r[0, i] / g
                _row_update(p, dx, h, ax / g, var, kvec, row)
                h[0], h[1] = 1.0, 0.0
                for i in range(3):
                    h[6 + i] = r[1, i] / g
                _row_update(p, dx, h, ay / g, var, kvec, row)
            else:
                _axis_update(p, dx, 1, -1.0, ax / g, var, kvec, row)
                _axis_update(p, dx, 0, 1.0, ay / g, var, kvec, row)
        _inject(q, b, a, dx)
        mag_dist[k] = False
        mag_ok = False
        if use_mag:
            cm.rot_matrix(q, r)
            mx = r[0, 0] * mag[k, 0] + r[0, 1] * mag[k, 1] + r[0, 2] * mag[k, 2]
            my = r[1, 0] * mag[k, 0] + r[1, 1] * mag[k, 1] + r[1, 2] * mag[k, 2]
            mz = r[2, 0] * mag[k, 0] + r[2, 1] * mag[k, 1] + r[2, 2] * mag[k, 2]
            mn = np.sqrt(mx * mx + my * my + mz * mz)
            hn = np.sqrt(mx * mx + my * my)
            if mn > 0.0 and hn > 0.0:
                dip = np.arcsin(mz / mn)
                if ref_n < 0.0:
                    ref_n, ref_d, cand_n, cand_d = mn, dip, mn, dip
                ok = (
                    abs(mn - ref_n) < prm[MAG_NORM_TOL] * ref_n
                    and abs(dip - ref_d) < prm[MAG_DIP_TOL]
                )
                if ok:
                    ref_n += a_ref * (mn - ref_n)
                    ref_d += a_ref * (dip - ref_d)
                    ref_age += dt
                    cand_t = 0.0
                else:
                    # a new homogeneous field: accepted once steady for as long as the
                    # reference was seen, at least MAG_NEW_FIELD_MIN, at most MAG_NEW_FIELD_TIME
                    same = (
                        abs(mn - cand_n) < prm[MAG_NORM_TOL] * cand_n
                        and abs(dip - cand_d) < prm[MAG_DIP_TOL]
                    )
                    if same:
                        cand_t += dt
                        cand_n += a_ref * (mn - cand_n)
                        cand_d += a_ref * (dip - cand_d)
                    else:
                        cand_n, cand_d, cand_t = mn, dip, 0.0
                    if cand_t > min(prm[MAG_NEW_FIELD_TIME], max(prm[MAG_NEW_FIELD_MIN], ref_age)):
                        ref_n, ref_d, ref_age, cand_t = cand_n, cand_d, cand_t, 0.0
                        ok = True
                mag_dist[k] = not ok
                mag_ok = ok
                if ok:
                    var = (prm[MAG_REST_NOISE] if rest[k] else prm[MAG_NOISE]) ** 2
                    _scalar_update(p, dx, 2, np.arctan2(mx, my), var, True, kvec, row)
                    cm.mul_exp_left(0.0, 0.0, dx[2], q)
                    cm.normalize(q)
                    if mon_k.in_run(mon):
                        mon_k.monitor_turn(mon, dx[2])
                    for i in range(3):
                        b[i] += dx[3 + i]
        # the monitor sees the vectors under the estimate before this sample's small corrections
        mode = mon_k.monitor(
            mon, (ax, ay, az), (mx, my, mz), mag_ok and heading_reset, alpha, cos_tilt, cos_heading,
            prm[RESET_TIME], prm[RESET_HEADING_TIME], prm[RESET_AGREE], dt,
        )  # fmt: skip
        if mode != 0:
            with_heading = mon_k.reset_correction(
                mon, mode, use_mag, ref_n, ref_d, prm[MAG_NORM_TOL], prm[MAG_DIP_TOL], corr
            )
            if mode == 1:
                ref_age = 0.0  # learnt under the wrong attitude: a steady field may replace it
        quat[k] = q
        bias[k] = b
        acc_bias[k] = a


@numba.njit(cache=True, inline="always")
def _spd_solve(a: np.ndarray, low: np.ndarray, inv: np.ndarray, y: np.ndarray) -> None:
    """``y ← a⁻¹ y`` for symmetric positive definite ``a`` (N_ERR², lower triangle read) by
    Cholesky, ``a = L Lᵀ``; ``low`` (N_ERR²) and ``inv`` (N_ERR, the reciprocal diagonal of
    ``L``) are work arrays. A pivot below 1e-300 is taken as 1e-300."""
    n = N_ERR
    for i in range(n):
        for j in range(i):
            s = a[i, j]
            for t in range(j):
                s -= low[i, t] * low[j, t]
            low[i, j] = s * inv[j]
        s = a[i, i]
        for t in range(i):
            s -= low[i, t] * low[i, t]
        inv[i] = 1.0 / np.sqrt(s if s > 1e-300 else 1e-300)
    for i in range(n):
        s = y[i]
        for t in range(i):
            s -= low[i, t] * y[t]
        y[i] = s * inv[i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for t in range(i + 1, n):
            s -= low[t, i] * y[t]
        y[i] = s * inv[i]
