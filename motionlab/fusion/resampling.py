"""Particle resampling schemes (To 2012, Appendix D; Douc, Cappé & Moulines 2005).

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
The ``nb_*`` kernel works in place on preallocated arrays (no allocation) for the filter's loop.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion.sphere import _nb_seed, _nb_uniform

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
