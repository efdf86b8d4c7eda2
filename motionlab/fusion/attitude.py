"""Attitude from vector observations: TRIAD, Davenport's q-method (QUEST's exact solution),
a reduced-order Gauss–Newton observation quaternion, and the initial orientation of a filter.

Conventions: ``q`` maps sensor-frame vectors into the ENU earth frame (scalar first), so a body
vector ``b`` and its reference ``r`` satisfy ``r = rotate(q, b)``. At rest the accelerometer reads
earth-up ``[0, 0, 1]`` (times g) in the sensor frame; the magnetometer's horizontal component
points north, earth ``[0, 1, 0]``. Functions accept single vectors ``(3,)`` or stacks ``(N, 3)``.

References: Black, AIAA J. 1964 (TRIAD); Davenport 1968 and Shuster & Oh, J. Guid. Control 1981
(q-method / QUEST); Liu 2010, thesis §5.1.3 eqs. (46)–(55) (reduced-order Gauss–Newton, errata
corrected: ``X_p`` is (3m)×3).
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError

UP = np.array([0.0, 0.0, 1.0])
NORTH = np.array([0.0, 1.0, 0.0])


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if not np.all(n > 1e-12):
        raise InputError(f"{name} has a zero-length vector", remedy="check the sensor signals")
    return v / n


def _triad_frame(v1: np.ndarray, v2: np.ndarray, name: str) -> np.ndarray:
    """Orthonormal triad (…, 3, 3) with columns t1 = v1, t2 ∝ v1 × v2, t3 = t1 × t2."""
    t1 = _unit(v1, name)
    c = np.cross(t1, np.asarray(v2, dtype=float))
    t2 = _unit(c, f"{name} (parallel vectors)")
    return np.stack([t1, t2, np.cross(t1, t2)], axis=-1)


def triad(
    v1_body: np.ndarray, v2_body: np.ndarray, v1_ref: np.ndarray, v2_ref: np.ndarray
) -> np.ndarray:
    """TRIAD attitude: ``v1`` is matched exactly, ``v2`` only fixes the rotation about it.

    Parameters
    ----------
    v1_body, v2_body
        Observed vectors in the sensor frame, (3,) or (N, 3), any length.
    v1_ref, v2_ref
        The same directions in the earth frame.

    Returns
    -------
    q
        (4,) or (N, 4) unit quaternion(s) with ``v_ref = rotate(q, v_body)`` for the first pair.
    """
    body = _triad_frame(v1_body, v2_body, "body vectors")
    ref = _triad_frame(v1_ref, v2_ref, "reference vectors")
    m = ref @ np.swapaxes(body, -1, -2)
    return rot.from_matrix(m)


def _left(p: np.ndarray) -> np.ndarray:
    """Matrix (…, 4, 4) of left multiplication ``p ⊗ q`` for pure quaternions ``p = [0, v]``."""
    x, y, z = np.moveaxis(p, -1, 0)
    o = np.zeros_like(x)
    return np.stack(
        [
            np.stack([o, -x, -y, -z], -1),
            np.stack([x, o, -z, y], -1),
            np.stack([y, z, o, -x], -1),
            np.stack([z, -y, x, o], -1),
        ],
        axis=-2,
    )


def _right(p: np.ndarray) -> np.ndarray:
    """Matrix (…, 4, 4) of right multiplication ``q ⊗ p`` for pure quaternions ``p = [0, v]``."""
    x, y, z = np.moveaxis(p, -1, 0)
    o = np.zeros_like(x)
    return np.stack(
        [
            np.stack([o, -x, -y, -z], -1),
            np.stack([x, o, z, -y], -1),
            np.stack([y, -z, o, x], -1),
            np.stack([z, y, -x, o], -1),
        ],
        axis=-2,
    )


def quest(
    body_vecs: np.ndarray, ref_vecs: np.ndarray, weights: np.ndarray | None = None
) -> np.ndarray:
    """Optimal attitude of weighted vector pairs (Wahba's problem) by Davenport's q-method.

    Maximises ``Σ wᵢ rᵢ·rotate(q, bᵢ)`` = ``qᵀ K q`` with the symmetric 4×4
    ``K = Σ wᵢ sym(R(bᵢ)ᵀ L(rᵢ))`` (``L``, ``R``: left/right quaternion-product matrices of the
    unit vectors), so ``q`` is the eigenvector of K's largest eigenvalue. This is the exact
    solution that QUEST approximates by Newton iteration on the characteristic polynomial.

    Parameters
    ----------
    body_vecs, ref_vecs
        (K, 3) or (N, K, 3) observed (sensor) and reference (earth) directions, K ≥ 2 and not
        all parallel. They are normalised here.
    weights
        (K,) non-negative weights (default equal).
    """
    b = _unit(body_vecs, "body vectors")
    r = _unit(ref_vecs, "reference vectors")
    if b.shape != r.shape or b.shape[-2] < 2:
        raise InputError(f"body {b.shape} and reference {r.shape} need matching (K≥2, 3) stacks")
    w = np.ones(b.shape[-2]) if weights is None else np.asarray(weights, dtype=float)
    m = np.einsum("k,...kji,...kjl->...il", w, _right(b), _left(r))
    k = 0.5 * (m + np.swapaxes(m, -1, -2))
    _, vecs = np.linalg.eigh(k)
    q = vecs[..., :, -1]
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def _gn_step(q: np.ndarray, obs: list[np.ndarray], refs: list[np.ndarray], weights) -> np.ndarray:
    """One reduced-order Gauss–Newton step on unit ``q`` (N, 4) (Liu eqs. (53)–(55))."""
    normal = np.zeros(q.shape[:-1] + (3, 3))
    grad = np.zeros(q.shape[:-1] + (3,))
    for y_obs, ref, w in zip(obs, refs, weights, strict=True):
        y = rot.rotate(rot.conj(q), ref)
        # X_p = 2[ŷ]x, so X_pᵀX_p = 4(I − ŷŷᵀ) and X_pᵀε = 2 ε×ŷ = 2 ỹ×ŷ (unit vectors)
        normal += w * 4.0 * (np.eye(3) - y[..., :, None] * y[..., None, :])
        grad += w * 2.0 * np.cross(y_obs, y)
    p = np.linalg.solve(normal + 1e-9 * np.eye(3), grad[..., None])[..., 0]
    return rot.normalize(q + rot.mul(q, np.concatenate([np.zeros(p.shape[:-1] + (1,)), p], -1)))


def gauss_newton(
    acc: np.ndarray,
    mag: np.ndarray,
    q0: np.ndarray,
    iterations: int = 5,
    mag_weight: float = 1.0,
) -> np.ndarray:
    """Observation quaternion(s) from accelerometer and magnetometer by Gauss–Newton.

    Minimises ``|ã − R(q)ᵀ up|² + w_m |m̃ − R(q)ᵀ m_ref|²`` over unit ``q`` with the reduced-order
    step of Liu (2010) eq. (55), ``q ← normalise(q + q ⊗ [0, p])``. ``m_ref = [0, cos δ, −sin δ]``
    uses each sample's own dip ``δ`` (from ``acc·mag``), so noise-free data are fitted exactly.

    Parameters
    ----------
    acc, mag
        (3,) or (N, 3) specific force (any scale) and magnetic field (any unit).
    q0
        (4,) or (N, 4) starting quaternion(s); the step converges from within about 90°.
    iterations
        Number of Gauss–Newton steps.
    mag_weight
        Weight of the magnetometer residual relative to the accelerometer's.
    """
    a = _unit(acc, "acc")
    m = _unit(mag, "mag")
    sin_dip = -np.sum(a * m, axis=-1, keepdims=True)
    cos_dip = np.sqrt(np.clip(1.0 - sin_dip**2, 0.0, 1.0))
    m_ref = np.concatenate([np.zeros_like(sin_dip), cos_dip, -sin_dip], axis=-1)
    q = rot.normalize(np.broadcast_to(np.asarray(q0, dtype=float), a.shape[:-1] + (4,)))
    for _ in range(iterations):
        q = _gn_step(q, [a, m], [np.broadcast_to(UP, a.shape), m_ref], [1.0, mag_weight])
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def tilt_quaternion(acc: np.ndarray) -> np.ndarray:
    """Smallest rotation taking the measured up direction ``acc`` to earth-up (heading fixed)."""
    a = _unit(acc, "acc")
    # q = normalise([1 + a·up, a × up]) is the half-way quaternion of the shortest arc
    w = 1.0 + a[..., 2:3]
    v = np.cross(a, np.broadcast_to(UP, a.shape))
    q = np.concatenate([w, v], axis=-1)
    flipped = w[..., 0] < 1e-9
    q = np.where(flipped[..., None], np.array([0.0, 1.0, 0.0, 0.0]), q)
    return rot.normalize(q)


def initial_orientation(acc: np.ndarray, mag: np.ndarray | None = None, n: int = 10) -> np.ndarray:
    """Orientation (4,) from the mean of the first ``n`` samples (sensor → ENU earth).

    With ``mag`` the heading points the field's horizontal part north (TRIAD, gravity exact);
    without it the heading is the arbitrary but fixed one of the shortest tilt rotation.
    """
    acc = np.asarray(acc, dtype=float)
    a = np.nanmean(acc[:n], axis=0) if acc.ndim == 2 else acc
    if mag is None:
        return tilt_quaternion(a)
    mag = np.asarray(mag, dtype=float)
    m = np.nanmean(mag[:n], axis=0) if mag.ndim == 2 else mag
    if np.linalg.norm(np.cross(_unit(a, "acc"), _unit(m, "mag"))) < 1e-6:
        return tilt_quaternion(a)
    return triad(a, m, UP, NORTH)
