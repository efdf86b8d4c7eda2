"""IMU + marker fusion inputs: marker reference vectors, registration and scenarios (Liu 2010).

Liu (2010, MS thesis §5.1.2, eq. (33)) feeds two marker vectors of the IMU's marker board, each
the direction between two markers, into the orientation filters as extra reference vectors: the
vector is fixed in the body, so the filter predicts its earth-frame direction ``R(q) a`` and
compares it with the measured one. Here every pair of markers of the sensor's cluster gives one
vector (a cluster of four gives six), so a partly hidden cluster still contributes the pairs it
shows; a pair is unavailable where a marker is missing or the pair's length is off the cluster's
rigid shape. Where no pair is seen the filters continue on the IMU alone (the thesis's even
scenarios, Table 2).

Conventions: quaternions scalar first; ``q`` maps sensor → ENU earth; the optical cluster
orientation ``B`` maps cluster → lab; ``X`` maps sensor → cluster and ``Y`` lab → earth, so the
sensor orientation is ``Y ⊗ B ⊗ X`` (as :mod:`motionlab.validation.align`). Times in s, positions
in m, angles in rad.

Registration (thesis §3.2 and §6.2, adapted to offline files whose lab frame is not the earth
frame, over every sample where both systems see the segment rather than one static pose):

- clock: the angular-speed cross-correlation of :func:`motionlab.validation.sync.synchronise`,
  then refined with ``X`` and the gyroscope bias by Gauss–Newton on the relative rotations over
  the lags ``L`` of ``LAGS_S``: ``log(A_k* A_k+L) = R(X)ᵀ log(B(τ_k)* B(τ_k+L)) + b ΔT`` with
  ``A`` the strapdown integral of the gyroscope and ``τ = offset + (1 + drift) t`` (an
  orientation error is the angular rate times the clock error, so the fusion needs the offset
  to a fraction of a millisecond);
- ``X`` (sensor → cluster): the Wahba fit of those relative rotations (Park & Martin 1994);
- ``Y`` (lab → earth), the thesis's two-vector solve (eqs. (2)–(4), as TRIAD): the vertical is the
  mean specific force and the north the mean undisturbed magnetic field, both carried into the lab
  frame through ``B X`` and pooled over the sensors (linear accelerations and sensor errors
  average out); a vertical within ``SNAP_DEG`` of a lab axis is taken as that axis (optical labs
  are levelled). Without a magnetometer the heading keeps the lab's x axis in the east–up plane.

Noise: the marker position noise ``σ`` is estimated from the clusters' rigid-fit residuals
(a fit of ``n`` markers leaves ``(3n − 6)/n · σ²`` per marker), and a pair of length ``L`` has a
direction noise of ``√2 σ / L`` rad per component; the filters weight the vectors by it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion.attitude import NORTH, UP, triad

#: bits of an estimator's per-sample ``used`` output: which measurements entered the update
USED_ACC, USED_MAG, USED_MARKERS = 1, 2, 4

LAGS_S = (0.2, 1.0)
LOWPASS_HZ = 4.0
SNAP_DEG = 2.0
MIN_PAIR_LENGTH_M = 0.01
LENGTH_TOL_SIGMAS = 6.0
MIN_SIGMA_M = 1e-4
CLOCK_ITERATIONS = 6
SYNC_WINDOWS = {"window_s": 4.0, "step_s": 2.0}  # short: occlusions leave few long windows
JUMP_CHI2 = 25.0  # |δ|² over its variance per axis: a 3-D correction beyond about 5σ
_STEP_S = 1e-3  # finite-difference step of the clock derivative


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


def scenario_counts(used: np.ndarray) -> dict[str, int]:
    """``{"1": n_1, ...}``: how many samples ran in each scenario."""
    values, counts = np.unique(scenario(used), return_counts=True)
    return {str(int(v)): int(c) for v, c in zip(values, counts, strict=True)}


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


# ------------------------------------------------------------------------------ registration


@dataclass
class SensorRegistration:
    """Clock and sensor → cluster rotation of one sensor (see the module docstring).

    ``offset_s``/``drift`` map the IMU clock to the optical one, ``t_ref = offset + (1 + drift)
    t``; ``gyro_bias`` (rad/s) is the bias fitted with ``X``; ``residual_deg`` the RMS misfit of
    the relative rotations over ``LAGS_S``.
    """

    offset_s: float
    drift: float
    sensor_to_cluster: np.ndarray
    gyro_bias: np.ndarray
    residual_deg: float
    n_rows: int

    def to_reference(self, t: np.ndarray) -> np.ndarray:
        return self.offset_s + (1.0 + self.drift) * np.asarray(t, dtype=float)


def _relative(t: np.ndarray, q: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Rotation vectors ``log(q_i* ⊗ q_j)`` (rows, 3) for the index pairs ``(start, end)``, in
    the moving frame of ``q`` (N, 4) low-passed at ``LOWPASS_HZ`` (a linear filter of the
    components, so it commutes with the constant rotations between the two systems)."""
    from motionlab.validation.optical import smooth_pose

    q = smooth_pose(t, q, np.zeros((len(t), 3)), LOWPASS_HZ)[0]
    return rot.to_rotvec(rot.mul(rot.conj(q[start]), q[end]))


def _row_pairs(t: np.ndarray, bad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end sample of the relative rotations: every lag of ``LAGS_S``, a start every
    quarter of the shortest lag, no lost gyroscope sample in between."""
    rate = 1.0 / np.median(np.diff(t))
    lags = [max(1, int(round(lag_s * rate))) for lag_s in LAGS_S]
    stride = max(1, lags[0] // 4)
    starts, ends = [], []
    for lag in lags:
        if len(t) > 2 * lag:
            spans_bad = np.convolve(bad, np.ones(lag + 1), "valid") > 0
            first = np.flatnonzero(~spans_bad)[::stride]
            starts.append(first)
            ends.append(first + lag)
    if not starts:
        raise InputError(f"{len(t)} samples are too few to register the markers", "markers")
    return np.concatenate(starts), np.concatenate(ends)


def register_sensor(
    t: np.ndarray,
    gyr: np.ndarray,
    t_opt: np.ndarray,
    q_opt: np.ndarray,
    offset_s: float = 0.0,
    drift: float = 0.0,
    refine_clock: bool = True,
) -> SensorRegistration:
    """Sensor → cluster rotation, gyroscope bias and refined clock of one sensor.

    Parameters
    ----------
    t, gyr
        IMU times (s, IMU clock) and gyroscope (N, 3) rad/s.
    t_opt, q_opt
        Optical times (s, optical clock) and cluster → lab orientations (M, 4), NaN in gaps.
    offset_s, drift
        Starting clock model (e.g. from :func:`motionlab.validation.sync.synchronise`).
    refine_clock
        Refine the clock model (False: keep it, e.g. for streams on one clock).
    """
    from motionlab.segments.frames import wahba
    from motionlab.validation.optical import resample_quat

    t = np.asarray(t, dtype=float)
    bad = ~np.isfinite(gyr).all(axis=1)
    i, j = _row_pairs(t, bad)
    a = rot.integrate_gyro(rot.IDENTITY, np.where(bad[:, None], 0.0, gyr), np.diff(t))
    da, span = _relative(t, a, i, j), (t[j] - t[i])[:, None]
    tc = t[i] - t[i].mean()
    m, bias, keep = np.eye(3), np.zeros(3), np.ones(len(i), bool)
    for it in range(CLOCK_ITERATIONS if refine_clock else 1):
        tau = offset_s + (1.0 + drift) * t
        db = _relative(t, resample_quat(t_opt, q_opt, tau), i, j)
        ok = keep & np.isfinite(db).all(axis=1)
        if ok.sum() < 20:
            raise InputError(
                "too little overlap of the IMU and the marker cluster to register them",
                "markers",
                remedy="check the marker map and that both systems recorded the same movement",
            )
        for _ in range(3):  # X and bias, alternately (the bias is small against the motion)
            m = wahba(db[ok], da[ok] - bias * span[ok])
            resid = da - bias * span - db @ m
            bias = bias + np.sum(resid[ok] * span[ok], axis=0) / np.sum(span[ok] ** 2)
        resid = da - bias * span - db @ m
        err = np.linalg.norm(resid, axis=1)
        if it == 0:  # drop glitches (marker swaps, ghost markers) before refining
            keep &= ~(err > 5.0 * np.nanmedian(err[ok]))
            ok &= keep
        if not refine_clock:
            break
        ahead = _relative(t, resample_quat(t_opt, q_opt, tau + _STEP_S), i, j)
        behind = _relative(t, resample_quat(t_opt, q_opt, tau - _STEP_S), i, j)
        ddb = (ahead - behind) @ m / (2.0 * _STEP_S)
        okd = ok & np.isfinite(ddb).all(axis=1)
        jac = np.column_stack([ddb[okd].ravel(), (ddb[okd] * tc[okd, None]).ravel()])
        step = np.linalg.lstsq(jac, resid[okd].ravel(), rcond=None)[0]
        offset_s += step[0] - step[1] * t[i].mean()
        drift += step[1]
    rms = float(np.degrees(np.sqrt(np.mean(err[ok] ** 2))))
    return SensorRegistration(
        float(offset_s), float(drift), rot.from_matrix(m), bias, rms, int(ok.sum())
    )


def _snap(up: np.ndarray) -> tuple[np.ndarray, str | None]:
    """``up`` replaced by the closest lab axis when within ``SNAP_DEG`` of it."""
    k = int(np.argmax(np.abs(up)))
    axis = np.zeros(3)
    axis[k] = np.sign(up[k])
    if np.degrees(np.arccos(np.clip(axis @ up, -1.0, 1.0))) <= SNAP_DEG:
        return axis, f"{'+' if axis[k] > 0 else '-'}{'xyz'[k]}"
    return up, None


def lab_to_earth(
    sensors: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]], field_tol_deg: float = 6.0
) -> tuple[np.ndarray, dict[str, Any]]:
    """Lab → earth rotation ``Y`` from gravity and the magnetic field seen in the lab frame.

    ``sensors`` holds per sensor ``(BX (N, 4), acc (N, 3), mag (N, 3) or None)``: the sensor →
    lab orientation from the markers (NaN where unknown) and the IMU's specific force and field.
    The lab vertical is the direction of the summed specific force (snapped to a lab axis within
    ``SNAP_DEG``); north is the horizontal part of the mean field direction over the samples
    within ``field_tol_deg`` of the median direction (a disturbed field is off it). Liu 2010,
    eqs. (2)–(4), solved by TRIAD.
    """
    up_sum, fields = np.zeros(3), []
    for bx, acc, mag in sensors:
        ok = np.isfinite(bx).all(axis=1)
        up_sum += np.sum(rot.rotate(bx[ok], acc[ok]), axis=0)
        if mag is not None:
            f = rot.rotate(bx[ok], mag[ok])
            fields.append(f / np.linalg.norm(f, axis=1, keepdims=True))
    if not np.linalg.norm(up_sum) > 0:
        raise InputError("no sample where the markers and the IMU overlap", "markers")
    up, snapped = _snap(up_sum / np.linalg.norm(up_sum))
    info: dict[str, Any] = {"vertical_axis": snapped, "vertical_lab": up}
    f = np.concatenate(fields) if fields else np.zeros((0, 3))
    f = f[np.isfinite(f).all(axis=1)]
    if len(f):
        med = np.median(f, axis=0)
        med /= np.linalg.norm(med)
        near = f @ med >= np.cos(np.radians(field_tol_deg))
        field_lab = np.mean(f[near], axis=0)
        info |= {"heading_from": "magnetometer", "field_fraction_used": float(near.mean())}
        y = triad(up, field_lab, UP, NORTH)
        info["dip_deg"] = float(
            np.degrees(np.arcsin(-(field_lab @ up) / np.linalg.norm(field_lab)))
        )
    else:  # 6-D: keep the lab x axis in the east-up plane
        x = np.eye(3)[0] if abs(up[0]) < 0.9 else np.eye(3)[1]
        y = triad(up, x, UP, np.array([1.0, 0.0, 0.0]))
        info["heading_from"] = "lab axes (no magnetometer)"
    return y, info


# ------------------------------------------------------------------------------ session


def _cluster_sensors(session: Any, mmap: Any, labels: list[str] | None) -> dict[str, Any]:
    """``{sensor label: SegmentMap}`` for the mapped marker clusters that carry a chosen sensor."""
    from motionlab.segments import sensor_for_segment

    out = {}
    for seg, spec in mmap.segments.items():
        label = spec.sensor or sensor_for_segment(session, seg)
        if label in session.sensors and spec.cluster and (labels is None or label in labels):
            out[label] = spec
    if not out:
        raise InputError(
            "no marker cluster of the marker map is on a sensor to fuse",
            mmap.path,
            remedy="name cluster segments after the sensors, or set sensor: in the marker map",
        )
    return out


def session_references(
    session: Any,
    marker_map: Any = None,
    protocol: Any = None,
    labels: list[str] | None = None,
    *,
    sync: bool = True,
    seed: int = 0,
) -> tuple[dict[str, MarkerReferences], dict[str, Any]]:
    """Marker reference vectors for the session's sensors that carry a marker cluster.

    Parameters
    ----------
    session
        A :class:`~motionlab.session.Session` with a marker set (``session.markers``).
    marker_map
        A :class:`~motionlab.validation.markermap.MarkerMap` (default: clusters found by name,
        :func:`~motionlab.validation.markermap.default_marker_map`).
    protocol
        Used by the default marker map to tell landmarks from cluster markers.
    labels
        Sensors to prepare (default: every sensor with a cluster).
    sync
        Estimate each sensor's clock against the optical one (False: one shared clock).
    seed
        Seed of the RANSAC in the coarse clock estimate.

    Returns
    -------
    references, info
        ``{label: MarkerReferences}`` on each sensor's own samples, and a JSON-able record:
        ``lab_to_earth`` (quaternion and how it was found) and per sensor the clock
        (``time_offset_s``, ``drift_ppm``), ``sensor_to_cluster``, the gyroscope bias, the
        registration residual, the marker noise and the visible fraction.
    """
    from motionlab.validation.markermap import check_marker_map, default_marker_map
    from motionlab.validation.optical import resample_quat, track_cluster
    from motionlab.validation.reference import choose_marker_set
    from motionlab.validation.sync import synchronise

    if not session.markers:
        raise InputError("the session holds no marker data", remedy="ingest a C3D/TRC file with it")
    name = marker_map.marker_set if marker_map is not None else None
    markers = choose_marker_set(list(session.markers.values()), name)
    mmap = marker_map or default_marker_map(markers, protocol, list(session.sensors))
    check_marker_map(mmap, markers)
    chosen = _cluster_sensors(session, mmap, labels)
    parts, pooled, info = {}, [], {"marker_set": markers.name, "sensors": {}}
    for label, spec in chosen.items():
        s = session.sensors[label]
        points = markers.positions[:, [markers.labels.index(m) for m in spec.cluster]]
        track = track_cluster(markers.time, points, spec.cluster, mmap.max_gap_s, mmap.lowpass_hz)
        offset, drift = 0.0, 0.0
        if sync:
            clock = synchronise(
                [(s.time, s.gyr)], [(track.time, track.quat)], seed=seed, **SYNC_WINDOWS
            )
            offset, drift = clock.model.offset_s, clock.model.drift
        reg = register_sensor(s.time, s.gyr, track.time, track.quat, offset, drift, sync)
        sigma_m = marker_noise(track.residual, track.n_visible)
        pairs, cluster_dirs, lab_dirs, sigma = pair_vectors(track.shape, points, sigma_m)
        tau = reg.to_reference(s.time)
        bx = rot.mul(resample_quat(track.time, track.quat, tau), reg.sensor_to_cluster)
        pooled.append((bx, s.acc, s.mag))
        parts[label] = (reg, rot.rotate(rot.conj(reg.sensor_to_cluster), cluster_dirs),
                        interpolate_vectors(markers.time, lab_dirs, tau), sigma,
                        [(spec.cluster[i], spec.cluster[j]) for i, j in pairs])  # fmt: skip
        info["sensors"][label] = {
            "segment": spec.name,
            "time_offset_s": reg.offset_s,
            "drift_ppm": reg.drift * 1e6,
            "sensor_to_cluster": reg.sensor_to_cluster,
            "gyro_bias_rad_s": reg.gyro_bias,
            "registration_residual_deg": reg.residual_deg,
            "marker_noise_mm": sigma_m * 1e3,
            "n_pairs": len(pairs),
        }
    y, info["lab_to_earth"] = lab_to_earth(pooled)
    info["lab_to_earth"]["quat"] = y
    refs = {}
    for label, (reg, body, lab, sigma, names) in parts.items():
        refs[label] = MarkerReferences(body, rot.rotate(y, lab), sigma, reg.gyro_bias, names)
        info["sensors"][label]["visible_fraction"] = float(refs[label].visible.mean())
    return refs, info
