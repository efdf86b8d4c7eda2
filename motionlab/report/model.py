"""What the report shows, computed once per session: the numbers behind pages, texts and CSVs.

Conventions: angles in degrees (the unit of the angle tables and metrics), times in s, rates in
Hz. A *view* (:class:`SessionView`) wraps one session that has been through the pipeline
(``results.angles`` and ``results.metrics``), with its protocol. The functions here only
read results the stages stored; they compute no kinematics of their own.

- :func:`rom_rows`: per task, joint and angle, the range of motion, the typical extremes (means of
  the per-cycle peaks), the protocol's normal range and a flag when the extremes leave it by
  more than :data:`TOLERANCE_DEG`, or the flexion peak falls short of its top by more than
  :data:`REACH_TOLERANCE_DEG` (:func:`compare`);
- :func:`symmetry_rows`: the left-right symmetry index of each range of motion (Robinson et al.
  1987, J Manipulative Physiol Ther 10:172): ``SI = 100 (R − L) / ((R + L) / 2)`` %, flagged above
  :data:`SYMMETRY_LIMIT_PCT`; not given when the mean range is below :data:`SYMMETRY_MIN_ROM_DEG`
  (a ratio of two small ranges is noise);
- :func:`quality_rows`: per sensor, rates, gaps, saturation, rest and magnetic disturbance;
- :func:`calibration_rows`: per segment and calibration step, method, ρ and residual angle
  (one row for a segment calibrated without any measured axis, so that every protocol segment with
  a sensor is counted);
- :func:`grade_rows`: per joint angle, its grade (``determined``, ``weak``, ``not determined``;
  :mod:`motionlab.segments.grades`) and the reason in plain words. Sessions calibrated before
  grades existed have none: every angle counts as ``determined`` there. Rows of :func:`rom_rows`
  and :func:`symmetry_rows` carry the grade. Only a ``determined`` angle is compared with its
  normal range (``status``; empty otherwise, so that nothing weak or undetermined is flagged) and
  only ranges ``determined`` on both sides give a symmetry index (NaN otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.binding import sensed_protocol, unsensed_joints
from motionlab.errors import InputError
from motionlab.kinematics.gps import gated_profile, variable_grades
from motionlab.kinematics.joint_types import JOINT_TYPES, angle_columns, plane, title
from motionlab.kinematics.metrics import THORAX as THORAX  # re-exported for the pages
from motionlab.protocol import Joint, Protocol, load_protocol
from motionlab.results import (
    AngleMetrics,
    Gait,
    GaitSummary,
    Metrics,
    MovementProfile,
    SegmentCalibration,
    SegmentRecord,
)
from motionlab.segments import sensor_for_segment
from motionlab.segments.grades import GRADES, _frame_grade, graded_angles
from motionlab.segments.steps import unfound_step
from motionlab.segments.trunk_axes import METHOD as TRUNK
from motionlab.session import Session

DETERMINED, WEAK, NOT_DETERMINED = GRADES

TOLERANCE_DEG = 5.0
# a flexion peak short of the band's top by more than this is a reduced range: healthy adults'
# peaks scatter about 5° (1 SD) around it (swing knee flexion 60 ± 5°, Kadaba et al. 1989,
# J Orthop Res 7:849), so 5° told a healthy walker peaking at 59.6° "below the normal 0-65°"
REACH_TOLERANCE_DEG = 10.0
SYMMETRY_LIMIT_PCT = 10.0
SYMMETRY_MIN_ROM_DEG = 10.0

SIDE_NAMES = {"r": "right", "l": "left", "": ""}


@dataclass(frozen=True)
class GradeRow:
    """One angle's grade (:func:`grade_rows`): ``joint`` (its name), ``angle`` (``flexion``,
    ...), ``column`` (the angle table's column), ``grade`` (``determined``, ``weak``, ``not
    determined``) and ``reason`` (plain words; empty when ``determined``)."""

    joint: str
    angle: str
    column: str
    grade: str
    reason: str


@dataclass(frozen=True)
class RomRow:
    """One task's range of motion of one angle (:func:`rom_rows`): ``task``, ``joint`` (its
    name), ``joint_type``, ``side`` (``r``, ``l`` or empty), ``angle``, ``plane``, ``column``;
    ``rom_deg``, ``min_deg``, ``max_deg`` over the task (deg); ``typical_min_deg`` /
    ``typical_max_deg``: the means of the per-cycle peaks (deg); ``repetitions`` (``None``:
    counted on an angle the recording did not determine, withheld with it); ``normal``:
    the protocol's normal range ``(low, high)`` deg or ``None``; ``status``: ``within``,
    ``below``, ``above``, ``wider`` (:func:`compare`), empty when not compared (no normal range,
    or the angle not ``determined``); ``grade`` and ``reason`` (:func:`grade_rows`); ``paced``:
    a flexion range outside normal the way the walk's pace outside the norms' moves it
    (:func:`pace_explains`), or above normal in a walk whose speed was not measured
    (:func:`pace_unmeasured`), shown but not flagged."""

    task: str
    joint: str
    joint_type: str
    side: str
    angle: str
    plane: str
    column: str
    rom_deg: float
    min_deg: float
    max_deg: float
    typical_min_deg: float
    typical_max_deg: float
    repetitions: int | None
    normal: tuple[float, float] | None
    status: str
    grade: str
    reason: str
    paced: bool = False

    @property
    def flagged(self) -> bool:
        """Outside the normal range and not explained by the walk's pace."""
        return self.status not in ("within", "") and not self.paced


@dataclass(frozen=True)
class SymmetryRow:
    """Left-right symmetry of one task's range of motion (:func:`symmetry_rows`): ``task``,
    ``joint_type``, ``angle``, ``plane``; ``right_rom_deg`` / ``left_rom_deg``: typical max −
    typical min of each side (deg); ``symmetry_index_pct`` (%, NaN when not given); ``flag``:
    beyond :data:`SYMMETRY_LIMIT_PCT`; ``grade`` and ``reason``: the worse side's."""

    task: str
    joint_type: str
    angle: str
    plane: str
    right_rom_deg: float
    left_rom_deg: float
    symmetry_index_pct: float
    flag: bool
    grade: str
    reason: str


@dataclass(frozen=True)
class QualityRow:
    """One sensor's data quality (:func:`quality_rows`): ``sensor`` (label), ``serial``,
    ``segment``, ``side``; ``rate_hz`` (Hz), ``jitter_ms`` (ms), ``samples``, ``duration_s``
    (s); ``dropped_samples``; ``gaps_filled`` and ``samples_filled`` (by ingest);
    ``gaps_kept`` and ``gaps_kept_s`` (s) left as gaps; ``saturated_samples``; ``rest_pct`` and
    ``mag_disturbed_pct`` (% of the samples, NaN without a fusion result); ``channels`` (comma
    separated); ``flags``: the QC flags raised."""

    sensor: str
    serial: str
    segment: str
    side: str
    rate_hz: float
    jitter_ms: float
    samples: int
    duration_s: float
    dropped_samples: int
    gaps_filled: int
    samples_filled: int
    gaps_kept: int
    gaps_kept_s: float
    saturated_samples: int
    rest_pct: float
    mag_disturbed_pct: float
    channels: str
    flags: list[str]


@dataclass(frozen=True)
class CalibrationRow:
    """One calibration step of one segment (:func:`calibration_rows`): ``segment``,
    ``sensor``, ``method`` (the segment's fit, ``not calibrated`` without one), ``step``
    (``none`` for a segment without a measured axis), ``kind`` (``static``, ``functional``,
    ``movement``; ``nominal`` without an axis), ``rho`` and ``reference_rho`` (NaN where
    none), ``residual_deg`` (deg), ``used`` (the axis entered the fit), ``hinge_check_deg``
    (deg, NaN where not checked), ``verdict`` (an axis found in the movement: its own check's
    ``determined``, ``weak`` or ``not determined``; ``None`` for a protocol step, judged by ρ)
    and ``segment_ok`` (the segment's quality passed)."""

    segment: str
    sensor: str
    method: str
    step: str
    kind: str
    rho: float
    reference_rho: float
    residual_deg: float
    used: bool
    hinge_check_deg: float
    segment_ok: bool
    verdict: str | None = None


@dataclass
class SessionView:
    """One analysed session and its protocol, with the names the report uses."""

    session: Session
    protocol: Protocol
    path: Path | None = None
    angles: dict[str, np.ndarray] = field(default_factory=dict)  # AngleTable.columns()
    metrics: Metrics = field(default_factory=lambda: Metrics(""))
    #: the protocol's joints left out for a segment with no sensor, with those segments
    #: (:func:`motionlab.binding.unsensed_joints`): the walk's hips without a pelvis sensor
    unmeasured: list[tuple[Joint, list[str]]] = field(default_factory=list)

    @property
    def subject(self) -> str:
        subj = self.session.metadata.get("subject") or {}
        return str(subj.get("id") or subj.get("name") or "not recorded")

    @property
    def recorded_on(self) -> str | None:
        """The session's date, if known: the sensor map's ``session.date``, else the day the
        files say they were recorded (``metadata["recorded"]``: DOT ``StartTime``, x-IMU3
        ``Command.json``).

        Never the day the recording was read in (the provenance's first time): that printed a
        recording made weeks before as "Session date" today, and ordered a subject's visits by
        when they were analysed."""
        ses = self.session.metadata.get("session") or {}
        date = ses.get("date") or self.session.metadata.get("recorded")
        return str(date) if date else None

    @property
    def date(self) -> str:
        """:attr:`recorded_on`, or ``not recorded``."""
        return self.recorded_on or "not recorded"

    @property
    def date_label(self) -> str:
        """The date for a heading: :attr:`recorded_on`, or ``date not recorded``."""
        return self.recorded_on or "date not recorded"

    @property
    def folder(self) -> str:
        """The session file's folder (``motionlab run -o visit2`` gives ``visit2``), or ``""``."""
        return self.path.resolve().parent.name if self.path is not None else ""

    @property
    def visit(self) -> str:
        """The visit's label on the progress pages: the sensor map's ``session.visit`` or
        ``session.id``, else the date, else the session file's :attr:`folder` (not the same
        "not recorded" for every undated visit)."""
        ses = self.session.metadata.get("session") or {}
        label = ses.get("visit") or ses.get("id") or self.recorded_on or self.folder
        return str(label) if label else "not recorded"

    def joints(self) -> list[Joint]:
        return list(self.protocol.joints.values())

    def blocks(self) -> dict[str, tuple[float, float]]:
        """Task blocks ``{task: (start_s, end_s)}`` of the metrics, in time order."""
        blocks = self.metrics.blocks
        order = sorted(blocks, key=lambda k: blocks[k].start_s)
        return {k: (blocks[k].start_s, blocks[k].end_s) for k in order}

    def tasks(self) -> list[str]:
        """Tasks with joint metrics, in time order."""
        per_task = self.metrics.joints
        return [k for k in self.blocks() if k in per_task] + [
            k for k in per_task if k not in self.blocks()
        ]


#: stride rejections that still are walking (a stride of the wrong length, or without one
#: final contact, may span anything: a seated rest between two bouts)
WALKING_REJECTS = ("turn", "start/stop", "low confidence")


def walking_spans(view: SessionView, task: str) -> list[tuple[float, float]] | None:
    """The spans ``[(start_s, end_s)]`` of ``task``'s block covered by strides of either leg
    (the gait analysis' stride table: kept, or rejected as :data:`WALKING_REJECTS`), merged
    where they overlap; ``None`` where ``task`` is no analysed walk. A walk block also holds
    what the walker did between bouts when the protocol has one task (sitting down)."""
    g = view.session.results.gait
    block = (g.tasks or {}).get(task) if g is not None and g.ok else None
    table = g.strides if block is not None else None
    if table is None or table.stride_time_s is None:
        return None
    start, length = np.asarray(table.start_s, float), np.asarray(table.stride_time_s, float)
    walking = np.asarray(table.kept, bool) | np.isin(np.asarray(table.reason), WALKING_REJECTS)
    ok = walking & np.isfinite(start) & np.isfinite(length)
    ok &= (start >= block.start_s) & (start <= block.end_s)
    spans: list[tuple[float, float]] = []
    for a, b in sorted(zip(start[ok], start[ok] + length[ok], strict=True)):
        if spans and a <= spans[-1][1]:
            spans[-1] = (spans[-1][0], max(spans[-1][1], b))
        else:
            spans.append((float(a), float(b)))
    return spans


def in_order(keys, order: list[str]) -> list[str]:
    """``keys`` sorted by their place in ``order`` (the others after them, as they come).

    Result trees read back from a session file are in alphabetical order; the report shows
    tasks in time order, joints and segments in protocol order.
    """
    keys = list(keys)
    rank = {k: i for i, k in enumerate(order)}
    return sorted(keys, key=lambda k: (rank.get(k, len(rank)), keys.index(k)))


def joint_title(joint: Joint) -> str:
    """``Right knee``, ``Lumbar spine``; generic joints by name: ``Wrist r (hinge)``."""
    jt = JOINT_TYPES[joint.type]
    if not jt.clinical:
        return f"{joint.name.replace('_', ' ')} ({jt.display})".capitalize()
    side = SIDE_NAMES.get(joint.side, joint.side) if jt.sided else ""
    return f"{side} {jt.display}".strip().capitalize()


def segment_title(protocol: Protocol, segment: str) -> str:
    """``right thigh``, ``pelvis``: a protocol segment in words (its side, then its name
    without the side suffix)."""
    spec = protocol.segments.get(segment)
    side = SIDE_NAMES.get(spec.side, "") if spec else ""
    return f"{side} {segment.split('_')[0]}".strip()


def joint_type_title(joint_type: str) -> str:
    """``Knee``, ``Lumbar spine``: a heading for all joints of one type."""
    jt = JOINT_TYPES.get(joint_type)
    return (jt.display if jt else joint_type).capitalize()


def angle_title(joint_type: str, angle: str) -> str:
    """Short display name of an angle for sentences: ``varus-valgus``, ``axial rotation``."""
    return title(joint_type, angle).split(" (")[0]


def angle_label(joint: Joint, angle: str) -> str:
    """``Flexion-extension (sagittal)``."""
    return f"{title(joint.type, angle)} ({plane(joint, angle)})".capitalize()


def symmetric_type(joint_type: str) -> bool:
    """Left and right joints of this type are compared (types that need a side)."""
    jt = JOINT_TYPES.get(joint_type)
    return bool(jt and jt.sided)


def load_view(session: Session, protocol: Protocol | None = None, path: Path | None = None):
    """A :class:`SessionView` of an analysed session (angles and metrics present).

    ``protocol`` defaults to the one the calibration used (its file, else the packaged name);
    its joints on an optional segment without a sensor are left out, as the analysis left them
    (:func:`motionlab.binding.sensed_protocol`), and kept in :attr:`SessionView.unmeasured`.
    """
    res = session.results
    missing = [k for k in ("calibration", "angles", "metrics") if k not in res.stages()]
    if missing or res.calibration is None or res.angles is None or res.metrics is None:
        raise InputError(
            f"has no {', '.join(missing)} results",
            path,
            "results/" + missing[0],
            "analyse it first: motionlab run, or calibrate, angles and metrics",
        )
    if protocol is None:
        cal = res.calibration
        candidates = [cal.protocol_path, cal.protocol]
        for cand in [c for c in candidates if c]:
            try:
                protocol = load_protocol(cand)
                break
            except InputError:
                continue
        if protocol is None:
            raise InputError(
                f"cannot find its protocol '{cal.protocol}'",
                path,
                "results/calibration/protocol",
                "give the protocol file as protocol=",
                argument="protocol",
            )
    unsensed = unsensed_joints(protocol, session)
    unmeasured = [(protocol.joints[k], segs) for k, segs in unsensed.items()]
    protocol = sensed_protocol(protocol, session)
    return SessionView(session, protocol, path, res.angles.columns(), res.metrics, unmeasured)


def visit_labels(views: list[SessionView]) -> list[str]:
    """Each view's :attr:`SessionView.visit`, told apart where two are the same (two sessions
    on one day): with the session file's folder, else with their place in the list."""
    labels = [v.visit for v in views]
    out = list(labels)
    for i, (view, label) in enumerate(zip(views, labels, strict=True)):
        if labels.count(label) > 1:
            out[i] = f"{label} ({view.folder or i + 1})"
    return [f"{x} ({i + 1})" if out.count(x) > 1 else x for i, x in enumerate(out)]


def normal_range(protocol: Protocol, task: str, column: str) -> tuple[float, float] | None:
    """The protocol's normal range (deg) of ``column`` in ``task``, side-specific or not."""
    table = protocol.normative.get(task) or {}
    generic = column
    for side in ("_r_", "_l_"):
        generic = generic.replace(side, "_")
    rng = table.get(column) or table.get(generic)
    return (float(rng[0]), float(rng[1])) if rng else None


def _extremes(m: AngleMetrics) -> tuple[float, float]:
    """Typical extremes: the means of the per-cycle peaks, else the block's min and max."""
    if m.repetitions >= 1 and np.isfinite(m.cycle_max_mean_deg):
        return float(m.cycle_min_mean_deg), float(m.cycle_max_mean_deg)
    return float(m.min_deg), float(m.max_deg)


#: the leg model's walking speed counts as outside the norms' band only beyond this share of
#: it: its error is measured on two walkers only, within 2 % and +12 % (``length_note`` on the
#: gait page)
PACE_SPEED_MARGIN = 0.1
#: the ranges a pace outside the norms' moves a sagittal range to: a faster walk flexes and
#: extends further, a slower one less (Fukuchi et al. 2019, Syst Rev 8:153, a meta-analysis of
#: 20 studies: joint angle amplitudes grow with speed)
PACE_STATUSES = {"faster": ("above", "wider"), "slower": ("below",)}


@dataclass(frozen=True)
class PaceMismatch:
    """One pace measure of a walk outside the band of the healthy walkers the normal ranges
    come from (:func:`pace_mismatches`): ``column`` of the gait summary, its ``value``,
    ``pace`` (``faster`` or ``slower``) and the ``band`` ``(low, high)``."""

    column: str
    value: float
    pace: str
    band: tuple[float, float]


def walk_summary(view: SessionView, task: str) -> GaitSummary | None:
    """The gait summary when ``task`` is a walk the gait analysis covered,
    else ``None``."""
    g = view.session.results.gait
    if g is None or not g.ok or g.summary is None or task not in (g.tasks or {}):
        return None
    return g.summary


def pace_mismatches(view: SessionView, task: str) -> list[PaceMismatch]:
    """The walk's cadence, and its walking speed by more than :data:`PACE_SPEED_MARGIN`, where
    outside the self-selected-speed bands of ``report_data/gait_normative.yaml``; empty when
    both are within them, not measured, or ``task`` is not a walk."""
    from motionlab.report.normative import gait_bands

    summary = walk_summary(view, task)
    if summary is None:
        return []
    bands = gait_bands()["spatiotemporal"]
    out = []
    for column, margin in (("cadence_steps_per_min", 0.0),
                           ("walking_speed_m_s", PACE_SPEED_MARGIN)):  # fmt: skip
        value = float(getattr(summary, column))
        lo, hi = (float(b) for b in bands[column])
        if np.isfinite(value) and not lo * (1 - margin) <= value <= hi * (1 + margin):
            out.append(PaceMismatch(column, value, "faster" if value > hi else "slower", (lo, hi)))
    return out


def walk_pace(view: SessionView, task: str) -> str:
    """``faster`` or ``slower`` than the norms' walkers (:func:`pace_mismatches`); ``mixed``
    when one measure says faster and the other slower; empty when neither is outside."""
    paces = {m.pace for m in pace_mismatches(view, task)}
    return paces.pop() if len(paces) == 1 else ("mixed" if paces else "")


def pace_unmeasured(view: SessionView, task: str) -> bool:
    """Whether ``task`` is a walk whose speed was not measured (no subject height) and whose
    cadence lay within the norms' band: a faster pace that would explain a flexion range above
    normal can then not be ruled out (the real full-body walker, 124 steps/min, walked at
    1.8 m/s by its height)."""
    summary = walk_summary(view, task)
    return (summary is not None and not np.isfinite(float(summary.walking_speed_m_s))
            and not pace_mismatches(view, task))  # fmt: skip


def pace_explains(pace: str, angle: str, status: str) -> bool:
    """Whether a flexion range's ``status`` is the way a walk's ``pace`` moves it
    (:data:`PACE_STATUSES`): a healthy walker at 1.8 m/s was told the knee's 4–79° was above
    the normal 0–65° of walkers at 1.1–1.6 m/s. Such a range is shown, not flagged; the other
    way (a range short of the norms at a faster pace) stays flagged."""
    return angle == "flexion" and status in PACE_STATUSES.get(pace, ())


def compare(low: float, high: float, normal: tuple[float, float] | None, reach: bool) -> str:
    """``within``, ``below``, ``above`` or ``wider`` than the normal range.

    An angle is flagged when its typical extremes leave the normal range by more than
    :data:`TOLERANCE_DEG` (``above``, ``below``, both: ``wider``); with ``reach`` (the flexion
    angle) also when its typical peak falls short of the range's upper end by more than
    :data:`REACH_TOLERANCE_DEG` (``below``: a reduced range of motion). The extremes are
    compared in whole degrees, as the report prints them.
    """
    if normal is None or not (np.isfinite(low) and np.isfinite(high)):
        return ""
    lo, hi = normal
    # judged as printed (whole degrees, :func:`~motionlab.report.sentences.span`): two ranges
    # that read 4–90° got 'below' and 'within' the normal 0–100° (89.6° and 90.2°)
    low, high = round(low), round(high)
    over_top, over_bottom = high > hi + TOLERANCE_DEG, low < lo - TOLERANCE_DEG
    if over_top and over_bottom:
        return "wider"
    if over_top:
        return "above"
    if over_bottom or (reach and high < hi - REACH_TOLERANCE_DEG):
        return "below"
    return "within"


#: two-sided 95 % quantile of the normal distribution (a mean's margin: Z95 × its SE)
Z95 = 1.96
#: the largest error (deg) of a fused sensor's inclination to expect, for a thorax's lean away
#: from its neutral posture: the default smoother's worst BROAD trial without magnetic
#: disturbance, 1.42° total (07_undisturbed_fast_rotation_B, docs/performance.md), rounded up
INCLINATION_ERROR_DEG = 2.0


def accuracy_bound(view: SessionView, joint_type: str, angle: str) -> float:
    """The ± bound (deg) the Expected accuracy page states for one angle of this protocol (the
    worst validation RMSE, rounded up; the larger of the simulated and the real recordings'
    where both are on file); NaN when none is."""
    from motionlab.report.normative import load_accuracy

    proto = (load_accuracy().get("protocols") or {}).get(view.protocol.name) or {}
    key = f"{joint_type}_{angle}"
    entries = [e for e in (proto.get(key), (proto.get("real") or {}).get(key)) if e]
    return max((entry_bound(e) for e in entries), default=float("nan"))


def entry_bound(entry: dict[str, Any]) -> float:
    """The ± bound (deg) of one figure of ``accuracy.yaml``: its worst RMSE (``max_rmse_deg``,
    else ``rmse_deg``), rounded up."""
    rmse = float(entry.get("rmse_deg", np.nan))
    worst = float(entry.get("max_rmse_deg", np.nan))
    return float(np.ceil(max(rmse, worst) if np.isfinite(worst) else rmse))


def clearly_above(value: float, limit: float, margin: float) -> bool:
    """Whether ``value`` exceeds ``limit`` by more than ``margin``, its own uncertainty (deg);
    an unknown margin (NaN) is never clearly above: a healthy knee's varus thrust of 3.3° was
    told it exceeded the 3° flagged, with an adduction known to ±2°."""
    return bool(np.isfinite(value) and np.isfinite(margin) and value - margin > limit)


def thrust_margin(view: SessionView, name: str, g) -> float:
    """The uncertainty (deg) of a knee's mean varus thrust (:class:`~motionlab.results.
    StanceMetrics` ``g``): its 95 % margin over the strides plus the adduction's stated accuracy
    (:func:`accuracy_bound`); NaN when no accuracy is on file."""
    joint = view.protocol.joints[name]
    n = max(int(g.strides), 1)
    sd = float(g.varus_thrust_sd_deg) if np.isfinite(g.varus_thrust_sd_deg) else 0.0
    return Z95 * sd / np.sqrt(n) + accuracy_bound(view, joint.type, "adduction")


def thrust_above(view: SessionView, name: str, g) -> bool:
    """Whether a knee's mean varus thrust clearly exceeds the protocol's limit: by more than
    its uncertainty (:func:`thrust_margin`)."""
    margin = thrust_margin(view, name, g)
    return clearly_above(float(g.varus_thrust_mean_deg), float(g.threshold_deg), margin)


def thrust_within(view: SessionView, name: str, g) -> bool:
    """Whether a knee's mean varus thrust is clearly within the protocol's limit: below it by
    more than its uncertainty (:func:`thrust_margin`). A thrust read 2.3° (27 strides) on a
    simulated knee whose true thrust was 4.1° (the skin's error, up to 1.4°) was told it was
    within the 3° flagged; an unknown margin is never clearly within."""
    margin = thrust_margin(view, name, g)
    value = float(g.varus_thrust_mean_deg)
    return bool(np.isfinite(value) and np.isfinite(margin) and value + margin < g.threshold_deg)


def trunk_above(a) -> bool:
    """Whether a trunk angle's peak (:class:`~motionlab.results.TrunkAngleStats` ``a``) clearly
    exceeds its limit: by more than :data:`INCLINATION_ERROR_DEG` (a lean of 10.2° against a
    10° limit was flagged as compensation)."""
    return clearly_above(float(a.peak_abs_deg), float(a.threshold_deg), INCLINATION_ERROR_DEG)


def grade_rows(view: SessionView) -> list[GradeRow]:
    """One row per angle column of every protocol joint: ``joint, angle, column, grade, reason``
    (:func:`motionlab.segments.grades.graded_angles`, as the stage commands print them)."""
    res = view.session.results
    method = res.angles.method if res.angles is not None else "imu"
    return [GradeRow(*row) for row in graded_angles(view.joints(), res.calibration, method)]


def angle_grades(view: SessionView) -> dict[str, tuple[str, str]]:
    """``{column: (grade, reason)}`` of every angle column (see :func:`grade_rows`)."""
    return {r.column: (r.grade, r.reason) for r in grade_rows(view)}


def angle_grade(view: SessionView, joint: str, angle: str) -> tuple[str, str]:
    """``(grade, reason)`` of one angle of a protocol joint (``determined`` when unknown)."""
    for r in grade_rows(view):
        if r.joint == joint and r.angle == angle:
            return r.grade, r.reason
    return DETERMINED, ""


def is_determined(grade: str) -> bool:
    """Whether a number of this grade may be compared, flagged, scored or stated as a finding
    (only ``determined``; a ``weak`` number is shown with its grade and described, no more)."""
    return grade == DETERMINED


def worst_grade(graded: list[tuple[str, str]]) -> tuple[str, str]:
    """The worst ``(grade, reason)`` of several; ``determined`` for none."""
    worst = (DETERMINED, "")
    for g in graded:
        if GRADES.index(g[0]) > GRADES.index(worst[0]):
            worst = g
    return worst


def segment_grade(view: SessionView, segment: str) -> tuple[str, str]:
    """``(grade, reason)`` of one segment's whole frame (for the metrics of a segment alone,
    such as trunk compensation); ``determined`` for a session without grades."""
    cal = view.session.results.calibration
    if cal is None or not cal.grades:
        return DETERMINED, ""
    return _frame_grade(segment, cal.segments.get(segment))


def grade_mark(grade: str, reason: str = "") -> str:
    """What follows a number of a graded angle: ``""`` (determined), ``"(weak: <reason>)"``,
    ``"(not determined)"``; without ``reason`` just the grade in brackets."""
    if grade == DETERMINED:
        return ""
    return f"({grade}: {reason})" if reason and grade == WEAK else f"({grade})"


def cycles_counted(task, joint, grades: dict) -> bool:
    """Whether ``joint``'s cycles in ``task`` were counted on something the recording
    determined: a walk's knees and hips count their leg's strides (the shank's gyroscope);
    other joints and tasks the repetitions of the joint's primary angle
    (:func:`~motionlab.kinematics.metrics.primary_plane`), whose grade then decides (the real
    full-body arm's elbows showed "5 cycles" of an elbow flexion not determined)."""
    from motionlab.kinematics.metrics import primary_plane

    if task is not None and task.is_gait and joint.type in ("knee", "hip"):
        return True
    column = angle_columns(joint)[primary_plane(joint, task)][1]
    return grades.get(column, (DETERMINED, ""))[0] != NOT_DETERMINED


def rom_rows(view: SessionView) -> list[RomRow]:
    """One row per task, joint and angle (see the module docstring)."""
    grades = angle_grades(view)
    rows = []
    tasks = {t.name: t for t in view.protocol.tasks}
    for task in view.tasks():
        per_col = view.metrics.joints[task]
        pace = walk_pace(view, task) or ("faster" if pace_unmeasured(view, task) else "")
        for joint in view.joints():
            counted = cycles_counted(tasks.get(task), joint, grades)
            for angle, col in angle_columns(joint):
                m = per_col.get(col)
                if m is None:
                    continue
                low, high = _extremes(m)
                normal = normal_range(view.protocol, task, col)
                grade, reason = grades.get(col, (DETERMINED, ""))
                status = compare(low, high, normal, angle == "flexion")
                status = status if is_determined(grade) else ""
                if tasks.get(task) is not None and tasks[task].is_gait and not m.repetitions:
                    status = ""  # a walk block without one stride is no walk to compare (a
                    # calibration period found as the walk: '-1 to 90° during gait, above')
                rows.append(
                    RomRow(
                        task=task,
                        joint=joint.name,
                        joint_type=joint.type,
                        side=joint.side,
                        angle=angle,
                        plane=plane(joint, angle),
                        column=col,
                        rom_deg=float(m.rom_deg),
                        min_deg=float(m.min_deg),
                        max_deg=float(m.max_deg),
                        typical_min_deg=low,
                        typical_max_deg=high,
                        repetitions=int(m.repetitions) if counted else None,
                        normal=normal,
                        status=status,
                        grade=grade,
                        reason=reason,
                        paced=pace_explains(pace, angle, status),
                    )
                )
    return rows


def symmetry_rows(view: SessionView) -> list[SymmetryRow]:
    """Left-right symmetry index per task and angle, for joints present on both sides."""
    by_key = {(r.task, r.joint_type, r.angle, r.side): r for r in rom_rows(view)}
    rows = []
    for (task, jtype, angle, side), right in by_key.items():
        left = by_key.get((task, jtype, angle, "l"))
        if side != "r" or left is None or not symmetric_type(jtype):
            continue
        r = right.typical_max_deg - right.typical_min_deg
        l = left.typical_max_deg - left.typical_min_deg
        mean = 0.5 * (r + l)
        si = 100.0 * (r - l) / mean if mean >= SYMMETRY_MIN_ROM_DEG else float("nan")
        grade, reason = worst_grade([(right.grade, right.reason), (left.grade, left.reason)])
        if not is_determined(grade):
            si = float("nan")
        rows.append(
            SymmetryRow(
                task=task,
                joint_type=jtype,
                angle=angle,
                plane=right.plane,
                right_rom_deg=r,
                left_rom_deg=l,
                symmetry_index_pct=si,
                flag=bool(np.isfinite(si) and abs(si) > SYMMETRY_LIMIT_PCT),
                grade=grade,
                reason=reason,
            )
        )
    return rows


def _share(mask: Any) -> float:
    m = np.asarray(mask, dtype=bool) if mask is not None else np.zeros(0, bool)
    return float(100.0 * m.mean()) if m.size else float("nan")


def _spans_s(spans: list) -> float:
    return float(sum(b - a for a, b in spans)) if spans else 0.0


def quality_rows(view: SessionView) -> list[QualityRow]:
    """Per sensor: placement, rate, jitter, gaps, saturation, rest and magnetic disturbance."""
    fusion = view.session.results.fusion
    rows = []
    for label, s in view.session.sensors.items():
        qc = s.qc or {}
        fz = fusion.get(label)
        sat = qc.get("saturated_samples", {}) or {}
        flags = sorted(k for k, v in (qc.get("flags") or {}).items() if v)  # as the file keeps them
        rows.append(
            QualityRow(
                sensor=label,
                serial=s.serial,
                segment=s.segment,
                side=s.side,
                rate_hz=float(s.rate_hz),
                jitter_ms=float(qc.get("jitter_ms", np.nan)),
                samples=int(s.n_samples),
                duration_s=float(s.duration_s),
                dropped_samples=int(qc.get("dropped_samples", 0)),
                gaps_filled=int(qc.get("gaps_filled", 0)),
                samples_filled=int(qc.get("samples_filled", 0)),
                gaps_kept=len(qc.get("gaps", [])),
                gaps_kept_s=_spans_s(qc.get("gaps", [])),
                saturated_samples=int(sum(sat.values())),
                rest_pct=_share(fz.rest if fz else None),
                mag_disturbed_pct=_share(fz.mag_disturbed if fz else None),
                channels=",".join(s.channels),
                flags=flags,
            )
        )
    return rows


#: quality flags about the magnetometer alone (:mod:`motionlab.qc`)
MAG_FLAGS = frozenset({"mag_scale_assumed", "mag_norm_out_of_range"})


def raised_flags(view: SessionView) -> dict[str, list[str]]:
    """``{sensor: quality flags}`` the report raises: the sensor's flags (:func:`quality_rows`)
    less the magnetometer's where its orientation was estimated without it (6-D), which they
    cannot touch; sensors with none left out. A seated trunk report listed "mag scale
    assumed" for every sensor of a 6-D run under "Quality checks raised"."""
    fusion = view.session.results.fusion
    out = {}
    for row in quality_rows(view):
        entry = fusion.get(row.sensor)
        unused = entry is not None and not entry.magnetometer
        flags = [f for f in row.flags if not (unused and f in MAG_FLAGS)]
        if flags:
            out[row.sensor] = flags
    return out


def _segment_ok(seg: str, res: SegmentRecord | None) -> bool:
    """Whether a segment's calibration passed its quality checks and determined its frame at
    least in part (false without one): the real full-body arm's thorax passed its checks while
    its frame, one measured axis against a contradicted placement hint, was not determined,
    and read "ok" beside a trunk compensation "not determined" for that reason."""
    if res is None or res.quality is None or not res.quality.ok:
        return False
    return _frame_grade(seg, res)[0] != NOT_DETERMINED


def _no_axis_row(view: SessionView, seg: str, res: SegmentRecord | None) -> CalibrationRow:
    """The one row of a segment without a measured axis (``nominal``) or without a calibration."""
    return CalibrationRow(
        segment=seg,
        sensor=(res.sensor if res else None) or sensor_for_segment(view.session, seg) or "",
        method=res.method if res else "not calibrated",
        step="none",
        kind="nominal" if res else "",
        rho=float("nan"),
        reference_rho=float("nan"),
        residual_deg=float("nan"),
        used=False,
        hinge_check_deg=float("nan"),
        segment_ok=_segment_ok(seg, res),
    )


def calibration_rows(view: SessionView) -> list[CalibrationRow]:
    """Per segment and calibration step: method, ρ, reference ρ and the residual angle.

    Every protocol segment with a sensor has at least one row: a segment whose calibration
    measured no axis (method ``nominal``: the placement hint only), or that has no calibration
    at all, gets one row with step ``none`` (and ``segment_ok`` from its quality, else false).
    """
    cal = view.session.results.calibration
    segments = cal.segments if cal is not None else {}
    order = [
        s
        for s in view.protocol.segments
        if s in segments or (cal is not None and sensor_for_segment(view.session, s) is not None)
    ]
    steps = [s.name for s in view.protocol.calibration]
    rows = []
    for seg in order + [s for s in segments if s not in order]:
        res = segments.get(seg)
        axes = res.axes if res else {}
        if not axes:
            rows.append(_no_axis_row(view, seg, res))
        for step in sorted(axes, key=lambda k: steps.index(k) if k in steps else len(steps)):
            a = axes[step]
            ref, residual, check = a.reference_rho, a.residual_deg, a.hinge_check_deg
            rows.append(
                CalibrationRow(
                    segment=seg,
                    sensor=res.sensor or sensor_for_segment(view.session, seg) or "",
                    method=res.method,
                    step=step,
                    kind=a.kind,
                    # an axis found in the movement (a hinge or two-axis fit, the pelvis's
                    # forward from the walk) has its own checks, not a ρ: the weight the frame
                    # fit gives it is set by its verdict, no measurement; the trunk's is one
                    rho=float(a.rho) if a.kind != "movement" or a.method == TRUNK else np.nan,
                    reference_rho=float(ref) if ref is not None else float("nan"),
                    residual_deg=float(residual) if residual is not None else float("nan"),
                    used=a.in_fit,
                    hinge_check_deg=float(check) if check is not None else float("nan"),
                    segment_ok=_segment_ok(seg, res),
                    verdict=a.verdict if a.kind == "movement" else None,
                )
            )
    return rows


def excluded(view: SessionView) -> list[str]:
    """Plain sentences on data left out of the analysis, and why."""
    out = []
    for s in view.session.sensors.values():
        gaps = (s.qc or {}).get("gaps", [])
        if gaps:
            a, b = max(gaps, key=lambda g: g[1] - g[0])
            out.append(
                f"{s.label}: {len(gaps)} gap(s), {_spans_s(gaps):.2f} s in all (longest "
                f"{b - a:.2f} s at {a:.1f} s), longer than the "
                f"{(s.qc or {}).get('gap_max_s', 0.1):g} s that are interpolated: no angles there"
            )
        for ch, spans in (s.qc or {}).get("nan_spans", {}).items():
            out.append(f"{s.label}: {ch} not a number for {_spans_s(spans):.2f} s - not used")
        # the reader's repair of a damaged file (ingest warns of it; run --quiet does not)
        out += [f"{s.label}: {n}" for n in s.attrs.get("notes", []) if "truncated" in n]
    out += _outside_angles(view)
    cal = view.session.results.calibration or SegmentCalibration("")
    for step, rng in cal.steps.items():
        if rng is None:
            out.append(
                f"calibration step {step} {unfound_step(step, view.protocol, cal.single_pose)}"
            )
    blocks = view.blocks()
    if blocks and len(view.angles.get("time_s", [])):
        t = view.angles["time_s"]
        inside = sum(b - a for a, b in blocks.values())
        # a protocol whose calibration movement is the block measured (lumbar_seated) left
        # nothing out: '100 s of 100 s; calibration steps and rests are left out' said otherwise
        left = ("; calibration steps and rests are left out" if inside < 0.99 * (t[-1] - t[0])
                else "")  # fmt: skip
        out.append(f"metrics use the task blocks only ({inside:.0f} s of {t[-1] - t[0]:.0f} s)"
                   f"{left}")  # fmt: skip
    return out


def _outside_angles(view: SessionView) -> list[str]:
    """A sentence per analysed sensor that recorded more than :data:`OUTSIDE_S` before the
    angles start or after they end (the angles need every sensor of a joint: one that stopped
    early, as a truncated file, ends them for all)."""
    t = np.asarray(view.angles.get("time_s", []), dtype=float)
    if not len(t):
        return []
    out = []
    for seg in view.protocol.segments:
        label = sensor_for_segment(view.session, seg)
        stream = view.session.sensors.get(label) if label else None
        if stream is None or not len(stream.time):
            continue
        before, after = t[0] - stream.time[0], stream.time[-1] - t[-1]
        if before > OUTSIDE_S:
            out.append(f"{label}: {before:.1f} s recorded before the angles start "
                       f"({t[0]:.1f} s, where another sensor starts) - not used")  # fmt: skip
        if after > OUTSIDE_S:
            out.append(f"{label}: {after:.1f} s recorded after the angles end "
                       f"({t[-1]:.1f} s, where another sensor stops) - not used")  # fmt: skip
    return out


#: how much (s) of a sensor's recording outside the angles' span :func:`excluded` names
OUTSIDE_S = 1.0


def gait_profile(view: SessionView) -> MovementProfile | None:
    """The session's Movement Analysis Profile and GPS as the angles' grades allow
    (:func:`motionlab.kinematics.gps.gated_profile` with this session's grades and kept strides:
    a session analysed before the gating, or whose grades changed since, is gated here); None
    without a gait analysis."""
    g = view.session.results.gait
    if g is None or not g.ok or g.map is None:
        return None
    counts = None
    if g.strides is not None and len(g.strides.kept):
        kept = np.asarray(g.strides.kept, dtype=bool)
        sides = np.asarray(g.strides.side, dtype=str)
        counts = {s: int(np.sum(kept & (sides == s))) for s in ("r", "l")}
    cal = view.session.results.calibration
    return gated_profile(g.map, variable_grades(view.protocol, cal), counts)


def gait_result(view: SessionView) -> Gait | None:
    """The session's gait analysis, or None when there is none (or no gait was found)."""
    g = view.session.results.gait
    return g if g is not None and g.ok else None
