"""Quaternion algebra, vectorised over time.

Conventions (fixed for all of motionlab):

- Hamilton product, scalar first ``[w, x, y, z]``, float64 arrays of shape ``(N, 4)`` or ``(4,)``.
- An orientation ``q`` maps sensor-frame vectors into the earth frame (ENU):
  ``v_earth = q ⊗ [0, v_sensor] ⊗ q*`` (:func:`rotate`).
- Sequences are kept sign-continuous, ``q_k · q_{k-1} ≥ 0`` (:func:`make_continuous`).
- scipy's :class:`~scipy.spatial.transform.Rotation` is scalar last; :func:`to_scipy` and
  :func:`from_scipy` are the only places that convert.

The numba helpers of the estimators' per-sample loops (quaternions as scalars, allocation-free)
are in :mod:`motionlab.quat_kernels`; :func:`integrate_gyro` runs its :func:`strapdown`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from motionlab.quat_kernels import mul_rows, rotate_rows, strapdown

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) of the same shape; the sign is kept."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def conj(q: np.ndarray) -> np.ndarray:
    """Conjugate ``[w, -x, -y, -z]`` (the inverse of a unit quaternion)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _by_rows(kernel, a: np.ndarray, b: np.ndarray, wa: int, wb: int, w_out: int):
    """``kernel(a, b, out)`` in one compiled loop (:mod:`motionlab.quat_kernels`, the same
    numbers as the broadcast formula) when ``a`` (N, wa) and ``b`` (N, wb) are rows of one
    length or single rows; ``None`` for any other shape (the caller broadcasts)."""
    if a.ndim > 2 or b.ndim > 2 or a.shape[-1] != wa or b.shape[-1] != wb:
        return None
    n_a, n_b = (len(a) if a.ndim == 2 else 1), (len(b) if b.ndim == 2 else 1)
    if n_a != n_b and 1 not in (n_a, n_b):
        return None
    out = np.empty((n_b if n_a == 1 else n_a, w_out))
    kernel(np.ascontiguousarray(a).reshape(-1, wa), np.ascontiguousarray(b).reshape(-1, wb), out)
    return out if a.ndim == 2 or b.ndim == 2 else out[0]


def mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q``, broadcasting over leading dimensions."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    rows = _by_rows(mul_rows, p, q, 4, 4, 4)
    if rows is not None:
        return rows
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vector(s) ``v`` (…, 3) by unit quaternion(s) ``q``: ``q ⊗ [0, v] ⊗ q*``."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    rows = _by_rows(rotate_rows, q, v, 4, 3, 3)
    if rows is not None:
        return rows
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (…, 3, 3) whose columns are the sensor axes in the earth frame."""
    q = normalize(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) with ``w ≥ 0`` from rotation matrices (…, 3, 3)."""
    from scipy.spatial.transform import Rotation  # here: scipy.spatial takes ~0.4 s to import

    m = np.asarray(m, dtype=float)
    q = from_scipy(Rotation.from_matrix(m.reshape(-1, 3, 3)))
    return q.reshape(m.shape[:-2] + (4,))


def to_scipy(q: np.ndarray) -> Rotation:
    """scipy Rotation from scalar-first quaternion(s)."""
    from scipy.spatial.transform import Rotation  # here: scipy.spatial takes ~0.4 s to import

    q = np.asarray(q, dtype=float)
    return Rotation.from_quat(q[..., [1, 2, 3, 0]])


def from_scipy(r: Rotation) -> np.ndarray:
    """Scalar-first quaternion(s) with ``w ≥ 0`` from a scipy Rotation."""
    q = r.as_quat()[..., [3, 0, 1, 2]]
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def from_rotvec(rv: np.ndarray) -> np.ndarray:
    """Quaternion(s) of rotation vector(s) (…, 3) in rad: ``exp(rv / 2)``."""
    rv = np.asarray(rv, dtype=float)
    angle = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle with its limit 1/2 at zero
    k = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return np.concatenate([np.cos(half), k * rv], axis=-1)


def to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector(s) (…, 3) in rad of the shortest rotation (angle ≤ π)."""
    q = np.asarray(q, dtype=float)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    vn = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(vn, q[..., :1])
    k = np.where(vn > 1e-12, angle / np.where(vn > 1e-12, vn, 1.0), 2.0)
    return k * q[..., 1:]


def from_axis_angle(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Quaternion(s) of a rotation by ``angle`` (rad) about ``axis`` (normalised here)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.asarray(angle, dtype=float)[..., None]
    return np.concatenate([np.cos(angle / 2), np.sin(angle / 2) * axis], axis=-1)


def angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, π]) of unit quaternion(s)."""
    q = np.asarray(q, dtype=float)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def twist_angle(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Twist (N,; rad, unwrapped) of rotations ``q`` (N, 4) about ``axis`` (unit, their own
    frame) in the swing-twist decomposition ``q = swing ⊗ twist``."""
    q = np.asarray(q, float)
    q = q * np.where(q[:, :1] < 0.0, -1.0, 1.0)  # one hemisphere: twist in [-π, π]
    return np.unwrap(2.0 * np.arctan2(q[:, 1:] @ np.asarray(axis, float), q[:, 0]))


def angle_between(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Geodesic distance (rad) between orientations: the angle of ``p ⊗ q*``."""
    return angle(mul(p, conj(q)))


def make_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs so that consecutive quaternions satisfy ``q_k · q_{k-1} ≥ 0``."""
    q = np.array(q, dtype=float)
    if q.ndim != 2 or len(q) < 2:
        return q
    dots = np.einsum("ij,ij->i", q[1:], q[:-1])
    flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
    return q * flips[:, None]


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Spherical linear interpolation from ``q0`` (t=0) to ``q1`` (t=1) along the short arc."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    t = np.asarray(t, dtype=float)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    small = theta < 1e-8
    s = np.where(small, 1.0, np.sin(theta))
    a = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / s)
    b = np.where(small, t, np.sin(t * theta) / s)
    return normalize(a * q0 + b * q1)


def resample(t: np.ndarray, q: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """SLERP-resample a quaternion time series onto ``t_new`` (clamped at the ends): each new
    time between its two neighbours by :func:`slerp` (any input norm; unit quaternions out).

    The result is sign-continuous and its first sample takes the sign of the input sample
    it lies next to, so resampling a continuous series at its own times returns it unchanged.
    """
    t = np.ascontiguousarray(t, dtype=float)
    q = np.ascontiguousarray(q, dtype=float)
    if t.ndim != 1 or q.shape != (len(t), 4) or len(t) < 2:
        raise ValueError("resample needs at least 2 quaternions (N, 4) at N times")
    if not (np.isfinite(t).all() and np.all(np.diff(t) > 0)):
        raise ValueError("resample needs finite, strictly increasing times")
    if not np.all(np.linalg.norm(q, axis=1) > 0):  # NaN too
        raise ValueError("resample needs quaternions of nonzero, finite norm")
    t_new = np.clip(np.asarray(t_new, dtype=float).ravel(), t[0], t[-1])
    if not np.isfinite(t_new).all():
        raise ValueError(f"resample needs new times within the range [{t[0]}, {t[-1]}]")
    ind = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, len(t) - 2)
    alpha = (t_new - t[ind]) / (t[ind + 1] - t[ind])
    qn = normalize(q)
    out = slerp(qn[ind], qn[ind + 1], alpha)
    out = make_continuous(out * np.where(out[:, :1] < 0, -1.0, 1.0))
    if len(out):
        k = min(int(np.searchsorted(t, t_new[0], side="right")) - 1, len(t) - 1)
        if np.dot(out[0], q[max(k, 0)]) < 0:
            out = -out
    return out


def mean(q: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Weighted quaternion mean (Markley et al. 2007): principal eigenvector of ``Σ wᵢ qᵢqᵢᵀ``."""
    q = np.asarray(q, dtype=float)
    w = np.ones(len(q)) if weights is None else np.asarray(weights, dtype=float)
    m = (q * w[:, None]).T @ q
    vals, vecs = np.linalg.eigh(m)
    out = vecs[:, -1]
    return out if out[0] >= 0 else -out


def angular_velocity(time: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(midpoints, ω)``: the interval midpoints (N−1,) in s and the angular velocity (N−1, 3)
    in rad/s in the moving frame there.

    ``ω_k = 2 log(q_k* ⊗ q_{k+1}) / (t_{k+1} − t_k)`` (Ricci 2015, eqs. 5.11-5.12); NaN where
    either orientation is NaN.
    """
    time = np.asarray(time, dtype=float)
    quat = np.asarray(quat, dtype=float)
    dq = mul(conj(quat[:-1]), quat[1:])
    return 0.5 * (time[1:] + time[:-1]), to_rotvec(dq) / np.diff(time)[:, None]


def integrate_gyro(q0: np.ndarray, gyr: np.ndarray, dt: float | np.ndarray) -> np.ndarray:
    """Strapdown integration of body angular velocity ``gyr`` (N×3, rad/s) from ``q0``.

    ``dt`` is a scalar step (s) or the N−1 sample intervals. Returns N×4 orientations,
    ``q_k = q_{k-1} ⊗ exp(ω̄ dt / 2)`` with ω̄ the mean of the two samples.
    """
    gyr = np.ascontiguousarray(gyr, dtype=float)
    if len(gyr) == 0:
        return np.empty((0, 4))
    dt_arr = np.broadcast_to(np.asarray(dt, dtype=float), (max(len(gyr) - 1, 0),))
    out = np.empty((len(gyr), 4))
    strapdown(np.array(q0, dtype=float), gyr, np.ascontiguousarray(dt_arr), out)
    return out
