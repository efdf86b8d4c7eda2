"""Metrics per task block, joint and plane, and the out-of-plane metrics; one tidy CSV table.

Per task block (the protocol's ``tasks``; times from the simulator's truth, the protocol's
``time_range`` or :func:`~motionlab.segments.steps.find_tasks`; a trunk protocol without tasks,
such as ``lumbar_seated``, measures the trunk movement its calibration found, as one block
without repetitions) and per angle column (degrees), from the angles low-passed as the angle table
is (:func:`~motionlab.kinematics.angle_filter.metrics_cutoff`: 6 Hz by default, and where the
table is as computed):

- ``rom_deg``, ``min_deg``, ``max_deg`` over the block (a gait task: over the kept strides of
  the joint's leg, where there are any);
- ``repetitions``: the cycles found — for a knee or hip in a gait task the strides of its leg
  that the gait analysis keeps (heel strike to heel strike, turns and gait initiation left out:
  :mod:`~motionlab.kinematics.session_strides`), else the repetitions of the joint's primary
  angle (the task's ``plane`` option, else flexion; :func:`~motionlab.kinematics.cycles.
  find_repetitions`);
- peaks: each cycle's maximum and minimum (``cycle_max_deg``, ``cycle_min_deg``) and their mean;
- the cycle-normalised curve, ``curve_mean_deg`` ± ``curve_sd_deg`` at 0, 1, …, 100 %.

Out-of-plane metrics (:mod:`~motionlab.kinematics.out_of_plane`), each when the protocol's
``metrics`` lists it: ``cross_talk`` during every single-plane block (a functional calibration step
that moves a joint's distal segment alone, or a task with a ``plane`` option), calibrated against
the protocol's nominal placement; ``out_of_plane_offset`` of lumbar joints per task with a
``plane``; ``trunk_compensation`` of the ``thorax`` segment per task; ``varus_thrust`` /
``stance_rotation`` of knees in gait tasks. Thresholds come from the protocol's ``thresholds``.

The result (:class:`~motionlab.results.Metrics`, ``session.results.metrics``) holds arrays and
JSON values only; :func:`metrics_table` flattens it into rows ``block, joint, angle, column, metric,
percent, value, unit``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics import cycles as cyc
from motionlab.kinematics import gait_events as ge
from motionlab.kinematics import out_of_plane as oop
from motionlab.kinematics.angle_filter import (
    ANGLES_LOWPASS_HZ,
    metrics_cutoff,
    smoothed_table,
)
from motionlab.kinematics.joint_types import angle_columns, split_column
from motionlab.kinematics.session_angles import angle_table, nominal_calibration
from motionlab.kinematics.session_strides import session_strides
from motionlab.protocol import Joint, Protocol, Task
from motionlab.results import (
    AngleMetrics,
    CrossTalk,
    Metrics,
    OutOfPlaneOffset,
    StanceMetrics,
    TaskBlock,
    TrunkCompensation,
)
from motionlab.segments import (
    reference_step,
    segment_orientations,
    streams_of,
    trunk_axes,
)
from motionlab.segments.sensors import angle_segments, sensor_quats
from motionlab.segments.steps import find_tasks, task_window
from motionlab.session import Session, estimate_rate

OUT_OF_PLANE = ("cross_talk", "out_of_plane_offset", "trunk_compensation", "varus_thrust")
THORAX = "thorax"


def wanted(protocol: Protocol) -> set[str]:
    """The out-of-plane metrics to compute: those the protocol lists (all if it lists none)."""
    listed = set(protocol.metrics)
    if "stance_rotation" in listed:
        listed.add("varus_thrust")
    return listed & set(OUT_OF_PLANE) if listed else set(OUT_OF_PLANE)


def _window(time: np.ndarray, t0: float, t1: float) -> slice:
    i0, i1 = np.searchsorted(time, [t0, t1], side="left")
    return slice(int(i0), int(max(i0, i1)))


def angle_metrics(
    values: np.ndarray, cycles: cyc.Cycles, within: np.ndarray | None = None
) -> AngleMetrics:
    """ROM, extremes, per-cycle peaks and the cycle-normalised mean ± SD of one angle (deg).

    ``within``: the samples (bool, like ``values``) the ROM and extremes are taken over (a
    walk's strides, :func:`cycle_samples`), else all of ``values``. The mean ± SD curve is of
    the cycles the angle covers whole (one through a gap of a sensor left a hole in it)."""
    v = np.asarray(values, dtype=float)
    over = v[within] if within is not None and within.any() else v
    curves = cyc.normalise(v, cycles)
    whole = np.isfinite(curves).all(axis=1)  # a cycle through a gap of this angle's sensors
    mean, sd = cyc.mean_sd(curves[whole] if whole.any() else curves)  # left a hole in the mean
    peaks_max = np.array(
        [np.nanmax(v[a : b + 1]) for a, b in zip(cycles.start, cycles.end, strict=True)]
    )
    peaks_min = np.array(
        [np.nanmin(v[a : b + 1]) for a, b in zip(cycles.start, cycles.end, strict=True)]
    )
    finite = np.isfinite(over).any()
    return AngleMetrics(
        rom_deg=float(np.nanmax(over) - np.nanmin(over)) if finite else float("nan"),
        min_deg=float(np.nanmin(over)) if finite else float("nan"),
        max_deg=float(np.nanmax(over)) if finite else float("nan"),
        repetitions=len(cycles),
        cycle_max_deg=peaks_max,
        cycle_min_deg=peaks_min,
        cycle_max_mean_deg=float(peaks_max.mean()) if len(cycles) else float("nan"),
        cycle_min_mean_deg=float(peaks_min.mean()) if len(cycles) else float("nan"),
        curve_mean_deg=mean,
        curve_sd_deg=sd,
    )


def cycle_samples(cycles: cyc.Cycles, n: int) -> np.ndarray:
    """(n,) bool: the samples from each cycle's start to its end."""
    out = np.zeros(n, bool)
    for a, b in zip(cycles.start, cycles.end, strict=True):
        out[a : b + 1] = True
    return out


def primary_plane(joint: Joint, task: Task | None) -> int:
    """Index of the angle whose repetitions define the cycles (task ``plane``, else flexion)."""
    plane = str(task.options.get("plane", "")) if task is not None else ""
    idx = oop.plane_index(joint, plane) if plane else None
    return 0 if idx is None else idx


def single_plane_blocks(
    protocol: Protocol, blocks: dict[str, tuple[float, float]], steps: dict[str, Any]
) -> list[tuple[str, Joint, int, tuple[float, float]]]:
    """``(block, joint, on-axis index, time range)`` of every single-plane movement of a joint.

    A functional calibration step counts for a joint when it names the distal segment's axis and
    not the proximal segment's; a task when it has a ``plane`` option.
    """
    out = []
    for step in protocol.calibration:
        rng = steps.get(step.name)
        if step.kind != "functional" or not rng:
            continue
        for joint in protocol.joints.values():
            if joint.distal in step.axis and joint.proximal not in step.axis:
                idx = oop.plane_index(joint, step.axis[joint.distal])
                out.append((step.name, joint, idx, tuple(rng)))
    for task in protocol.tasks:
        plane = str(task.options.get("plane", ""))
        if task.name in blocks and plane:
            for joint in protocol.joints.values():
                idx = oop.plane_index(joint, plane)
                if idx is not None:
                    out.append((task.name, joint, idx, blocks[task.name]))
    return out


def _repeated(moving: np.ndarray, window: slice, rate: float) -> slice:
    """The part of ``window`` from the first repetition of the ``moving`` angle to the end of
    its last (:func:`~motionlab.kinematics.cycles.find_repetitions`), or all of it with fewer
    than two: a step found from where the arm started moving also holds getting into its
    posture (a pronation step's elbow flexed to 90° first, which read as 90° of cross-talk)."""
    reps = cyc.find_repetitions(np.asarray(moving[window], float), rate)
    if len(reps) < 2:
        return window
    return slice(window.start + int(reps.start[0]), window.start + int(reps.end[-1]) + 1)


def _outside(
    protocol: Protocol, name: str, span: tuple[float, float], time: np.ndarray
) -> InputError:
    """The error for a task block with fewer than 3 angle samples: a ``time_range`` of the
    protocol's is named by its file and key, a block found in the data by the task."""
    data = f"{time[0]:.1f} to {time[-1]:.1f} s" if len(time) else "none"
    message = (f"task '{name}' ({span[0]:.1f} to {span[1]:.1f} s) is outside the angle data "
               f"({data})")  # fmt: skip
    given = [i for i, t in enumerate(protocol.tasks) if t.name == name and t.time_range]
    if given:
        remedy = f"give a time_range inside {data}, or leave it out to find the task"
        return InputError(message, protocol.path, f"key tasks[{given[0]}].time_range", remedy)
    return InputError(message, where=f"task {name}", remedy="check the task times")


def compute_metrics(
    protocol: Protocol,
    table: dict[str, np.ndarray],
    seg_q: dict[str, tuple[np.ndarray, np.ndarray]],
    blocks: dict[str, tuple[float, float]],
    steps: dict[str, Any],
    nominal_table: dict[str, np.ndarray] | None = None,
    strides: dict[str, ge.Strides] | None = None,
    lowpass_hz: float = ANGLES_LOWPASS_HZ,
) -> Metrics:
    """The metrics (see the module docstring).

    ``table`` is an angle table (``time_s`` and degree columns), ``seg_q`` calibrated segment
    orientations ``{segment: (time, q)}``, ``blocks`` the task time ranges (s), ``steps`` the
    calibration step ranges, ``nominal_table`` the angles with nominal mountings (cross-talk),
    ``strides`` ``{shank segment: strides (s)}`` of the gait tasks
    (:func:`~motionlab.kinematics.session_strides.session_strides`: the gait analysis's; the
    kept ones are a walk's cycles). The metrics are taken from both tables low-passed at
    ``lowpass_hz`` (:func:`~motionlab.kinematics.angle_filter.smoothed_table`; the tables given
    are not changed).
    """
    table = smoothed_table(table, lowpass_hz)
    if nominal_table is not None:
        nominal_table = smoothed_table(nominal_table, lowpass_hz)
    time = np.asarray(table["time_s"], dtype=float)
    rate = estimate_rate(time)
    todo = wanted(protocol)
    th = protocol.thresholds
    tasks = {t.name: t for t in protocol.tasks}
    joints: dict[str, dict[str, AngleMetrics]] = {}
    stance: dict[str, dict[str, StanceMetrics]] = {}
    offset: dict[str, dict[str, OutOfPlaneOffset]] = {}
    trunk: dict[str, TrunkCompensation] = {}
    cross: dict[str, dict[str, CrossTalk]] = {}
    for name, (t0, t1) in blocks.items():
        task, win = tasks.get(name), _window(time, t0, t1)
        if win.stop - win.start < 3:
            raise _outside(protocol, name, (t0, t1), time)
        per_col: dict[str, Any] = {}
        walk = task is not None and task.is_gait
        kept = {
            seg: kept_cycles(st, time[win]) for seg, st in (strides or {}).items()
        } if walk else {}  # fmt: skip
        for joint in protocol.joints.values():
            cols = [col for _, col in angle_columns(joint)]
            # a walk's cycles are the kept strides of the joint's leg (its ROM is over them: the
            # block also holds what the walker did between bouts, turns, a seated rest); none
            # kept: no cycles, the ROM over the block
            leg = _leg_shank(protocol, joint, kept)
            within = cycle_samples(kept[leg], win.stop - win.start) if leg else None
            if leg:
                cycles = kept[leg]
                if joint.type == "knee" and "varus_thrust" in todo:
                    found = oop.stance_metrics(
                        table[cols[1]][win],
                        table[cols[2]][win],
                        table[cols[0]][win],
                        cycles,
                        float(th.get("varus_thrust_deg", 3.0)),
                    )
                    stance.setdefault(name, {})[joint.name] = replace(
                        found,
                        heel_strike_s=time[win][cycles.start],
                        toe_off_s=time[win][cycles.peak],
                    )
            elif task is None and name in steps:
                cycles = cyc.Cycles.empty()  # a calibration movement in any order: no cycles
            else:
                plane = primary_plane(joint, task)
                cycles = cyc.find_repetitions(table[cols[plane]][win], rate)
            for col in cols:
                per_col[col] = replace(
                    angle_metrics(table[col][win], cycles, within),
                    cycle_start_s=time[win][cycles.start],
                )
            if joint.type == "lumbar" and "out_of_plane_offset" in todo and task is not None:
                plane = task.options.get("plane")
                if plane and oop.plane_index("lumbar", str(plane)) is not None:
                    offset.setdefault(name, {})[joint.name] = _offset(
                        protocol, joint, seg_q, time, win, steps, str(plane), cycles, th
                    )
        joints[name] = per_col
        if "trunk_compensation" in todo and THORAX in seg_q:
            tq, q = seg_q[THORAX]
            trunk[name] = oop.trunk_compensation(
                tq, q, _window(tq, t0, t1), dict(th.get("trunk_compensation_deg", {}))
            )
    if "cross_talk" in todo:
        for block, joint, idx, (t0, t1) in single_plane_blocks(protocol, blocks, steps):
            win = _repeated(table[angle_columns(joint)[idx][1]], _window(time, t0, t1), rate)
            cross.setdefault(block, {})[joint.name] = oop.cross_talk(
                table, nominal_table, joint, idx, win
            )
    return Metrics(
        protocol.name,
        joints=joints,
        blocks={k: TaskBlock(float(v[0]), float(v[1])) for k, v in blocks.items()},
        gait=stance or None,
        out_of_plane_offset=offset or None,
        trunk_compensation=trunk or None,
        cross_talk=cross or None,
    )


def _leg_shank(protocol: Protocol, joint: Joint, strides: dict[str, cyc.Cycles]) -> str | None:
    """The shank (a key of ``strides``) of the leg ``joint`` belongs to: its own distal
    segment (the knee), or the distal segment of the knee below it (the hip)."""
    below = [j.distal for j in protocol.joints.values() if j.proximal == joint.distal]
    return next((s for s in [joint.distal, *below] if s in strides), None)


def kept_cycles(strides: ge.Strides, time: np.ndarray) -> cyc.Cycles:
    """The kept strides that lie within ``time`` (s, a block's samples) as cycles of its sample
    indices: ``start`` the initial contact, ``peak`` the final contact (toe-off), ``end`` the
    next initial contact, each the nearest sample."""
    inside = strides.kept & (strides.ic >= time[0]) & (strides.next_ic <= time[-1])
    if not inside.any():
        return cyc.Cycles.empty()

    def nearest(t: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(time, t), 1, len(time) - 1)
        return np.where(t - time[i - 1] < time[i] - t, i - 1, i).astype(int)

    a, p, b = (nearest(x[inside]) for x in (strides.ic, strides.fc, strides.next_ic))
    return cyc.Cycles(a, p, b)


def _offset(protocol, joint, seg_q, time, win, steps, plane, cycles, th) -> OutOfPlaneOffset:
    qp = rot.resample(*seg_q[joint.proximal], time)
    qd = rot.resample(*seg_q[joint.distal], time)
    axis_deg = oop.axis_angles(qp, qd)
    ref_name = reference_step(protocol, joint.proximal, joint.distal)
    rng = steps.get(ref_name) if ref_name else None
    sel = (time >= rng[0]) & (time <= rng[1]) if rng else np.zeros(len(time), bool)
    if sel.sum() < 3:  # no standing pose: the rest before the task
        sel = (time >= time[win][0] - oop.NEUTRAL_S) & (time < time[win][0])
    reference = axis_deg[sel].mean(axis=0) if sel.any() else axis_deg[win][0]
    return oop.out_of_plane_offset(
        axis_deg,
        reference,
        oop.plane_index("lumbar", plane),
        win,
        cycles,
        float(th.get("out_of_plane_offset_deg", 5.0)),
    )


def session_metrics(
    session: Session,
    protocol: Protocol,
    tasks: dict[str, tuple[float, float]] | None = None,
) -> Metrics:
    """Metrics of a calibrated session; ``tasks`` ``{name: (start_s, end_s)}`` or found.

    The angles are computed as ``motionlab angles`` does (calibrated, heading-aligned IMU
    orientations) and again with the nominal mountings for the cross-talk comparison, and
    low-passed as the session's angle table is (:func:`~motionlab.kinematics.angle_filter.
    metrics_cutoff`).
    """
    cal = session.results.calibration
    if cal is None:
        raise InputError(
            "not calibrated", where="results/calibration", remedy="run motionlab calibrate first"
        )
    steps = {k: tuple(v) for k, v in cal.steps.items() if v is not None}
    if tasks is None and cal.single_pose:
        tasks, source = {}, "detected"  # the recording is the calibration pose: no task in it
    elif tasks is None and not protocol.tasks and trunk_axes.applies(protocol):
        # the trunk movement, in any order, is both the calibration's movement and what a
        # clinician wants measured: its range of motion is the block's
        move = next(s.name for s in protocol.calibration if s.axis_method == trunk_axes.METHOD)
        tasks = {move: steps[move]} if move in steps else {}
        source = "calibration movement"
    elif tasks is None:
        streams = streams_of(session, protocol)
        after, before = task_window(streams, protocol, cal.steps)
        tasks = find_tasks(streams, protocol, after_s=after, steps=cal.steps, before_s=before)
        source = "detected"
    else:
        source = "given"
    gait_tasks = {t.name for t in protocol.tasks if t.is_gait}
    quats = sensor_quats(session, protocol, angle_segments(session, protocol))  # the thorax too
    seg_q = segment_orientations(protocol, cal, quats)
    table = angle_table(seg_q, protocol, cal)
    nominal = None
    if "cross_talk" in wanted(protocol):
        nominal = angle_table(
            segment_orientations(protocol, nominal_calibration(protocol, cal.steps), quats),
            protocol,
        )
    walks = {k: v for k, v in tasks.items() if k in gait_tasks}
    legs = session_strides(session, protocol, cal, walks) if walks else {}
    exported = session.results.angles
    cutoff = metrics_cutoff(exported.lowpass_hz if exported is not None else 0.0)
    strides = {k: v.strides for k, v in legs.items()}
    out = compute_metrics(protocol, table, seg_q, tasks, steps, nominal, strides, cutoff)
    out.blocks = {k: replace(v, source=source) for k, v in out.blocks.items()}
    return out


_UNITS = {"repetitions": "1", "strides": "1", "compensated": "1"}
#: the scalar rows of every angle in every block of :func:`metrics_table` (its curves aside)
ANGLE_METRICS = ("rom_deg", "min_deg", "max_deg", "repetitions", "cycle_max_mean_deg",
                 "cycle_min_mean_deg")  # fmt: skip
#: the grade of a row of a joint with no sensor on one of its segments (:func:`with_not_measured`;
#: not one of :data:`motionlab.segments.grades.GRADES`: nothing was computed to grade)
NOT_MEASURED = "not measured"


def metric_unit(metric: str) -> str:
    """The unit of a metrics-table row: ``1`` for counts and flags, ``%`` for ``*_pct``, else
    ``deg``."""
    return _UNITS.get(metric, "%" if metric.endswith("_pct") else "deg")


def metrics_table(metrics: Metrics, joints: dict[str, list[str]] | None = None) -> pd.DataFrame:
    """Rows ``block, joint, angle, column, metric, percent, value, unit`` of every scalar and
    curve: ``joint`` the protocol's joint name and ``column`` the angle column the row is of
    (as ``grades.csv`` and the angle tables name them; empty for a row of no angle column)
    where ``joints`` (``{joint name: its angle columns}``, :func:`protocol_columns`) tells them,
    else the column's own prefix (``trunk_lean`` for a ``trunk_lean`` joint named otherwise).

    Per-cycle arrays are summarised by their mean; the cycle-normalised curves give one row per
    percent. Long sample-by-sample series (offset, trunk angles) stay in the session only.
    """
    rows: list[tuple] = []
    name_of = {c: j for j, cols in (joints or {}).items() for c in cols}
    column_of = {(j, split_column(c)[1]): c for j, cols in (joints or {}).items() for c in cols}

    def add(block, joint, angle, metric, value, percent=None, column=None):
        if isinstance(value, (bool, np.bool_)):
            value = float(value)
        column = column or column_of.get((joint, angle), "")
        unit = metric_unit(metric)
        rows.append((block, joint, angle, column, metric, percent, float(value), unit))

    for block, cols in metrics.joints.items():
        for col, m in cols.items():
            prefix, angle = split_column(col)
            joint = name_of.get(col, prefix)
            for key in ANGLE_METRICS:
                add(block, joint, angle, key, getattr(m, key), column=col)
            for pct, (mu, sd) in enumerate(zip(m.curve_mean_deg, m.curve_sd_deg, strict=True)):
                add(block, joint, angle, "curve_mean_deg", mu, pct, column=col)
                add(block, joint, angle, "curve_sd_deg", sd, pct, column=col)
    for block, joints in (metrics.cross_talk or {}).items():
        for joint, c in joints.items():
            add(block, joint, c.on_axis, "cross_talk_on_axis_rom_deg", c.on_axis_rom_deg)
            for angle, e in c.off_axis.items():
                add(block, joint, angle, "cross_talk_rom_deg", e.rom_deg)
                add(block, joint, angle, "cross_talk_ratio_pct", e.ratio_pct)
                if e.nominal_rom_deg is not None:
                    add(block, joint, angle, "cross_talk_nominal_rom_deg", e.nominal_rom_deg)
                if e.change_pct is not None:
                    add(block, joint, angle, "cross_talk_change_pct", e.change_pct)
    for block, joints in (metrics.out_of_plane_offset or {}).items():
        for joint, o in joints.items():
            axes = "-".join(o.axes)
            add(block, joint, axes, "out_of_plane_peak_deg", o.peak_deg)
            add(block, joint, axes, "out_of_plane_mean_deg", o.mean_deg)
            add(block, joint, axes, "out_of_plane_above_pct", o.above_pct)
    for block, t in (metrics.trunk_compensation or {}).items():
        for angle in oop.TRUNK_ANGLES:
            a = t.per_angle[angle]
            add(block, "trunk", angle, "trunk_peak_abs_deg", a.peak_abs_deg)
            add(block, "trunk", angle, "trunk_max_deg", a.max_deg)
            add(block, "trunk", angle, "trunk_min_deg", a.min_deg)
            add(block, "trunk", angle, "trunk_above_pct", a.above_pct)
        add(block, "trunk", "", "compensated", t.compensated)
    for block, joints in (metrics.gait or {}).items():
        for joint, g in joints.items():
            add(block, joint, "", "strides", g.strides)
            add(block, joint, "adduction", "varus_thrust_mean_deg", g.varus_thrust_mean_deg)
            add(block, joint, "adduction", "varus_thrust_sd_deg", g.varus_thrust_sd_deg)
            add(block, joint, "adduction", "varus_thrust_above_pct", g.varus_thrust_above_pct)
            add(block, joint, "rotation", "stance_rotation_range_mean_deg",
                g.stance_rotation_range_mean_deg)  # fmt: skip
            add(block, joint, "rotation", "stance_rotation_range_sd_deg",
                g.stance_rotation_range_sd_deg)  # fmt: skip
    return pd.DataFrame(
        rows,
        columns=["block", "joint", "angle", "column", "metric", "percent", "value", "unit"],
    )


def not_measured_note(segments: list[str]) -> str:
    """Why a joint was not measured: ``not measured: no pelvis sensor`` (``segments``: its
    segments with no sensor, :func:`motionlab.binding.unsensed_joints`)."""
    return f"not measured: no {' or '.join(segments)} sensor"


def with_not_measured(
    table: pd.DataFrame, protocol: Protocol, unsensed: dict[str, list[str]], blocks: list[str]
) -> pd.DataFrame:
    """``table`` (:class:`motionlab.pipeline.PipelineResult`'s ``metrics``: ``block, joint,
    angle, column, metric, value, unit, grade``) followed by the scalar rows
    :func:`metrics_table` would have had for the joints the recording did not measure
    (``unsensed``: ``{joint: its segments with no sensor}``,
    :func:`motionlab.binding.unsensed_joints`): per block and angle the :data:`ANGLE_METRICS`,
    ``value`` empty (NaN), ``grade`` :data:`NOT_MEASURED`, so that a table gathered over
    sessions says that a joint is missing from one (why: :func:`not_measured_note`, which
    :func:`motionlab.report.csv.with_normals` adds). ``table`` itself without such joints."""
    if not unsensed:
        return table
    columns = protocol_columns(protocol)
    rows = [
        (block, joint, split_column(col)[1], col, metric, np.nan, metric_unit(metric),
         NOT_MEASURED)
        for block in blocks
        for joint in unsensed
        for col in columns[joint]
        for metric in ANGLE_METRICS
    ]  # fmt: skip
    missing = pd.DataFrame(rows, columns=["block", "joint", "angle", "column", "metric", "value",
                                          "unit", "grade"])  # fmt: skip
    return pd.concat([table, missing], ignore_index=True)


def protocol_columns(protocol: Protocol) -> dict[str, list[str]]:
    """``{joint name: its angle columns}`` of a protocol, for :func:`metrics_table`."""
    return {name: [c for _, c in angle_columns(j)] for name, j in protocol.joints.items()}
