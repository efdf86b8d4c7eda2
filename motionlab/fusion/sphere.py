"""Random samples and averages on the unit-quaternion sphere S³.

Conventions: quaternions scalar first ``[w, x, y, z]``; a sample "about μ" is ``q ⊗ μ`` with ``q``
drawn about the identity (To 2012, Table 6-3 step 19). Rotation vectors are in rad.

- :func:`sample_vmf`: von Mises–Fisher ``f(x) ∝ exp(κ μᵀx)`` by Wood's (1994) rejection sampler
  with the p = 4 constants (To 2012, Table 6-3 with the errata of the project note: b, x₀, c and
  the Beta(3/2, 3/2) variable all for S³).
- :func:`sample_bingham`: Bingham ``f(x) ∝ exp(−xᵀAx)`` by Kent, Ganeiber & Mardia (2013)
  acceptance–rejection from an angular central Gaussian envelope, optionally restricted to the
  band ``xᵀAx ≤ z_max`` (To's "NU" band density, §6.5.6, with the antipodal symmetry kept).
- :func:`weighted_mean`: Markley et al. (2007) eigenvector mean by power iteration (numba),
  warm-started; agrees with :func:`motionlab.rotations.mean`.

Every sampler takes a seed; the same seed gives the same numbers. The private ``_nb_*`` kernels
share one small xoroshiro128+ generator (state: two uint64) so the particle filter can draw
without allocating.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.rotations import mul

_U64 = np.uint64


# ---------------------------------------------------------------- generator (xoroshiro128+)


@numba.njit(cache=True)
def _nb_seed(state: np.ndarray, seed: int) -> None:
    """Fill the two-word state from ``seed`` with splitmix64 (Vigna)."""
    z = _U64(seed) + _U64(0x9E3779B97F4A7C15)
    for i in range(2):
        z = z + _U64(0x9E3779B97F4A7C15)
        x = z
        x = (x ^ (x >> _U64(30))) * _U64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> _U64(27))) * _U64(0x94D049BB133111EB)
        state[i] = x ^ (x >> _U64(31))


@numba.njit(cache=True, inline="always")
def _nb_uniform(state: np.ndarray) -> float:
    """Uniform double in [0, 1) (xoroshiro128+, Blackman & Vigna 2018)."""
    s0 = state[0]
    s1 = state[1]
    result = s0 + s1
    s1 ^= s0
    state[0] = ((s0 << _U64(24)) | (s0 >> _U64(40))) ^ s1 ^ (s1 << _U64(16))
    state[1] = (s1 << _U64(37)) | (s1 >> _U64(27))
    return float(result >> _U64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, inline="always")
def _nb_normal(state: np.ndarray) -> float:
    """Standard normal by Box–Muller (one of the pair)."""
    u1 = 1.0 - _nb_uniform(state)
    u2 = _nb_uniform(state)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


# ---------------------------------------------------------------- quaternion product


# ---------------------------------------------------------------- von Mises–Fisher (Wood 1994)


@numba.njit(cache=True)
def _nb_vmf(state: np.ndarray, kappa: float, out: np.ndarray) -> None:
    """One vMF(κ) sample about the identity into ``out`` (length 4), for p = 4.

    Wood (1994) with b = (−2κ + √(4κ²+9))/3 written as 3/(2κ + √(4κ²+9)) to avoid cancellation,
    x₀ = (1−b)/(1+b), c = κx₀ + 3 log(1−x₀²); Z ~ Beta(3/2, 3/2) by Ulrich's polar method;
    W = (1 − (1+b)Z)/(1 − (1−b)Z), accepted when κW + 3 log(1 − x₀W) − c ≥ log U.
    1 − W and W − x₀ are formed directly so that κ up to ~1e12 stays exact.
    """
    if kappa <= 0.0:
        # uniform on S³: normalised Gaussian
        n2 = 0.0
        for i in range(4):
            out[i] = _nb_normal(state)
            n2 += out[i] * out[i]
        n = np.sqrt(n2)
        for i in range(4):
            out[i] /= n
        return
    b = 3.0 / (2.0 * kappa + np.sqrt(4.0 * kappa * kappa + 9.0))
    one_m_x0 = 2.0 * b / (1.0 + b)
    x0 = 1.0 - one_m_x0
    log_1mx02 = np.log(one_m_x0 * (1.0 + x0))
    while True:
        # Ulrich: Z = 1/2 + u v √(1 − s)/s with (u, v) uniform in the unit disc, s = u² + v²
        while True:
            u = 2.0 * _nb_uniform(state) - 1.0
            v = 2.0 * _nb_uniform(state) - 1.0
            s = u * u + v * v
            if 0.0 < s < 1.0:
                break
        z = 0.5 + u * v * np.sqrt(1.0 - s) / s
        den = 1.0 - (1.0 - b) * z
        one_m_w = 2.0 * b * z / den
        w = 1.0 - one_m_w
        w_m_x0 = one_m_x0 - one_m_w
        t = kappa * w_m_x0 + 3.0 * (np.log(one_m_x0 + x0 * one_m_w) - log_1mx02)
        if t >= np.log(1.0 - _nb_uniform(state)):
            break
    # uniform direction on S² (To, Table 6-3 steps 13–15)
    cz = 2.0 * _nb_uniform(state) - 1.0
    phi = 2.0 * np.pi * _nb_uniform(state)
    r = np.sqrt(max(one_m_w * (1.0 + w), 0.0))
    rho = np.sqrt(1.0 - cz * cz)
    out[0] = w
    out[1] = r * rho * np.cos(phi)
    out[2] = r * rho * np.sin(phi)
    out[3] = r * cz


# ---------------------------------------------------------------- Bingham (Kent et al. 2013)


@numba.njit(cache=True)
def _nb_bingham_b(lam: np.ndarray) -> float:
    """Envelope constant b: the root in (0, 4] of Σᵢ 1/(b + 2λᵢ) = 1 (Kent et al. 2013, eq. 3.5)."""
    lo = 1e-12
    hi = 4.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        f = 0.0
        for i in range(4):
            f += 1.0 / (mid + 2.0 * lam[i])
        if f > 1.0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-13 * hi:
            break
    return 0.5 * (lo + hi)


@numba.njit(cache=True)
def _nb_bingham(
    state: np.ndarray, lam: np.ndarray, basis: np.ndarray, b: float, zmax: float, out: np.ndarray
) -> None:
    """One Bingham sample ``f(x) ∝ exp(−xᵀAx)``, ``A = basis · diag(lam) · basisᵀ``, ``lam ≥ 0``.

    Envelope: angular central Gaussian with Ω = I + 2A/b, drawn as y ~ N(0, Ω⁻¹), x = y/|y|;
    accept when log U < −z + 2 log(1 + 2z/b) + (4 − b)/2 − 2 log(4/b), z = xᵀAx (q = 4).
    Samples with z > ``zmax`` are rejected as well (the band restriction).
    """
    while True:
        n2 = 0.0
        z = 0.0
        for i in range(4):
            y = _nb_normal(state) / np.sqrt(1.0 + 2.0 * lam[i] / b)
            out[i] = y
            n2 += y * y
            z += lam[i] * y * y
        z /= n2
        if z > zmax:
            continue
        log_ratio = -z + 2.0 * np.log(1.0 + 2.0 * z / b) + 0.5 * (4.0 - b) - 2.0 * np.log(4.0 / b)
        if np.log(1.0 - _nb_uniform(state)) < log_ratio:
            break
    n = np.sqrt(n2)
    y0 = out[0] / n
    y1 = out[1] / n
    y2 = out[2] / n
    y3 = out[3] / n
    for i in range(4):
        out[i] = basis[i, 0] * y0 + basis[i, 1] * y1 + basis[i, 2] * y2 + basis[i, 3] * y3


# ---------------------------------------------------------------- weighted mean (Markley 2007)


@numba.njit(cache=True)
def _nb_mean(q: np.ndarray, w: np.ndarray, guess: np.ndarray, out: np.ndarray) -> None:
    """Markley mean of ``q`` (N, 4) with weights ``w`` into ``out``, warm-started at ``guess``."""
    m00 = m01 = m02 = m03 = m11 = m12 = m13 = m22 = m23 = m33 = 0.0
    for i in range(q.shape[0]):
        a0 = q[i, 0]
        a1 = q[i, 1]
        a2 = q[i, 2]
        a3 = q[i, 3]
        wa0 = w[i] * a0
        wa1 = w[i] * a1
        wa2 = w[i] * a2
        wa3 = w[i] * a3
        m00 += wa0 * a0
        m01 += wa0 * a1
        m02 += wa0 * a2
        m03 += wa0 * a3
        m11 += wa1 * a1
        m12 += wa1 * a2
        m13 += wa1 * a3
        m22 += wa2 * a2
        m23 += wa2 * a3
        m33 += wa3 * a3
    _nb_principal(m00, m01, m02, m03, m11, m12, m13, m22, m23, m33, guess, out)


@numba.njit(cache=True)
def _nb_principal(m00, m01, m02, m03, m11, m12, m13, m22, m23, m33, guess, out) -> None:
    """Principal eigenvector of the symmetric PSD M = Σ wᵢ qᵢqᵢᵀ (upper entries given) by power
    iteration from ``guess`` (its sign is kept); converges at the rate λ₂/λ₁, fast for a
    concentrated cloud. ``guess`` and ``out`` may be the same array.
    """
    v0, v1, v2, v3 = guess[0], guess[1], guess[2], guess[3]
    for _ in range(200):
        n0 = m00 * v0 + m01 * v1 + m02 * v2 + m03 * v3
        n1 = m01 * v0 + m11 * v1 + m12 * v2 + m13 * v3
        n2 = m02 * v0 + m12 * v1 + m22 * v2 + m23 * v3
        n3 = m03 * v0 + m13 * v1 + m23 * v2 + m33 * v3
        nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
        if nn == 0.0:
            break
        n0 /= nn
        n1 /= nn
        n2 /= nn
        n3 /= nn
        d = (n0 - v0) ** 2 + (n1 - v1) ** 2 + (n2 - v2) ** 2 + (n3 - v3) ** 2
        v0, v1, v2, v3 = n0, n1, n2, n3
        if d < 1e-26:
            break
    out[0] = v0
    out[1] = v1
    out[2] = v2
    out[3] = v3


# ---------------------------------------------------------------- public wrappers


@numba.njit(cache=True)
def _vmf_batch(kappa: float, n: int, seed: int) -> np.ndarray:
    state = np.empty(2, dtype=np.uint64)
    _nb_seed(state, seed)
    out = np.empty((n, 4))
    for i in range(n):
        _nb_vmf(state, kappa, out[i])
    return out


@numba.njit(cache=True)
def _bingham_batch(
    lam: np.ndarray, basis: np.ndarray, zmax: float, n: int, seed: int
) -> np.ndarray:
    state = np.empty(2, dtype=np.uint64)
    _nb_seed(state, seed)
    b = _nb_bingham_b(lam)
    out = np.empty((n, 4))
    for i in range(n):
        _nb_bingham(state, lam, basis, b, zmax, out[i])
    return out


def sample_vmf(mu: np.ndarray, kappa: float, n: int, seed: int = 0) -> np.ndarray:
    """``n`` unit quaternions from the von Mises–Fisher density ``∝ exp(κ μᵀx)`` on S³.

    Parameters
    ----------
    mu
        Mean direction (4,), normalised here.
    kappa
        Concentration ≥ 0 (0 is uniform). For large κ the rotation vector of ``x ⊗ μ*`` is
        approximately N(0, 4/κ · I) in rad².
    n, seed
        Sample count and seed (same seed, same samples).

    Returns
    -------
    (n, 4) samples ``q ⊗ μ`` with ``q`` drawn about the identity (Wood 1994; To 2012 Table 6-3).
    """
    mu = np.asarray(mu, dtype=float)
    mu = mu / np.linalg.norm(mu)
    if not np.isfinite(kappa) or kappa < 0:
        raise ValueError(f"kappa must be finite and ≥ 0, got {kappa}")
    return mul(_vmf_batch(float(kappa), int(n), int(seed)), mu)


def sample_bingham(a: np.ndarray, n: int, seed: int = 0, zmax: float = np.inf) -> np.ndarray:
    """``n`` samples from the Bingham density ``∝ exp(−xᵀAx)`` on S³ (Kent et al. 2013).

    Parameters
    ----------
    a
        (4, 4) symmetric matrix; only its shape matters up to adding a multiple of I, so it is
        shifted to have smallest eigenvalue 0 (the mode is that eigenvector, ±).
    n, seed
        Sample count and seed.
    zmax
        Band limit: samples with ``xᵀAx > zmax`` (after the shift) are rejected, i.e. the density
        is truncated to the band around the mode (To's NU density, 2012 §6.5.6). ``inf`` gives the
        plain Bingham distribution.

    Returns
    -------
    (n, 4) unit quaternions; the sign of each sample is arbitrary (the density is antipodal).
    """
    a = np.asarray(a, dtype=float)
    if a.shape != (4, 4) or not np.allclose(a, a.T):
        raise ValueError("a must be a symmetric 4×4 matrix")
    lam, basis = np.linalg.eigh(0.5 * (a + a.T))
    lam = lam - lam[0]
    return _bingham_batch(lam, np.ascontiguousarray(basis), float(zmax), int(n), int(seed))


def bingham_from_covariance(mu: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Bingham matrix A whose samples have rotation-vector covariance ≈ ``cov`` about ``mu``.

    Near the mode, ``x = exp(r/2) ⊗ μ`` gives ``xᵀAx ≈ ½ rᵀ cov⁻¹ r`` for
    ``A = L(μ)ᵀ diag(0, 2cov⁻¹) L(μ)`` restricted as below, so ``r ~ N(0, cov)`` to second order.
    """
    mu = np.asarray(mu, dtype=float)
    mu = mu / np.linalg.norm(mu)
    cov = np.asarray(cov, dtype=float)
    av = 2.0 * np.linalg.inv(cov)
    # x = e ⊗ μ  ⇒  e = x ⊗ μ*, a linear orthogonal map R_μ* (right multiplication matrix)
    w, x, y, z = mu[0], -mu[1], -mu[2], -mu[3]
    right = np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])
    a_e = np.zeros((4, 4))
    a_e[1:, 1:] = av
    return right.T @ a_e @ right


def weighted_mean(q: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Markley's weighted quaternion mean (principal eigenvector of ``Σ wᵢ qᵢqᵢᵀ``), ``w ≥ 0``.

    Same result as :func:`motionlab.rotations.mean`; this is the allocation-free numba form the
    particle filter calls every sample, warm-started from the largest-weight quaternion.
    """
    q = np.ascontiguousarray(q, dtype=float)
    w = np.ones(len(q)) if weights is None else np.ascontiguousarray(weights, dtype=float)
    out = np.empty(4)
    _nb_mean(q, w, q[int(np.argmax(w))].copy(), out)
    return out if out[0] >= 0 else -out
