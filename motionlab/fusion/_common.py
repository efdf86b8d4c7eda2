"""Pieces shared by the fusion estimators: the magnetometer's preparation, and numba helpers of
their kernels (small dense solves; the quaternion products of :mod:`motionlab.quat_kernels`,
named here too, so a kernel reads all its helpers as ``cm.<name>``).

Private. Quaternions are scalar first ``[w, x, y, z]``; an orientation ``q`` maps sensor → ENU
earth. Rotation vectors are in rad; ``gyr`` rad/s, ``acc`` m/s², ``mag`` µT, (N, 3) sensor frame.
The numba helpers work on scalars or preallocated arrays and allocate nothing, so the per-sample
loops of the filters stay allocation-free.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import detect
from motionlab.fusion.attitude import initial_orientation
from motionlab.quat_kernels import (  # noqa: F401 (the kernels read them as cm.<name>)
    conj_mul_shortest,
    exp_rotvec,
    lmul,
    log_rotvec,
    mul_exp_left,
    mul_exp_right,
    normalize,
    normq,
    qmul,
    rmul,
    rot_matrix,
)


def prepare_mag(
    gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None, rate: float, norm_tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, tuple[float, float]]:
    """Magnetometer reference and pre-flags, and the initial orientation.

    The magnetometer is used (9-D) when a reference field is found
    (:func:`~motionlab.fusion.detect.field_reference`, field-norm tolerance ``norm_tol`` µT) and
    enough of the recording is undisturbed (:func:`~motionlab.fusion.detect.mag_usable`); the
    initial orientation comes from the first samples whose field is undisturbed.

    Returns
    -------
    q0, mag, pre, use_mag, (ref_norm, ref_dip)
        ``pre`` (N,) bool marks the samples whose field must not be used; without a usable
        magnetometer every sample is marked and ``mag`` is a dummy (1, 3) array. The reference
        field's norm (µT) and dip (rad) are NaN without one.
    """
    use_mag = mag is not None
    ref = (np.nan, np.nan)
    pre = np.ones(len(gyr), dtype=bool)
    if use_mag:
        ref = detect.field_reference(mag, acc, norm_tol=norm_tol)
        pre = detect.mag_disturbance(mag, acc, None, rate, norm_tol=norm_tol, reference=ref)
        use_mag = bool(np.isfinite(ref[0])) and detect.mag_usable(pre)
    start = np.isfinite(acc).all(axis=1) & ~pre if use_mag else np.ones(len(acc), bool)
    first = int(np.argmax(start))
    q0 = initial_orientation(acc[first:], mag[first:] if use_mag else None)
    if not use_mag:
        mag, pre = np.zeros((1, 3)), np.ones(len(gyr), dtype=bool)
    return q0, mag, pre, use_mag, (float(ref[0]), float(ref[1]))


# ---------------------------------------------------------------- small dense solves


@numba.njit(cache=True, inline="always")
def solve_sym3(xx, xy, xz, yy, yz, zz, g0, g1, g2):
    """Solve the symmetric 3×3 system ``N p = g`` by Cramer's rule (``N`` by its upper
    triangle); returns ``p`` as three scalars."""
    c00 = yy * zz - yz * yz
    c01 = xz * yz - xy * zz
    c02 = xy * yz - xz * yy
    det = xx * c00 + xy * c01 + xz * c02
    c11 = xx * zz - xz * xz
    c12 = xy * xz - xx * yz
    c22 = xx * yy - xy * xy
    return (
        (c00 * g0 + c01 * g1 + c02 * g2) / det,
        (c01 * g0 + c11 * g1 + c12 * g2) / det,
        (c02 * g0 + c12 * g1 + c22 * g2) / det,
    )


@numba.njit(cache=True)
def cholesky(a: np.ndarray, n: int, low: np.ndarray) -> None:
    """Lower Cholesky factor of the leading n×n of ``a`` into ``low`` (upper part zeroed)."""
    for i in range(n):
        for j in range(n):
            low[i, j] = 0.0
    for i in range(n):
        for j in range(i + 1):
            s = a[i, j]
            for t in range(j):
                s -= low[i, t] * low[j, t]
            if i == j:
                low[i, i] = np.sqrt(s if s > 1e-300 else 1e-300)
            else:
                low[i, j] = s / low[j, j]


@numba.njit(cache=True)
def chol_solve(a: np.ndarray, n: int, low: np.ndarray, b: np.ndarray, m: int) -> None:
    """Solve ``a x = b`` in place (``b ← x``) for the leading n×n of symmetric positive
    definite ``a`` and the leading n×m of ``b``; ``low`` is an n×n work array."""
    cholesky(a, n, low)
    for c in range(m):
        for i in range(n):
            s = b[i, c]
            for t in range(i):
                s -= low[i, t] * b[t, c]
            b[i, c] = s / low[i, i]
        for i in range(n - 1, -1, -1):
            s = b[i, c]
            for t in range(i + 1, n):
                s -= low[t, i] * b[t, c]
            b[i, c] = s / low[i, i]


@numba.njit(cache=True)
def keep_heading(before: np.ndarray, q: np.ndarray) -> None:
    """Undo the turn about earth-up of a measurement update, in place: ``q ← s ⊗ before`` with
    ``s`` the swing of ``q ⊗ before*`` (its swing-twist split about +z, the twist dropped).

    For updates by gravity alone: it carries no heading, so a Kalman filter turns the heading
    only through the covariance's tilt-heading terms, which in 6-D turned the EKF's, UKF's and
    KF's headings by 18-193° in the first seconds of real seated trunk recordings that start in
    movement (the accelerometer's linear acceleration read as tilt).
    """
    dw, dx, dy, dz = qmul(q[0], q[1], q[2], q[3], before[0], -before[1], -before[2], -before[3])
    n = np.sqrt(dw * dw + dz * dz)
    if n < 1e-12:  # a half turn about a horizontal axis: no twist to drop
        return
    tw, tz = dw / n, dz / n
    sw, sx, sy, sz = qmul(dw, dx, dy, dz, tw, 0.0, 0.0, -tz)
    q[0], q[1], q[2], q[3] = qmul(sw, sx, sy, sz, before[0], before[1], before[2], before[3])
