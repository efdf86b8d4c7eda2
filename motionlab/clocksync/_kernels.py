"""The joint-centre residuals of :class:`motionlab.clocksync.joint_centre.Pair` and their
Jacobian, compiled (numba): one loop over the samples, the sensor's cubic spline walked
interval by interval."""

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _cross3(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@numba.njit(cache=True, inline="always")
def _at_centre(s0, s1, s2, w0, w1, w2, a0, a1, a2, r0, r1, r2, b0, b1, b2):
    """``f_J = f + b + ω̇ × r + ω × (ω × r)``: a sensor's specific force ``f`` (``s``) moved by
    the lever ``r`` to the joint centre with its rate ``ω`` (``w``) and angular acceleration
    ``ω̇`` (``a``), plus the bias ``b``; added in that order."""
    u0, u1, u2 = _cross3(w0, w1, w2, r0, r1, r2)
    c0, c1, c2 = _cross3(a0, a1, a2, r0, r1, r2)
    e0, e1, e2 = _cross3(w0, w1, w2, u0, u1, u2)
    return s0 + b0 + c0 + e0, s1 + b1 + c1 + e1, s2 + b2 + c2 + e2


@numba.njit(cache=True)
def pair_residuals(
    t: np.ndarray,
    t_mid: float,
    knots: np.ndarray,
    coef: np.ndarray,
    ref: np.ndarray,
    p: np.ndarray,
    res: np.ndarray,
    jac: np.ndarray,
) -> None:
    """The unfiltered residuals of :class:`~motionlab.clocksync.joint_centre.Pair` into ``res``
    (N) and, when ``jac`` has columns, their Jacobian (14, N: one row per parameter) in
    ``p = [r₁, r₂, b₁, b₂, c₀, c₁]``, or with one row the derivative in ``c₀`` alone.

    Sensor 2 is the cubic spline (``knots`` (M+1), ``coef`` (4, M, 9) as
    :class:`scipy.interpolate.CubicSpline`'s, extrapolated past the ends) of ``[f, ω, ω̇]``
    read at ``t + c₀ + c₁ (t − t_mid)``; the reference's rows ``ref`` (N, 9) are at ``t``.
    Residual ``‖f_J1‖ − ‖f_J2‖`` with ``f_J = f + b + ω̇ × r + ω × (ω × r)``; its gradient
    in a lever ``r`` is ``±(f_J × ω̇ + ω × (ω × f_J)) / ‖f_J‖``, in a bias ``±f_J / ‖f_J‖``, and
    in the clock ``−f_J2 · ḟ_J2 / ‖f_J2‖`` (times ``t − t_mid`` for the drift), ``ḟ_J2`` from
    the spline's derivative.
    """
    m = coef.shape[1]
    v = np.empty(9)
    d = np.empty(9)
    with_jac = jac.shape[1] > 0
    full = jac.shape[0] == 14
    i = 0
    if len(t):  # start the walk below from the first sample's interval (a block's window)
        i = min(max(np.searchsorted(knots, t[0] + p[12] + p[13] * (t[0] - t_mid)) - 1, 0), m - 1)
    for k in range(len(t)):
        x = t[k] + (p[12] + p[13] * (t[k] - t_mid))
        # the spline's interval: knots[i] <= x < knots[i + 1], the first and last extended
        # (times increase, so it moves forward from the previous sample's)
        while i > 0 and x < knots[i]:
            i -= 1
        while i < m - 1 and x >= knots[i + 1]:
            i += 1
        s = x - knots[i]
        for j in range(9):
            v[j] = ((coef[0, i, j] * s + coef[1, i, j]) * s + coef[2, i, j]) * s + coef[3, i, j]
            if with_jac:
                d[j] = (3.0 * coef[0, i, j] * s + 2.0 * coef[1, i, j]) * s + coef[2, i, j]
        # reference: f_J1
        w0, w1, w2 = ref[k, 3], ref[k, 4], ref[k, 5]
        a0, a1, a2 = ref[k, 6], ref[k, 7], ref[k, 8]
        s0, s1, s2 = ref[k, 0], ref[k, 1], ref[k, 2]
        f0, f1, f2 = _at_centre(
            s0, s1, s2, w0, w1, w2, a0, a1, a2, p[0], p[1], p[2], p[6], p[7], p[8]
        )
        n1 = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        # sensor 2: f_J2
        x0, x1, x2 = v[3], v[4], v[5]
        y0, y1, y2 = v[6], v[7], v[8]
        g0, g1, g2 = _at_centre(
            v[0], v[1], v[2], x0, x1, x2, y0, y1, y2, p[3], p[4], p[5], p[9], p[10], p[11]
        )
        n2 = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        res[k] = n1 - n2
        if not with_jac:
            continue
        if full:
            c0, c1, c2 = _cross3(f0, f1, f2, a0, a1, a2)
            u0, u1, u2 = _cross3(w0, w1, w2, f0, f1, f2)
            e0, e1, e2 = _cross3(w0, w1, w2, u0, u1, u2)
            jac[0, k], jac[1, k], jac[2, k] = (c0 + e0) / n1, (c1 + e1) / n1, (c2 + e2) / n1
            c0, c1, c2 = _cross3(g0, g1, g2, y0, y1, y2)
            u0, u1, u2 = _cross3(x0, x1, x2, g0, g1, g2)
            e0, e1, e2 = _cross3(x0, x1, x2, u0, u1, u2)
            jac[3, k], jac[4, k], jac[5, k] = -(c0 + e0) / n2, -(c1 + e1) / n2, -(c2 + e2) / n2
            jac[6, k], jac[7, k], jac[8, k] = f0 / n1, f1 / n1, f2 / n1
            jac[9, k], jac[10, k], jac[11, k] = -g0 / n2, -g1 / n2, -g2 / n2
        # d/dt of f_J2 = ḟ + ω̈ × r + ω̇ × (ω × r) + ω × (ω̇ × r)
        u0, u1, u2 = _cross3(x0, x1, x2, p[3], p[4], p[5])  # ω × r
        h0, h1, h2 = _cross3(d[3], d[4], d[5], u0, u1, u2)
        c0, c1, c2 = _cross3(d[6], d[7], d[8], p[3], p[4], p[5])
        u0, u1, u2 = _cross3(d[3], d[4], d[5], p[3], p[4], p[5])  # ω̇ × r
        e0, e1, e2 = _cross3(x0, x1, x2, u0, u1, u2)
        q0 = d[0] + c0 + h0 + e0
        q1 = d[1] + c1 + h1 + e1
        q2 = d[2] + c2 + h2 + e2
        dc = -(g0 * q0 + g1 * q1 + g2 * q2) / n2
        if full:
            jac[12, k] = dc
            jac[13, k] = dc * (t[k] - t_mid)
        else:
            jac[0, k] = dc


@numba.njit(cache=True)
def pair_residual_rows(
    t: np.ndarray,
    t_mid: float,
    knots: np.ndarray,
    coef: np.ndarray,
    ref: np.ndarray,
    ps: np.ndarray,
    same_body: np.ndarray,
    res: np.ndarray,
) -> None:
    """:func:`pair_residuals`' residuals (no Jacobian) at each row of ``ps`` (G, 14) into the
    rows of ``res`` (G, N), the same numbers by the same operations, all rows sample by sample:
    the reference's ``‖f_J1‖`` is computed once for consecutive rows with the same levers and
    biases (``same_body[g]``: row ``g``'s ``r₁`` and ``b₁`` are row ``g − 1``'s), as on the grid
    of offsets :meth:`~motionlab.clocksync.joint_centre.Pair.costs` searches."""
    m = coef.shape[1]
    n_rows = ps.shape[0]
    start = np.zeros(n_rows, dtype=np.int64)  # each row's spline interval, walked forward
    if len(t):
        for g in range(n_rows):
            first = t[0] + ps[g, 12] + ps[g, 13] * (t[0] - t_mid)
            start[g] = min(max(np.searchsorted(knots, first) - 1, 0), m - 1)
    n1 = 0.0
    for k in range(len(t)):
        w0, w1, w2 = ref[k, 3], ref[k, 4], ref[k, 5]
        a0, a1, a2 = ref[k, 6], ref[k, 7], ref[k, 8]
        for g in range(n_rows):
            p = ps[g]
            if g == 0 or not same_body[g]:  # reference: f_J1
                s0, s1, s2 = ref[k, 0], ref[k, 1], ref[k, 2]
                f0, f1, f2 = _at_centre(
                    s0, s1, s2, w0, w1, w2, a0, a1, a2, p[0], p[1], p[2], p[6], p[7], p[8]
                )
                n1 = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
            x = t[k] + (p[12] + p[13] * (t[k] - t_mid))
            i = start[g]
            while i > 0 and x < knots[i]:
                i -= 1
            while i < m - 1 and x >= knots[i + 1]:
                i += 1
            start[g] = i
            s = x - knots[i]
            v0 = ((coef[0, i, 0] * s + coef[1, i, 0]) * s + coef[2, i, 0]) * s + coef[3, i, 0]
            v1 = ((coef[0, i, 1] * s + coef[1, i, 1]) * s + coef[2, i, 1]) * s + coef[3, i, 1]
            v2 = ((coef[0, i, 2] * s + coef[1, i, 2]) * s + coef[2, i, 2]) * s + coef[3, i, 2]
            x0 = ((coef[0, i, 3] * s + coef[1, i, 3]) * s + coef[2, i, 3]) * s + coef[3, i, 3]
            x1 = ((coef[0, i, 4] * s + coef[1, i, 4]) * s + coef[2, i, 4]) * s + coef[3, i, 4]
            x2 = ((coef[0, i, 5] * s + coef[1, i, 5]) * s + coef[2, i, 5]) * s + coef[3, i, 5]
            y0 = ((coef[0, i, 6] * s + coef[1, i, 6]) * s + coef[2, i, 6]) * s + coef[3, i, 6]
            y1 = ((coef[0, i, 7] * s + coef[1, i, 7]) * s + coef[2, i, 7]) * s + coef[3, i, 7]
            y2 = ((coef[0, i, 8] * s + coef[1, i, 8]) * s + coef[2, i, 8]) * s + coef[3, i, 8]
            # sensor 2: f_J2
            g0, g1, g2 = _at_centre(
                v0, v1, v2, x0, x1, x2, y0, y1, y2, p[3], p[4], p[5], p[9], p[10], p[11]
            )
            res[g, k] = n1 - np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
