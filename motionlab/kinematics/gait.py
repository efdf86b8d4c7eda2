"""Gait analysis of a calibrated session: events, strides, spatio-temporal parameters, pelvis
angles, cycle curves and the GPS/MAP (:class:`~motionlab.results.Gait`, ``session.results.gait``).

Steps: the gait tasks' time ranges (``results.metrics.blocks`` of tasks whose kind is gait
or walk) → events and strides per side (:func:`.session_strides.session_strides`, the strides
the joint metrics take too: each knee's shank sagittal angular velocity, turns from the
vertical angular velocity of the pelvis sensor, else of the side's shank sensor) →
spatio-temporal parameters (:mod:`.spatiotemporal`) → pelvis angles relative to the walking
direction (:mod:`.pelvis`, with a pelvis sensor) → per side the mean curve over kept strides of
pelvis, hip and knee angles (low-passed as the metrics take them:
:func:`.angle_filter.as_metrics_take`) → GPS and MAP (:mod:`.gps`), only from determined
variables and sides with enough strides (:func:`.gps.gated_profile`).

A session without a gait task, without shank sensors or without strides gives
``Gait(status="no gait: <why>")`` and nothing else.
"""

from __future__ import annotations

import numpy as np

from motionlab.binding import sensor_for_segment
from motionlab.kinematics import spatiotemporal as sp
from motionlab.kinematics.angle_filter import as_metrics_take, metrics_cutoff, smoothed
from motionlab.kinematics.cycles import CURVE_POINTS
from motionlab.kinematics.gps import (
    JOINT_VARIABLES,
    PELVIS,
    gated_profile,
    movement_analysis_profile,
    variable_grades,
)
from motionlab.kinematics.pelvis import (
    PELVIS_COLUMNS,
    pelvis_angles,
    side_angles,
    walking_heading,
)
from motionlab.kinematics.session_angles import session_segments
from motionlab.kinematics.session_strides import PELVIS_SEGMENT, session_strides
from motionlab.protocol import Protocol
from motionlab.results import (
    Gait,
    GaitEvents,
    GaitPelvis,
    SegmentCalibration,
    StrideTable,
    TaskBlock,
)
from motionlab.session import Session, estimate_rate


def _leg_reach(
    session: Session, protocol: Protocol, cal: SegmentCalibration
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], str]:
    """``({side: (time s, leg reach m)}, how)`` from each knee's thigh and shank
    (:func:`.spatiotemporal.leg_reach`); empty with the reason when lengths or sensors lack."""
    lengths = sp.segment_lengths(session.metadata.get("subject"))
    if lengths is None:
        return {}, "not measured: no subject height_m (or thigh_m and shank_m) in the sensor map"
    knees = [j for j in protocol.joints.values() if j.type == "knee"]
    segs = [s for j in knees for s in (j.proximal, j.distal)]
    if any(sensor_for_segment(session, s) is None for s in segs):
        return {}, "not measured: a thigh or shank sensor is missing"
    poses = session_segments(session, protocol, cal, segments=segs)
    out = {}
    for j in knees:
        (t, q_t), (t_s, q_s) = poses[j.proximal], poses[j.distal]
        thigh = np.interp(t_s, t, np.sin(sp.sagittal_inclination(q_t)))
        out[j.side] = (t_s, lengths[0] * thigh + lengths[1] * np.sin(sp.sagittal_inclination(q_s)))
    if set(out) != {"r", "l"}:
        return {}, "not measured: needs both legs"
    return out, f"{sp.LENGTH_MODEL}; lengths: {lengths[2]}"


def legs_not_linked(session: Session, protocol: Protocol) -> str:
    """Why the two legs' knee sensors are not on one clock (``not given: ...``), or empty: the
    clock sync ran and could not link them (:meth:`~motionlab.results.ClockSync.not_linked`:
    no pelvis sensor joins them and the heel strikes did not time one leg against the other),
    or could not time one of them (:meth:`~motionlab.results.ClockSync.untimed`: kept as
    recorded, its offset from the other leg unknown). Empty without a clock sync (the recorded
    clocks are taken as one) and for one leg."""
    sync = session.results.clock_sync
    knees = [j for j in protocol.joints.values() if j.type == "knee"]
    if sync is None or len({j.side for j in knees if sensor_for_segment(session, j.distal)}) < 2:
        return ""
    labels = [sensor_for_segment(session, s) for j in knees for s in (j.proximal, j.distal)]
    labels = [lab for lab in labels if lab is not None]
    if why := sync.not_linked(labels):
        why = f"are not linked ({why}"
    elif fit := sync.untimed(labels):
        why = (f"were not all timed ({fit.sensor}'s kept as recorded, "
               f"{fit.status.removeprefix('not reliable: ')}: one leg's offset from the other "
               "unknown")  # fmt: skip
    else:
        return ""
    return (
        f"not given: the two legs' sensor clocks {why}; sensors on one radio clock their files "
        "do not show, e.g. a legacy Xsens Awinda export, need no clock sync: --no-clock-sync)"
    )


def gait_spans(session: Session, protocol: Protocol) -> dict[str, tuple[float, float]]:
    """``{task: (start_s, end_s)}`` of the protocol's gait tasks found in the session."""
    metrics = session.results.metrics
    blocks = metrics.blocks if metrics is not None else {}
    out = {}
    for task in protocol.tasks:
        b = blocks.get(task.name)
        if task.is_gait and b is not None:
            out[task.name] = (float(b.start_s), float(b.end_s))
    return out


def _curve(time: np.ndarray, values: np.ndarray, t0: float, t1: float) -> np.ndarray:
    pct = np.linspace(t0, t1, CURVE_POINTS)
    return np.interp(pct, time, values, left=np.nan, right=np.nan)


def analyse_gait(session: Session, protocol: Protocol) -> Gait:
    """``session.results.gait`` (module docstring); the session must be calibrated and have
    angles and metrics."""
    spans = gait_spans(session, protocol)
    if not spans:
        return Gait("no gait: the protocol has no gait task, or none was found")
    cal = session.results.calibration or SegmentCalibration("")
    legs = session_strides(session, protocol, cal, spans)
    if not legs:
        shanks = [sensor_for_segment(session, j.distal) for j in protocol.joints.values()
                  if j.type == "knee"]  # fmt: skip
        if any(label is not None for label in shanks):  # orientations only (an .sto)
            return Gait("no gait: the shank sensors carry no gyroscope (orientations only)")
        return Gait("no gait: no shank sensor under a knee joint")
    pelvis_label = sensor_for_segment(session, PELVIS_SEGMENT)
    strides = {leg.side: leg.strides for leg in legs.values()}
    events = {
        leg.side: GaitEvents(leg.events.ic, leg.events.ic_confidence, leg.events.fc,
                             leg.events.fc_confidence)
        for leg in legs.values()
    }  # fmt: skip
    not_linked = legs_not_linked(session, protocol)
    if not_linked:  # a leg's reach at the other's events: at an unknown offset
        reach, speed_note = {}, "not measured: " + not_linked.removeprefix("not given: ")
    else:
        reach, speed_note = _leg_reach(session, protocol, cal)
    table = sp.stride_table(strides, events, reach)
    if not_linked:
        table = sp.withhold_both_legs(table)
    if not table["kept"].any():
        return Gait("no gait: no stride passed the checks", events=events)
    columns = {c: table[c].to_numpy() for c in table.columns if c not in ("side", "reason")}
    out = Gait(
        "ok",
        tasks={k: TaskBlock(a, b) for k, (a, b) in spans.items()},
        events=events,
        strides=StrideTable(
            **columns, side=table["side"].to_numpy(str), reason=table["reason"].to_numpy(str)
        ),
        summary=sp.summary(table, not_linked),
        walking_speed=speed_note,
    )
    angles = session.results.angles
    # the curves from the angles low-passed as the metrics take theirs: the table's columns
    # at their own cut-off, the pelvis's (computed here) at the same
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if angles is not None:
        for col in angles.data:
            if angles.units[col] == "deg":
                series[col] = (np.asarray(angles.time), as_metrics_take(angles, col))
    if pelvis_label is not None:
        t_p, q_p = session_segments(session, protocol, cal, segments=[PELVIS_SEGMENT])[
            PELVIS_SEGMENT
        ]
        rate = 1.0 / float(np.median(np.diff(t_p)))
        stride_s = float(table.loc[table["kept"], "stride_time_s"].median())
        heading = walking_heading(q_p, rate, stride_s)
        pel = np.degrees(pelvis_angles(q_p, heading))
        out.pelvis = GaitPelvis(
            t_p,
            *(pel[:, i] for i in range(len(PELVIS_COLUMNS))),
            method=(
                "pelvis frame from the calibration (gravity in the stand; forward from the "
                "placement hint, or from the walk's first or last steps or its turns where the "
                "hint is contradicted); walking direction = pelvis heading averaged over one stride"
            ),
        )
    curves: dict[str, dict[str, np.ndarray]] = {}
    pelvis_deg = None  # low-passed once for both sides (a side only flips signs)
    if out.pelvis is not None:
        t_p = np.asarray(out.pelvis.time_s, float)
        cutoff = metrics_cutoff(angles.lowpass_hz if angles is not None else 0.0)
        pelvis_deg = np.column_stack([smoothed(c, estimate_rate(t_p), cutoff, t_p)
                                      for c in out.pelvis.angles_deg().T])  # fmt: skip
    for side, st in strides.items():
        keep = st.kept
        var_series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for v in JOINT_VARIABLES:
            joint, angle = v.split("_")
            col = f"{joint}_{side}_{angle}_deg"
            if col in series:
                var_series[v] = series[col]
        if pelvis_deg is not None:
            pel = side_angles(pelvis_deg, side)
            for i, v in enumerate(PELVIS):
                var_series[v] = (t_p, pel[:, i])
        curves[side] = {}
        for v, (t, x) in var_series.items():
            # contiguous once: np.interp would copy a column (the pelvis's) for every stride
            t, x = np.ascontiguousarray(t, float), np.ascontiguousarray(x, float)
            cyc = np.array([_curve(t, x, a, b) for a, b in zip(st.ic[keep], st.next_ic[keep],
                                                              strict=True)])  # fmt: skip
            if len(cyc):
                curves[side][v] = np.nanmean(cyc, axis=0)
                curves[side][f"{v}_sd"] = (
                    np.nanstd(cyc, axis=0, ddof=1) if len(cyc) > 1 else (np.zeros(CURVE_POINTS))
                )
    out.curves = curves
    means = {s: {k: v for k, v in c.items() if not k.endswith("_sd")} for s, c in curves.items()}
    kept_n = {side: int(np.sum(st.kept)) for side, st in strides.items()}
    out.map = gated_profile(
        movement_analysis_profile(means), variable_grades(protocol, cal), kept_n
    )
    return out
