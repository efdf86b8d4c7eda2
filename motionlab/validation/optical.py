"""Optical segment frames: marker clusters by a least-squares rigid fit, and rigid-body streams.

Conventions: the first array dimension is time; marker positions are (N, M, 3) in m with NaN
where a marker was not seen; quaternions are Hamilton, scalar first, mapping the cluster frame
into the optical lab frame.

A cluster is three or more markers on one rigid plate. Its shape (marker positions in the cluster
frame) is the generalised Procrustes mean of the recording, expressed in its principal axes
(x along the largest spread, z normal to the plate, origin at the centroid). Each frame is then
fitted by the weighted least-squares rigid transform of Arun, Huang & Blostein (1987, IEEE PAMI
9:698; the SVD solution of Kabsch 1976 with the reflection fix of Umeyama 1991) over the markers
seen in that frame, at least three and not collinear, with the RMS residual per frame. Gaps where
the cluster cannot be fitted are filled by SLERP when they are short (``max_gap_s``) and left NaN
and flagged otherwise. The pose is then low-passed (zero-phase 4th-order Butterworth on the
sign-continuous quaternion components and the origin, 6 Hz by default, as Winter (2009) uses
for gait markers), which removes most of the marker noise and keeps the movement.
Angular velocity from an orientation sequence follows Ricci (2015, eqs. 5.11-5.12):
``ω_k = 2 log(q_k* ⊗ q_{k+1}) / Δt`` in the moving frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from motionlab import rotations as rot
from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.timebase import runs
from motionlab.validation._kernels import cross_covariance

MIN_MARKERS = 3
DEFAULT_MAX_GAP_S = 0.1
DEFAULT_LOWPASS_HZ = 6.0
_PROCRUSTES_ITERATIONS = 3
_SHAPE_FRAMES = 3000
_COLLINEAR = 1e-3  # second singular value / first below this: the visible markers are a line


@dataclass
class ClusterTrack:
    """A marker cluster followed through a recording.

    ``quat`` (N, 4) cluster → lab and ``origin`` (N, 3) m are NaN in long gaps; ``residual``
    (N,) is the RMS distance (m) between measured and fitted markers (NaN where not fitted);
    ``n_visible`` the markers used per frame; ``interpolated`` marks frames filled across a
    short gap and ``flagged`` the frames of long gaps; ``shape`` (K, 3) holds the markers in the
    cluster frame (m).
    """

    time: np.ndarray
    quat: np.ndarray
    origin: np.ndarray
    residual: np.ndarray
    n_visible: np.ndarray
    interpolated: np.ndarray
    flagged: np.ndarray
    shape: np.ndarray
    labels: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, float | int]:
        """Visible, interpolated and flagged fractions, long-gap count, residual RMS (mm)."""
        fitted = np.isfinite(self.residual)
        flagged = self.flagged.astype(int)
        return {
            "fitted_fraction": float(fitted.mean()) if len(fitted) else 0.0,
            "interpolated_fraction": float(self.interpolated.mean()) if len(fitted) else 0.0,
            "flagged_fraction": float(self.flagged.mean()) if len(fitted) else 0.0,
            "n_long_gaps": int(np.sum(np.diff(np.r_[0, flagged]) == 1)),
            "residual_rms_mm": float(np.sqrt(np.nanmean(self.residual**2)) * 1e3)
            if fitted.any()
            else float("nan"),
        }


def rigid_fit(
    shape: np.ndarray,
    points: np.ndarray,
    visible: np.ndarray | None = None,
    residual: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Least-squares rigid transform of ``shape`` (K, 3) onto ``points`` (N, K, 3), per frame.

    ``points ≈ R shape + t`` over the markers ``visible`` (N, K) in each frame (default: the
    finite ones). Returns ``quat`` (N, 4) of R, ``origin`` (N, 3) = t, and the RMS residual
    (N,) in the units of the points (``None`` with ``residual=False``: a fit whose residual is
    not used, as the shape's iterations, skips it). Frames with fewer than three usable
    markers, or with the usable markers on a line, are NaN.
    """
    shape = np.ascontiguousarray(shape, dtype=float)  # one compiled layout for the kernel
    points = np.ascontiguousarray(points, dtype=float)
    ok = np.isfinite(points).all(axis=-1) & np.isfinite(shape).all(axis=-1)
    if visible is not None:
        ok &= np.asarray(visible, dtype=bool)
    n_ok = ok.sum(axis=1)
    s = np.where(np.isfinite(shape), shape, 0.0)
    denom = np.maximum(n_ok, 1.0)[:, None]
    cp, cs, h = np.empty((len(ok), 3)), np.empty((len(ok), 3)), np.empty((len(ok), 3, 3))
    cross_covariance(shape, points, ok, cp, cs, h)  # the centroids, Σ (s - s̄)(p - p̄)ᵀ
    u, sv, vt = np.linalg.svd(h)
    fix = np.ones((len(h), 3))
    fix[:, 2] = np.where(_det3(vt) * _det3(u) < 0, -1.0, 1.0)  # the sign of det(V Uᵀ)
    r = np.swapaxes(vt, 1, 2) @ (fix[:, :, None] * np.swapaxes(u, 1, 2))
    t = cp - np.einsum("nij,nj->ni", r, cs)
    rms = None
    if residual:
        fitted = np.einsum("nij,kj->nki", r, s) + t[:, None]
        sq = np.sum((fitted - points) ** 2, axis=-1)
        rms = np.sqrt(np.sum(np.where(ok, sq, 0.0), axis=1) / denom[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        planar = sv[:, 1] > _COLLINEAR * sv[:, 0]
    good = (n_ok >= MIN_MARKERS) & planar
    quat = np.full((len(h), 4), np.nan)
    if good.any():
        quat[good] = rot.from_matrix(r[good])
    t[~good] = np.nan
    if rms is not None:
        rms[~good] = np.nan
    return rot.make_continuous(quat), t, rms


def _det3(m: np.ndarray) -> np.ndarray:
    """Determinants (N,) of 3 × 3 matrices (N, 3, 3) by cofactors: for the SVD's orthogonal
    factors (±1) the sign is that of ``np.linalg.det``'s LU, without its cost."""
    return (
        m[:, 0, 0] * (m[:, 1, 1] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 1])
        - m[:, 0, 1] * (m[:, 1, 0] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 0])
        + m[:, 0, 2] * (m[:, 1, 0] * m[:, 2, 1] - m[:, 1, 1] * m[:, 2, 0])
    )


def _principal_axes(shape: np.ndarray) -> np.ndarray:
    """``shape`` centred and rotated into its principal axes (x largest spread, z normal).

    Signs: the marker farthest along x (then y) has a positive coordinate; z = x × y.
    """
    known = np.isfinite(shape).all(axis=1)
    centred = shape - shape[known].mean(axis=0)
    _, _, vt = np.linalg.svd(centred[known])
    axes = vt.copy()
    for i in (0, 1):
        proj = centred[known] @ axes[i]
        if proj[np.argmax(np.abs(proj))] < 0:
            axes[i] = -axes[i]
    axes[2] = np.cross(axes[0], axes[1])
    return centred @ axes.T


def cluster_shape(points: np.ndarray) -> np.ndarray:
    """Mean cluster shape (K, 3) in its principal axes from positions (N, K, 3) with NaN gaps.

    Starts from the frame that sees the most markers, then alternates rigid fits of every frame
    and the median of each marker's position in the cluster frame (generalised Procrustes).
    Raises :class:`InputError` when no frame sees three markers.
    """
    points = np.asarray(points, dtype=float)
    if len(points) > _SHAPE_FRAMES:  # the shape needs a few thousand frames, not all
        points = points[np.linspace(0, len(points) - 1, _SHAPE_FRAMES).astype(int)]
    seen = np.isfinite(points).all(axis=-1)
    counts = seen.sum(axis=1)
    if len(counts) == 0 or counts.max() < MIN_MARKERS:
        raise InputError(
            f"no frame shows {MIN_MARKERS} markers of the cluster at once",
            remedy="check the marker labels in the marker map",
        )
    best = int(np.argmax(counts))
    shape = np.where(seen[best][:, None], points[best], np.nan)
    for _ in range(_PROCRUSTES_ITERATIONS):
        shape = _principal_axes(shape)
        q, t, _ = rigid_fit(shape, points, residual=False)
        local = local_coordinates(q, t, points)
        seen_once = np.isfinite(local).all(axis=-1).any(axis=0)
        shape[seen_once] = np.nanmedian(local[:, seen_once], axis=0)
    return _principal_axes(shape)


def local_coordinates(quat: np.ndarray, origin: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Positions (N, K, 3) expressed in the moving frame: ``Rᵀ (p − t)``; NaN where unknown."""
    q = np.asarray(quat, dtype=float)[:, None, :]
    return rot.rotate(rot.conj(q), np.asarray(points, float) - np.asarray(origin, float)[:, None])


def fill_gaps(
    time: np.ndarray, quat: np.ndarray, origin: np.ndarray, max_gap_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fill short gaps of a pose sequence; flag long ones.

    A gap is a run of NaN frames between two fitted frames; when those two frames are at most
    ``max_gap_s`` apart the gap is filled by SLERP (orientation) and linear interpolation
    (origin). Runs at the start or end, and longer gaps, stay NaN. Returns the filled
    ``quat``, ``origin`` and the boolean masks ``interpolated`` and ``flagged`` (N,).
    """
    time = np.asarray(time, dtype=float)
    quat = np.array(quat, dtype=float)
    origin = np.array(origin, dtype=float)
    ok = np.isfinite(quat).all(axis=1)
    idx = np.flatnonzero(ok)
    missing = ~ok
    if len(idx) == 0:
        return quat, origin, np.zeros(len(time), bool), missing
    k = np.searchsorted(idx, np.arange(len(time)))  # next fitted frame
    inside = missing & (k > 0) & (k < len(idx))
    prev = idx[np.clip(k - 1, 0, len(idx) - 1)]
    nxt = idx[np.clip(k, 0, len(idx) - 1)]
    span = time[nxt] - time[prev]
    short = inside & (span <= max_gap_s + 1e-9)
    if short.any():
        frac = (time[short] - time[prev[short]]) / span[short]
        quat[short] = rot.slerp(quat[prev[short]], quat[nxt[short]], frac)
        origin[short] = origin[prev[short]] + frac[:, None] * (
            origin[nxt[short]] - origin[prev[short]]
        )
    return rot.make_continuous(quat), origin, short, missing & ~short


def smooth_pose(
    time: np.ndarray, quat: np.ndarray, origin: np.ndarray, cutoff_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """Zero-phase low-pass of a pose sequence, run by run between NaN gaps.

    Quaternion components (sign-continuous) and origin are filtered by a 4th-order Butterworth
    at ``cutoff_hz`` and the quaternions renormalised; runs too short to filter are kept.
    """
    quat = rot.make_continuous(np.array(quat, dtype=float))
    origin = np.array(origin, dtype=float)
    rate = 1.0 / np.median(np.diff(time)) if len(time) > 1 else 0.0
    if not cutoff_hz or cutoff_hz >= 0.45 * rate:
        return quat, origin
    sos = butter(4, cutoff_hz, fs=rate)
    ok = np.isfinite(quat).all(axis=1) & np.isfinite(origin).all(axis=1)
    for a, b in runs(ok):  # one filter call per run
        if b - a > 30:
            quat[a:b] = rot.normalize(sosfiltfilt(sos, quat[a:b], axis=0))
            origin[a:b] = sosfiltfilt(sos, origin[a:b], axis=0)
    return quat, origin


def track_cluster(
    time: np.ndarray,
    points: np.ndarray,
    labels: list[str] | None = None,
    max_gap_s: float = DEFAULT_MAX_GAP_S,
    lowpass_hz: float = DEFAULT_LOWPASS_HZ,
) -> ClusterTrack:
    """Follow a marker cluster (positions (N, K, 3), m) through a recording; see the module.

    ``lowpass_hz`` 0 keeps the raw fitted poses.
    """
    points = np.asarray(points, dtype=float)
    shape = cluster_shape(points)
    quat, origin, residual = rigid_fit(shape, points)
    seen = np.isfinite(points).all(axis=-1) & np.isfinite(shape).all(axis=-1)
    quat, origin, interpolated, flagged = fill_gaps(time, quat, origin, max_gap_s)
    quat, origin = smooth_pose(time, quat, origin, lowpass_hz)
    return ClusterTrack(
        time=np.asarray(time, dtype=float),
        quat=quat,
        origin=origin,
        residual=residual,
        n_visible=np.where(np.isfinite(residual), seen.sum(axis=1), 0),
        interpolated=interpolated,
        flagged=flagged,
        shape=shape,
        labels=list(labels or []),
    )


def resample_quat(time: np.ndarray, quat: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """SLERP ``quat`` (N, 4) at ``t_new``; NaN outside ``time`` or next to a NaN sample.

    A query that falls exactly on a sample returns that sample (even beside a NaN one).
    """
    time = np.asarray(time, dtype=float)
    quat = np.asarray(quat, dtype=float)
    t_new = np.asarray(t_new, dtype=float)
    out = np.full((len(t_new), 4), np.nan)
    if len(time) == 0:
        return out
    k = np.clip(np.searchsorted(time, t_new, side="right") - 1, 0, max(len(time) - 2, 0))
    k1 = np.minimum(k + 1, len(time) - 1)
    inside = (t_new >= time[0]) & (t_new <= time[-1])
    span = time[k1] - time[k]
    frac = np.clip(np.where(span > 0, (t_new - time[k]) / np.where(span > 0, span, 1), 0), 0, 1)
    finite = np.isfinite(quat).all(axis=1)
    at0 = inside & (frac <= 1e-12) & finite[k]
    at1 = inside & ~at0 & (frac >= 1 - 1e-12) & finite[k1]
    mid = inside & ~at0 & ~at1 & finite[k] & finite[k1]
    out[at0] = quat[k[at0]]
    out[at1] = quat[k1[at1]]
    if mid.any():
        out[mid] = rot.slerp(quat[k[mid]], quat[k1[mid]], frac[mid])
    return rot.make_continuous(out)
