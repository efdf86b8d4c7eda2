"""Segment frame from two or more axes measured in the sensor frame.

Given unit vectors ``v_i`` measured in sensor coordinates that should equal known segment axes
``r_i`` (segment coordinates) after the mounting rotation ``M`` (segment → sensor, ``v ≈ M r``),
with reliabilities ``ρ_i``: Ricci (2015, eqs. 6.3-6.13) minimises ``Σ ρ_i ‖v_i − M r_i‖²`` by
Levenberg-Marquardt on a quaternion. For unit vectors this is the weighted Wahba problem, solved in
closed form by the SVD of ``B = Σ ρ_i v_i r_iᵀ`` (orthogonal Procrustes, Markley 1988), the
solver used here; :func:`lm_fit` is Ricci's Algorithm 1 kept as a cross-check.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot


def wahba(v: np.ndarray, r: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Rotation matrix ``M`` (3, 3) minimising ``Σ w_i ‖v_i − M r_i‖²`` (v, r: (K, 3))."""
    v = np.asarray(v, dtype=float)
    r = np.asarray(r, dtype=float)
    w = np.ones(len(v)) if weights is None else np.asarray(weights, dtype=float)
    b = (w[:, None] * v).T @ r
    u, _, vt = np.linalg.svd(b)
    d = np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0
    return u @ np.diag([1.0, 1.0, d]) @ vt


def lm_fit(
    v: np.ndarray,
    r: np.ndarray,
    weights: np.ndarray | None = None,
    q0: np.ndarray | None = None,
    lam: float = 1e-3,
    tol: float = 1e-12,
    max_iter: int = 100,
) -> tuple[np.ndarray, int]:
    """Ricci's Algorithm 1: weighted LM for ``ε = r − Mᵀ v`` (eqs. 6.5-6.12).

    Returns ``M`` (segment → sensor) and the number of iterations. ``q0`` is the initial
    sensor → segment quaternion (identity as in the thesis); λ fixed at 10⁻³, stop when the
    relative change of the cost is below ``tol``. The step is a small rotation ``δ`` applied as
    ``q ⊗ exp(δ/2)`` with the analytic Jacobian ``R(q) [v]×`` instead of Ricci's update of the
    four quaternion components, whose norm direction has no gradient and makes it stall.
    """
    v = np.asarray(v, dtype=float)
    r = np.asarray(r, dtype=float)
    w = np.repeat(np.ones(len(v)) if weights is None else np.asarray(weights, float), 3)
    q = rot.IDENTITY.copy() if q0 is None else rot.normalize(q0)

    def residual(q: np.ndarray) -> np.ndarray:
        return (r - rot.rotate(q, v)).ravel()  # R(q) maps sensor → segment (eq. 6.5)

    cost = float(residual(q) @ (w * residual(q)))
    it = 0
    while it < max_iter and cost > 0:
        it += 1
        eps = residual(q)
        skew = np.zeros((len(v), 3, 3))  # [v]× so that δ × v = -[v]× δ
        skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
        skew -= np.transpose(skew, (0, 2, 1))
        jac = (rot.to_matrix(q) @ skew).reshape(-1, 3)  # dε/dδ = R(q) [v]×
        jtwj = jac.T @ (w[:, None] * jac)
        delta = -np.linalg.solve(jtwj + lam * np.diag(np.diag(jtwj)) + 1e-12 * np.eye(3),
                                 jac.T @ (w * eps))  # fmt: skip
        q = rot.normalize(rot.mul(q, rot.from_rotvec(delta)))
        new_cost = float(residual(q) @ (w * residual(q)))
        done = abs(new_cost - cost) <= tol * max(cost, 1e-300)
        cost = new_cost
        if done:
            break
    return rot.to_matrix(rot.conj(q)), it


def residual_angles(m: np.ndarray, v: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Angle (deg) between each measured axis ``v_i`` and the fitted ``M r_i`` (Ricci eq. 6.18)."""
    fitted = np.asarray(r, float) @ np.asarray(m).T
    cos = np.clip(np.sum(fitted * np.asarray(v, float), axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def min_axis_separation(r: np.ndarray, v: np.ndarray) -> float:
    """Smallest angle (deg, 0-90) between measured axes that stand for different segment axes."""
    r = np.asarray(r, float)
    v = np.asarray(v, float)
    best = 90.0
    for i in range(len(v)):
        for j in range(i + 1, len(v)):
            if abs(float(r[i] @ r[j])) > 0.99:  # the same segment axis measured twice
                continue
            angle = np.degrees(np.arccos(np.clip(abs(float(v[i] @ v[j])), 0.0, 1.0)))
            best = min(best, float(angle))
    return best


def align_one(v: np.ndarray, r: np.ndarray, m_nominal: np.ndarray) -> np.ndarray:
    """Mounting from one axis: the smallest rotation of the nominal ``M`` that makes ``M r = v``.

    The heading about the measured axis stays as the protocol's nominal placement says.
    """
    a = m_nominal @ np.asarray(r, float)
    b = np.asarray(v, float)
    cross = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(cross), float(a @ b))
    if np.linalg.norm(cross) < 1e-12:
        if a @ b > 0:
            return m_nominal.copy()
        perp = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        cross, angle = perp, np.pi
    turn = rot.to_matrix(rot.from_axis_angle(cross, angle))
    return turn @ m_nominal


def turn_about(
    m: np.ndarray, axis: np.ndarray, v: np.ndarray, r: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """``m`` turned about the sensor-frame ``axis`` so that ``m r_i`` best meet ``v_i``.

    Only the components perpendicular to ``axis`` count (a 2-D Procrustes in that plane), so the
    axis ``m`` already maps exactly stays where it is (TRIAD-like: a primary axis, then a
    secondary direction for the rotation about it).
    """
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    a = np.asarray(r, float) @ m.T
    b = np.asarray(v, float)
    a -= np.outer(a @ axis, axis)
    b -= np.outer(b @ axis, axis)
    w = np.asarray(weights, float)
    sin = float(np.sum(w * (np.cross(a, b) @ axis)))
    cos = float(np.sum(w * np.sum(a * b, axis=1)))
    if abs(sin) + abs(cos) < 1e-12:
        return m
    turn = rot.to_matrix(rot.from_axis_angle(axis, np.arctan2(sin, cos)))
    return turn @ m


def level(m: np.ndarray, up: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``m`` turned by the smallest rotation that lays the segment axis ``r`` horizontal, i.e.
    makes ``M r`` perpendicular to the sensor-frame ``up`` (a static pose's gravity).

    The rotation is about ``M r × up``, so nothing else about the frame changes more than needed;
    an axis pointing straight up or down has no such rotation and ``m`` is returned.
    """
    a = m @ np.asarray(r, float)
    up = np.asarray(up, float) / np.linalg.norm(up)
    n = np.cross(a, up)
    if np.linalg.norm(n) < 1e-9:
        return m
    elevation = np.arcsin(np.clip(float(a @ up), -1.0, 1.0))
    return rot.to_matrix(rot.from_axis_angle(n, -elevation)) @ m
