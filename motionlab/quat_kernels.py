"""Allocation-free numba helpers for quaternions, and strapdown integration.

Quaternions are scalar first ``[w, x, y, z]`` (Hamilton), as four scalars or preallocated
``(4,)`` arrays; rotation vectors in rad, rates in rad/s. The helpers allocate nothing, so the
per-sample loops of the estimators' kernels (``motionlab/fusion/_*_kernels.py``, which read them
through :mod:`motionlab.fusion._common`) stay allocation-free; :func:`strapdown` is the loop of
:func:`motionlab.rotations.integrate_gyro`. The vectorised quaternion algebra is
:mod:`motionlab.rotations`. Base layer: imports nothing of motionlab.
"""

from __future__ import annotations

import numba
import numpy as np

# ---------------------------------------------------------------- quaternions as scalars


@numba.njit(cache=True, inline="always")
def qmul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product ``a ⊗ b`` as four scalars."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@numba.njit(cache=True, inline="always")
def normq(w, x, y, z):
    """``q / |q|`` as four scalars."""
    n = 1.0 / np.sqrt(w * w + x * x + y * y + z * z)
    return w * n, x * n, y * n, z * n


@numba.njit(cache=True, inline="always")
def conj_mul_shortest(qa: np.ndarray, qb: np.ndarray):
    """``qa* ⊗ qb`` as four scalars, sign chosen so that the scalar part is ≥ 0 (the shorter of
    the two rotations, whose logarithm is the relative rotation vector)."""
    w = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]
    x = qa[0] * qb[1] - qa[1] * qb[0] - qa[2] * qb[3] + qa[3] * qb[2]
    y = qa[0] * qb[2] + qa[1] * qb[3] - qa[2] * qb[0] - qa[3] * qb[1]
    z = qa[0] * qb[3] - qa[1] * qb[2] + qa[2] * qb[1] - qa[3] * qb[0]
    if w < 0.0:
        return -w, -x, -y, -z
    return w, x, y, z


# ---------------------------------------------------------------- quaternions in arrays


@numba.njit(cache=True, inline="always")
def rmul(a: np.ndarray, b0: float, b1: float, b2: float, b3: float) -> None:
    """``a ← a ⊗ b`` for a length-4 row ``a``, normalised."""
    r0, r1, r2, r3 = qmul(a[0], a[1], a[2], a[3], b0, b1, b2, b3)
    a[0], a[1], a[2], a[3] = normq(r0, r1, r2, r3)


@numba.njit(cache=True, inline="always")
def lmul(b0: float, b1: float, b2: float, b3: float, a: np.ndarray) -> None:
    """``a ← b ⊗ a`` for a length-4 row ``a``, normalised."""
    r0, r1, r2, r3 = qmul(b0, b1, b2, b3, a[0], a[1], a[2], a[3])
    a[0], a[1], a[2], a[3] = normq(r0, r1, r2, r3)


@numba.njit(cache=True, inline="always")
def normalize(q: np.ndarray) -> None:
    """In place ``q ← q / |q|``."""
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    q[0], q[1], q[2], q[3] = q[0] / n, q[1] / n, q[2] / n, q[3] / n


@numba.njit(cache=True, inline="always")
def rot_matrix(q: np.ndarray, r: np.ndarray) -> None:
    """Rotation matrix of ``q`` (sensor → earth) into the preallocated 3×3 ``r``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    r[0, 1] = 2.0 * (x * y - w * z)
    r[0, 2] = 2.0 * (x * z + w * y)
    r[1, 0] = 2.0 * (x * y + w * z)
    r[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    r[1, 2] = 2.0 * (y * z - w * x)
    r[2, 0] = 2.0 * (x * z - w * y)
    r[2, 1] = 2.0 * (y * z + w * x)
    r[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@numba.njit(cache=True, inline="always")
def exp_rotvec(rx: float, ry: float, rz: float):
    """``exp(r)`` of the rotation vector ``r`` (rad): ``[cos(|r|/2), sin(|r|/2) r/|r|]``."""
    a = np.sqrt(rx * rx + ry * ry + rz * rz)
    c = np.cos(0.5 * a)
    s = np.sin(0.5 * a) / a if a > 1e-12 else 0.5
    return c, s * rx, s * ry, s * rz


@numba.njit(cache=True, inline="always")
def log_rotvec(w: float, x: float, y: float, z: float):
    """The rotation vector (rad) of the unit quaternion ``[w, x, y, z]``, ``log`` as
    ``2 atan2(|v|, w) v / |v|`` (the shorter rotation when ``w ≥ 0``; the caller picks the
    sign)."""
    vn = np.sqrt(x * x + y * y + z * z)
    c = 2.0 * np.arctan2(vn, w) / vn if vn > 1e-12 else 2.0
    return c * x, c * y, c * z


@numba.njit(cache=True, inline="always")
def mul_exp_right(q: np.ndarray, rx: float, ry: float, rz: float, out: np.ndarray) -> None:
    """``out ← q ⊗ exp(r)`` for the rotation vector ``r`` (rad); ``out`` may be ``q``."""
    pw, px, py, pz = exp_rotvec(rx, ry, rz)
    out[0], out[1], out[2], out[3] = qmul(q[0], q[1], q[2], q[3], pw, px, py, pz)


@numba.njit(cache=True, inline="always")
def mul_exp_left(rx: float, ry: float, rz: float, q: np.ndarray) -> None:
    """In place ``q ← exp(r) ⊗ q`` for the rotation vector ``r`` (rad, earth frame)."""
    pw, px, py, pz = exp_rotvec(rx, ry, rz)
    q[0], q[1], q[2], q[3] = qmul(pw, px, py, pz, q[0], q[1], q[2], q[3])


@numba.njit(cache=True)
def strapdown(q0: np.ndarray, gyr: np.ndarray, dt: np.ndarray, out: np.ndarray) -> None:
    """Strapdown integration of body rates ``gyr`` (N×3, rad/s) from ``q0`` into ``out`` (N×4):
    ``q_k = q_{k-1} ⊗ exp(ω̄ dt_{k-1} / 2)``, normalised, with ω̄ the mean of the two samples (the
    midpoint rule, exact for piecewise-linear rates up to O(dt³)); ``dt`` the N−1 intervals."""
    q = q0.copy()
    out[0] = q
    for k in range(1, gyr.shape[0]):
        h = dt[k - 1]
        rx = 0.5 * (gyr[k - 1, 0] + gyr[k, 0]) * h
        ry = 0.5 * (gyr[k - 1, 1] + gyr[k, 1]) * h
        rz = 0.5 * (gyr[k - 1, 2] + gyr[k, 2]) * h
        mul_exp_right(q, rx, ry, rz, q)
        normalize(q)
        out[k] = q


@numba.njit(cache=True)
def mul_rows(p: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = p[i] ⊗ q[i]`` (Hamilton, scalar first) for (N, 4) or (1, 4) ``p`` and ``q``
    (a single row is used for every ``i``), in :func:`motionlab.rotations.mul`'s order of
    operations (the same numbers to the bit)."""
    one_p, one_q = p.shape[0] == 1, q.shape[0] == 1
    for i in range(out.shape[0]):
        a = 0 if one_p else i
        b = 0 if one_q else i
        pw, px, py, pz = p[a, 0], p[a, 1], p[a, 2], p[a, 3]
        qw, qx, qy, qz = q[b, 0], q[b, 1], q[b, 2], q[b, 3]
        out[i, 0] = pw * qw - px * qx - py * qy - pz * qz
        out[i, 1] = pw * qx + px * qw + py * qz - pz * qy
        out[i, 2] = pw * qy - px * qz + py * qw + pz * qx
        out[i, 3] = pw * qz + px * qy - py * qx + pz * qw


@numba.njit(cache=True)
def rotate_rows(q: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = q[i] ⊗ [0, v[i]] ⊗ q[i]*`` for (N, 4) or (1, 4) ``q`` and (N, 3) or (1, 3)
    ``v`` (a single row is used for every ``i``), in :func:`motionlab.rotations.rotate`'s order
    of operations (``t = 2 u × v``, ``v + w t + u × t``: the same numbers to the bit)."""
    one_q, one_v = q.shape[0] == 1, v.shape[0] == 1
    for i in range(out.shape[0]):
        a = 0 if one_q else i
        b = 0 if one_v else i
        w, ux, uy, uz = q[a, 0], q[a, 1], q[a, 2], q[a, 3]
        vx, vy, vz = v[b, 0], v[b, 1], v[b, 2]
        tx = 2.0 * (uy * vz - uz * vy)
        ty = 2.0 * (uz * vx - ux * vz)
        tz = 2.0 * (ux * vy - uy * vx)
        out[i, 0] = vx + w * tx + (uy * tz - uz * ty)
        out[i, 1] = vy + w * ty + (uz * tx - ux * tz)
        out[i, 2] = vz + w * tz + (ux * ty - uy * tx)
