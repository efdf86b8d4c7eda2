"""Numba kernels of the quaternion particle filter (:mod:`motionlab.fusion.particle`).

Private: the filter loop :func:`nb_filter` and the small in-place quaternion helpers it uses.
Particles are offsets ``Lᵢ`` with ``qᵢ = Lᵢ ⊗ G`` (G: the shared gyroscope integral); every work
array is allocated once, before the time loop.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import sphere as sph
from motionlab.fusion.resampling import nb_resample

#: quasi-static samples for the tilt divergence test: | |acc| − g | / g and |ω| (rad/s) below these
QUIET_ACC = 0.05
QUIET_RATE = 0.5


@numba.njit(cache=True)
def _nb_eig3(c: np.ndarray, vecs: np.ndarray, lam: np.ndarray) -> None:
    """Eigen-decomposition of the symmetric 3×3 ``c`` (destroyed) by cyclic Jacobi, in place."""
    for i in range(3):
        for j in range(3):
            vecs[i, j] = 1.0 if i == j else 0.0
    for _ in range(30):
        off = c[0, 1] ** 2 + c[0, 2] ** 2 + c[1, 2] ** 2
        if off < 1e-30 * (c[0, 0] ** 2 + c[1, 1] ** 2 + c[2, 2] ** 2) + 1e-300:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                if c[p, q] == 0.0:
                    continue
                theta = 0.5 * (c[q, q] - c[p, p]) / c[p, q]
                t = np.sign(theta) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta == 0.0:
                    t = 1.0
                cs = 1.0 / np.sqrt(t * t + 1.0)
                sn = t * cs
                for k in range(3):
                    ckp = c[k, p]
                    ckq = c[k, q]
                    c[k, p] = cs * ckp - sn * ckq
                    c[k, q] = sn * ckp + cs * ckq
                for k in range(3):
                    cpk = c[p, k]
                    cqk = c[q, k]
                    c[p, k] = cs * cpk - sn * cqk
                    c[q, k] = sn * cpk + cs * cqk
                for k in range(3):
                    vkp = vecs[k, p]
                    vkq = vecs[k, q]
                    vecs[k, p] = cs * vkp - sn * vkq
                    vecs[k, q] = sn * vkp + cs * vkq
    for i in range(3):
        lam[i] = c[i, i]


@numba.njit(cache=True, inline="always")
def _nb_rmul(a: np.ndarray, b0: float, b1: float, b2: float, b3: float) -> None:
    """``a ← a ⊗ b`` for a length-4 row ``a``, normalised."""
    a0, a1, a2, a3 = a[0], a[1], a[2], a[3]
    r0 = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3
    r1 = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2
    r2 = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1
    r3 = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0
    n = 1.0 / np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
    a[0] = r0 * n
    a[1] = r1 * n
    a[2] = r2 * n
    a[3] = r3 * n


@numba.njit(cache=True, inline="always")
def _nb_lmul(b0: float, b1: float, b2: float, b3: float, a: np.ndarray) -> None:
    """``a ← b ⊗ a`` for a length-4 row ``a``, normalised."""
    a0, a1, a2, a3 = a[0], a[1], a[2], a[3]
    r0 = b0 * a0 - b1 * a1 - b2 * a2 - b3 * a3
    r1 = b0 * a1 + b1 * a0 + b2 * a3 - b3 * a2
    r2 = b0 * a2 - b1 * a3 + b2 * a0 + b3 * a1
    r3 = b0 * a3 + b1 * a2 - b2 * a1 + b3 * a0
    n = 1.0 / np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
    a[0] = r0 * n
    a[1] = r1 * n
    a[2] = r2 * n
    a[3] = r3 * n


@numba.njit(cache=True, inline="always")
def _nb_rot(q: np.ndarray, vx: float, vy: float, vz: float, out: np.ndarray) -> None:
    """``out = R(q) v`` (sensor → earth for an orientation q)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out[0] = vx + w * tx + (y * tz - z * ty)
    out[1] = vy + w * ty + (z * tx - x * tz)
    out[2] = vz + w * tz + (x * ty - y * tx)


@numba.njit(cache=True)
def _nb_draw(state, proposal, kappa, lam4, basis, b, zmax, out):
    """One kernel rotation about the identity: vMF(κ) or the band-limited Bingham."""
    if proposal == 0:
        sph._nb_vmf(state, kappa, out)
    else:
        sph._nb_bingham(state, lam4, basis, b, zmax, out)
        if out[0] < 0.0:
            for i in range(4):
                out[i] = -out[i]


@numba.njit(cache=True)
def _nb_spread(state, parts, center, sigma, proposal, zmax, lam4, basis, jit):
    """Redraw all particles about ``center`` with isotropic spread ``sigma`` (rad per axis)."""
    kappa = 4.0 / (sigma * sigma)
    for i in range(4):
        lam4[i] = 0.0 if i == 0 else 2.0 / (sigma * sigma)
        for j in range(4):
            basis[i, j] = 1.0 if i == j else 0.0
    b = sph._nb_bingham_b(lam4)
    for p in range(parts.shape[0]):
        _nb_draw(state, proposal, kappa, lam4, basis, b, zmax, jit)
        for i in range(4):
            parts[p, i] = center[i]
        _nb_rmul(parts[p], jit[0], jit[1], jit[2], jit[3])


@numba.njit(cache=True)
def _nb_kernel_shape(parts, w, mean, h, floor, proposal, cov, vecs, lam3, lam4, basis):
    """Regularisation kernel from the weighted cloud's rotation-vector covariance scaled by h².

    Returns the vMF concentration (isotropic: κ = 4/(h²·tr(C)/3)) and, for the Bingham kernel,
    fills ``lam4``/``basis`` with A = diag(0, 2(h²C)⁻¹) in C's eigenbasis and returns its b.
    """
    for i in range(3):
        for j in range(3):
            cov[i, j] = 0.0
    for p in range(parts.shape[0]):
        # e = mean* ⊗ Lp; rotation vector ≈ 2 e_v with e_w ≥ 0
        a0, a1, a2, a3 = parts[p, 0], parts[p, 1], parts[p, 2], parts[p, 3]
        e0 = mean[0] * a0 + mean[1] * a1 + mean[2] * a2 + mean[3] * a3
        e1 = mean[0] * a1 - mean[1] * a0 - mean[2] * a3 + mean[3] * a2
        e2 = mean[0] * a2 + mean[1] * a3 - mean[2] * a0 - mean[3] * a1
        e3 = mean[0] * a3 - mean[1] * a2 + mean[2] * a1 - mean[3] * a0
        s = 2.0 if e0 >= 0.0 else -2.0
        r0, r1, r2 = s * e1, s * e2, s * e3
        cov[0, 0] += w[p] * r0 * r0
        cov[0, 1] += w[p] * r0 * r1
        cov[0, 2] += w[p] * r0 * r2
        cov[1, 1] += w[p] * r1 * r1
        cov[1, 2] += w[p] * r1 * r2
        cov[2, 2] += w[p] * r2 * r2
    cov[1, 0] = cov[0, 1]
    cov[2, 0] = cov[0, 2]
    cov[2, 1] = cov[1, 2]
    kappa = 4.0 / (h * h * (cov[0, 0] + cov[1, 1] + cov[2, 2]) / 3.0 + floor)
    b = 1.0
    if proposal == 1:
        _nb_eig3(cov, vecs, lam3)
        for i in range(4):
            for j in range(4):
                basis[i, j] = 0.0
        basis[0, 0] = 1.0
        lam4[0] = 0.0
        for k in range(3):
            lam4[k + 1] = 2.0 / (h * h * max(lam3[k], 0.0) + floor)
            for i in range(3):
                basis[i + 1, k + 1] = vecs[i, k]
        b = sph._nb_bingham_b(lam4)
    return kappa, b


@numba.njit(cache=True)
def nb_filter(
    gyr, acc, mag, use_mag, mag_flag, rest, dt, q0, g_ref, m_ref, dip_ref, proposal, scheme,
    alpha, ess_thr, h, zmax, sig_p, acc_sig, acc_rest_sig, acc_norm_gain, acc_gate, kap_m,
    kap_m_rest, m_tol, dip_tol, dip_gate, bias_tau, rest_tau, bias_max, sig0, reset_angle,
    reset_time, seed, n, quat, bias_out, ess_out, reset_out, gated_out,
):  # fmt: skip
    """The filter over all samples; work arrays are allocated once, before the time loop."""
    state = np.empty(2, dtype=np.uint64)
    sph._nb_seed(state, seed)
    parts = np.empty((n, 4))
    tmp = np.empty((n, 4))
    w = np.full(n, 1.0 / n)
    lik = np.empty(n)
    work = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    cov = np.empty((3, 3))
    vecs = np.empty((3, 3))
    lam3 = np.empty(3)
    lam4 = np.empty(4)
    basis = np.empty((4, 4))
    jit = np.empty(4)
    mean = q0.copy()
    center = np.empty(4)
    v3 = np.empty(3)
    g = np.array([1.0, 0.0, 0.0, 0.0])
    b = np.zeros(3)
    _nb_spread(state, parts, q0, sig0, proposal, zmax, lam4, basis, jit)
    half = np.sqrt(3.0 * dt) * sig_p
    floor = sig_p * sig_p * dt
    e_tilt = 0.0
    e_head = 0.0
    out_prev = q0.copy()
    inv_sum = 1.0
    for k in range(gyr.shape[0]):
        # -- gyroscope: the shared strapdown integral G (To eq. 231), bias-compensated
        if k > 0:
            rx = (gyr[k, 0] - b[0]) * dt
            ry = (gyr[k, 1] - b[1]) * dt
            rz = (gyr[k, 2] - b[2]) * dt
            ang = np.sqrt(rx * rx + ry * ry + rz * rz)
            sk = np.sin(0.5 * ang) / ang if ang > 1e-12 else 0.5
            _nb_rmul(g, np.cos(0.5 * ang), sk * rx, sk * ry, sk * rz)
        # -- measurements in the particles' offset frame: R(G)·v
        an = np.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
        _nb_rot(g, acc[k, 0] / g_ref, acc[k, 1] / g_ref, acc[k, 2] / g_ref, v3)
        ax, ay, az = v3[0], v3[1], v3[2]
        dev = abs(an - g_ref) / g_ref
        wn = np.sqrt(gyr[k, 0] ** 2 + gyr[k, 1] ** 2 + gyr[k, 2] ** 2)
        ka = 0.0
        if dev < acc_gate:
            ka = 0.5 / ((acc_rest_sig if rest[k] else acc_sig) + acc_norm_gain * dev) ** 2
        km = 0.0
        mx = my = mz = 0.0
        psi = 0.0
        gated = True
        if use_mag:
            _nb_rot(g, mag[k, 0], mag[k, 1], mag[k, 2], v3)
            mx, my, mz = v3[0], v3[1], v3[2]
            mn = np.sqrt(mx * mx + my * my + mz * mz)
            _nb_rot(mean, mx, my, mz, v3)
            dip = np.arcsin(min(1.0, max(-1.0, -v3[2] / mn))) if mn > 1e-9 else 0.0
            dd = dip - dip_ref
            gated = mag_flag[k] or abs(dd) > dip_gate or mn < 1e-9
            psi = np.arctan2(v3[0], v3[1])
            if not gated:
                km = 0.5 * (kap_m_rest if rest[k] else kap_m)
                km /= 1.0 + ((mn - m_ref) / m_tol) ** 2 + (dd / dip_tol) ** 2
        gated_out[k] = gated
        # -- observed corrections of the prior mean (To's q_obs residuals, eqs. 232-234): tilt
        # from the earth-frame horizontal acc/g (δ × e_z = −h), heading from the field angle ψ
        _nb_rot(mean, ax, ay, az, v3)
        ox = v3[1]
        oy = -v3[0]
        m0, m1, m2, m3 = mean[0], mean[1], mean[2], mean[3]
        lmax = -np.inf
        for p in range(n):
            a = parts[p]
            if k > 0:
                n1 = (2.0 * sph._nb_uniform(state) - 1.0) * half
                n2 = (2.0 * sph._nb_uniform(state) - 1.0) * half
                n3 = (2.0 * sph._nb_uniform(state) - 1.0) * half
                _nb_rmul(a, 1.0, 0.5 * n1, 0.5 * n2, 0.5 * n3)
            # earth-frame offset from the prior mean: δ = 2 vec(L ⊗ m*), hemisphere-aligned
            sg = 2.0 if a[0] * m0 + a[1] * m1 + a[2] * m2 + a[3] * m3 >= 0.0 else -2.0
            dx = sg * (a[1] * m0 - a[0] * m1 - a[2] * m3 + a[3] * m2) - ox
            dy = sg * (a[2] * m0 - a[0] * m2 + a[1] * m3 - a[3] * m1) - oy
            lp = -ka * (dx * dx + dy * dy)
            if km > 0.0:
                dz = sg * (a[3] * m0 - a[0] * m3 - a[1] * m2 + a[2] * m1) - psi
                lp -= km * dz * dz
            lik[p] = lp
            if lp > lmax:
                lmax = lp
        # weights (kept unnormalised between samples: scale by the previous sum here), ESS and
        # the scatter Σ wᵢLᵢLᵢᵀ of Markley's mean in one pass
        sw = 0.0
        s2 = 0.0
        m00 = m01 = m02 = m03 = m11 = m12 = m13 = m22 = m23 = m33 = 0.0
        for p in range(n):
            wp = w[p] * inv_sum * np.exp(lik[p] - lmax)
            w[p] = wp
            sw += wp
            s2 += wp * wp
            a0, a1, a2, a3 = parts[p, 0], parts[p, 1], parts[p, 2], parts[p, 3]
            wa0 = wp * a0
            wa1 = wp * a1
            wa2 = wp * a2
            m00 += wa0 * a0
            m01 += wa0 * a1
            m02 += wa0 * a2
            m03 += wa0 * a3
            m11 += wa1 * a1
            m12 += wa1 * a2
            m13 += wa1 * a3
            m22 += wa2 * a2
            m23 += wa2 * a3
            m33 += wp * a3 * a3
        inv_sum = 1.0 / sw
        ess = sw * sw / s2
        # -- Markley mean, warm-started from the previous one
        p0, p1, p2, p3 = mean[0], mean[1], mean[2], mean[3]
        sph._nb_principal(m00, m01, m02, m03, m11, m12, m13, m22, m23, m33, mean, mean)
        # -- bias (BC): the sensor-frame rotation of the mean's correction δ = prev* ⊗ mean
        d0 = p0 * mean[0] + p1 * mean[1] + p2 * mean[2] + p3 * mean[3]
        sd = 2.0 if d0 >= 0.0 else -2.0
        cx = sd * (p0 * mean[1] - p1 * mean[0] - p2 * mean[3] + p3 * mean[2])
        cy = sd * (p0 * mean[2] + p1 * mean[3] - p2 * mean[0] - p3 * mean[1])
        cz = sd * (p0 * mean[3] - p1 * mean[2] + p2 * mean[1] - p3 * mean[0])
        # sensor frame: R(G)ᵀ c
        _nb_rot_inv(g, cx, cy, cz, v3)
        for i in range(3):
            b[i] -= v3[i] / bias_tau
            if rest[k]:
                b[i] += dt / rest_tau * (gyr[k, i] - b[i])
            b[i] = min(bias_max, max(-bias_max, b[i]))
        # -- divergence: low-passed tilt and heading misfit of the mean
        if dev < QUIET_ACC and wn < QUIET_RATE:
            _nb_rot(mean, ax, ay, az, v3)
            c = min(1.0, max(-1.0, v3[2] / np.sqrt(v3[0] ** 2 + v3[1] ** 2 + v3[2] ** 2)))
            e_tilt += dt / reset_time * (np.arccos(c) - e_tilt)
        if km > 0.0:
            e_head += dt / reset_time * (abs(psi) - e_head)
        if e_tilt > reset_angle or e_head > reset_angle or ess < ess_thr * n:
            for p in range(n):
                w[p] *= inv_sum
            inv_sum = 1.0
        if e_tilt > reset_angle or e_head > reset_angle:
            _nb_vector_attitude(mean, ax, ay, az, mx, my, mz, not gated, center, v3)
            _nb_spread(state, parts, center, sig0, proposal, zmax, lam4, basis, jit)
            for p in range(n):
                w[p] = 1.0 / n
            mean[:] = center
            e_tilt = 0.0
            e_head = 0.0
            reset_out[k] = True
        elif ess < ess_thr * n:
            # -- resample, then regularise with the proposal kernel
            kappa, bb = _nb_kernel_shape(
                parts, w, mean, h, floor, proposal, cov, vecs, lam3, lam4, basis
            )
            nb_resample(state, scheme, alpha, w, idx, work)
            for p in range(n):
                for i in range(4):
                    tmp[p, i] = parts[idx[p], i]
            shrink = np.sqrt(max(1.0 - h * h, 0.0))
            for p in range(n):
                _nb_shrink(mean, tmp[p], shrink, parts[p])
                _nb_draw(state, proposal, kappa, lam4, basis, bb, zmax, jit)
                _nb_rmul(parts[p], jit[0], jit[1], jit[2], jit[3])
        # -- output q = mean ⊗ G, sign-continuous
        o0 = mean[0] * g[0] - mean[1] * g[1] - mean[2] * g[2] - mean[3] * g[3]
        o1 = mean[0] * g[1] + mean[1] * g[0] + mean[2] * g[3] - mean[3] * g[2]
        o2 = mean[0] * g[2] - mean[1] * g[3] + mean[2] * g[0] + mean[3] * g[1]
        o3 = mean[0] * g[3] + mean[1] * g[2] - mean[2] * g[1] + mean[3] * g[0]
        if o0 * out_prev[0] + o1 * out_prev[1] + o2 * out_prev[2] + o3 * out_prev[3] < 0.0:
            o0, o1, o2, o3 = -o0, -o1, -o2, -o3
        quat[k, 0] = o0
        quat[k, 1] = o1
        quat[k, 2] = o2
        quat[k, 3] = o3
        out_prev[0], out_prev[1], out_prev[2], out_prev[3] = o0, o1, o2, o3
        for i in range(3):
            bias_out[k, i] = b[i]
        ess_out[k] = ess / n


@numba.njit(cache=True, inline="always")
def _nb_rot_inv(q: np.ndarray, vx: float, vy: float, vz: float, out: np.ndarray) -> None:
    """``out = R(q)ᵀ v`` (earth → sensor)."""
    w, x, y, z = q[0], -q[1], -q[2], -q[3]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out[0] = vx + w * tx + (y * tz - z * ty)
    out[1] = vy + w * ty + (z * tx - x * tz)
    out[2] = vz + w * tz + (x * ty - y * tx)


@numba.njit(cache=True, inline="always")
def _nb_shrink(mean: np.ndarray, a: np.ndarray, f: float, out: np.ndarray) -> None:
    """``out = mean ⊗ exp(f · log(mean* ⊗ a))``: pull ``a`` towards the mean (Liu & West 2001)."""
    e0 = mean[0] * a[0] + mean[1] * a[1] + mean[2] * a[2] + mean[3] * a[3]
    e1 = mean[0] * a[1] - mean[1] * a[0] - mean[2] * a[3] + mean[3] * a[2]
    e2 = mean[0] * a[2] + mean[1] * a[3] - mean[2] * a[0] - mean[3] * a[1]
    e3 = mean[0] * a[3] - mean[1] * a[2] + mean[2] * a[1] - mean[3] * a[0]
    if e0 < 0.0:
        e0, e1, e2, e3 = -e0, -e1, -e2, -e3
    vn = np.sqrt(e1 * e1 + e2 * e2 + e3 * e3)
    half = np.arctan2(vn, e0)
    k = np.sin(f * half) / vn if vn > 1e-15 else f
    for i in range(4):
        out[i] = mean[i]
    _nb_rmul(out, np.cos(f * half), k * e1, k * e2, k * e3)


@numba.njit(cache=True)
def _nb_vector_attitude(mean, ax, ay, az, mx, my, mz, use_mag, out, v3):
    """The mean corrected to the measured gravity (shortest arc) and, with ``use_mag``, north."""
    _nb_rot(mean, ax, ay, az, v3)
    un = np.sqrt(v3[0] ** 2 + v3[1] ** 2 + v3[2] ** 2)
    ux, uy, uz = v3[0] / un, v3[1] / un, v3[2] / un
    for i in range(4):
        out[i] = mean[i]
    if 1.0 + uz > 1e-9:
        _nb_lmul(1.0 + uz, uy, -ux, 0.0, out)
    else:
        _nb_lmul(0.0, 1.0, 0.0, 0.0, out)
    if use_mag:
        _nb_rot(out, mx, my, mz, v3)
        psi = np.arctan2(v3[0], v3[1])
        _nb_lmul(np.cos(0.5 * psi), 0.0, 0.0, np.sin(0.5 * psi), out)
