"""Exports of a session for other tools: OpenSim ``.sto``/``.mot``, C3D and JSON.

- ``sto``: the sensor orientations (sensor → earth; the fusion results, else the vendor's
  quaternions) as OpenSense reads them (:func:`motionlab.io.opensim.write_sto`): one column per
  IMU named after its OpenSim body (``tibia_r_imu``, ``humerus_l_imu``) where the segment kind
  has one (:data:`motionlab.kinematics.segment_types.SEGMENT_TYPES`), else the sensor label.
  Like the files OpenSense's own readers write, the orientations stay in the IMU system's Z-up
  earth frame (ENU here); OpenSense turns them into its Y-up ground with
  ``sensor_to_opensim_rotations = -1.5708 0 0`` (its default). All sensors are SLERP-resampled onto
  the first one's time stamps, within the span they share.
- ``mot``: the joint angles as an OpenSim motion file (``inDegrees=yes``, degrees): angles
  that are coordinates of OpenSim's Rajagopal (2015) full-body model, the model OpenSense's
  tutorials use, get its coordinate names and signs (:data:`OPENSIM_COORDINATES`:
  ``knee_angle_r``, ``hip_flexion_r``, ``lumbar_extension`` = −lumbar flexion, …); the others
  keep motionlab's names without ``_deg`` (``knee_r_adduction``: Rajagopal's knee has one
  degree of freedom). The zeros are motionlab's (the calibration pose), not the model's.
- ``c3d``: the joint angles as ``POINT:ANGLES`` model outputs (one point per joint, its three
  angles as X, Y, Z in deg, ``ANGLE_UNITS`` deg) and the markers, if any (mm), all on the angles'
  time stamps (markers interpolated through the validation's clock fit when there is one).
- ``json``: :func:`results_json` — metadata, sensors, angle columns with their grades, the
  metric table, calibration and validation summaries; units in every name; NaN as ``null``;
  indented, each list of numbers on one line (:func:`json_text`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from motionlab import __version__
from motionlab import rotations as rot
from motionlab.atomic import atomic_path
from motionlab.binding import unsensed_joints
from motionlab.errors import InputError
from motionlab.io.c3d import MODEL_KINDS, unique_labels
from motionlab.io.opensim import write_mot, write_sto
from motionlab.kinematics.joint_types import angle_columns, opensim_coordinates
from motionlab.kinematics.metrics import metrics_table, not_measured_note
from motionlab.kinematics.segment_types import opensim_imu_name
from motionlab.plain import plain
from motionlab.protocol import Protocol, load_protocol
from motionlab.results import OpticalSync, SegmentCalibration
from motionlab.segments.grades import (
    NOT_DETERMINED,
    graded_table,
    method_column_grade,
    trunk_grade,
)
from motionlab.session import MarkerSet, ModelOutput, Session

FORMATS = ("sto", "mot", "c3d", "json")
JSON_FORMAT = "motionlab-results"
JSON_VERSION = 1

#: motionlab angle column → (OpenSim coordinate of the Rajagopal 2015 model, sign), from the
#: joint table (:attr:`motionlab.kinematics.joint_types.JointType.opensim`, which says why the
#: signs are what they are)
OPENSIM_COORDINATES: dict[str, tuple[str, float]] = opensim_coordinates()


def opensim_columns(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Angle columns (deg) renamed to OpenSim coordinates with their signs
    (:data:`OPENSIM_COORDINATES`); unmapped columns keep their names."""
    out = {}
    for col, values in columns.items():
        name, sign = OPENSIM_COORDINATES.get(col, (col, 1.0))
        out[name] = sign * np.asarray(values, dtype=float) if sign != 1.0 else values
    return out


# ------------------------------------------------------------------------------ orientations


def imu_name(label: str, segment: str, side: str) -> str:
    """OpenSense column name: ``<body>_imu`` (``tibia_r_imu``) when the segment maps to an
    OpenSim body (:func:`motionlab.kinematics.segment_types.opensim_imu_name`), else the sensor
    label."""
    return opensim_imu_name(segment, side) or label


def orientations(session: Session) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (s) and each sensor's orientation (sensor → earth, (N, 4)) on a common time base.

    Per sensor: the fusion result if any, else the vendor quaternions. The time base is the first
    such sensor's time stamps within the span all share; the others are SLERP-resampled onto it
    (samples in a gap longer than 1.5 sample intervals become NaN).
    """
    fusion = session.results.fusion
    streams: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for label, s in session.sensors.items():
        q = fusion[label].quat if label in fusion else s.quat
        if q is None:
            continue
        name = imu_name(label, s.segment, s.side)
        if name in streams:
            name = label
        streams[name] = (np.asarray(s.time, dtype=float), np.asarray(q, dtype=float))
    if not streams:
        raise InputError(
            "no sensor orientations to export",
            remedy="run 'motionlab fuse' first, or ingest files with vendor quaternions",
        )
    start = max(t[0] for t, _ in streams.values())
    end = min(t[-1] for t, _ in streams.values())
    t0 = next(iter(streams.values()))[0]
    time = t0[(t0 >= start - 1e-9) & (t0 <= end + 1e-9)]
    if len(time) < 1:
        raise InputError("the sensors' recordings do not overlap in time", remedy="sync them")
    return time, {name: _on(time, t, q) for name, (t, q) in streams.items()}


def _on(time: np.ndarray, t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``q`` (on ``t``) at ``time``: unchanged when the stamps are the same, else SLERP."""
    if len(t) == len(time) and np.array_equal(t, time):
        return q
    ok = np.isfinite(q).all(axis=1)
    if ok.sum() < 2:
        return np.full((len(time), 4), np.nan)
    out = rot.resample(t[ok], q[ok], time)
    dt = np.median(np.diff(t))
    k = np.clip(np.searchsorted(t[ok], time), 1, ok.sum() - 1)
    span = t[ok][k] - t[ok][k - 1]
    out[span > 1.5 * dt] = np.nan
    return out


# ------------------------------------------------------------------------------ angles


def angle_table(session: Session) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (s) and the joint angle columns (``knee_r_flexion_deg`` → (N,), deg)."""
    angles = session.results.angles
    if angles is None:
        raise InputError(
            "no joint angles to export", remedy="run 'motionlab angles' (or 'motionlab run') first"
        )
    columns = {k: np.asarray(v, dtype=float) for k, v in angles.data.items()
               if angles.units[k] == "deg"}  # fmt: skip
    return np.asarray(angles.time, dtype=float), columns


def joint_columns(session: Session) -> dict[str, list[str]]:
    """Joint → its three angle columns in decomposition order (from the protocol the session
    was calibrated with), else the columns grouped by the joint names of the grades."""
    _, columns = angle_table(session)
    cal = session.results.calibration or SegmentCalibration("")
    proto = _calibrated_protocol(session)
    if proto is not None:
        out = {name: [c for _, c in angle_columns(j)] for name, j in proto.joints.items()}
        if all(c in columns for cols in out.values() for c in cols):
            return out
    joints = sorted(cal.grades, key=len, reverse=True)
    out: dict[str, list[str]] = {}
    for col in columns:
        joint = next((j for j in joints if col.startswith(f"{j}_")), col.rsplit("_", 2)[0])
        out.setdefault(joint, []).append(col)
    return out


def not_measured(session: Session) -> dict[str, dict[str, Any]]:
    """``{joint: {"segments": [...], "reason": "not measured: no pelvis sensor"}}`` of the
    joints of the protocol the session was calibrated with that have no sensor on a segment
    (:func:`motionlab.binding.unsensed_joints`: the walk's hips without a pelvis sensor); empty
    when every joint was measured or the protocol cannot be found."""
    proto = _calibrated_protocol(session)
    if proto is None:
        return {}
    return {joint: {"segments": segs, "reason": not_measured_note(segs)}
            for joint, segs in unsensed_joints(proto, session).items()}  # fmt: skip


def _calibrated_protocol(session: Session) -> Protocol | None:
    """The protocol the session was calibrated with, or ``None`` (not calibrated, or its file
    is gone)."""
    cal = session.results.calibration
    if cal is None:
        return None
    try:
        return load_protocol(cal.protocol_source)
    except (InputError, OSError, TypeError, KeyError):
        return None


# ------------------------------------------------------------------------------ writers


def write_c3d(
    path: str | Path,
    time: np.ndarray,
    outputs: list[ModelOutput],
    markers: MarkerSet | None = None,
    marker_time: np.ndarray | None = None,
    descriptions: dict[str, str] | None = None,
    force: bool = False,
) -> None:
    """A C3D file at the rate of ``time``: the markers (mm; sampled at ``marker_time``, their
    clock's stamps for each frame, linearly) then the model outputs, each kind listed in
    ``POINT:<KIND>`` with ``POINT:<KIND>_UNITS`` (``ANGLE_UNITS``…); ``descriptions`` fill
    ``POINT:DESCRIPTIONS`` by label.

    C3D frames are evenly spaced: the samples go to the frame nearest their time on the grid
    from the first sample at the median rate (the header's first frame is that time's), and a
    gap in ``time`` stays a gap (residual −1), where writing the samples back to back put
    every later frame up to 0.7 s early. A point with every component NaN has residual −1; a
    NaN component of a point otherwise valid is written as 0 (the description says which)."""
    import ezc3d

    rate = 1.0 / float(np.median(np.diff(time))) if len(time) > 1 else 100.0
    frame = np.rint((np.asarray(time, float) - time[0]) * rate).astype(int)
    grid = time[0] + np.arange(frame[-1] + 1) / rate
    labels, blocks = [], []
    if markers is not None and markers.n_markers:
        t_m = grid if marker_time is None else np.interp(grid, time, marker_time)
        labels += list(markers.labels)
        blocks.append(_interp(markers.time, markers.positions, t_m) * 1000.0)
    labels += [o.name for o in outputs]
    for o in outputs:
        on_grid = np.full((len(grid), 1, 3), np.nan)
        on_grid[frame, 0] = np.asarray(o.data, dtype=float)
        blocks.append(on_grid)
    if not labels:
        raise InputError("nothing to write", path, remedy="the session has no angles or markers")
    labels = unique_labels(labels)[0]  # C3D tools look points up by label
    xyz = np.concatenate(blocks, axis=1)  # (N, P, 3)
    c3d = ezc3d.c3d()
    c3d["header"]["points"]["first_frame"] = max(0, round(float(time[0]) * rate))
    point = c3d["parameters"]["POINT"]
    point["RATE"]["value"] = [float(np.round(rate, 6))]
    point["LABELS"]["value"] = labels
    point["UNITS"]["value"] = ["mm"]
    for kind, (key, unit_key, _) in MODEL_KINDS.items():
        of_kind = [o for o in outputs if o.kind == kind]
        if of_kind:
            c3d.add_parameter("POINT", key, [o.name for o in of_kind])
            c3d.add_parameter("POINT", unit_key, [of_kind[0].unit])
    described = descriptions or {}
    c3d.add_parameter("POINT", "DESCRIPTIONS", [described.get(lab, "") for lab in labels])
    seen = np.isfinite(xyz).any(axis=2)
    pts = np.ones((4, xyz.shape[1], xyz.shape[0]))
    pts[:3] = np.transpose(np.where(np.isfinite(xyz), xyz, 0.0), (2, 1, 0))
    c3d["data"]["points"] = pts
    c3d["data"]["meta_points"] = {
        "residuals": np.where(seen, 0.0, -1.0).T[None],
        "camera_masks": np.zeros((7, xyz.shape[1], xyz.shape[0]), dtype=bool),
    }
    with atomic_path(path, force=force) as tmp:
        real = tmp.with_suffix(".c3d")  # ezc3d appends .c3d to other names
        try:
            c3d.write(str(real))
            real.replace(tmp)
        finally:
            real.unlink(missing_ok=True)


def _interp(t: np.ndarray, values: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Linear interpolation of (N, …) ``values`` along time; NaN next to a NaN or outside."""
    flat = values.reshape(len(t), -1)
    out = np.full((len(t_new), flat.shape[1]), np.nan)
    k = np.searchsorted(t, t_new, side="right") - 1
    inside = (k >= 0) & (k < len(t) - 1) | np.isclose(t_new, t[-1])
    k = np.clip(k, 0, len(t) - 2)
    w = ((t_new - t[k]) / (t[k + 1] - t[k]))[:, None]
    est = (1 - w) * flat[k] + w * flat[k + 1]
    est = np.where(np.isclose(w, 0.0), flat[k], est)
    out[inside] = est[inside]
    return out.reshape((len(t_new), *values.shape[1:]))


def _scalars(tree: Any) -> Any:
    """A results subtree without per-sample arrays (longer than 16 values)."""
    if isinstance(tree, dict):
        return {k: _scalars(v) for k, v in tree.items()
                if not (isinstance(v, np.ndarray) and v.size > 16)}  # fmt: skip
    return tree


def judged_columns(session: Session) -> dict[str, tuple[str, str]]:
    """``{angle column: (grade, reason)}`` where the calibration graded the joint's angles, as
    the angle method allows (:func:`~motionlab.segments.grades.method_column_grade`): what
    every export withholds a value by."""
    res = session.results
    grades = res.calibration.grades if res.calibration is not None else {}
    method = res.angles.method if res.angles is not None else "imu"
    return {
        c: method_column_grade(method, c, g, r)
        for joint, cols in joint_columns(session).items()
        if joint in grades and len(grades[joint].grades) == len(cols)
        for c, g, r in zip(cols, grades[joint].grades, grades[joint].reasons, strict=False)
    }


def _determined_only(session: Session, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``columns`` without those of an angle ``not determined`` (a .mot's coordinates: a
    coordinate left out is one the file does not give; OpenSim reads the others)."""
    judged = judged_columns(session)
    return {c: v for c, v in columns.items() if judged.get(c, ("",))[0] != NOT_DETERMINED}


#: decimals of the JSON's angle series (deg, as the CSVs' ``%.4f``) and of its times (s)
JSON_ANGLE_DECIMALS = 4
JSON_TIME_DECIMALS = 6


def results_json(session: Session) -> dict[str, Any]:
    """The machine-readable results (:data:`JSON_FORMAT`, version :data:`JSON_VERSION`).

    Keys: ``software``, ``metadata``, ``sensors`` (label, segment, side, rate_hz, QC flags),
    ``angles`` (``time_s`` to 1e-6 s, ``method``, ``lowpass_hz`` (the angles' low-pass, 0: as
    computed) and per joint its ``columns`` (name → values, deg, to 1e-4 deg as in the CSVs) and
    ``grades``
    and ``reasons`` when the calibration graded them), ``metrics`` (rows ``block, joint, angle,
    column, metric, percent, value, unit, grade``), ``not_measured`` (the protocol's joints
    with no sensor on a segment, :func:`not_measured`; absent when none), ``calibration`` (ok,
    warnings),
    ``validation`` (its scalars), ``fusion`` (estimator per sensor). Standard JSON: NaN is
    ``null``, and so is a measured value of an angle ``not determined`` (its column's series
    and its metric rows' values; the grade and reason say why; the session file keeps what was
    computed).
    """
    out: dict[str, Any] = {
        "format": JSON_FORMAT,
        "version": JSON_VERSION,
        "software": f"motionlab {__version__}",
        "metadata": session.metadata,
        "sensors": [
            {
                "label": s.label,
                "segment": s.segment,
                "side": s.side,
                "rate_hz": s.rate_hz,
                "n_samples": s.n_samples,
                "qc_flags": sorted(k for k, v in s.qc.get("flags", {}).items() if v),
            }
            for s in session.sensors.values()
        ],
    }
    res = session.results
    judged = judged_columns(session)
    graded = {c: g for c, (g, _) in judged.items()}
    if res.angles is not None:
        time, columns = angle_table(session)
        # to the CSVs' 1e-4 deg (and 1e-6 s): the 100-Hz series of a 1-h walk made a 98-MB
        # file of 17-digit floats
        time = np.round(time, JSON_TIME_DECIMALS)
        columns = {c: np.round(v, JSON_ANGLE_DECIMALS) for c, v in columns.items()}
        joints = {}
        for joint, cols in joint_columns(session).items():
            entry: dict[str, Any] = {
                "columns": {
                    c: None if graded.get(c) == NOT_DETERMINED else columns[c]
                    for c in cols
                    if c in columns
                }
            }
            if all(c in judged for c in cols):
                entry["grades"] = {c: judged[c][0] for c in cols}
                entry["reasons"] = {c: judged[c][1] for c in cols}
            joints[joint] = entry
        out["angles"] = {"time_s": time, "method": res.angles.method,
                         "lowpass_hz": res.angles.lowpass_hz, "joints": joints}  # fmt: skip
    if res.metrics is not None:
        table = metrics_table(res.metrics, joint_columns(session))
        table = graded_table(table, graded, trunk_grade(res.calibration))
        out["metrics"] = table.astype(object).where(table.notna(), None).to_dict("records")
    missing = not_measured(session)
    if missing:
        out["not_measured"] = missing
    if res.calibration is not None:
        cal = res.calibration
        out["calibration"] = {"ok": cal.ok, "protocol": cal.protocol, "warnings": cal.warnings}
    if res.fusion:
        out["fusion"] = {
            k: {"estimator": v.name, "magnetometer": v.magnetometer} for k, v in res.fusion.items()
        }
    if res.validation is not None:
        out["validation"] = _scalars(res.validation.to_tree())
    return plain(out)


def _numbers(values: list) -> bool:
    """Whether ``values`` are numbers and ``null`` only (no bool, which is an int)."""
    return all(
        v is None or (isinstance(v, int | float) and not isinstance(v, bool)) for v in values
    )


def json_text(tree: Any, level: int = 0) -> str:
    """``tree`` (plain values: :func:`~motionlab.plain.plain`) as ``json.dumps(tree, indent=1,
    allow_nan=False)`` writes it, but a list of numbers (and ``null``) on one line: the angle
    series of a 10-minute walk were 45 % indentation and line breaks (docs/performance.md,
    "Long recordings"). The same values when read."""
    pad, end = " " * (level + 1), "\n" + " " * level
    if isinstance(tree, dict) and tree:
        items = (f"{pad}{json.dumps(k)}: {json_text(v, level + 1)}" for k, v in tree.items())
        return "{\n" + ",\n".join(items) + end + "}"
    if isinstance(tree, list) and tree and not _numbers(tree):
        return "[\n" + ",\n".join(pad + json_text(v, level + 1) for v in tree) + end + "]"
    return json.dumps(tree, allow_nan=False, separators=(",", ": "))


def write_json(session: Session, path: str | Path, force: bool = False) -> None:
    """:func:`results_json` written to ``path`` (atomic, indented, lists of numbers on one line:
    :func:`json_text`; UTF-8)."""
    text = json_text(results_json(session))
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")


def export_session(session: Session, fmt: str, path: str | Path, force: bool = False) -> str:
    """Write ``session`` as ``fmt`` (:data:`FORMATS`) to ``path``; a one-line summary."""
    if fmt == "sto":
        time, quats = orientations(session)
        # a row where a sensor was in a gap is left out, not written as NaN: OpenSense and
        # motionlab's reader take the time stamps as they come (a NaN row read back was refused)
        whole = np.all([np.isfinite(q).all(axis=1) for q in quats.values()], axis=0)
        time, quats = time[whole], {k: q[whole] for k, q in quats.items()}
        write_sto(path, time, quats, force=force)
        gaps = f"; {int((~whole).sum())} rows in a sensor's gap left out" if not whole.all() else ""
        return f"{len(quats)} IMU orientations, {len(time)} samples{gaps}: {', '.join(quats)}"
    if fmt == "mot":
        time, columns = angle_table(session)
        columns = _determined_only(session, columns)
        order = [c for cols in joint_columns(session).values() for c in cols if c in columns]
        columns = {c: columns[c] for c in order + [c for c in columns if c not in order]}
        renamed = opensim_columns(columns)
        write_mot(path, time, renamed, force=force)
        n_os = sum(c in OPENSIM_COORDINATES for c in columns)
        return (
            f"{len(columns)} joint angles (deg; {n_os} as OpenSim coordinates), {len(time)} samples"
        )
    if fmt == "c3d":
        time, columns = angle_table(session)
        judged = judged_columns(session)
        outputs, descriptions = [], {}
        for joint, cols in joint_columns(session).items():
            gone = [c for c in cols[:3] if judged.get(c, ("",))[0] == NOT_DETERMINED]
            xyz = [
                columns[c] if c in columns and c not in gone else np.full(len(time), np.nan)
                for c in (cols + [""] * 3)[:3]
            ]
            outputs.append(ModelOutput(f"{joint}_angles", "angles", "deg", np.column_stack(xyz)))
            descriptions[f"{joint}_angles"] = (
                "X, Y, Z: "
                + ", ".join(cols[:3])
                + (f" ({', '.join(gone)} not determined: written as 0)" if gone else "")
            )
        markers = next((m for m in session.markers.values() if m.n_markers), None)
        marker_time = None
        if markers is not None:
            val = session.results.validation
            sync = val.sync if val is not None else OpticalSync()
            offset, ppm = sync.time_offset_s, sync.drift_ppm
            marker_time = offset + (1.0 + ppm * 1e-6) * time
        write_c3d(path, time, outputs, markers, marker_time, descriptions, force=force)
        n_markers = markers.n_markers if markers is not None else 0
        return f"{len(outputs)} joint angle points (POINT:ANGLES, deg), {n_markers} markers"
    if fmt == "json":
        write_json(session, path, force=force)
        return "results as JSON"
    raise InputError(f"unknown export format '{fmt}'", path, remedy=f"use {', '.join(FORMATS)}")
