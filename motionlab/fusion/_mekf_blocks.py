"""Numba kernels of the smoother's multi-rate MEKF (see :mod:`motionlab.fusion.mekf`).

The orientation is integrated at the full rate; the covariance is propagated, the measurements
applied and the RTS backward pass run only at **update instants** ``u_0 = 0``,
``u_j = min(j m, N − 1)``: block ``j ≥ 1`` holds the samples ``u_{j−1} < s ≤ u_j``. Over a block
the error state ``[δθ, δb, δa]`` (earth-frame attitude error, gyroscope and accelerometer bias;
as :mod:`._mekf_kernels`) moves with the accumulated transition
``Φ = [[I, −dt Σ_s R_s, 0], [0, I, 0], [0, 0, I]]`` (``R_s`` the rotation matrix of the sample's
integrated orientation) and process noise ``Q = c diag(qa I, qb I, qc I)`` (``c`` samples). The
block's measurements, each taken under its own sample's integrated orientation, are applied at
``u_j`` as their means with the variance divided by their count: for a constant error state the
exact equivalent of the ``c`` sequential scalar updates where their rows are the same (the
accelerometer rows in motion, the steady rests' gyroscope bias, the magnetometer heading, taken
as the weighted mean direction of the samples' horizontal fields); at rest the bias columns
``R δa / g`` of the accelerometer rows are the block's mean (the sensor barely turns). What it
neglects is the error state's change within the block (``dt R δb`` per sample: a bias error of
0.01 rad/s moves the attitude by 0.02° over a 40-ms block). The same split as in strapdown
navigation, where the attitude is integrated at the IMU's rate and the error-state Kalman filter
runs at a lower one (e.g. Groves, *Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems*, 2nd ed., 2013).

Conventions: quaternions scalar first, sensor → ENU earth; gyroscope rad/s, accelerometer m/s².
Nothing in the loops allocates. With ``m = 1`` and no magnetometer the forward pass is the online
filter's :func:`._mekf_kernels.forward` to rounding (``tests/test_mekf_blocks.py``).
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion import _mekf_kernels as kn
from motionlab.fusion import _mekf_monitor as mon_k

N_ERR = kn.N_ERR


def instants(n: int, m: int) -> np.ndarray:
    """The update instants (B,) int of ``n`` samples in blocks of ``m``: 0, m, 2m, …, n − 1."""
    return np.append(np.arange(0, n - 1, m), n - 1)


@numba.njit(cache=True, inline="always")
def _step(q: np.ndarray, rx: float, ry: float, rz: float) -> None:
    """``q ← q ⊗ exp(r)`` (not normalised) for a rotation vector ``r`` (rad): below 0.1 rad
    by the series of ``cos(|r|/2)`` and ``sin(|r|/2)/|r|`` in ``|r|²`` to the ``|r|⁶`` term
    (truncation below 2e-16), else by :func:`motionlab.quat_kernels.mul_exp_right`."""
    a2 = rx * rx + ry * ry + rz * rz
    if a2 >= 0.01:
        cm.mul_exp_right(q, rx, ry, rz, q)
        return
    c = 1.0 - a2 * (1.0 / 8.0 - a2 * (1.0 / 384.0 - a2 * (1.0 / 46080.0)))
    sn = 0.5 - a2 * (1.0 / 48.0 - a2 * (1.0 / 3840.0 - a2 * (1.0 / 645120.0)))
    q[0], q[1], q[2], q[3] = cm.qmul(q[0], q[1], q[2], q[3], c, sn * rx, sn * ry, sn * rz)


@numba.njit(cache=True)
def forward(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray,
    use_mag: bool,
    blk_scale: np.ndarray,
    rest: np.ndarray,
    steady: np.ndarray,
    blk_extra: np.ndarray,
    dt: float,
    m: int,
    q0: np.ndarray,
    p0: np.ndarray,
    prm: np.ndarray,
    quat: np.ndarray,
    qprior: np.ndarray,
    gsum: np.ndarray,
    bias: np.ndarray,
    acc_bias: np.ndarray,
    reset: np.ndarray,
    p_post: np.ndarray,
    field: np.ndarray,
) -> None:
    """The multi-rate error-state EKF (module docstring) over all samples, into preallocated
    outputs.

    Per sample: ``quat`` (N×4) the forward estimate (integrated within a block, the posterior at
    its instant). Per block ``j`` (B of them, :func:`instants`): ``qprior`` (B×4) the integrated
    orientation at ``u_j`` before the update, ``gsum`` (B×3×3) ``Σ_s R_s`` over the block,
    ``bias``/``acc_bias`` (B×3) the posterior biases, ``reset`` (B, int8) the reset applied at
    the block (1 attitude, 0 none), ``p_post`` (B×N_PACKED, or 1 row: not stored) the posterior
    covariance's upper triangle, ``field`` (B×3, or 1 row: not wanted) the mean earth-frame
    field of the block's samples under their integrated orientation.

    ``blk_scale`` (B): the block's heading-variance factor (offline gate, infinite: its field is
    not used; :func:`motionlab.fusion.detect.field_gate`), against the fixed reference field
    ``prm[MAG_FIXED_NORM]``, ``prm[MAG_FIXED_DIP]`` (heading resets are off). ``blk_extra``
    (B, rad², or length 1: none): attitude variance added to the block's prior (packet-loss
    gaps). ``rest``/``steady`` (N): as :func:`._mekf_kernels.forward`. A block in which a reset
    is applied uses no other measurement (its samples' vectors were taken under the estimate
    the reset replaces).
    """
    n = gyr.shape[0]
    nb = qprior.shape[0]
    q = q0.copy()
    b = np.zeros(3)
    a = np.zeros(3)
    p = p0.copy()
    r = np.empty((3, 3))
    rs = np.empty((3, 3))
    hr = np.empty((2, 3))
    t = np.empty((3, 6))
    dx = np.zeros(N_ERR)
    kvec = np.empty(N_ERR)
    row = np.empty(N_ERR)
    h = np.zeros(N_ERR)
    mon = np.empty(mon_k.N_MONITOR)
    corr = np.zeros(3)
    sg = np.zeros(3)
    mon_k.monitor_clear(mon)
    cos_tilt = np.cos(prm[kn.RESET_TILT])
    cos_heading = np.cos(prm[kn.RESET_HEADING])
    qa = prm[kn.GYR_NOISE] ** 2 * dt
    qb = prm[kn.BIAS_RW] ** 2 * dt
    qc = prm[kn.ACC_BIAS_RW] ** 2 * dt
    g = prm[kn.GRAVITY]
    var_m = prm[kn.ACC_NOISE] ** 2
    var_r = prm[kn.ACC_REST_NOISE] ** 2
    w_mag_m = 1.0 / prm[kn.MAG_NOISE] ** 2
    w_mag_r = 1.0 / prm[kn.MAG_REST_NOISE] ** 2
    ref_n, ref_d = prm[kn.MAG_FIXED_NORM], prm[kn.MAG_FIXED_DIP]
    extra = blk_extra.shape[0] == nb
    store = p_post.shape[0] == nb
    want_field = field.shape[0] == nb
    mode = 0
    with_heading = False
    hi = -1
    for j in range(nb):
        lo = hi + 1
        hi = min(j * m, n - 1)
        cnt = hi - lo + 1
        for i in range(3):
            sg[i] = 0.0
            for c in range(3):
                rs[i, c] = 0.0
        for c in range(3):
            hr[0, c] = 0.0
            hr[1, c] = 0.0
        mxs, mys, cm_ = 0.0, 0.0, 0
        rxs, rys, cr = 0.0, 0.0, 0
        cs = 0
        eax, eay, eaz = 0.0, 0.0, 0.0
        fx, fy, fz = 0.0, 0.0, 0.0
        hx, hy, wsum = 0.0, 0.0, 0.0
        use_field = use_mag and np.isfinite(blk_scale[j])
        for s in range(lo, hi + 1):
            if s > 0:
                _step(q, (gyr[s, 0] - b[0]) * dt, (gyr[s, 1] - b[1]) * dt, (gyr[s, 2] - b[2]) * dt)
                if s == hi:
                    cm.normalize(q)
            cm.rot_matrix(q, r)
            if s > 0:
                for i in range(3):
                    for c in range(3):
                        rs[i, c] += r[i, c]
            cx, cy, cz = acc[s, 0] - a[0], acc[s, 1] - a[1], acc[s, 2] - a[2]
            ax = r[0, 0] * cx + r[0, 1] * cy + r[0, 2] * cz
            ay = r[1, 0] * cx + r[1, 1] * cy + r[1, 2] * cz
            az = r[2, 0] * cx + r[2, 1] * cy + r[2, 2] * cz
            eax += ax
            eay += ay
            eaz += az
            if rest[s]:
                rxs += ax
                rys += ay
                cr += 1
                for c in range(3):
                    hr[0, c] += r[0, c]
                    hr[1, c] += r[1, c]
                if steady[s]:
                    for i in range(3):
                        sg[i] += gyr[s, i]
                    cs += 1
            else:
                mxs += ax
                mys += ay
                cm_ += 1
            if want_field or use_mag:
                ex = r[0, 0] * mag[s, 0] + r[0, 1] * mag[s, 1] + r[0, 2] * mag[s, 2]
                ey = r[1, 0] * mag[s, 0] + r[1, 1] * mag[s, 1] + r[1, 2] * mag[s, 2]
                ez = r[2, 0] * mag[s, 0] + r[2, 1] * mag[s, 1] + r[2, 2] * mag[s, 2]
                fx += ex
                fy += ey
                fz += ez
                if use_field:
                    hn = np.sqrt(ex * ex + ey * ey)
                    if hn > 0.0:
                        w = w_mag_r if rest[s] else w_mag_m
                        hx += w * ex / hn
                        hy += w * ey / hn
                        wsum += w
            quat[s] = q
        for i in range(4):
            qprior[j, i] = q[i]
        for i in range(3):
            for c in range(3):
                gsum[j, i, c] = rs[i, c]
        if j > 0:
            kn._predict(p, rs, dt, cnt * qa, cnt * qb, cnt * qc, t)
        for i in range(N_ERR):
            dx[i] = 0.0
        reset[j] = mode
        kn._inflate(p, mode, prm[kn.ATT_INIT])
        if extra:
            for i in range(3):
                p[i, i] += blk_extra[j]
        if mode != 0:
            var = prm[kn.RESET_NOISE] ** 2
            kn._scalar_update(p, dx, 0, corr[0], var, False, kvec, row)
            kn._scalar_update(p, dx, 1, corr[1] - dx[1], var, False, kvec, row)
            if with_heading:
                kn._scalar_update(p, dx, 2, corr[2] - dx[2], var, False, kvec, row)
            kn._inject(q, b, a, dx)
            mon_k.monitor_clear(mon)
            mode = 0
        else:
            if cs > 0:
                var = prm[kn.REST_NOISE] ** 2 / cs
                for i in range(3):
                    z = sg[i] / cs - b[i] - dx[3 + i]
                    kn._scalar_update(p, dx, 3 + i, z, var, False, kvec, row)
            if not mon_k.tilt_run(mon):
                if cr > 0:
                    h[0], h[1], h[2] = 0.0, -1.0, 0.0
                    for i in range(3):
                        h[6 + i] = hr[0, i] / (cr * g)
                    kn._row_update(p, dx, h, rxs / (cr * g), var_r / cr, kvec, row)
                    h[0], h[1] = 1.0, 0.0
                    for i in range(3):
                        h[6 + i] = hr[1, i] / (cr * g)
                    kn._row_update(p, dx, h, rys / (cr * g), var_r / cr, kvec, row)
                if cm_ > 0:
                    kn._axis_update(p, dx, 1, -1.0, mxs / (cm_ * g), var_m / cm_, kvec, row)
                    kn._axis_update(p, dx, 0, 1.0, mys / (cm_ * g), var_m / cm_, kvec, row)
            if wsum > 0.0:
                before = dx[2]
                psi = np.arctan2(hx, hy)
                kn._scalar_update(p, dx, 2, psi - dx[2], blk_scale[j] / wsum, True, kvec, row)
                if mon_k.in_run(mon):
                    mon_k.monitor_turn(mon, dx[2] - before)
            kn._inject(q, b, a, dx)
            # the monitor sees the block's mean vectors under the estimate before its update
            mode = mon_k.monitor(
                mon, (eax / cnt, eay / cnt, eaz / cnt), (fx / cnt, fy / cnt, fz / cnt), False,
                min(1.0, cnt * dt / prm[kn.RESET_TAU]), cos_tilt, cos_heading,
                prm[kn.RESET_TIME], prm[kn.RESET_HEADING_TIME], prm[kn.RESET_AGREE], cnt * dt,
            )  # fmt: skip
            if mode != 0:
                with_heading = mon_k.reset_correction(
                    mon, mode, use_mag, ref_n, ref_d, prm[kn.MAG_NORM_TOL], prm[kn.MAG_DIP_TOL],
                    corr,
                )  # fmt: skip
        quat[hi] = q
        for i in range(3):
            bias[j, i] = b[i]
            acc_bias[j, i] = a[i]
        if store:
            kn._pack_upper(p, p_post[j])
        if want_field:
            field[j, 0], field[j, 1], field[j, 2] = fx / cnt, fy / cnt, fz / cnt


@numba.njit(cache=True, inline="always")
def _error_angle(qs: np.ndarray, qbar: np.ndarray, e: np.ndarray) -> None:
    """``e[0:3]`` ← the rotation vector of ``qs ⊗ conj(qbar)`` (rad, earth frame)."""
    s0, s1, s2, s3 = qs[0], qs[1], qs[2], qs[3]
    ew = s0 * qbar[0] + s1 * qbar[1] + s2 * qbar[2] + s3 * qbar[3]
    ex = -s0 * qbar[1] + s1 * qbar[0] - s2 * qbar[3] + s3 * qbar[2]
    ey = -s0 * qbar[2] + s1 * qbar[3] + s2 * qbar[0] - s3 * qbar[1]
    ez = -s0 * qbar[3] - s1 * qbar[2] + s2 * qbar[1] + s3 * qbar[0]
    if ew < 0.0:
        ew, ex, ey, ez = -ew, -ex, -ey, -ez
    e[0], e[1], e[2] = cm.log_rotvec(ew, ex, ey, ez)


@numba.njit(cache=True, inline="always")
def _turn_row(
    field: np.ndarray, j: int, rx: float, ry: float, rz: float, qs: np.ndarray, r: np.ndarray
) -> None:
    """``field[j] ← exp(r) field[j]``: the row turned by the rotation vector ``r`` (rad, earth
    frame); ``qs`` (4) and ``r`` (3×3) are workspace."""
    qs[0], qs[1], qs[2], qs[3] = 1.0, 0.0, 0.0, 0.0
    cm.mul_exp_left(rx, ry, rz, qs)
    cm.normalize(qs)
    cm.rot_matrix(qs, r)
    x, y, z = field[j, 0], field[j, 1], field[j, 2]
    for i in range(3):
        field[j, i] = r[i, 0] * x + r[i, 1] * y + r[i, 2] * z


@numba.njit(cache=True)
def backward(
    dt: float,
    m: int,
    quat: np.ndarray,
    qprior: np.ndarray,
    gsum: np.ndarray,
    bias: np.ndarray,
    acc_bias: np.ndarray,
    p_post: np.ndarray,
    reset: np.ndarray,
    blk_extra: np.ndarray,
    prm: np.ndarray,
    interp: bool,
    bias_out: np.ndarray,
    acc_bias_out: np.ndarray,
    field: np.ndarray,
) -> None:
    """Rauch–Tung–Striebel backward pass at the update instants of a :func:`forward` pass.

    ``e_j = P_j Φᵀ (P⁻_{j+1})⁻¹ e⁻_{j+1}`` (Särkkä 2013, eq. 8.6, on the error state), the prior
    ``P⁻_{j+1}`` recomputed from ``P_j`` with the block's ``gsum`` as the forward pass did it.
    The smoothed states at the instants overwrite ``quat[u_j]``, ``bias``, ``acc_bias`` (B×3).
    With ``interp`` every sample between two instants takes the forward estimate corrected by
    the attitude error interpolated linearly between the smoothed one after ``u_j`` and before
    ``u_{j+1}`` (what the block's bias error does to the integrated orientation, linear in time),
    ``bias_out``/``acc_bias_out`` (N×3) the smoothed biases interpolated linearly, and the
    quaternions' signs are made continuous from sample 0. Without,
    only the instants are written. ``field`` (B×3, or 1 row: none), the blocks' mean earth-frame
    fields of the forward pass, is turned by each block's mean correction (under the smoothed
    estimate, for the magnetometer gate).
    """
    n = quat.shape[0]
    nb = qprior.shape[0]
    r = np.empty((3, 3))
    t = np.empty((3, 6))
    pk = np.empty((N_ERR, N_ERR))
    pp = np.empty((N_ERR, N_ERR))
    low = np.empty((N_ERR, N_ERR))
    inv = np.empty(N_ERR)
    e = np.empty(N_ERR)
    ep = np.empty(N_ERR)
    f = np.empty(N_ERR)
    qs = np.empty(4)
    qa = prm[kn.GYR_NOISE] ** 2 * dt
    qb = prm[kn.BIAS_RW] ** 2 * dt
    qc = prm[kn.ACC_BIAS_RW] ** 2 * dt
    extra = blk_extra.shape[0] == nb
    turn = field.shape[0] == nb
    up = min((nb - 1) * m, n - 1)
    if interp:
        for i in range(3):
            bias_out[up, i] = bias[nb - 1, i]
            acc_bias_out[up, i] = acc_bias[nb - 1, i]
    for j in range(nb - 2, -1, -1):
        uj = j * m
        cnt = up - uj
        # the smoothed error at u_{j+1} against the forward prior there
        _error_angle(quat[up], qprior[j + 1], e)
        for i in range(3):
            e[3 + i] = bias[j + 1, i] - bias[j, i]
            e[6 + i] = acc_bias[j + 1, i] - acc_bias[j, i]
        for i in range(N_ERR):
            ep[i] = e[i]
        c = 0
        for i in range(N_ERR):
            for k in range(i, N_ERR):
                v = p_post[j, c]
                pk[i, k] = pk[k, i] = pp[i, k] = pp[k, i] = v
                c += 1
        for i in range(3):
            for k in range(3):
                r[i, k] = gsum[j + 1, i, k]
        kn._predict(pp, r, dt, cnt * qa, cnt * qb, cnt * qc, t)
        kn._inflate(pp, reset[j + 1], prm[kn.ATT_INIT])
        if extra:
            for i in range(3):
                pp[i, i] += blk_extra[j + 1]
        kn._spd_solve(pp, low, inv, e)
        # f = Φᵀ y with Φ = [[I, −dt Σ R, 0], [0, I, 0], [0, 0, I]]
        for i in range(3):
            f[i] = e[i]
            f[3 + i] = e[3 + i] - dt * (r[0, i] * e[0] + r[1, i] * e[1] + r[2, i] * e[2])
            f[6 + i] = e[6 + i]
        for i in range(N_ERR):
            s = 0.0
            for k in range(N_ERR):
                s += pk[i, k] * f[k]
            e[i] = s
        if turn:  # the block's samples carry, on average, the mean of the two ends' corrections
            mean = 0.5 * (e[0] + ep[0]), 0.5 * (e[1] + ep[1]), 0.5 * (e[2] + ep[2])
            _turn_row(field, j + 1, mean[0], mean[1], mean[2], qs, r)
        if interp:
            # the corrections of the two ends as quaternions, interpolated linearly (normalised
            # with the product: the same as interpolating the rotation vector to second order
            # in their difference, the block's bias drift)
            d0w, d0x, d0y, d0z = cm.exp_rotvec(e[0], e[1], e[2])
            d1w, d1x, d1y, d1z = cm.exp_rotvec(ep[0], ep[1], ep[2])
            if d0w * d1w + d0x * d1x + d0y * d1y + d0z * d1z < 0.0:
                d1w, d1x, d1y, d1z = -d1w, -d1x, -d1y, -d1z
            for s in range(uj + 1, up):
                w = (s - uj) / cnt
                v = 1.0 - w
                r0, r1, r2, r3 = cm.qmul(
                    v * d0w + w * d1w, v * d0x + w * d1x, v * d0y + w * d1y, v * d0z + w * d1z,
                    quat[s, 0], quat[s, 1], quat[s, 2], quat[s, 3],
                )  # fmt: skip
                nrm = 1.0 / np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
                quat[s, 0], quat[s, 1], quat[s, 2], quat[s, 3] = (
                    r0 * nrm,
                    r1 * nrm,
                    r2 * nrm,
                    r3 * nrm,
                )
                for i in range(3):
                    bias_out[s, i] = v * (bias[j, i] + e[3 + i]) + w * bias[j + 1, i]
                    acc_bias_out[s, i] = v * (acc_bias[j, i] + e[6 + i]) + w * acc_bias[j + 1, i]
        cm.mul_exp_left(e[0], e[1], e[2], quat[uj])
        cm.normalize(quat[uj])
        for i in range(3):
            bias[j, i] += e[3 + i]
            acc_bias[j, i] += e[6 + i]
            if interp:
                bias_out[uj, i] = bias[j, i]
                acc_bias_out[uj, i] = acc_bias[j, i]
        up = uj
    if interp:
        # signs continuous from sample 0 (as motionlab.rotations.make_continuous)
        for s in range(1, n):
            dot = 0.0
            for i in range(4):
                dot += quat[s, i] * quat[s - 1, i]
            if dot < 0.0:
                for i in range(4):
                    quat[s, i] = -quat[s, i]
    if turn:
        # block 0 (sample 0) carries its own correction: the instant's
        _error_angle(quat[0], qprior[0], e)
        _turn_row(field, 0, e[0], e[1], e[2], qs, r)


def compiled() -> bool | None:
    """Whether numba's on-disk cache holds code for :func:`forward` and :func:`backward` (so
    this process loads them, as on every run after the first), ``False`` when numba will compile
    them first (the first run after installing or upgrading: about half a minute), ``None`` when
    this numba's cache cannot be asked (its cache classes are numba's own, not public API)."""
    try:
        return all(bool(k._cache._cache_file._load_index()) for k in (forward, backward))
    except Exception:  # noqa: BLE001 - any failure to read numba's internals: unknown
        return None
