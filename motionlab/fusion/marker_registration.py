"""Registration of a marker cluster with its IMU, and the marker references of a session.

Conventions: quaternions scalar first; ``q`` maps sensor → ENU earth; the optical cluster
orientation ``B`` maps cluster → lab; ``X`` maps sensor → cluster and ``Y`` lab → earth, so the
sensor orientation is ``Y ⊗ B ⊗ X`` (as :mod:`motionlab.validation.align`). Times in s.

Liu (2010, thesis §3.2 and §6.2) registers IMU and marker board from one static pose in a lab
frame that is the earth frame. Offline files have their own lab frame and clocks, so here every
sample where both systems see the segment is used:

- clock: the angular-speed cross-correlation of
  :func:`motionlab.validation.time_alignment.synchronise`, then refined with ``X`` and the
  gyroscope bias by Gauss–Newton on the relative rotations over the lags ``L`` of ``LAGS_S``:
  ``log(A_k* A_k+L) = R(X)ᵀ log(B(τ_k)* B(τ_k+L))`` with ``A``
  the strapdown integral of the bias-corrected gyroscope (the bias left in the relative
  rotations, ``≈ b ΔT``, is fitted and removed in turn) and ``τ = offset + (1 + drift) t`` (an
  orientation error is the angular rate times the clock error, so the fusion needs the offset
  to a fraction of a millisecond);
- ``X`` (sensor → cluster): the Wahba fit of those relative rotations (Park & Martin 1994);
- ``Y`` (lab → earth), the thesis's two-vector solve (eqs. (2)–(4), as TRIAD): the vertical is the
  mean specific force and the north the mean undisturbed magnetic field, both carried into the lab
  frame through ``B X`` and pooled over the sensors (linear accelerations and sensor errors
  average out; each magnetometer's hard iron, which turns with the sensor, is fitted with the
  field); a vertical within ``SNAP_DEG`` of a lab axis is taken as that axis (optical labs are
  levelled). Without a magnetometer the heading keeps the lab's x axis in the east–up plane.
  The earth frame's heading is the magnetometers': their remaining calibration errors (soft
  iron, axis misalignment) turn the estimate about the vertical.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.fusion.attitude import NORTH, UP, triad
from motionlab.fusion.markers import (
    MarkerReferences,
    interpolate_vectors,
    marker_noise,
    pair_vectors,
)
from motionlab.fusion.stage import filled_spans
from motionlab.results import LabToEarth, MarkerFusion
from motionlab.segments.frames import wahba
from motionlab.timebase import find_gaps
from motionlab.validation.markermap import check_marker_map, default_marker_map
from motionlab.validation.optical import resample_quat, smooth_pose, track_cluster
from motionlab.validation.reference import choose_marker_set
from motionlab.validation.time_alignment import synchronise

LAGS_S = (0.2, 1.0, 2.0, 4.0)
LOWPASS_HZ = 4.0
SNAP_DEG = 2.0
CLOCK_ITERATIONS = 8
CLOCK_TOL_S = 2e-5  # clock steps below this end the refinement
SYNC_WINDOWS = {"window_s": 4.0, "step_s": 2.0}  # short: occlusions leave few long windows
_STEP_S = 1e-3  # finite-difference step of the clock derivative


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
    q = smooth_pose(t, q, np.zeros((len(t), 3)), LOWPASS_HZ)[0]
    return rot.to_rotvec(rot.mul(rot.conj(q[start]), q[end]))


def _row_pairs(t: np.ndarray, bad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end sample of the relative rotations: every lag of ``LAGS_S``, a start every
    quarter of the shortest lag, no ``bad`` sample (an interval the gyroscope did not measure
    starts or ends there) from start to end."""
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


def unmeasured(t: np.ndarray, gyr: np.ndarray, filled_spans: Any = None) -> np.ndarray:
    """Samples (bool, N) next to an interval the gyroscope did not measure: a lost (non-finite)
    sample, the sample before a gap in ``t`` (an interval over ``GAP_FACTOR`` nominal ones),
    and the instants ingest made up inside its ``filled_spans`` (``[start_s, end_s]`` pairs,
    the recorded stamps either side, :func:`motionlab.fusion.stage.filled_spans`). A rotation
    between two samples with one of these between them is not the sensor's: at heel strike a
    60-ms gap bridged by a line missed 2.5° of a simulated thigh's turn."""
    bad = ~np.isfinite(gyr).all(axis=1)
    bad[find_gaps(t)] = True
    for start, end in np.asarray([] if filled_spans is None else filled_spans).reshape(-1, 2):
        bad |= (t > start) & (t < end)
    return bad


def register_sensor(
    t: np.ndarray,
    gyr: np.ndarray,
    t_opt: np.ndarray,
    q_opt: np.ndarray,
    offset_s: float = 0.0,
    drift: float = 0.0,
    refine_clock: bool = True,
    filled_spans: Any = None,
) -> SensorRegistration:
    """Sensor → cluster rotation, gyroscope bias and refined clock of one sensor.

    Parameters
    ----------
    t, gyr
        IMU times (s, IMU clock) and gyroscope (N, 3) rad/s.
    t_opt, q_opt
        Optical times (s, optical clock) and cluster → lab orientations (M, 4), NaN in gaps.
    offset_s, drift
        Starting clock model (e.g. from :func:`motionlab.validation.time_alignment.synchronise`).
    refine_clock
        Refine the clock model (False: keep it, e.g. for streams on one clock).
    filled_spans
        Gaps ingest filled in ``t`` (``[start_s, end_s]`` pairs): no relative rotation spans
        them (:func:`unmeasured`).
    """
    t = np.asarray(t, dtype=float)
    bad = unmeasured(t, gyr, filled_spans)
    i, j = _row_pairs(t, bad)
    gyr = np.where(np.isfinite(gyr), gyr, 0.0)

    def imu_relative(bias: np.ndarray, seen: np.ndarray) -> np.ndarray:
        # the IMU's orientations only where the optical ones exist, so that both are low-passed
        # over the same runs (the filter's start and end transients then match too)
        a = rot.integrate_gyro(rot.IDENTITY, gyr - bias, np.diff(t))
        return _relative(t, np.where(seen[:, None], a, np.nan), i, j)

    def optical(tau: np.ndarray) -> np.ndarray:
        # NaN next to the unmeasured intervals too: both systems low-passed by the same runs
        b = resample_quat(t_opt, q_opt, tau)
        b[bad] = np.nan
        return b

    span, tc = (t[j] - t[i])[:, None], t[i] - t[i].mean()
    m, bias, keep = np.eye(3), np.zeros(3), np.ones(len(i), bool)
    for it in range(CLOCK_ITERATIONS if refine_clock else 1):
        tau = offset_s + (1.0 + drift) * t
        b = optical(tau)
        seen = np.isfinite(b).all(axis=1)
        db = _relative(t, b, i, j)
        da = imu_relative(bias, seen)
        ok = keep & np.isfinite(db).all(axis=1) & np.isfinite(da).all(axis=1)
        if ok.sum() < 20:
            raise InputError(
                "too little overlap of the IMU and the marker cluster to register them",
                "markers",
                remedy="check the marker map and that both systems recorded the same movement",
            )
        for _ in range(2):  # X, then the bias left in the relative rotations (≈ b ΔT), again
            m = wahba(db[ok], da[ok])
            resid = da - db @ m
            bias = bias + np.sum(resid[ok] * span[ok], axis=0) / np.sum(span[ok] ** 2)
            da = imu_relative(bias, seen)
        resid = da - db @ m
        err = np.linalg.norm(resid, axis=1)
        if it == 0:  # drop glitches (marker swaps, ghost markers) before refining
            keep &= ~(err > 5.0 * np.nanmedian(err[ok]))
            ok &= keep
        if not refine_clock:
            break
        ahead = _relative(t, optical(tau + _STEP_S), i, j)
        behind = _relative(t, optical(tau - _STEP_S), i, j)
        ddb = (ahead - behind) @ m / (2.0 * _STEP_S)
        okd = ok & np.isfinite(ddb).all(axis=1)
        jac = np.column_stack([ddb[okd].ravel(), (ddb[okd] * tc[okd, None]).ravel()])
        step = np.linalg.lstsq(jac, resid[okd].ravel(), rcond=None)[0]
        offset_s += step[0] - step[1] * t[i].mean()
        drift += step[1]
        if abs(step[0]) < CLOCK_TOL_S and abs(step[1]) * np.ptp(t) < CLOCK_TOL_S:
            break
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


def _lab_field(
    items: list[tuple[np.ndarray, np.ndarray]], tol_ut: float
) -> tuple[np.ndarray, float]:
    """The earth field in the lab frame (µT) and the fraction of samples that agree with it.

    ``items`` holds per sensor the sensor → lab rotation matrices (n, 3, 3) and the field
    (n, 3). Each sensor's hard iron ``h`` turns with it while the earth field ``c`` stays fixed
    in the lab, so ``R_k m_k = c + R_k h`` is solved for ``c`` and every ``h`` by least squares
    (minimum norm where a sensor turned about one axis only); samples further than ``tol_ut``
    (or three times the median) from the fit are dropped (disturbances) and the fit repeated.
    """
    s = len(items)
    keep = [np.ones(len(m), bool) for _, m in items]
    for _ in range(3):
        a = np.zeros((3 + 3 * s, 3 + 3 * s))
        b = np.zeros(3 + 3 * s)
        for i, ((r, m), k) in enumerate(zip(items, keep, strict=True)):
            y = np.einsum("nij,nj->ni", r[k], m[k])
            hi = slice(3 + 3 * i, 6 + 3 * i)
            a[:3, :3] += k.sum() * np.eye(3)
            a[:3, hi] += r[k].sum(axis=0)
            a[hi, :3] = a[:3, hi].T
            a[hi, hi] = k.sum() * np.eye(3)
            b[:3] += y.sum(axis=0)
            b[hi] = m[k].sum(axis=0)
        theta = np.linalg.lstsq(a, b, rcond=1e-8)[0]
        c = theta[:3]
        resid = [np.linalg.norm(np.einsum("nij,nj->ni", r, m - theta[3 + 3 * i : 6 + 3 * i]) - c,
                                axis=1) for i, (r, m) in enumerate(items)]  # fmt: skip
        limit = max(tol_ut, 3.0 * float(np.median(np.concatenate(resid))))
        keep = [e <= limit for e in resid]
    return c, float(np.mean(np.concatenate(keep)))


def lab_to_earth(
    sensors: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]], field_tol_ut: float = 4.0
) -> LabToEarth:
    """Lab → earth rotation ``Y`` (``quat``) from gravity and the magnetic field seen in the lab
    frame, with how it was found.

    ``sensors`` holds per sensor ``(BX (N, 4), acc (N, 3), mag (N, 3) or None)``: the sensor →
    lab orientation from the markers (NaN where unknown) and the IMU's specific force and field.
    The lab vertical is the direction of the summed specific force (snapped to a lab axis within
    ``SNAP_DEG``); north is the horizontal part of the earth field in the lab frame, fitted with
    each magnetometer's hard iron (:func:`_lab_field`). Liu 2010, eqs. (2)–(4), solved by TRIAD.
    """
    up_sum, fields = np.zeros(3), []
    for bx, acc, mag in sensors:
        ok = np.isfinite(bx).all(axis=1) & np.isfinite(acc).all(axis=1)
        up_sum += np.sum(rot.rotate(bx[ok], acc[ok]), axis=0)
        if mag is not None:
            ok &= np.isfinite(mag).all(axis=1)
            fields.append((rot.to_matrix(bx[ok]), mag[ok]))
    if not np.linalg.norm(up_sum) > 0:
        raise InputError("no sample where the markers and the IMU overlap", "markers")
    up, snapped = _snap(up_sum / np.linalg.norm(up_sum))
    if sum(len(m) for _, m in fields) < 10:  # 6-D: keep the lab x axis in the east-up plane
        x = np.eye(3)[0] if abs(up[0]) < 0.9 else np.eye(3)[1]
        y = triad(up, x, UP, np.array([1.0, 0.0, 0.0]))
        return LabToEarth(y, snapped, up, "lab axes (no magnetometer)")
    field_lab, used = _lab_field(fields, field_tol_ut)
    norm = float(np.linalg.norm(field_lab))
    dip = float(np.degrees(np.arcsin(-field_lab @ up / norm)))
    return LabToEarth(triad(up, field_lab, UP, NORTH), snapped, up, "magnetometer", used, norm, dip)


# ------------------------------------------------------------------------------ session


def _cluster_sensors(session: Any, mmap: Any, labels: list[str] | None) -> dict[str, Any]:
    """``{sensor label: SegmentMap}`` for the mapped marker clusters that carry a chosen sensor."""
    out = {}
    for seg, spec in mmap.segments.items():
        label = spec.sensor or sensor_for_segment(session, seg)
        if label not in session.sensors or not spec.cluster:
            continue
        s = session.sensors[label]
        if s.gyr is not None and s.acc is not None and (labels is None or label in labels):
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
) -> tuple[dict[str, MarkerReferences], dict[str, MarkerFusion]]:
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
    references, fused
        ``{label: MarkerReferences}`` on each sensor's own samples, and per sensor what its
        cluster gave (``{label: MarkerFusion}``: the clock, ``sensor_to_cluster``, the gyroscope
        bias, the registration residual, the marker noise, the visible fraction and the lab's
        rotation to the earth).
    """
    if not session.markers:
        raise InputError("the session holds no marker data", remedy="ingest a C3D/TRC file with it")
    name = marker_map.marker_set if marker_map is not None else None
    markers = choose_marker_set(list(session.markers.values()), name)
    mmap = marker_map or default_marker_map(markers, protocol, list(session.sensors))
    check_marker_map(mmap, markers)
    chosen = _cluster_sensors(session, mmap, labels)
    parts, pooled = {}, []
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
        reg = register_sensor(
            s.time, s.gyr, track.time, track.quat, offset, drift, sync, filled_spans(s)
        )
        sigma_m = marker_noise(track.residual, track.n_visible)
        pairs, cluster_dirs, lab_dirs, sigma = pair_vectors(track.shape, points, sigma_m)
        tau = reg.to_reference(s.time)
        bx = rot.mul(resample_quat(track.time, track.quat, tau), reg.sensor_to_cluster)
        pooled.append((bx, s.acc, s.mag))
        parts[label] = (spec.name, reg, sigma_m, len(pairs),
                        rot.rotate(rot.conj(reg.sensor_to_cluster), cluster_dirs),
                        interpolate_vectors(markers.time, lab_dirs, tau), sigma,
                        [(spec.cluster[i], spec.cluster[j]) for i, j in pairs])  # fmt: skip
    lab = lab_to_earth(pooled)
    refs, fused = {}, {}
    for label, (segment, reg, sigma_m, n_pairs, body, dirs, sigma, names) in parts.items():
        lab_dirs = rot.rotate(lab.quat, dirs)
        refs[label] = MarkerReferences(body, lab_dirs, sigma, reg.gyro_bias, names)
        fused[label] = MarkerFusion(
            segment, reg.offset_s, reg.drift * 1e6, reg.sensor_to_cluster, reg.gyro_bias,
            reg.residual_deg, sigma_m * 1e3, n_pairs, float(refs[label].visible.mean()), lab,
        )  # fmt: skip
    return refs, fused
