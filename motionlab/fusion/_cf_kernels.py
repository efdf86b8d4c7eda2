"""Numba kernels of the complementary filters (:mod:`motionlab.fusion.complementary`).

Each kernel runs one filter over whole arrays with scalar locals only (no allocation in the
loop). Quaternions are scalar first, sensor → ENU earth; ``pre[k]`` marks samples whose
magnetometer must not be used (precomputed disturbance, or no magnetometer at all: then ``mag``
is a dummy (1, 3) array that is never read). ``gating = (ref_norm, ref_dip, norm_tol, dip_tol)``
is the undisturbed field (µT, rad) and the in-loop tolerances.

Liu's filter also takes optical reference vectors (:mod:`motionlab.fusion.markers`): ``ref_body``
(K, 3) unit marker-pair directions in the sensor frame, ``ref_earth`` (N, K, 3) their measured
directions in the earth frame (NaN where not seen) and ``ref_w`` (K,) their weights; with K = 0
the filter is the IMU-only one. ``used[k]`` records the measurements of each sample as bits
(``USED_ACC``, ``USED_MAG``, ``USED_MARKERS``), from which the thesis's scenario is read.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion.detect import nb_field_disturbed
from motionlab.fusion.markers import USED_ACC, USED_MAG, USED_MARKERS

_DAMP = 1e-6  # Levenberg-Marquardt damping of the 3x3 Gauss-Newton normal matrix


@numba.njit(cache=True, inline="always")
def _unit(x, y, z):
    n = np.sqrt(x * x + y * y + z * z)
    if n < 1e-12:
        return 0.0, 0.0, 0.0, 0.0
    return x / n, y / n, z / n, n


@numba.njit(cache=True, inline="always")
def _to_earth(w, x, y, z, vx, vy, vz):
    """``R(q) v``."""
    return (
        (1.0 - 2.0 * (y * y + z * z)) * vx
        + 2.0 * (x * y - w * z) * vy
        + 2.0 * (x * z + w * y) * vz,
        2.0 * (x * y + w * z) * vx
        + (1.0 - 2.0 * (x * x + z * z)) * vy
        + 2.0 * (y * z - w * x) * vz,
        2.0 * (x * z - w * y) * vx
        + 2.0 * (y * z + w * x) * vy
        + (1.0 - 2.0 * (x * x + y * y)) * vz,
    )


@numba.njit(cache=True, inline="always")
def _to_sensor(w, x, y, z, vx, vy, vz):
    """``R(q)ᵀ v``."""
    return _to_earth(w, -x, -y, -z, vx, vy, vz)


@numba.njit(cache=True, inline="always")
def _gyro_step(w, x, y, z, gx, gy, gz, dt):
    """First-order strapdown step ``q + Δt/2 q ⊗ [0, ω]``, normalised (Liu eq. (30))."""
    dw, dx, dy, dz = cm.qmul(w, x, y, z, 0.0, gx, gy, gz)
    h = 0.5 * dt
    return cm.normq(w + h * dw, x + h * dx, y + h * dy, z + h * dz)


@numba.njit(cache=True, inline="always")
def _mag_ok(pre, k, w, x, y, z, mag, gating):
    if pre[k]:
        return False
    ref_norm, ref_dip, norm_tol, dip_tol = gating
    return not nb_field_disturbed(
        w, x, y, z, mag[k, 0], mag[k, 1], mag[k, 2], ref_norm, ref_dip, norm_tol, dip_tol
    )


@numba.njit(cache=True, inline="always")
def _gn_add(n, g, wt, ox, oy, oz, yx, yy, yz):
    """Accumulate one unit observation ``o`` with prediction ``y`` into the normal equations:
    ``N += 4w(I − yyᵀ)``, ``g += 2w o×y`` (Liu eq. (55) with ``X_p = 2[y]×``)."""
    n[0] += 4.0 * wt * (1.0 - yx * yx)
    n[1] += -4.0 * wt * yx * yy
    n[2] += -4.0 * wt * yx * yz
    n[3] += 4.0 * wt * (1.0 - yy * yy)
    n[4] += -4.0 * wt * yy * yz
    n[5] += 4.0 * wt * (1.0 - yz * yz)
    g[0] += 2.0 * wt * (oy * yz - oz * yy)
    g[1] += 2.0 * wt * (oz * yx - ox * yz)
    g[2] += 2.0 * wt * (ox * yy - oy * yx)


@numba.njit(cache=True, inline="always")
def _gn_add_markers(w, x, y, z, ref_body, ref_earth, ref_w, k, n, g):
    """Accumulate the marker vectors seen at sample ``k``; returns how many there were.

    A body-fixed unit vector ``a`` measured in the earth frame as ``o`` is predicted as
    ``R(q) a`` (Liu eq. (33), ``q ⊗ m ⊗ q*``); with ``q ← q ⊗ [1, p]`` the reduced-order
    Jacobian is ``X_p = −2 R [a]×``, so ``N += 4w(I − aaᵀ)`` and ``g += 2w a × Rᵀo``.
    Returns the number of vectors and the sum of their weights.
    """
    count = 0
    wsum = 0.0
    for j in range(ref_body.shape[0]):
        ox, oy, oz = ref_earth[k, j, 0], ref_earth[k, j, 1], ref_earth[k, j, 2]
        if not (np.isfinite(ox) and np.isfinite(oy) and np.isfinite(oz)):
            continue
        sx, sy, sz = _to_sensor(w, x, y, z, ox, oy, oz)
        ax, ay, az = ref_body[j, 0], ref_body[j, 1], ref_body[j, 2]
        _gn_add(n, g, ref_w[j], -sx, -sy, -sz, ax, ay, az)  # o×y with o = −Rᵀo, y = a
        count += 1
        wsum += ref_w[j]
    return count, wsum


@numba.njit(cache=True, inline="always")
def _marker_step(var, wsum, mu, floor):
    """Step ``s`` of a marker update and the new attitude variance (scalar Kalman schedule).

    ``var`` (rad², per axis) is the variance of the prediction (it grows while the markers are
    hidden, so the first samples after a gap take large steps); the marker solution has
    ``r = 3/(2Σw)`` per axis (normal matrix ``≈ (8/3)Σw I`` of spread vectors).
    ``s = var/(var + r)``, not below ``floor``; a correction ``mu`` (rad) beyond 5σ of both (a
    jump the variance did not foresee, e.g. samples lost from the IMU stream) first raises
    ``var`` to the per-axis share of ``mu²``.
    """
    r = 1.5 / wsum
    if mu * mu > 75.0 * (var + r):
        var = mu * mu / 3.0
    s = max(var / (var + r), floor)
    return min(s, 1.0), (1.0 - s) * var


@numba.njit(cache=True, inline="always")
def _solve_sym(n, g):
    """Solve the damped symmetric 3×3 system ``(N + λI) p = g`` (N packed xx,xy,xz,yy,yz,zz)."""
    return cm.solve_sym3(
        n[0] + _DAMP, n[1], n[2], n[3] + _DAMP, n[4], n[5] + _DAMP, g[0], g[1], g[2]
    )


@numba.njit(cache=True)
def madgwick_kernel(gyr, acc, mag, pre, q0, dt, beta, n_start, startup_gain, gating):
    nn = gyr.shape[0]
    out = np.empty((nn, 4))
    dist = np.empty(nn, dtype=np.bool_)
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    for k in range(nn):
        b = beta * startup_gain if k < n_start else beta
        dw, dx, dy, dz = cm.qmul(w, x, y, z, 0.0, 0.5 * gyr[k, 0], 0.5 * gyr[k, 1], 0.5 * gyr[k, 2])
        ax, ay, az, an = _unit(acc[k, 0], acc[k, 1], acc[k, 2])
        use_m = _mag_ok(pre, k, w, x, y, z, mag, gating)
        dist[k] = not use_m
        if an > 0.0:
            # f = q* d q − s; ∇(½|f|²) = −2 q ⊗ (v ⊗ e) with v = q* d q, e = v − s
            vx, vy, vz = _to_sensor(w, x, y, z, 0.0, 0.0, 1.0)
            ex, ey, ez = vx - ax, vy - ay, vz - az
            sw = -(vx * ex + vy * ey + vz * ez)
            sx, sy, sz = vy * ez - vz * ey, vz * ex - vx * ez, vx * ey - vy * ex
            if use_m:
                mx, my, mz, mn = _unit(mag[k, 0], mag[k, 1], mag[k, 2])
                hx, hy, hz = _to_earth(w, x, y, z, mx, my, mz)
                # earth reference with the measured dip, horizontal part north (paper eq. (46))
                vx, vy, vz = _to_sensor(w, x, y, z, 0.0, np.sqrt(hx * hx + hy * hy), hz)
                ex, ey, ez = vx - mx, vy - my, vz - mz
                sw -= vx * ex + vy * ey + vz * ez
                sx += vy * ez - vz * ey
                sy += vz * ex - vx * ez
                sz += vx * ey - vy * ex
            gw, gx, gy, gz = cm.qmul(w, x, y, z, sw, sx, sy, sz)
            gn = np.sqrt(gw * gw + gx * gx + gy * gy + gz * gz)
            if gn > 1e-12:
                s = b / gn  # subtracting β∇/|∇| with ∇ = −(q ⊗ s): add
                dw += s * gw
                dx += s * gx
                dy += s * gy
                dz += s * gz
        w, x, y, z = cm.normq(w + dt * dw, x + dt * dx, y + dt * dy, z + dt * dz)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
    return out, dist


@numba.njit(cache=True)
def mahony_kernel(gyr, acc, mag, pre, q0, dt, kp, ki, kmag, n_start, startup_gain, gating):
    nn = gyr.shape[0]
    out = np.empty((nn, 4))
    bias = np.empty((nn, 3))
    dist = np.empty(nn, dtype=np.bool_)
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    bx, by, bz = 0.0, 0.0, 0.0
    for k in range(nn):
        ex, ey, ez = 0.0, 0.0, 0.0
        ax, ay, az, an = _unit(acc[k, 0], acc[k, 1], acc[k, 2])
        vx, vy, vz = _to_sensor(w, x, y, z, 0.0, 0.0, 1.0)
        if an > 0.0:
            # measured × predicted (Mahony 2008 eq. (32); To 2018 eq. (209) corrected)
            ex, ey, ez = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
        use_m = _mag_ok(pre, k, w, x, y, z, mag, gating)
        dist[k] = not use_m
        if use_m:
            hx, hy, _ = _to_earth(w, x, y, z, mag[k, 0], mag[k, 1], mag[k, 2])
            hn = np.sqrt(hx * hx + hy * hy)
            if hn > 1e-12:
                # earth error ĥ_xy × north = [0, 0, hx/|h_xy|], mapped into the sensor frame
                e_up = kmag * hx / hn
                ex += e_up * vx
                ey += e_up * vy
                ez += e_up * vz
        if k < n_start:
            gain = kp * startup_gain
        else:
            gain = kp
            bx -= ki * ex * dt
            by -= ki * ey * dt
            bz -= ki * ez * dt
        w, x, y, z = _gyro_step(
            w,
            x,
            y,
            z,
            gyr[k, 0] - bx + gain * ex,
            gyr[k, 1] - by + gain * ey,
            gyr[k, 2] - bz + gain * ez,
            dt,
        )
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
        bias[k, 0], bias[k, 1], bias[k, 2] = bx, by, bz
    return out, bias, dist


@numba.njit(cache=True, inline="always")
def _gn_imu(w, x, y, z, ax, ay, az, wa, use_a, mag, k, wm, use_m, cos_dip, sin_dip, nrm, g):
    """Normal equations ``nrm``, ``g`` (reset here) of the usable unit acc and mag observations;
    the reduced-order Gauss–Newton step ``p`` at ``q`` is then ``_solve_sym(nrm, g)``."""
    for i in range(6):
        nrm[i] = 0.0
    g[0], g[1], g[2] = 0.0, 0.0, 0.0
    if use_a:
        vx, vy, vz = _to_sensor(w, x, y, z, 0.0, 0.0, 1.0)
        _gn_add(nrm, g, wa, ax, ay, az, vx, vy, vz)
    if use_m:
        mx, my, mz, _ = _unit(mag[k, 0], mag[k, 1], mag[k, 2])
        yx, yy, yz = _to_sensor(w, x, y, z, 0.0, cos_dip, -sin_dip)
        _gn_add(nrm, g, wm, mx, my, mz, yx, yy, yz)


@numba.njit(cache=True)
def liu_kernel(
    gyr, acc, mag, pre, q0, dt, gain, wa, wm, acc_tol, gravity, n_start, startup_gain, gating,
    ref_body, ref_earth, ref_w, ref_gain, ref_drift, gap_var,
):  # fmt: skip
    nn = gyr.shape[0]
    out = np.empty((nn, 4))
    dist = np.empty(nn, dtype=np.bool_)
    used = np.empty(nn, dtype=np.int8)
    nrm = np.empty(6)
    g = np.empty(3)
    ref_dip = gating[1]
    cd, sd = np.cos(ref_dip), np.sin(ref_dip)
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    var = 1.0  # attitude variance (rad²) of the IMU prediction, for the marker steps
    for k in range(nn):
        w, x, y, z = _gyro_step(w, x, y, z, gyr[k, 0], gyr[k, 1], gyr[k, 2], dt)
        ax, ay, az, an = _unit(acc[k, 0], acc[k, 1], acc[k, 2])
        use_a = an > 0.0 and abs(an - gravity) < acc_tol
        use_m = _mag_ok(pre, k, w, x, y, z, mag, gating)
        dist[k] = not use_m
        _gn_imu(w, x, y, z, ax, ay, az, wa, use_a, mag, k, wm, use_m, cd, sd, nrm, g)
        n_ref, wsum = _gn_add_markers(w, x, y, z, ref_body, ref_earth, ref_w, k, nrm, g)
        used[k] = USED_ACC * use_a + USED_MAG * use_m + USED_MARKERS * (n_ref > 0)
        if n_ref == 0:  # the attitude error grows while the markers are hidden
            sp = np.sqrt(var) + ref_drift * dt
            var = sp * sp
        var += gap_var[k]  # what the bridge of a packet-loss gap just ended may have missed
        if use_a or use_m or n_ref > 0:
            px, py, pz = _solve_sym(nrm, g)
            s = min(1.0, gain * dt * (startup_gain if k < n_start else 1.0))
            if n_ref > 0:
                mu = 2.0 * np.sqrt(px * px + py * py + pz * pz)
                s, var = _marker_step(var, wsum, mu, ref_gain * dt)
            dw, dx, dy, dz = cm.qmul(w, x, y, z, 0.0, px, py, pz)
            w, x, y, z = cm.normq(w + s * dw, x + s * dx, y + s * dy, z + s * dz)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
    return out, dist, used


@numba.njit(cache=True)
def adaptive_kernel(
    gyr, acc, mag, pre, q0, dt, beta, eps_acc, eps_mag, bias_gain, gravity, n_start,
    startup_gain, gating,
):  # fmt: skip
    nn = gyr.shape[0]
    out = np.empty((nn, 4))
    bias = np.empty((nn, 3))
    dist = np.empty(nn, dtype=np.bool_)
    nrm = np.empty(6)
    g = np.empty(3)
    ref_norm, ref_dip = gating[0], gating[1]
    cd, sd = np.cos(ref_dip), np.sin(ref_dip)
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    bx, by, bz = 0.0, 0.0, 0.0
    for k in range(nn):
        w, x, y, z = _gyro_step(w, x, y, z, gyr[k, 0] - bx, gyr[k, 1] - by, gyr[k, 2] - bz, dt)
        ax, ay, az, an = _unit(acc[k, 0], acc[k, 1], acc[k, 2])
        use_a = an > 0.0 and abs(an - gravity) < eps_acc
        use_m = _mag_ok(pre, k, w, x, y, z, mag, gating)
        if use_m:
            mn = np.sqrt(mag[k, 0] ** 2 + mag[k, 1] ** 2 + mag[k, 2] ** 2)
            use_m = abs(mn - ref_norm) < eps_mag
        dist[k] = not use_m
        if use_a or use_m:
            _gn_imu(w, x, y, z, ax, ay, az, 1.0, use_a, mag, k, 1.0, use_m, cd, sd, nrm, g)
            px, py, pz = _solve_sym(nrm, g)
            # δθ = 2p is the full Gauss-Newton correction (rotation vector, sensor frame)
            tx, ty, tz = 2.0 * px, 2.0 * py, 2.0 * pz
            if not use_a:  # magnetometer alone: heading only
                vx, vy, vz = _to_sensor(w, x, y, z, 0.0, 0.0, 1.0)
                c = tx * vx + ty * vy + tz * vz
                tx, ty, tz = c * vx, c * vy, c * vz
            mu = np.sqrt(tx * tx + ty * ty + tz * tz)
            bdt = beta * dt * (startup_gain if k < n_start else 1.0)
            gam = bdt / (mu + bdt)
            tx, ty, tz = gam * tx, gam * ty, gam * tz
            dw, dx, dy, dz = cm.qmul(w, x, y, z, 0.0, 0.5 * tx, 0.5 * ty, 0.5 * tz)
            w, x, y, z = cm.normq(w + dw, x + dx, y + dy, z + dz)
            if k >= n_start:
                bx -= bias_gain * tx
                by -= bias_gain * ty
                bz -= bias_gain * tz
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
        bias[k, 0], bias[k, 1], bias[k, 2] = bx, by, bz
    return out, bias, dist
