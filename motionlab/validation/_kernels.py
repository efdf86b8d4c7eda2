"""The cross-covariance of :func:`motionlab.validation.optical.rigid_fit`, compiled (numba):
numpy's masked copies and einsums over (N, K, 3) temporaries took 1.2 of the fit's 9 ms on a
3 000-frame, 4-marker cluster (20 fits per validated knee or elbow session); the same sums in
the same order, so the same numbers to the bit.

Why the rest of the fit stays in numpy: the rotation, translation and residual from the SVD
were 3 ms more, but numpy computes their products with fused multiply-adds (BLAS, SIMD
einsum), which a plain loop does not reproduce, and a last-bit difference there moved the
validation's spatial alignment (``align.align``, a soft-L1 least-squares fit stopped by its
tolerances) by up to 6e-4° on the demo sessions: visible in ``results.json``'s third
decimal."""

import numba
import numpy as np


@numba.njit(cache=True)
def cross_covariance(
    shape: np.ndarray, points: np.ndarray, ok: np.ndarray, cp: np.ndarray, cs: np.ndarray,
    h: np.ndarray,
) -> None:  # fmt: skip
    """Per frame ``n``, over the markers ``ok[n]`` (N, K) only: the centroids of ``points``
    (N, K, 3) into ``cp`` (N, 3) and of ``shape`` (K, 3) into ``cs`` (N, 3) (0 when none is
    seen), and ``h[n] = Σ (s − c_s)(p − c_p)ᵀ`` (N, 3, 3)."""
    n_frames, n_markers = ok.shape
    for n in range(n_frames):
        seen = 0.0
        for k in range(n_markers):
            if ok[n, k]:
                seen += 1.0
        denom = max(seen, 1.0)
        for j in range(3):
            sum_p = 0.0
            sum_s = 0.0
            for k in range(n_markers):
                if ok[n, k]:
                    sum_p += points[n, k, j]
                    sum_s += shape[k, j]
            cp[n, j] = sum_p / denom
            cs[n, j] = sum_s / denom
        for i in range(3):
            for j in range(3):
                acc = 0.0
                for k in range(n_markers):
                    if ok[n, k]:
                        acc += (shape[k, i] - cs[n, i]) * (points[n, k, j] - cp[n, j])
                h[n, i, j] = acc
