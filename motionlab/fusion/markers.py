"""IMU + marker fusion inputs: marker reference vectors and Liu's sensor scenarios (Liu 2010).

Liu (2010, MS thesis §5.1.2, eq. (33)) feeds two marker vectors of the IMU's marker board, each
the direction between two markers, into the orientation filters as extra reference vectors: the
vector is fixed in the body, so the filter predicts its earth-frame direction ``R(q) a`` and
compares it with the measured one. Here every pair of markers of the sensor's cluster gives one
vector (a cluster of four gives six), so a partly hidden cluster still contributes the pairs it
shows; a pair is unavailable where a marker is missing or the pair's length is off the cluster's
rigid shape. Where no pair is seen the filters continue on the IMU alone (the thesis's even
scenarios, Table 2). The registration that puts the vectors into the sensor and earth frames is
in :mod:`motionlab.fusion.marker_registration`.

Conventions: quaternions scalar first; ``q`` maps sensor → ENU earth. Times in s, positions in m,
angles in rad.

Noise: the marker position noise ``σ`` is estimated from the clusters' rigid-fit residuals
(a fit of ``n`` markers leaves ``(3n − 6)/n · σ²`` per marker); a pair of length ``L`` has a
direction noise of ``√2 σ / L`` rad per component, and as the ``K`` pairs of ``M`` markers reuse
the same noise they are weighted as ``M − 1`` independent ones (``σ`` times ``√(K/(M − 1))``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from motionlab.errors import InputError

#: bits of an estimator's per-sample ``used`` output: which measurements entered the update
USED_ACC, USED_MAG, USED_MARKERS = 1, 2, 4

MIN_PAIR_LENGTH_M = 0.01
LENGTH_TOL_SIGMAS = 6.0
MIN_SIGMA_M = 1e-4
JUMP_CHI2 = 25.0  # |δ|² over its variance per axis: a 3-D correction beyond about 5σ


@dataclass
class MarkerReferences:
    """Marker reference vectors of one sensor on its own sample times.

    Attributes
    ----------
    body
        (K, 3) unit directions of the marker pairs in the sensor frame (from the cluster shape
        and the registration ``X``).
    earth
        (N, K, 3) measured unit directions in the ENU earth frame, NaN where the pair is not seen.
    sigma
        (K,) direction noise of each pair (rad, per component).
    gyro_bias
        (3,) gyroscope bias (rad/s) found by the registration; the filters start from it (the
        complementary filter, which has no bias state, subtracts it).
    pairs
        The marker labels of each pair.
    """

    body: np.ndarray
    earth: np.ndarray
    sigma: np.ndarray
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pairs: list[tuple[str, str]] = field(default_factory=list)

    @classmethod
    def none(cls, n: int) -> MarkerReferences:
        """No reference vectors for ``n`` samples: the filters run on the IMU alone."""
        return cls(np.zeros((0, 3)), np.zeros((n, 0, 3)), np.zeros(0))

    @property
    def available(self) -> np.ndarray:
        """(N, K) bool: pair k seen at sample n."""
        return np.isfinite(self.earth).all(axis=-1)

    @property
    def visible(self) -> np.ndarray:
        """(N,) bool: at least one pair seen."""
        return self.available.any(axis=1)

    def validated(self, n: int) -> MarkerReferences:
        """A contiguous float64 copy checked against ``n`` samples (raises :class:`InputError`)."""
        body = np.ascontiguousarray(self.body, dtype=float)
        earth = np.ascontiguousarray(self.earth, dtype=float)
        sigma = np.ascontiguousarray(self.sigma, dtype=float)
        k = len(body)
        if body.shape != (k, 3) or earth.shape != (n, k, 3) or sigma.shape != (k,):
            raise InputError(
                f"marker references have shapes body {body.shape}, earth {earth.shape}, sigma "
                f"{sigma.shape}; expected (K, 3), ({n}, K, 3), (K,)",
                where="references",
                remedy="build them on the sensor's sample times (session_references)",
            )
        bias = np.asarray(self.gyro_bias, dtype=float)
        finite = np.isfinite(body).all() and np.isfinite(sigma).all() and np.isfinite(bias).all()
        if not (finite and np.all(sigma > 0) and bias.shape == (3,)):
            raise InputError(
                "marker references need finite body vectors, positive noise and a (3,) bias",
                where="references",
            )
        body = body / np.linalg.norm(body, axis=1, keepdims=True)
        earth = earth / np.linalg.norm(earth, axis=-1, keepdims=True)
        return MarkerReferences(body, earth, sigma, bias, list(self.pairs))


def interval_rates(gyr: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Bias-corrected gyroscope rates averaged over each sample interval (trapezoid).

    The filter kernels turn sample ``k`` over the interval ending at ``k``; for a gyroscope that
    samples the instantaneous rate this leads the true orientation by half a sample (about
    ``|ω| Δt / 2``, half a degree RMS on a shank in gait at 100 Hz). The registration relates
    the markers to the gyroscope's instants (midpoint integration), so with marker references
    the kernels get ``(ω_k−1 + ω_k)/2 − b``, which keeps the prediction on those instants.
    """
    out = np.array(gyr, dtype=float)
    out[1:] = 0.5 * (out[1:] + out[:-1])
    return np.ascontiguousarray(out - bias)


@numba.njit(cache=True)
def marker_jump(
    r: np.ndarray,
    body: np.ndarray,
    earth: np.ndarray,
    var: np.ndarray,
    k: int,
    var_att: float,
) -> float:
    """Attitude variance (rad², per axis) to add when the marker vectors of sample ``k`` call
    for a correction of the prediction ``r`` = R(q) (3×3) beyond what its variance ``var_att``
    (per axis) and their noise ``var`` (K,) allow, else 0.

    The correction is the weighted least-squares rotation ``δ`` (earth frame) with
    ``δ × Ra ≈ o − Ra`` over the seen vectors: ``N δ = Σ wⱼ Raⱼ × oⱼ``,
    ``N = Σ wⱼ (I − Raⱼ Raⱼᵀ)``, ``wⱼ = 1/varⱼ``; it is a jump when ``|δ|²`` exceeds ``JUMP_CHI2``
    times ``var_att + tr(N⁻¹)/3``. Such a jump is not noise (IMU samples were lost, the
    gyroscope saturated): the filters widen their attitude uncertainty by ``|δ|²/3`` so that the
    markers pull them back at once.
    """
    n00 = n01 = n02 = n11 = n12 = n22 = 0.0
    g0 = g1 = g2 = 0.0
    for j in range(body.shape[0]):
        ox, oy, oz = earth[k, j, 0], earth[k, j, 1], earth[k, j, 2]
        if not np.isfinite(ox):
            continue
        ax = r[0, 0] * body[j, 0] + r[0, 1] * body[j, 1] + r[0, 2] * body[j, 2]
        ay = r[1, 0] * body[j, 0] + r[1, 1] * body[j, 1] + r[1, 2] * body[j, 2]
        az = r[2, 0] * body[j, 0] + r[2, 1] * body[j, 1] + r[2, 2] * body[j, 2]
        w = 1.0 / var[j]
        n00 += w * (1.0 - ax * ax)
        n01 -= w * ax * ay
        n02 -= w * ax * az
        n11 += w * (1.0 - ay * ay)
        n12 -= w * ay * az
        n22 += w * (1.0 - az * az)
        g0 += w * (ay * oz - az * oy)
        g1 += w * (az * ox - ax * oz)
        g2 += w * (ax * oy - ay * ox)
    c00, c01, c02 = n11 * n22 - n12 * n12, n02 * n12 - n01 * n22, n01 * n12 - n02 * n11
    c11, c12, c22 = n00 * n22 - n02 * n02, n01 * n02 - n00 * n12, n00 * n11 - n01 * n01
    det = n00 * c00 + n01 * c01 + n02 * c02
    if not det > 1e-12 * (n00 + n11 + n22) ** 3:  # fewer than two distinct vectors
        return 0.0
    d0 = (c00 * g0 + c01 * g1 + c02 * g2) / det
    d1 = (c01 * g0 + c11 * g1 + c12 * g2) / det
    d2 = (c02 * g0 + c12 * g1 + c22 * g2) / det
    d2sum = d0 * d0 + d1 * d1 + d2 * d2
    if d2sum <= JUMP_CHI2 * (var_att + (c00 + c11 + c22) / (3.0 * det)):
        return 0.0
    return d2sum / 3.0


def scenario(used: np.ndarray) -> np.ndarray:
    """Liu's sensor scenario (Table 2) of each sample from an estimator's ``used`` bits.

    With the gyroscope always present: 1 markers + mag + acc, 2 mag + acc, 3 markers + acc,
    4 acc, 5 markers + mag, 6 mag, 7 markers, 8 gyroscope alone (9 and 10 are the gyro-less
    scenarios, which no registered estimator runs).
    """
    used = np.asarray(used, dtype=np.int8)
    return (
        1
        + ((used & USED_MARKERS) == 0)
        + 2 * ((used & USED_MAG) == 0)
        + 4 * ((used & USED_ACC) == 0)
    ).astype(np.int8)


# ------------------------------------------------------------------------------ marker pairs


def marker_noise(residual: np.ndarray, n_visible: np.ndarray) -> float:
    """Marker position noise σ (m) from rigid-fit RMS residuals (N,) of ``n_visible`` markers."""
    ok = np.isfinite(residual) & (n_visible >= 4)
    if not ok.any():
        return MIN_SIGMA_M * 10
    n = n_visible[ok].astype(float)
    dof = 3.0 * n - 6.0
    median_chi2 = dof * (1.0 - 2.0 / (9.0 * dof)) ** 3  # Wilson–Hilferty
    return max(float(np.sqrt(np.median(residual[ok] ** 2 * n / median_chi2))), MIN_SIGMA_M)


def pair_vectors(
    shape: np.ndarray, points: np.ndarray, sigma_m: float
) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray, np.ndarray]:
    """Unit directions of every marker pair of a cluster.

    Parameters
    ----------
    shape
        (M, 3) marker positions in the cluster frame (m; NaN for a marker never seen).
    points
        (F, M, 3) measured positions in the lab frame (m; NaN where not seen).
    sigma_m
        Marker position noise (m).

    Returns
    -------
    pairs, cluster (K, 3), lab (F, K, 3), sigma (K,)
        Marker index pairs, their unit directions in the cluster frame and measured in the lab
        (NaN where a marker is missing or the length is off the shape by more than
        ``LENGTH_TOL_SIGMAS`` noise), and their direction noise (rad).
    """
    i, j = np.triu_indices(len(shape), 1)
    d = shape[j] - shape[i]
    length = np.linalg.norm(d, axis=1)
    keep = np.isfinite(length) & (length >= MIN_PAIR_LENGTH_M)
    i, j, d, length = i[keep], j[keep], d[keep], length[keep]
    dl = points[:, j] - points[:, i]
    ll = np.linalg.norm(dl, axis=-1)
    tol = LENGTH_TOL_SIGMAS * np.sqrt(2.0) * sigma_m
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(ll) & (np.abs(ll - length) <= tol)
    lab = np.where(ok[..., None], dl / np.where(ok, ll, 1.0)[..., None], np.nan)
    # the K pairs reuse the noise of the markers: weight them as M − 1 independent ones
    sigma = np.sqrt(2.0) * sigma_m / length * np.sqrt(len(length) / max(len(shape) - 1, 1))
    return list(zip(i.tolist(), j.tolist(), strict=True)), d / length[:, None], lab, sigma


def interpolate_vectors(time: np.ndarray, vectors: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Linear interpolation of unit vectors (F, K, 3) at ``t_new``, renormalised; NaN outside
    ``time`` or next to a NaN frame."""
    k = np.clip(np.searchsorted(time, t_new, side="right") - 1, 0, len(time) - 2)
    frac = np.clip((t_new - time[k]) / (time[k + 1] - time[k]), 0.0, 1.0)[:, None, None]
    out = (1.0 - frac) * vectors[k] + frac * vectors[k + 1]
    exact0, exact1 = frac[:, 0, 0] == 0.0, frac[:, 0, 0] == 1.0
    out[exact0] = vectors[k[exact0]]  # a query on a frame does not need its neighbour
    out[exact1] = vectors[k[exact1] + 1]
    out[(t_new < time[0]) | (t_new > time[-1])] = np.nan
    return out / np.linalg.norm(out, axis=-1, keepdims=True)
