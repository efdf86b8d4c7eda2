"""CSV tables for researchers: one angle time series per joint, metrics, out-of-plane metrics,
the grade of every angle, data quality and calibration quality. Every numeric column carries its
unit in its name (``_deg``, ``_s``, ``_hz``, ``_ms``, ``_pct``, ``_n`` for counts, ``_ratio`` for
unitless ratios).

A measured number whose angle is ``not determined`` is an empty cell (the row, its grade and the
counts stay; ``grades.csv`` says why, the session file keeps what was computed): the report does
not print such a number, and a table read without the grade must not show it either.

Files (in ``csv_dir``): ``<joint>_angles.csv`` (``time_s`` + one column per angle, degrees;
numbers only), ``metrics.csv`` (range of motion per task, joint and angle, with the normal range,
the symmetry index and the angle's ``grade``), ``out_of_plane.csv`` (with the ``grade`` of the
angle a row refers to; the worst of the joint's angles for the lumbar offset, the thorax frame's
for trunk compensation), ``grades.csv`` (``joint, angle, column, grade, reason``: one row per
angle column; ``determined``, ``weak`` or ``not determined``, see
:mod:`motionlab.segments.grades`), ``quality.csv`` (per sensor) and ``calibration.csv`` (per
segment and calibration step: ρ, residual, ``in_fit``, and for an axis found in the movement
its own check's ``movement_axis_verdict``). Existing files are replaced only with ``force``,
which also removes the tables of these names an earlier run wrote and this one does not
(another protocol's joints, a gait table), so the folder never mixes two runs.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from motionlab.atomic import atomic_path, check_output
from motionlab.errors import InputError
from motionlab.kinematics.gait_course import walk_courses
from motionlab.kinematics.joint_types import angle_columns, plane
from motionlab.kinematics.metrics import NOT_MEASURED, not_measured_note
from motionlab.kinematics.spatiotemporal import (
    BOTH_LEGS,
    MIN_STRIDES,
    STRIDE_COLUMNS,
    summary_rows,
    too_few,
)
from motionlab.report.model import (
    DETERMINED,
    NOT_DETERMINED,
    THORAX,
    SessionView,
    angle_grade,
    calibration_rows,
    gait_result,
    grade_rows,
    normal_range,
    quality_rows,
    rom_rows,
    segment_grade,
    symmetry_rows,
    worst_grade,
)
from motionlab.report.sentences import paced_words

FLOAT_FORMAT = "%.4f"


def _withheld(grade: str, value):
    """``value``, or NaN (an empty cell) where its angle is not determined: a number the
    calibration could not stand behind is not exported as one (``grades.csv`` says why; the
    session file keeps what was computed)."""
    if grade != NOT_DETERMINED:
        return value
    return np.full(np.shape(value), np.nan) if np.ndim(value) else np.nan


def angle_frames(view: SessionView) -> dict[str, pd.DataFrame]:
    """``{"<joint>_angles.csv": DataFrame(time_s, <joint>_<angle>_deg ...)}``; a column whose
    angle is not determined is empty."""
    t = view.angles["time_s"]
    out = {}
    for joint in view.joints():
        cols = {"time_s": t} | {
            col: _withheld(angle_grade(view, joint.name, angle)[0], view.angles[col])
            for angle, col in angle_columns(joint)
        }
        out[f"{joint.name}_angles.csv"] = pd.DataFrame(cols)
    return out


#: the columns of metrics.csv, whatever the protocol (the header alone without a task)
METRICS_COLUMNS = ("task", "joint", "angle", "plane", "rom_deg", "min_deg", "max_deg",
                   "typical_min_deg", "typical_max_deg", "cycles_n", "normal_min_deg",
                   "normal_max_deg", "vs_normal", "symmetry_index_pct", "grade")  # fmt: skip
#: metrics.csv's columns of an angle in a task that a table of one row per number repeats on
#: each of the angle's rows (:func:`with_normals`)
NORMAL_COLUMNS = ("normal_min_deg", "normal_max_deg", "vs_normal")


def metrics_frame(view: SessionView) -> pd.DataFrame:
    """Range of motion per task, joint and angle, with normal range, flag and symmetry; the
    angles of a joint with no sensor on a segment (:attr:`SessionView.unmeasured`) empty, graded
    ``not measured``."""
    si = {(s.task, s.joint_type, s.angle): s.symmetry_index_pct for s in symmetry_rows(view)}
    rows = []
    for r in rom_rows(view):
        lo, hi = r.normal if r.normal else (np.nan, np.nan)
        measured = {
            "rom_deg": r.rom_deg,
            "min_deg": r.min_deg,
            "max_deg": r.max_deg,
            "typical_min_deg": r.typical_min_deg,
            "typical_max_deg": r.typical_max_deg,
        }
        if r.grade == NOT_DETERMINED:
            vs_normal = "not compared"
        else:
            vs_normal = r.status or ("not compared" if r.normal else "no normal range")
            vs_normal += f" ({paced_words(view, r)})" if r.paced else ""
        rows.append(
            {"task": r.task, "joint": r.joint, "angle": r.angle, "plane": r.plane}
            | {k: _withheld(r.grade, v) for k, v in measured.items()}
            | {
                "cycles_n": r.repetitions,
                "normal_min_deg": lo,
                "normal_max_deg": hi,
                "vs_normal": vs_normal,
                "symmetry_index_pct": _withheld(
                    r.grade, si.get((r.task, r.joint_type, r.angle), np.nan)
                ),
                "grade": r.grade,
            }
        )
    for task in view.tasks():
        for joint, _, angle, column in _unmeasured_angles(view):
            lo, hi = normal_range(view.protocol, task, column) or (np.nan, np.nan)
            rows.append(
                dict.fromkeys(METRICS_COLUMNS, np.nan)  # nothing measured: every number empty
                | {"task": task, "joint": joint.name, "angle": angle, "plane": plane(joint, angle)}
                | {"normal_min_deg": lo, "normal_max_deg": hi, "vs_normal": "not compared"}
                | {"grade": NOT_MEASURED}
            )
    return pd.DataFrame(rows, columns=list(METRICS_COLUMNS))


def _unmeasured_angles(view: SessionView) -> list[tuple]:
    """``(joint, its segments with no sensor, angle, column)`` of every angle of the joints the
    recording did not measure (:attr:`SessionView.unmeasured`)."""
    return [
        (joint, segments, angle, column)
        for joint, segments in view.unmeasured
        for angle, column in angle_columns(joint)
    ]


def with_normals(view: SessionView, table: pd.DataFrame) -> pd.DataFrame:
    """A metrics table of one row per number (``block, joint, angle, column, ..., grade``:
    :attr:`motionlab.pipeline.PipelineResult.metrics`) with what ``metrics.csv`` says of the
    row's angle in its task, from the same rows (:func:`metrics_frame`): its normal range
    (``normal_min_deg``, ``normal_max_deg``, deg) and ``vs_normal``, empty for a row of no
    angle there; and a ``note``: why the row's angle is weak or not determined (the reason of
    ``grades.csv``, ``not measured: no pelvis sensor`` for a joint with no sensor; the thorax
    frame's for the trunk's rows), else empty."""
    angles = metrics_frame(view)[["task", "joint", "angle", *NORMAL_COLUMNS]]
    keys = ["block", "joint", "angle"]
    out = table.merge(angles.rename(columns={"task": "block"}), on=keys, how="left")
    grades = grades_frame(view)
    reasons = dict(zip(grades["column"], zip(grades["grade"], grades["reason"], strict=True),
                       strict=True))  # fmt: skip
    trunk = segment_grade(view, THORAX)
    graded = [
        trunk if j == "trunk" and a else reasons.get(c, (DETERMINED, ""))
        for j, a, c in zip(out["joint"], out["angle"], out["column"], strict=True)
    ]
    out["note"] = [reason if grade != DETERMINED else "" for grade, reason in graded]
    out["vs_normal"] = out["vs_normal"].fillna("")
    return out


def _or_nan(value: float | None) -> float:
    return np.nan if value is None else value


#: out-of-plane columns that are settings or counts, not measured angles: kept whatever the grade
_SETTINGS = ("threshold_deg", "count_n")

#: the columns of out_of_plane.csv, whatever the protocol (a row fills those of its metric)
OUT_OF_PLANE_COLUMNS = ("metric", "task", "joint", "angle", "value_deg", "sd_deg", "min_deg",
                        "max_deg", "mean_deg", "threshold_deg", "above_threshold_pct",
                        "count_n", "of_moving_angle_pct", "moving_angle_rom_deg",
                        "without_calibration_deg", "calibration_change_pct", "grade")  # fmt: skip


def out_of_plane_frame(view: SessionView) -> pd.DataFrame:
    """One row per out-of-plane number: metric, task, joint, angle and its value columns."""
    m = view.metrics
    rows = []

    def add(metric, task, joint, angle, grade=None, **values):
        if grade is None:
            grade = angle_grade(view, joint, angle)[0]
        kept = {k: v if k in _SETTINGS else _withheld(grade, v) for k, v in values.items()}
        rows.append(
            {"metric": metric, "task": task, "joint": joint, "angle": angle, **kept}
            | {"grade": grade}
        )

    for task, joints in (m.gait or {}).items():
        for joint, g in joints.items():
            add(
                "varus_thrust",
                task,
                joint,
                "adduction",
                value_deg=g.varus_thrust_mean_deg,
                sd_deg=g.varus_thrust_sd_deg,
                threshold_deg=g.threshold_deg,
                above_threshold_pct=g.varus_thrust_above_pct,
                count_n=g.strides,
            )
            add(
                "stance_rotation_range",
                task,
                joint,
                "rotation",
                value_deg=g.stance_rotation_range_mean_deg,
                sd_deg=g.stance_rotation_range_sd_deg,
                count_n=g.strides,
            )
    trunk = segment_grade(view, THORAX)[0]
    for task, t in (m.trunk_compensation or {}).items():
        for angle in ("flexion", "lateral_bending", "axial_rotation"):
            a = t.per_angle[angle]
            add(
                "trunk_compensation",
                task,
                "trunk",
                angle,
                grade=trunk,
                value_deg=a.peak_abs_deg,
                min_deg=a.min_deg,
                max_deg=a.max_deg,
                threshold_deg=a.threshold_deg,
                above_threshold_pct=a.above_pct,
            )
    for task, joints in (m.out_of_plane_offset or {}).items():
        for joint, o in joints.items():
            graded = [(r.grade, "") for r in grade_rows(view) if r.joint == joint]
            add(
                "out_of_plane_offset",
                task,
                joint,
                "-".join(o.axes),
                grade=worst_grade(graded)[0],
                value_deg=o.peak_deg,
                mean_deg=o.mean_deg,
                threshold_deg=o.threshold_deg,
                above_threshold_pct=o.above_pct,
            )
    for block, joints in (m.cross_talk or {}).items():
        for joint, c in joints.items():
            for angle, e in c.off_axis.items():
                add(
                    "cross_talk",
                    block,
                    joint,
                    angle,
                    value_deg=e.rom_deg,
                    of_moving_angle_pct=e.ratio_pct,
                    moving_angle_rom_deg=c.on_axis_rom_deg,
                    without_calibration_deg=_or_nan(e.nominal_rom_deg),
                    calibration_change_pct=_or_nan(e.change_pct),
                )
    # one layout for every protocol (a batch stacks them), an empty cell where a metric has no
    # such number; a protocol with none of these metrics (a rig's hinges) gets the header
    extra = [k for r in rows for k in r if k not in OUT_OF_PLANE_COLUMNS]
    return pd.DataFrame(rows, columns=[*OUT_OF_PLANE_COLUMNS, *dict.fromkeys(extra)])


def quality_frame(view: SessionView) -> pd.DataFrame:
    """Per sensor: placement, sampling and the data-quality numbers of the report."""
    rows = []
    for q in quality_rows(view):
        rows.append(
            {
                "sensor": q.sensor,
                "serial": q.serial,
                "segment": q.segment,
                "side": q.side,
                "channels": q.channels,
                "rate_hz": q.rate_hz,
                "jitter_ms": q.jitter_ms,
                "duration_s": q.duration_s,
                "samples_n": q.samples,
                "missing_samples_n": q.dropped_samples,
                "gaps_filled_n": q.gaps_filled,
                "samples_filled_n": q.samples_filled,
                "gaps_kept_n": q.gaps_kept,
                "gaps_kept_s": q.gaps_kept_s,
                "saturated_samples_n": q.saturated_samples,
                "at_rest_pct": q.rest_pct,
                "mag_disturbed_pct": q.mag_disturbed_pct,
                "qc_flags": ";".join(q.flags),
            }
        )
    return pd.DataFrame(rows)


def grades_frame(view: SessionView) -> pd.DataFrame:
    """One row per angle column: ``joint, angle, column, grade, reason``; the angles of a joint
    with no sensor on a segment (:attr:`SessionView.unmeasured`) graded ``not measured``."""
    columns = ["joint", "angle", "column", "grade", "reason"]
    rows = [asdict(r) for r in grade_rows(view)] + [
        dict(zip(columns, (j.name, a, c, NOT_MEASURED, not_measured_note(segs)), strict=True))
        for j, segs, a, c in _unmeasured_angles(view)
    ]
    return pd.DataFrame(rows, columns=columns)


def calibration_frame(view: SessionView) -> pd.DataFrame:
    rows = [
        {
            "segment": r.segment,
            "sensor": r.sensor,
            "method": r.method,
            "step": r.step,
            "kind": r.kind,
            "rho_ratio": r.rho,
            "reference_rho_ratio": r.reference_rho,
            "residual_deg": r.residual_deg,
            "in_fit": r.used,
            "movement_axis_verdict": r.verdict or "",
            "segment_ok": r.segment_ok,
        }
        for r in calibration_rows(view)
    ]
    return pd.DataFrame(rows)


#: the summary's numbers from the leg model's lengths (``Gait.walking_speed`` says why not)
LENGTH_PARAMETERS = ("step_length_m", "stride_length_m", "walking_speed_m_s")


def gait_summary_frame(view: SessionView) -> pd.DataFrame | None:
    """``spatiotemporal_summary.csv`` (:func:`~motionlab.kinematics.spatiotemporal.summary_rows`)
    with the reason a number is not given in the ``note`` its row had empty: a leg not measured
    (one leg's sensors: its rows, and the other's numbers that need both legs), a length or speed
    not measured (``Gait.walking_speed``: no subject height, a leg's sensor missing), a mean of
    too few strides (none too); None without a gait analysis."""
    g = gait_result(view)
    if g is None:
        return None
    rows = summary_rows(g.summary)
    measured = set(g.strides.side.tolist()) if g.strides is not None else set()
    if len(measured) == 1:  # one leg's sensors: the other leg's rows, and what needs both
        leg = "right" if measured == {"r"} else "left"
        blank = rows["mean"].isna() & (rows["note"] == "")
        other = rows["side"].isin({"r", "l"} - measured)
        rows.loc[blank & other, "note"] = f"not measured: only the {leg} leg measured"
        both = rows["parameter"].isin(BOTH_LEGS) & ~other
        rows.loc[blank & both, "note"] = f"only the {leg} leg measured: needs both legs"
    why = g.walking_speed or ""
    if why.startswith("not measured"):
        blank = rows["parameter"].isin(LENGTH_PARAMETERS) & rows["mean"].isna()
        rows.loc[blank & (rows["note"] == ""), "note"] = why
    fewest = g.summary.min_strides or MIN_STRIDES
    few = rows["mean"].isna() & (rows["note"] == "") & (rows["count_n"] < fewest)
    rows.loc[few, "note"] = [too_few(int(n)) for n in rows.loc[few, "count_n"]]
    return rows


def gait_frames(view: SessionView) -> dict[str, pd.DataFrame]:
    """``spatiotemporal.csv`` (one row per stride, kept or not, with the reason) and
    ``spatiotemporal_summary.csv`` (per side and parameter its ``unit``, mean, SD, CV, SE,
    median, quartiles and the number ``count_n`` of strides or step pairs (``count_of``); NaN
    below 3 strides; ``note``: why a number is withheld, :func:`gait_summary_frame`), for a
    walk of 3 min or more ``spatiotemporal_course.csv``
    (:meth:`~motionlab.kinematics.gait_course.WalkCourse.rows`); nothing without a gait
    analysis."""
    g = gait_result(view)
    if g is None:
        return {}
    strides = g.strides.frame()[["side", "start_s", "kept", "reason", *STRIDE_COLUMNS]]
    out = {
        "spatiotemporal.csv": strides,
        "spatiotemporal_summary.csv": gait_summary_frame(view),
    }
    courses = walk_courses(g)
    if courses:  # a walk of 3 min or more, part by part
        out["spatiotemporal_course.csv"] = pd.concat([c.rows() for c in courses])
    return out


def tables(view: SessionView) -> dict[str, pd.DataFrame]:
    """Every CSV of one session, by file name."""
    return (
        angle_frames(view)
        | {
            "metrics.csv": metrics_frame(view),
            "out_of_plane.csv": out_of_plane_frame(view),
            "grades.csv": grades_frame(view),
            "quality.csv": quality_frame(view),
            "calibration.csv": calibration_frame(view),
        }
        | gait_frames(view)
    )


def write_csvs(view: SessionView, csv_dir: str | Path, force: bool = False) -> list[Path]:
    """Write :func:`tables` into ``csv_dir`` (created); returns the paths written."""
    csv_dir = Path(csv_dir)
    if csv_dir.exists() and not csv_dir.is_dir():
        raise InputError("is not a folder", csv_dir, remedy="give a folder for the CSV tables")
    frames = tables(view)
    paths = [csv_dir / name for name in frames]
    if csv_dir.is_dir():
        for p in paths:
            check_output(p, force)
    csv_dir.mkdir(parents=True, exist_ok=True)
    for path, frame in zip(paths, frames.values(), strict=True):
        with atomic_path(path, force=force) as tmp:
            write_frame(frame, tmp)
    if force:
        for stale in set(_own_tables(csv_dir)) - set(paths):
            stale.unlink(missing_ok=True)
    return paths


#: the tables :func:`tables` can write, besides ``<joint>_angles.csv``
TABLE_NAMES = (
    "metrics.csv",
    "out_of_plane.csv",
    "grades.csv",
    "quality.csv",
    "calibration.csv",
    "spatiotemporal.csv",
    "spatiotemporal_summary.csv",
    "spatiotemporal_course.csv",
)


def _own_tables(csv_dir: Path) -> list[Path]:
    """The files in ``csv_dir`` named as this module's tables (an earlier run's)."""
    return [p for p in csv_dir.glob("*_angles.csv") if p.is_file()] + [
        csv_dir / n for n in TABLE_NAMES if (csv_dir / n).is_file()
    ]


def write_frame(frame: pd.DataFrame, path: str | Path) -> None:
    """``frame.to_csv(path, index=False, float_format=FLOAT_FORMAT)``, the same bytes; a frame
    of float columns only (the angle time series) is formatted a row at a time, several times
    faster than pandas' value at a time (missing values are empty fields, as pandas writes
    them)."""
    if frame.empty or not all(dt == np.float64 for dt in frame.dtypes):
        frame.to_csv(path, index=False, float_format=FLOAT_FORMAT)
        return
    values = frame.to_numpy()
    head = io.StringIO()
    csv.writer(head, lineterminator=os.linesep).writerow(frame.columns)
    row_format = ",".join([FLOAT_FORMAT] * values.shape[1])
    missing = np.isnan(values).any(axis=1)
    lines = [
        ",".join("" if v != v else FLOAT_FORMAT % v for v in row)
        if gap
        else row_format % tuple(row)
        for row, gap in zip(values.tolist(), missing.tolist(), strict=True)
    ]
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(head.getvalue())
        f.write(os.linesep.join(lines) + os.linesep)
