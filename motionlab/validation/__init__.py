"""Validation against optical motion capture: ``validate(session, reference, ...) -> Validation``.

Steps (each in its own module):

1. optical segment orientations from the marker map: cluster fits, rigid bodies, anatomical
   frames from landmarks fixed in the cluster frames (:mod:`.markermap`, :mod:`.optical`,
   :mod:`.cast`, :mod:`.anatomy`, :mod:`.reference`);
2. time alignment of the IMU and optical clocks (:mod:`.time_alignment`);
3. both streams on one clock: the IMU (session) clock, at the samples of the first sensor;
4. the two constant rotations between the systems (:mod:`.align`);
5. orientation errors per sensor (:mod:`.orientation_error`: BROAD total/heading/inclination
   RMSE and the geodesic median/IQR/95th percentile of Ricci 2015);
6. joint angles of the optical segments through the same code as the IMU's
   (:func:`motionlab.kinematics.joint_angles.joint_angles`) and their agreement per angle and
   per repetition (:mod:`.agreement`).

The result (:class:`~motionlab.results.Validation`) is returned; :func:`motionlab.stages.validate`
stores it in ``session.results.validation``, and :mod:`.figures` draws it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.kinematics.angle_filter import smoothed
from motionlab.kinematics.cycles import Cycles
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.kinematics.joint_types import angle_columns
from motionlab.kinematics.session_angles import session_angles
from motionlab.protocol import Protocol
from motionlab.results import (
    AngleAgreement,
    AngleAgreements,
    AngleTable,
    OrientationErrors,
    RepetitionAgreement,
    SegmentCalibration,
    SensorOrientationError,
    Validation,
)
from motionlab.segments.sensors import sensor_orientation
from motionlab.session import MarkerSet, Session, estimate_rate
from motionlab.validation.agreement import agreement, per_repetition, repetitions
from motionlab.validation.align import MIN_CONDITIONING, Alignment
from motionlab.validation.align import align as estimate_alignment
from motionlab.validation.markermap import MarkerMap, check_marker_map, default_marker_map
from motionlab.validation.optical import resample_quat
from motionlab.validation.orientation_error import error_angles, orientation_errors
from motionlab.validation.reference import OpticalSegment, choose_marker_set, optical_segments
from motionlab.validation.time_alignment import no_sync, synchronise
from motionlab.validation.time_offset import (
    SYNC_SOURCES,
    gyro_sampling,
    imu_signal,
    sync_notes,
)

__all__ = ["validate"]

MOVEMENT_RAD_S = 0.3  # angular speed above which a sample counts as movement
#: an agreement over fewer seconds compared than this is not stated
MIN_COMPARED_S = 2.0
MOVEMENT_PAD_S = 0.25


def _pairs(session: Session, mmap: MarkerMap) -> dict[str, str]:
    """``{sensor label: segment}`` for the mapped segments that carry a sensor."""
    out = {}
    for seg, spec in mmap.segments.items():
        label = spec.sensor or sensor_for_segment(session, seg)
        if label is not None and label in session.sensors:
            out[label] = seg
        elif spec.sensor:
            raise InputError(
                f"no sensor '{spec.sensor}' in the session",
                mmap.path,
                f"segments.{seg}.sensor",
                f"sensors are {', '.join(session.sensors)}",
            )
    if not out:
        raise InputError(
            "no mapped segment carries a sensor of the session",
            mmap.path,
            remedy=f"name segments after sensors ({', '.join(session.sensors)}) or set sensor:",
        )
    return out


def movement_mask(session: Session, labels: list[str], t: np.ndarray) -> np.ndarray:
    """Samples of ``t`` (IMU clock) in movement: the sensors' own ``movement`` channel when all
    have one (BROAD), else any sensor turning faster than 0.3 rad/s, padded by 0.25 s."""
    sensors = [session.sensors[k] for k in labels]
    if all("movement" in s.extra for s in sensors):
        out = np.zeros(len(t), bool)
        for s in sensors:
            k = np.clip(np.searchsorted(s.time, t), 0, len(s.time) - 1)
            out |= np.asarray(s.extra["movement"], bool)[k]
        return out
    moving = np.zeros(len(t), bool)
    for s in sensors:
        speed = np.linalg.norm(s.gyr, axis=1) if s.gyr is not None else np.zeros(len(s.time))
        fast = s.time[speed > MOVEMENT_RAD_S]
        if len(fast):
            k = np.clip(np.searchsorted(fast, t), 1, len(fast) - 1)
            near = np.minimum(np.abs(fast[k] - t), np.abs(fast[k - 1] - t))
            moving |= near <= MOVEMENT_PAD_S
    return moving


def _angular_velocity(session: Session, label: str, q: np.ndarray, source: str) -> tuple:
    """``(time, ω)`` of a sensor for the sync: its gyroscope at the times its samples describe
    (interval centres unless the stream is point-sampled), or (``source="orientation"``, or
    without a gyroscope) differences of its orientation (:mod:`.time_alignment`)."""
    s = session.sensors[label]
    return imu_signal(s.time, s.gyr, q, source, gyro_sampling(s.attrs))


def _common_time(session: Session, labels: list[str]) -> np.ndarray:
    t = np.asarray(session.sensors[labels[0]].time, dtype=float)
    t0 = max(session.sensors[k].time[0] for k in labels)
    t1 = min(session.sensors[k].time[-1] for k in labels)
    return t[(t >= t0) & (t <= t1)]


def _orientation(
    q_est: np.ndarray, q_ref: np.ndarray, mask: np.ndarray | None
) -> SensorOrientationError:
    """Per-sample total, heading and inclination errors (deg) and their statistics over
    ``mask`` (none when no sample has both orientations)."""
    per_sample = {f"{k}_deg": v for k, v in error_angles(q_est, q_ref).items()}
    try:
        stats = orientation_errors(q_est, q_ref, mask)
    except InputError:
        stats = {}
    return SensorOrientationError(**per_sample, **stats)


def _optical_segment_quats(
    optical: dict[str, OpticalSegment],
    al: Alignment,
    seg_of: dict[str, str],
    calibration: SegmentCalibration | None,
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, str]]:
    """Segment → lab orientation per segment: anatomical (landmarks) or, without landmarks,
    the cluster carried to the IMU segment frame (``B X q_mount``)."""
    label_of = {seg: label for label, seg in seg_of.items()}
    out, source = {}, {}
    for seg, o in optical.items():
        q = o.segment_quat()
        if q is not None:
            out[seg] = (o.time, q)
            source[seg] = "segment_frame" if o.info.segment_frame else "landmarks"
            continue
        cal = calibration.segments.get(seg) if calibration is not None else None
        if seg in label_of and cal is not None:
            x = al.sensor_to_cluster[label_of[seg]]
            out[seg] = (o.time, rot.mul(o.quat, rot.mul(x, np.asarray(cal.mounting))))
            source[seg] = "imu_calibration"
    return out, source


def _joint_angles(qp: np.ndarray, qd: np.ndarray, joint) -> dict[str, np.ndarray]:
    """:func:`joint_angles` on the rows where both orientations exist, NaN elsewhere."""
    ok = np.isfinite(qp).all(axis=1) & np.isfinite(qd).all(axis=1)
    names = [col for _, col in angle_columns(joint)]
    out = {col: np.full(len(ok), np.nan) for col in names}
    if ok.any():
        for col, values in joint_angles(qp[ok], qd[ok], joint).items():
            out[col][ok] = values
    return out


def same_branch(estimate: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(estimate, reference)`` (deg) on one branch: the reference made continuous over its
    finite samples (no jump of a whole turn between them), the estimate moved by whole turns
    to within ±180° of it at each sample; NaN stays NaN."""
    est = np.array(estimate, dtype=float)
    ref = np.array(reference, dtype=float)
    ok = np.isfinite(ref)
    if ok.any():
        ref[ok] = np.degrees(np.unwrap(np.radians(ref[ok])))
    both = ok & np.isfinite(est)
    est[both] = ref[both] + (est[both] - ref[both] + 180.0) % 360.0 - 180.0
    return est, ref


def angle_agreement(
    imu_deg: np.ndarray,
    ref_deg: np.ndarray,
    mask: np.ndarray | None,
    reps: Cycles | None = None,
    time: np.ndarray | None = None,
) -> AngleAgreement:
    """The agreement of an IMU angle curve with the reference's (deg, on one time base), per
    repetition too when ``reps`` (:func:`repetitions`) holds two or more (``time``: its s).

    Both are compared on one branch (:func:`same_branch`): an angle that wraps at ±180° in
    one system and not in the other is no 360° error (a real rig's ball joint read a largest
    error of 352° and twice its RMSE from two such samples)."""
    imu_deg, ref_deg = same_branch(imu_deg, ref_deg)
    per_rep = None
    if reps is not None and len(reps) >= 2:
        per_rep = RepetitionAgreement(**per_repetition(imu_deg, ref_deg, reps, time))
    stats = agreement(imu_deg, ref_deg, mask)
    return AngleAgreement(**stats, imu_deg=imu_deg, ref_deg=ref_deg, repetitions=per_rep)


def _angles(
    session: Session,
    protocol: Protocol,
    seg_quats: dict[str, tuple[np.ndarray, np.ndarray]],
    to_reference,
    movement: tuple[np.ndarray, np.ndarray] | None,
) -> tuple[AngleAgreements, list[str]]:
    """IMU and optical joint angles on the IMU angle time base and their agreement."""
    notes = []
    table = session.results.angles
    if table is None:
        columns = session_angles(session, protocol, session.results.calibration)
        table = AngleTable.from_columns(columns)
    t = np.asarray(table.time, dtype=float)
    rate = estimate_rate(t)
    mask = None
    if movement is not None:
        k = np.clip(np.searchsorted(movement[0], t), 0, len(movement[0]) - 1)
        mask = movement[1][k]
    out = AngleAgreements(time_s=t)
    for joint in protocol.joints.values():
        if joint.proximal not in seg_quats or joint.distal not in seg_quats:
            notes.append(f"joint {joint.name}: no optical frame for both segments")
            continue
        t_ref = to_reference(t)
        qp = resample_quat(*seg_quats[joint.proximal], t_ref)
        qd = resample_quat(*seg_quats[joint.distal], t_ref)
        # low-passed as the IMU angles are, so that neither side is judged on what the
        # other's filter took out
        ref = {
            c: smoothed(v, rate, table.lowpass_hz) for c, v in _joint_angles(qp, qd, joint).items()
        }
        primary = angle_columns(joint)[0][1]
        reps = repetitions(ref[primary], rate)
        for col, ref_deg in ref.items():
            if col not in table.data:
                notes.append(f"{col}: not in the IMU angle table")
                continue
            imu_deg = np.asarray(table.data[col], dtype=float)
            out.columns[col] = angle_agreement(imu_deg, ref_deg, mask, reps, t)
    return out, notes


def withhold(val: Validation, protocol: Protocol | None) -> Validation:
    """``val`` with the agreements it cannot state withheld: their statistics NaN (orientation
    errors ``None``) and ``withheld`` saying why; the curves stay. Why, first that applies:

    - the clock sync is graded ``poor``: the curves may be compared at the wrong times (real
      trunk trials once locked onto ±10-14 s with 1.7 s shared, RMSE 28-131° printed);
    - a sensor's alignment with its marker cluster was not determined: it turned about one
      axis only, or hardly at all (a still pelvis under a moving trunk; conditioning below
      :data:`~motionlab.validation.align.MIN_CONDITIONING`), so its sensor-to-cluster rotation
      about that axis is what the fit made up (a wheelchair's sensor read 1.1° "total" error
      and every lean angle against it 34-127°); its orientation errors and the angles of its
      segment's joints;
    - an angle compared over less than :data:`MIN_COMPARED_S`.
    """
    common = "the clock sync is poor" if val.sync.grade == "poor" else None
    loose = {
        label: f"{label} turned about one axis only (or hardly at all), so its alignment with "
        "its marker cluster is not determined"
        for label, c in (val.alignment.conditioning if val.alignment else {}).items()
        if val.mode in ("full", "heading") and c < MIN_CONDITIONING
    }  # fmt: skip
    orientation = val.orientation
    for label, e in list(orientation.sensors.items()):
        why = common or loose.get(label)
        if why and e.withheld is None:
            orientation.sensors[label] = dataclasses.replace(
                e, total_rmse_deg=None, heading_rmse_deg=None, inclination_rmse_deg=None,
                median_deg=None, iqr_deg=None, p95_deg=None, withheld=why,
            )  # fmt: skip
    if val.angles is None or not val.angles.columns:
        return val
    rate = estimate_rate(np.asarray(val.angles.time_s, float))
    segment_reason = {seg: loose[label] for label, seg in val.pairs.items() if label in loose}
    joint_reason: dict[str, str] = {}
    for joint in protocol.joints.values() if protocol is not None else []:
        why = segment_reason.get(joint.proximal) or segment_reason.get(joint.distal)
        if why:
            joint_reason.update({col: why for _, col in angle_columns(joint)})
    for col, a in list(val.angles.columns.items()):
        why = common or joint_reason.get(col)
        if why is None and a.n_samples < MIN_COMPARED_S * rate:
            why = f"compared over {a.n_samples / rate:.1f} s only"
        if why and a.withheld is None:
            nan = float("nan")
            val.angles.columns[col] = dataclasses.replace(
                a, rmse_deg=nan, bias_deg=nan, sd_deg=nan, max_abs_deg=nan,
                rmse_centred_deg=nan, r=nan, cmc=nan, loa_deg=[nan, nan], repetitions=None,
                withheld=why,
            )  # fmt: skip
    return val


def validate(
    session: Session,
    reference: MarkerSet | None = None,
    marker_map: MarkerMap | None = None,
    protocol: Protocol | None = None,
    mode: str = "full",
    *,
    sync: bool = True,
    movement_only: bool = False,
    seed: int = 0,
    static: MarkerSet | None = None,
    sync_on: str = "gyroscope",
) -> Validation:
    """Compare the session's IMU orientations and joint angles with an optical reference.

    Parameters
    ----------
    session
        The IMU session: its fusion results (``motionlab fuse``) or, for sensors without raw
        acc and gyr, the vendor's orientations; a sensor with raw signals and no fusion
        result is refused (:func:`motionlab.segments.sensors.sensor_orientation`).
    reference
        The optical marker set (default: the session's own, named by the map or the only one).
    marker_map
        Which markers form which segment (default: :func:`default_marker_map`).
    protocol
        Needed for joint angles and landmarks (default: orientations only).
    mode
        Spatial alignment: ``full``, ``heading`` or ``none`` (:mod:`.align`).
    sync
        Estimate the clock model (``False``: the streams already share a clock).
    movement_only
        Restrict the statistics to movement phases (:func:`movement_mask`).
    static
        A static trial with the cluster markers and the landmarks, in which the landmarks are
        fixed in the cluster frames (default: a static window of ``reference``; :mod:`.cast`).
    sync_on
        The IMU side of the sync: ``gyroscope`` (interval averages, :mod:`.time_alignment`) or
        ``orientation`` (differences of the orientations being validated).

    Returns
    -------
    Validation
        (:func:`motionlab.stages.validate` stores it): ``sync``, ``alignment``, ``optical``,
        ``orientation`` (per sensor) and ``angles`` (per angle column).
    """
    if reference is None:
        name = marker_map.marker_set if marker_map else None
        reference = choose_marker_set(list(session.markers.values()), name)
    mmap = marker_map or default_marker_map(reference, protocol, list(session.sensors))
    check_marker_map(mmap, reference)
    optical = optical_segments(reference, mmap, protocol, static)
    seg_of = _pairs(session, mmap)
    labels = list(seg_of)
    imu_q = {k: sensor_orientation(session, k) for k in labels}

    if sync_on not in SYNC_SOURCES:
        raise InputError(
            f"unknown sync signal '{sync_on}'", remedy=f"use {', '.join(SYNC_SOURCES)}"
        )
    if sync:
        clock = synchronise(
            [_angular_velocity(session, k, imu_q[k], sync_on) for k in labels],
            [(optical[seg_of[k]].time, optical[seg_of[k]].quat) for k in labels],
            seed=seed,
        )
    else:
        clock = no_sync()
    t = _common_time(session, labels)
    t_ref = clock.model.to_reference(t)
    pairs = {
        k: (
            resample_quat(session.sensors[k].time, imu_q[k], t),
            resample_quat(optical[seg_of[k]].time, optical[seg_of[k]].quat, t_ref),
        )
        for k in labels
    }
    al = estimate_alignment(pairs, mode, rate=estimate_rate(t))
    moving = movement_mask(session, labels, t) if movement_only else None
    orientation = OrientationErrors(time_s=t)
    for k, (a, b) in pairs.items():
        orientation.sensors[k] = _orientation(a, al.reference(k, b), moving)

    sync_record = clock.record(sync_on if sync else "", labels)
    residual = clock.pair_residuals()
    notes = [f"segment {seg}: no sensor" for seg in mmap.segments if seg not in seg_of.values()]
    notes += sync_notes(sync_record) if sync else []
    spread = np.ptp(residual[np.isfinite(residual)]) if np.isfinite(residual).any() else 0.0
    if spread * estimate_rate(t) > 1.0:
        synced = session.results.clock_sync is not None
        notes.append(
            f"the sensors' clocks disagree with the cameras' by up to {spread * 1e3:.0f} ms "
            "between sensors: they are not on one clock; "
            + ("the sensor sync left them so far apart, and their angles may carry it"
               if synced else "synchronise them first (motionlab sync, which run does by "
               "default)")
        )  # fmt: skip
    frames: dict[str, str] = {}
    angles = None
    if protocol is not None and protocol.joints:
        seg_quats, frames = _optical_segment_quats(optical, al, seg_of, session.results.calibration)
        movement = (t, moving) if moving is not None else None
        angles, angle_notes = _angles(
            session, protocol, seg_quats, clock.model.to_reference, movement
        )
        notes += angle_notes
    result = Validation(
        mode=mode,
        marker_set=reference.name,
        movement_only=movement_only,
        pairs={k: seg_of[k] for k in labels},
        sync=sync_record,
        alignment=al.record(),
        optical={
            seg: dataclasses.replace(
                o.info, source=o.source, landmarks=o.landmarks, frame=frames.get(seg)
            )
            for seg, o in optical.items()
        },
        orientation=orientation,
        angles=angles,
        notes=notes,
    )
    return withhold(result, protocol)
