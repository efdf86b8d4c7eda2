"""Particle resampling (To 2012, Appendix D; Douc, Cappé & Moulines 2005) and regularisation.

Given normalised weights ``w`` (N,), a scheme chooses N parent indices; particle ``i`` is copied
``kᵢ`` times with ``E[kᵢ] = N·wᵢ`` (auxiliary: ``N·aᵢ`` with importance weights ``wᵢ/aᵢ``):

- ``systematic`` (To Table D-1, Kitagawa 1996): one uniform offset ``u``, points ``(j + u)/N``;
  ``kᵢ`` is ``⌊Nwᵢ⌋`` or ``⌈Nwᵢ⌉``.
- ``residual`` (Table D-2, Liu & Chen 1998): ``⌊Nwᵢ⌋`` copies, the remaining ``R`` drawn
  multinomially from the residuals ``(Nwᵢ − ⌊Nwᵢ⌋)/R``.
- ``deterministic``: Kitagawa's deterministic variant, systematic with the fixed offset ½ — no
  randomness, ``|kᵢ − Nwᵢ| < 1``.
- ``auxiliary`` (Table D-3, after Pitt & Shephard 1999): multinomial from the flattened weights
  ``aᵢ = ((α − 1)wᵢ + 1/N)/α``, then the importance correction ``w'ⱼ ∝ w_{pⱼ}/a_{pⱼ}`` (the printed
  table omits it; without it the scheme is biased towards uniform weights).

Multinomial draws use sorted uniforms from exponential spacings (O(N), no sort).

Regularisation (the "move" after resampling, Musso et al. 2001, with Liu & West's 2001 shrinkage):
``nb_kernel_shape`` measures the weighted cloud's rotation-vector covariance about its mean and
shapes the kernel — isotropic von Mises–Fisher or the anisotropic band-limited Bingham of
:mod:`motionlab.fusion.sphere` (To 2012 §6.5.6) — and ``nb_regularise`` moves every copied parent
towards the mean and turns it by one kernel draw, which keeps the cloud's covariance.

The ``nb_*`` kernels work in place on preallocated arrays (no allocation) for the filter's loop.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion.sphere import (
    _nb_bingham,
    _nb_bingham_b,
    _nb_seed,
    _nb_uniform,
    _nb_vmf,
)

SCHEMES = ("systematic", "residual", "deterministic", "auxiliary")


@numba.njit(cache=True)
def _nb_stratified_walk(w: np.ndarray, offset: float, idx: np.ndarray) -> None:
    n = w.shape[0]
    c = w[0]
    i = 0
    for j in range(n):
        u = (j + offset) / n
        while u > c and i < n - 1:
            i += 1
            c += w[i]
        idx[j] = i


@numba.njit(cache=True)
def _nb_multinomial(state: np.ndarray, p: np.ndarray, m: int, idx: np.ndarray, start: int) -> None:
    """``m`` sorted multinomial draws from ``p`` (sums to 1) into ``idx[start:start+m]``.

    Sorted uniforms ``u₍ⱼ₎ = Sⱼ/S_{m+1}`` with ``S`` cumulative Exp(1) variables: a first pass
    gives ``S_{m+1}``, the generator is rewound and the same variables are replayed for the walk.
    """
    if m == 0:
        return
    s0 = state[0]
    s1 = state[1]
    total = 0.0
    for _ in range(m + 1):
        total -= np.log(1.0 - _nb_uniform(state))
    state[0] = s0
    state[1] = s1
    n = p.shape[0]
    s = 0.0
    c = p[0]
    i = 0
    for j in range(m):
        s -= np.log(1.0 - _nb_uniform(state))
        u = s / total
        while u > c and i < n - 1:
            i += 1
            c += p[i]
        idx[start + j] = i
    _nb_uniform(state)  # consume the (m+1)-th variable of the first pass


@numba.njit(cache=True)
def nb_resample(
    state: np.ndarray,
    scheme: int,
    alpha: float,
    w: np.ndarray,
    idx: np.ndarray,
    work: np.ndarray,
) -> None:
    """Parent indices into ``idx`` and the new normalised weights into ``w`` (in place).

    ``scheme`` is the position in :data:`SCHEMES`; ``work`` is a length-N float scratch array.
    """
    n = w.shape[0]
    if scheme == 0:
        _nb_stratified_walk(w, _nb_uniform(state), idx)
    elif scheme == 2:
        _nb_stratified_walk(w, 0.5, idx)
    elif scheme == 1:
        k = 0
        for i in range(n):
            c = int(np.floor(n * w[i]))
            for _ in range(c):
                if k < n:
                    idx[k] = i
                    k += 1
            work[i] = n * w[i] - c
        r = n - k
        if r > 0:
            tot = 0.0
            for i in range(n):
                tot += work[i]
            for i in range(n):
                work[i] /= tot
            _nb_multinomial(state, work, r, idx, k)
    else:
        for i in range(n):
            work[i] = ((alpha - 1.0) * w[i] + 1.0 / n) / alpha
        _nb_multinomial(state, work, n, idx, 0)
        for i in range(n):
            work[i] = w[i] / work[i]  # importance ratio per parent
        tot = 0.0
        for j in range(n):
            tot += work[idx[j]]
        for j in range(n):
            w[j] = work[idx[j]] / tot
        return
    for j in range(n):
        w[j] = 1.0 / n


# ---------------------------------------------------------------- regularisation


@numba.njit(cache=True, inline="always")
def _nb_rotate_columns(a: np.ndarray, p: int, q: int, cs: float, sn: float) -> None:
    """Givens rotation of columns ``p`` and ``q`` of the 3-row ``a`` in place (``a ← a G``)."""
    for k in range(3):
        akp = a[k, p]
        akq = a[k, q]
        a[k, p] = cs * akp - sn * akq
        a[k, q] = sn * akp + cs * akq


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
                _nb_rotate_columns(c, p, q, cs, sn)
                _nb_rotate_columns(c.T, p, q, cs, sn)
                _nb_rotate_columns(vecs, p, q, cs, sn)
    for i in range(3):
        lam[i] = c[i, i]


@numba.njit(cache=True)
def nb_draw(state, proposal, kappa, lam4, basis, b, zmax, out):
    """One kernel rotation about the identity: vMF(κ) or the band-limited Bingham."""
    if proposal == 0:
        _nb_vmf(state, kappa, out)
    else:
        _nb_bingham(state, lam4, basis, b, zmax, out)
        if out[0] < 0.0:
            for i in range(4):
                out[i] = -out[i]


@numba.njit(cache=True)
def nb_spread(state, parts, center, sigma, proposal, zmax, lam4, basis, jit):
    """Redraw all particles about ``center`` with isotropic spread ``sigma`` (rad per axis)."""
    kappa = 4.0 / (sigma * sigma)
    for i in range(4):
        lam4[i] = 0.0 if i == 0 else 2.0 / (sigma * sigma)
        for j in range(4):
            basis[i, j] = 1.0 if i == j else 0.0
    b = _nb_bingham_b(lam4)
    for p in range(parts.shape[0]):
        nb_draw(state, proposal, kappa, lam4, basis, b, zmax, jit)
        for i in range(4):
            parts[p, i] = center[i]
        cm.rmul(parts[p], jit[0], jit[1], jit[2], jit[3])


@numba.njit(cache=True)
def nb_kernel_shape(parts, w, mean, h, floor, proposal, cov, vecs, lam3, lam4, basis):
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
        b = _nb_bingham_b(lam4)
    return kappa, b


@numba.njit(cache=True, inline="always")
def _nb_shrink(mean: np.ndarray, a: np.ndarray, f: float, out: np.ndarray) -> None:
    """``out = mean ⊗ exp(f · log(mean* ⊗ a))``: pull ``a`` towards the mean (Liu & West 2001)."""
    e0, e1, e2, e3 = cm.conj_mul_shortest(mean, a)
    vn = np.sqrt(e1 * e1 + e2 * e2 + e3 * e3)
    half = np.arctan2(vn, e0)
    k = np.sin(f * half) / vn if vn > 1e-15 else f
    for i in range(4):
        out[i] = mean[i]
    cm.rmul(out, np.cos(f * half), k * e1, k * e2, k * e3)


@numba.njit(cache=True)
def nb_regularise(state, parts, tmp, idx, mean, h, proposal, kappa, lam4, basis, b, zmax, jit):
    """Replace the particles by their parents ``idx``, each shrunk towards ``mean`` by
    ``√(1 − h²)`` (Liu & West 2001) and turned by a kernel draw (``nb_draw``), so that the
    cloud's covariance is kept in expectation (Musso et al. 2001)."""
    n = parts.shape[0]
    for p in range(n):
        for i in range(4):
            tmp[p, i] = parts[idx[p], i]
    shrink = np.sqrt(max(1.0 - h * h, 0.0))
    for p in range(n):
        _nb_shrink(mean, tmp[p], shrink, parts[p])
        nb_draw(state, proposal, kappa, lam4, basis, b, zmax, jit)
        cm.rmul(parts[p], jit[0], jit[1], jit[2], jit[3])


@numba.njit(cache=True)
def _resample_batch(w: np.ndarray, scheme: int, alpha: float, seed: int):
    state = np.empty(2, dtype=np.uint64)
    _nb_seed(state, seed)
    w = w.copy()
    idx = np.empty(w.shape[0], dtype=np.int64)
    work = np.empty(w.shape[0])
    nb_resample(state, scheme, alpha, w, idx, work)
    return idx, w


def resample(
    weights: np.ndarray, scheme: str = "systematic", seed: int = 0, alpha: float = 2.0
) -> tuple[np.ndarray, np.ndarray]:
    """Parent indices (N,) and new weights (N,) for normalised ``weights`` (N,).

    ``scheme`` is one of :data:`SCHEMES`; ``alpha`` ≥ 1 is the auxiliary flattening constant
    (α → ∞: multinomial on ``w``; α = 1: uniform parents with full importance correction).
    """
    if scheme not in SCHEMES:
        raise ValueError(f"unknown resampling scheme {scheme!r}, choose one of {SCHEMES}")
    w = np.ascontiguousarray(weights, dtype=float)
    w = w / w.sum()
    return _resample_batch(w, SCHEMES.index(scheme), float(alpha), int(seed))
