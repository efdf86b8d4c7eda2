"""Plain-language sentences for the report: findings, meanings of metrics, quality notes.

Numbers are rounded to whole degrees (the accuracy of wearable-sensor joint angles does not
support more) and every sentence names the side, the joint, the movement and the task, so that it
can be read on its own ("Right knee flexion range 5–52° during gait, below the normal 0–65°").

Findings obey the grade of their angle (:func:`~motionlab.report.model.grade_rows`): only a
``determined`` number is a finding (a range against its normal range, an asymmetry, a varus
thrust, a trunk compensation, an out-of-plane offset). A ``weak`` angle is described on its joint
page with its grade ("range −30 to 16° during walk (weak: <reason>)", :func:`weak_lines`), never
compared with a normal range; what the recording did not determine is said once per joint, in a
clinician's words with the one most useful remedy (:func:`missing_lines`: "Right knee:
flexion-extension not determined (axis) — walk 10 straight steps at an even pace."), the long
reasons staying on the calibration page.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.kinematics.joint_types import JOINT_TYPES, angle_names, joint_type
from motionlab.report.model import (
    NOT_DETERMINED,
    PACE_STATUSES,
    REACH_TOLERANCE_DEG,
    SIDE_NAMES,
    THORAX,
    TOLERANCE_DEG,
    WEAK,
    RomRow,
    SessionView,
    angle_grade,
    angle_title,
    calibration_rows,
    entry_bound,
    grade_rows,
    is_determined,
    joint_title,
    normal_range,
    pace_mismatches,
    quality_rows,
    rom_rows,
    segment_grade,
    segment_title,
    symmetry_rows,
    thrust_above,
    thrust_margin,
    thrust_within,
    trunk_above,
    walk_pace,
    walk_summary,
    walking_spans,
    worst_grade,
)
from motionlab.results import NOT_LINKED

#: what each out-of-plane metric means, in one sentence
MEANING = {
    "cross_talk": (
        "Cross-talk is motion the sensors report in the other planes while the joint moves in "
        "one plane; it holds the joint's own coupled motion too (e.g. a knee's screw-home "
        "rotation and varus as it flexes), and values well beyond that mean the sensor axes "
        "were not aligned with the joint. 'Change' compares it with the protocol's nominal sensor "
        "placement: negative where the calibration reduced it, positive where it raised it."
    ),
    "varus_thrust": (
        "Varus thrust is the sudden increase of knee varus (bow-leg angle) just after the heel "
        "strikes the ground, measured in each stride from heel strike to the knee's "
        "loading-response flexion peak (weight acceptance, at least the first sixth of stance); "
        "a thrust of more than a few degrees is linked to "
        "progression of medial knee osteoarthritis."
    ),
    "stance_rotation": (
        "Stance rotation range is how much the shank twists on the thigh while the foot is on "
        "the ground; a larger range than usual suggests rotational laxity of the knee."
    ),
    "out_of_plane_offset": (
        "The out-of-plane offset is how far the trunk leaves the intended plane of a movement "
        "(e.g. twisting while bending forward); large values mean the movement was not performed "
        "in one plane."
    ),
    "trunk_compensation": (
        "Trunk compensation is leaning or twisting the trunk to help the arm reach; it is common "
        "after stroke or with a stiff shoulder or elbow, and healthy adults move the trunk little "
        "when reaching within arm's length."
    ),
}

TRUNK_WORDS = {"flexion": "forward lean", "lateral_bending": "side lean", "axial_rotation": "twist"}
STATUS_WORDS = {"within": "within", "below": "below", "above": "above", "wider": "wider than"}


def deg(x: float) -> str:
    """``'12°'``, ``'-3°'``, or ``'n/a'``."""
    return f"{x:.0f}°" if np.isfinite(x) else "n/a"


def span(low: float, high: float) -> str:
    """``'5–58°'``; ``'-3 to 5°'`` when an end is negative (a dash would read as a minus)."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "n/a"
    lo, hi = round(low), round(high)
    return f"{lo}–{hi}°" if lo >= 0 and hi >= 0 else f"{lo} to {hi}°"


def task_name(task: str) -> str:
    return task.replace("_", " ")


def strides_s(view: SessionView, task: str) -> float | None:
    """Seconds (s) of ``task``'s block covered by strides of either leg
    (:func:`~motionlab.report.model.walking_spans`), or ``None`` where ``task`` is no analysed
    walk."""
    spans = walking_spans(view, task)
    return None if spans is None else float(sum(b - a for a, b in spans))


def tasks_analysed(view: SessionView) -> str:
    """``'gait (21 s, 19 s of it walking), squat (11 s)'``: each task block's length, and for a
    walk how much of it its strides cover, turns and starts included (a walk block also holds
    what the walker did between bouts when the protocol has one task: sitting down); the gait
    page says how many of those strides were kept."""
    out = []
    for name, (a, b) in view.blocks().items():
        walked = strides_s(view, name)
        more = f", {walked:.0f} s of it walking" if walked is not None else ""
        out.append(f"{task_name(name)} ({b - a:.0f} s{more})")
    return ", ".join(out)


def _joint_words(joint_type: str, joint: str = "", side: str = "") -> tuple[str, str]:
    """``("right", "knee")`` of a report row's joint type, joint name and side; generic joints by
    name: ``("", "wrist r hinge")`` (by the type's name without a joint name)."""
    jt = JOINT_TYPES.get(joint_type)
    if jt is not None and not jt.clinical:
        name = str(joint or jt.name).replace("_", " ")
        if jt.display.lower() in name.lower():  # 'hinge34', not 'hinge34 hinge' (hinge angle)
            return "", name
        return "", f"{name} {jt.display}"
    words = SIDE_NAMES.get(side, "") if jt is None or jt.sided else ""
    return words, jt.display if jt is not None else joint_type


def _sign_words(row: RomRow) -> str:
    """``' (to the right +)'``: which way is positive, for a clinical joint's range with a
    negative end whose angle's name does not say it ('-15 to 14°' of lateral bending names
    neither side; flexion-extension, varus-valgus name the positive one first); else ''."""
    jt = JOINT_TYPES.get(row.joint_type)
    low = row.typical_min_deg
    if jt is None or not jt.clinical or jt.angle_names is None or not low < -0.5:  # or NaN
        return ""
    i = jt.angle_names.index(row.angle)
    sense = jt.positive[i]
    return "" if jt.titles[i].startswith(sense.removesuffix(" +")) else f" ({sense})"


def rom_sentence(row: RomRow) -> str:
    """One row of :func:`~motionlab.report.model.rom_rows` as a sentence."""
    side, joint = _joint_words(row.joint_type, row.joint, row.side)
    angle = angle_title(row.joint_type, row.angle)
    if " against " in angle:  # the title names both segments: 'trunk rotation against the chair'
        side, joint = "", ""
    text = (
        f"{side} {joint} {angle} range {span(row.typical_min_deg, row.typical_max_deg)}"
        f"{_sign_words(row)} during {task_name(row.task)}"
    ).strip()
    text = text[0].upper() + text[1:]
    if row.normal is not None and row.status:
        lo, hi = row.normal
        allowed = allowance(row)
        text += f", {STATUS_WORDS[row.status]} the normal {span(lo, hi)}"
        if short_of_reach(row):  # '3–89°, below the normal 0–100°' read as a contradiction
            allowed = f"its peak more than {REACH_TOLERANCE_DEG:g}° short of {hi:g}°"
        text += f" ({allowed})" if allowed else ""
    return text + "."


def short_of_reach(row: RomRow) -> bool:
    """Whether a range is ``below`` normal only for its peak falling short of the normal
    range's top (:func:`~motionlab.report.model.compare`'s reach), its low end within."""
    if row.status != "below" or row.normal is None:
        return False
    return round(row.typical_min_deg) >= row.normal[0] - TOLERANCE_DEG


def allowance(row: RomRow) -> str:
    """``'allowing 5°'`` for a range called within the normal one whose printed ends pass
    it (by no more than :data:`~motionlab.report.model.TOLERANCE_DEG`): 'range -14 to 40°,
    within the normal -10 to 35°' read as a contradiction; else ``''``."""
    if row.status != "within" or row.normal is None:
        return ""
    low, high = round(row.typical_min_deg), round(row.typical_max_deg)
    past = low < row.normal[0] or high > row.normal[1]
    return f"allowing {TOLERANCE_DEG:g}°" if past else ""


#: where the pace caveat (:func:`pace_note`) comes from
PACE_SOURCE = (
    "Moissenet F, Leboeuf F, Armand S. Lower limb sagittal gait kinematics can be predicted "
    "based on walking speed, gender, age and BMI. Sci Rep 2019, doi:10.1038/s41598-019-45397-4 "
    "(a walking-speed mismatch alone moves sagittal angles by more than 5°); Fukuchi CA, "
    "Fukuchi RK, Duarte M. Effects of walking speed on gait biomechanics in healthy "
    "participants: a systematic review and meta-analysis. Syst Rev 2019, "
    "doi:10.1186/s13643-019-1063-z (joint angle amplitudes grow with speed)"
)


def pace_note(view: SessionView, task: str) -> tuple[str, str]:
    """Why ``task``'s sagittal ranges may leave the normal ones for the pace alone: its walk's
    cadence or walking speed outside the band of the healthy walkers the normal ranges come
    from (:func:`~motionlab.report.model.pace_mismatches`). ``(sentence, tag)``: the finding
    that says so, and the words a range flagged in spite of it carries when the walk is faster
    by one measure and slower by the other (else empty: a range the pace explains is not
    flagged, :func:`~motionlab.report.model.pace_explains`, and one it does not explain owes it
    nothing); both empty when the pace is within the band, not measured, or ``task`` is not a
    walk."""
    found = pace_mismatches(view, task)
    if not found:
        return "", ""
    words = {
        "cadence_steps_per_min": ("{:.0f} steps/min", "{:g}–{:g}"),
        "walking_speed_m_s": ("about {:.1f} m/s", "{:g}–{:g} m/s"),
    }
    compared = ", and ".join(
        f"{words[m.column][0].format(m.value)}, {m.pace} than the "
        f"{words[m.column][1].format(*m.band)}"
        for m in found
    )
    pace = walk_pace(view, task)
    consequence = {
        "faster": "joint ranges grow with walking speed, so a flexion range above the normal "
        "one is shown but not flagged (one short of it still is)",
        "slower": "joint ranges shrink at slower speeds, so a flexion range short of the normal "
        "one is shown but not flagged (one above it still is)",
    }.get(
        pace, "joint ranges change with walking speed, so part of a flagged range may be the pace"
    )
    sentence = (
        f"{task_name(task).capitalize()} at {compared}{',' if len(found) > 1 else ''} of the "
        f"walkers the normal ranges come from: {consequence}."
    )
    return sentence, ("a pace unlike the norms'" if pace == "mixed" else "")


def first_pose(view: SessionView):
    """The protocol's first still calibration step (where the segments' frames are set), or
    ``None``."""
    return next((s for s in view.protocol.calibration if s.kind == "static"), None)


def zero_words(view: SessionView) -> str:
    """`` 0° is each joint's position in the calibration pose 'standing', where …``: the
    protocol's first still pose, where the segments' frames are set, so a seated rest held
    10° flexed reads as 0° (its trunk's '-11 to 59°' read as 11° of extension); empty for a
    protocol without one."""
    step = first_pose(view)
    if step is None:
        return ""
    pose = f"'{step.name.replace('_', ' ')}'"
    pose += f" ({step.pose})" if step.pose and step.pose != step.name else ""
    return (f" 0° is each joint's position in the calibration pose {pose}, where the segments' "
            "axes were set.")  # fmt: skip


def paced_words(view: SessionView, row: RomRow) -> str:
    """Why a range outside normal is shown but not flagged, in a few words for a table:
    ``'the pace: not flagged'``, or ``'speed not measured: not flagged'``
    (:func:`unknown_speed_tag`)."""
    return f"{'speed not measured' if unknown_speed_tag(view, row) else 'the pace'}: not flagged"


def unknown_speed_tag(view: SessionView, row: RomRow) -> str:
    """The words a flexion range above the normal one carries when its walk's speed was not
    measured (no subject height) and its cadence did not say the walk was faster than the
    norms' walkers (:func:`pace_note`): the pace that would explain it cannot be ruled out (a
    healthy walker at 1.8 m/s flexed the knee 4-79°, the normal being 0-65° at 1.1-1.6 m/s),
    so the range is shown, not flagged (:func:`~motionlab.report.model.pace_unmeasured`);
    else empty."""
    summary = walk_summary(view, row.task)
    if (row.angle != "flexion" or row.status not in PACE_STATUSES["faster"] or summary is None
            or np.isfinite(float(summary.walking_speed_m_s))):  # fmt: skip
        return ""
    return ("walking speed not measured without a subject height in the sensor map; ranges grow "
            "with it")  # fmt: skip


def angle_words(view: SessionView, joint: str, angle: str) -> str:
    """``'Right knee internal-external rotation'``, ``'Ball12 (ball joint) rotation about z'``."""
    j = view.protocol.joints[joint]
    return f"{joint_title(j)} {angle_title(j.type, angle)}"


def graded(sentence: str, grade: str, reason: str) -> str:
    """A description with its grade: as is (``determined``), else ending with
    ``(weak: <reason>)`` or ``(not determined: <reason>)``; for joint pages, never a finding."""
    if grade not in (WEAK, NOT_DETERMINED):
        return sentence
    return f"{sentence.removesuffix('.')} ({grade}{': ' + reason if reason else ''})."


def _oop_findings(view: SessionView) -> tuple[list[str], list[str]]:
    """Varus thrust, trunk compensation and out-of-plane offset, each only from determined
    angles (the varus thrust from the knee's ab-adduction, the offset from every angle of its
    joint, the trunk compensation from the thorax frame): ``(flagged, not flagged)``, a varus
    thrust within its limit or not clearly above it among the second (it led the healthy
    demo's findings)."""
    out, calm = [], []
    m = view.metrics
    for task, joints in (m.gait or {}).items():
        for name, g in joints.items():
            joint = view.protocol.joints[name]
            side = SIDE_NAMES.get(joint.side, "").capitalize()
            thrust = g.varus_thrust_mean_deg
            varus = angle_grade(view, name, "adduction")[0]
            if not np.isfinite(thrust) or not is_determined(varus):
                continue
            limit = g.threshold_deg
            if thrust_above(view, name, g):
                verdict = f"above the {limit:g}° this protocol flags"
            elif thrust > limit:  # over the limit, but not by more than its own uncertainty
                verdict = f"not clearly above the {limit:g}° flagged, given its accuracy"
            elif thrust_within(view, name, g):
                verdict = f"within the {limit:g}° this protocol flags"
            else:  # under the limit, but not by more than its own uncertainty
                verdict = (
                    f"not clearly within the {limit:g}° flagged, given its accuracy of "
                    f"±{thrust_margin(view, name, g):.1f}°"
                )
            (out if thrust_above(view, name, g) else calm).append(
                f"{side} knee varus thrust {thrust:.1f}° in stance during {task_name(task)} "
                f"({verdict}; {g.strides} strides)."
            )
    if is_determined(segment_grade(view, THORAX)[0]):
        for task, t in (m.trunk_compensation or {}).items():
            parts = [
                f"{TRUNK_WORDS[k]} up to {t.per_angle[k].peak_abs_deg:.0f}°"
                for k in TRUNK_WORDS
                if trunk_above(t.per_angle[k])
            ]
            if parts:
                out.append(
                    f"Trunk compensation during {task_name(task)}: {', '.join(parts)} away from "
                    "the neutral posture."
                )
    for task, joints in (m.out_of_plane_offset or {}).items():
        for name, o in joints.items():
            grade = worst_grade([(r.grade, r.reason) for r in grade_rows(view) if r.joint == name])[
                0
            ]
            if is_determined(grade) and o.above_pct > 0:
                out.append(
                    f"Trunk out-of-plane offset during {task_name(task)}: "
                    f"peak {o.peak_deg:.0f}°, "
                    f"above {o.threshold_deg:g}° for {o.above_pct:.0f}% of the movement."
                )
    return out, calm


def _unnormed(view: SessionView, ranges: list[RomRow]) -> list[RomRow]:
    """The ranges of a joint and task the protocol gives no normal range for (the seated
    trunk's, the trunk's lean against the chair): every plane of a joint without one dominant
    axis, the flexion of a hinge (its other angles check the hinge; a squat's knee)."""
    normed = {(r.task, r.joint) for r in ranges if r.normal is not None}
    joints = view.protocol.joints
    return [
        r for r in ranges
        if (r.task, r.joint) not in normed
        and (not joint_type(r.joint_type).hinge or r.angle == angle_names(joints[r.joint])[0])
    ]  # fmt: skip


def findings(view: SessionView, limit: int = 12) -> list[str]:
    """The main findings of one session, most important first, at most ``limit``; every one
    from ``determined`` numbers only (module docstring).

    A walk's pace outside the normal ranges' (:func:`pace_note`) comes first, then ranges
    outside normal, left-right asymmetries, out-of-plane findings that are flagged, the ranges
    within normal of the primary (flexion) angles, the out-of-plane measures within their
    limits, the determined ranges of a joint and task the protocol gives no normal range for
    (the seated trunk's: measured, compared with nothing), and data or calibration problems.
    What the recording did not determine is not a finding: see :func:`missing_lines`.
    """
    ranges = rom_rows(view)
    suspect = beyond_anatomy(view)
    rows = [r for r in ranges if r.normal is not None and is_determined(r.grade)
            and r.column not in suspect]  # fmt: skip
    outside, paced, paces = [], [], []
    for r in rows:
        if r.status in ("within", ""):
            continue
        pace, tag = pace_note(view, r.task) if r.angle == "flexion" else ("", "")
        paces += [pace] if pace else []
        tag = tag or ("" if pace else unknown_speed_tag(view, r))
        if r.paced:  # the pace outside the norms', or a speed not measured (tagged so)
            why = f" ({tag}): not flagged." if tag else ": not flagged at this pace."
            paced.append(rom_sentence(r).removesuffix(".") + why)
        else:
            sentence = rom_sentence(r)
            outside.append(sentence.removesuffix(".") + f" ({tag})." if tag else sentence)
    inside = [rom_sentence(r) for r in rows if r.status == "within" and r.angle == "flexion"]
    measured = [
        rom_sentence(r).removesuffix(".") + f" (measured; no normal range for {task_name(r.task)})."
        for r in _unnormed(view, ranges)
        if is_determined(r.grade)
        and r.column not in suspect
        and np.isfinite([r.typical_min_deg, r.typical_max_deg]).all()
    ]
    asym = []
    for s in symmetry_rows(view):
        # a flag needs a symmetry index, which needs both sides determined (symmetry_rows)
        off = any(c.startswith(f"{s.joint_type}_") and c.endswith(f"_{s.angle}_deg")
                  for c in suspect)  # fmt: skip
        if s.flag and s.angle == "flexion" and not off:  # other planes: the comparison page
            joint = _joint_words(s.joint_type)[1]
            angle = angle_title(s.joint_type, s.angle)
            asym.append(
                f"{joint.capitalize()} {angle} range during {task_name(s.task)} differs "
                f"between sides: right {s.right_rom_deg:.0f}°, left {s.left_rom_deg:.0f}° "
                f"(symmetry index {s.symmetry_index_pct:+.0f}%)."
            )
    oop, calm = _oop_findings(view)
    problems = quality_notes(view)
    items = list(dict.fromkeys(paces + outside + asym + oop + paced + inside + calm + measured))
    if len(items) > limit - len(problems[:2]):
        items = items[: limit - len(problems[:2])]
    if not items and not ranges:  # not "no normal range": the protocol may have them
        items = [
            "No finding can be stated: the recording holds none of the protocol's tasks, so "
            "there is no range of motion to describe."
        ]
    elif not items and not any(is_determined(r.grade) for r in ranges):
        items = [
            "No finding can be stated: no angle was graded determined by this recording (the "
            "weak and undetermined ones are listed below)."
        ]
    elif not items and any(r.status == "within" for r in rows):  # only secondary planes
        items = [rom_sentence(r) for r in rows if r.status == "within"]
        items = items[: limit - len(problems[:2])]
    elif not items:  # every determined angle passed its joint's anatomical range
        items = [
            "No finding can be stated: every angle the recording determined passed its joint's "
            "anatomical range; check the sensors' placement and the calibration."
        ]
    return items + problems[:2]


#: words of a grade's reason that say the hinge axis itself was not measured well
AXIS_WORDS = ("hinge", "differ", "not about", "single axis", "flexion axis", "puts the axis")

#: the trunk's flexion axis is the one it turns about most one-sidedly (segments.trunk_axes)
_TRUNK_BEND = "bend the trunk forward and back up a few times, further forward than to the sides"
#: what to do for each joint type so that its hinge axis is measured
_BEND = {
    "knee": "walk 10 straight steps at an even pace",
    "hip": "walk 10 straight steps at an even pace",
    "elbow": "bend and straighten the elbow slowly 5 times",
    "lumbar": _TRUNK_BEND,
    "trunk_lean": _TRUNK_BEND,
}


def cause_and_remedy(view: SessionView, joint_name: str, reason: str) -> tuple[str, str]:
    """``(cause, remedy)`` in a clinician's words of a grade's ``reason``
    (:mod:`motionlab.segments.grades`; its first clause, the main one):
    ``("axis", "walk 10 straight steps at an even pace")``."""
    joint = view.protocol.joints[joint_name]
    jt = JOINT_TYPES.get(joint.type)
    display = jt.display if jt is not None else joint.type
    bend = _BEND.get(joint.type, f"move the {display} slowly through its range 5 times")
    seg = next((sg for sg in (joint.proximal, joint.distal) if sg in reason), "")
    spec = view.protocol.segments.get(seg)
    where = f"{SIDE_NAMES.get(spec.side, '')} {seg.split('_')[0]}".strip() if spec else seg
    r = reason.lower().removeprefix("hinge axis from movement: ").split("; ")[0]
    if r.startswith("the accelerometer-only method"):  # segments.grades.METHOD_LIMITS
        return "the accelerometer-only method", (
            "compute the angles from the fused orientations (motionlab angles without "
            "--method accel-only)"
        )
    if "not timed against each other" in r:  # segments.grades.clock_graded: clocks as recorded
        return "the sensors' clocks were not synchronised", (
            "record with the sensors' clocks synchronised by their software (sensors that "
            "share one clock: run with --no-clock-sync)"
        )
    if "packet-loss gap" in r:  # segments.gap_headings: a hidden turn the heading keeps
        return "lost packets may have turned a sensor's heading", (
            "keep the receiver close to the subject and in sight of the sensors, so that fewer "
            "packets are lost"
        )
    if "tied only where a pose was held" in r:  # segments.grades.hold_graded: drift between
        still = first_pose(view)
        pose = (still.pose or still.name.replace("_", " ")) if still else "standing"
        if "drifting apart at" in r:  # fast: the hold shortened by the anchors' drift rate
            return "the sensors' headings drift apart fast between poses", (
                f"hold the {pose} pose still for 5 s before and after every task (each pose "
                "held ties the headings again), or calibrate the gyroscopes first (motionlab "
                "sensorcal, then --calibration)"
            )
        return "the sensors' headings drift between poses", (
            f"hold the {pose} pose still for 5 s every 2 minutes of the recording (each pose "
            "held ties the headings again)"
        )
    if "from hanging in the" in r:  # segments.arm_sides: the stand was no stand for the arm
        return "the forearm did not hang in the pose taken for the stand", (
            "record a stand before or after the movement: 5 s still, arms hanging by the sides, "
            "elbows straight, palms forward"
        )
    if "look swapped left for right" in r:  # segments.arm_sides: an elbow reads varus
        return "the arm's sensors look swapped left for right", (
            "check the sensor map: the right arm's sensors on the right arm's segments, the "
            "left's on the left"
        )
    if "sensors look swapped" in r:  # segments.trunk_axes: the spine extended as it leaned
        return "the thorax and pelvis sensors look swapped", (
            "check the sensor map: give the upper-back sensor the thorax and the lower-back "
            "sensor the pelvis"
        )
    if "axis's sign is not clear" in r:  # a trunk rest held leaning (segments.trunk_axes)
        return "direction of flexion", "rest sitting or standing upright for a few seconds"
    if "headings are tied at the rest only" in r:  # segments.trunk_axes: drift not followed
        return "the sensors' headings may drift apart", (
            "sit or stand still for 2 s during the recording (the default 6-D fusion then "
            "follows the drift), or calibrate the gyroscopes (motionlab sensorcal, then "
            "--calibration)"
        )
    if "nothing in the recording signs it" in r:  # segments.grades: a frame half a turn off?
        return f"which way the {where} sensor sits", (
            f"strap the {where} sensor as the protocol places it (see Sensors and placements)"
        )
    if "screw-home" in r:  # segments.grades._coupled_axis_grade: the shank's axis is turned
        step = r.split("record '")[1].split("'")[0] if "record '" in r else ""
        instruction = next(
            (s.instructions for s in view.protocol.calibration if s.name == step), ""
        )
        return "shank axis from the knee's own flexion", (
            f"record the optional straight-leg swings ({instruction.split('): ', 1)[-1]})"
            if instruction
            else "record a movement of the straight leg (the knee locked) for the shank's axis"
        )
    if "which way the axis points" in r or "direction of flexion" in r:
        return "direction of flexion", f"stand still 5 s with the {display} straight, then {bend}"
    if "its zero" in r:
        return "zero", f"stand still 5 s at the start with the {display} straight"
    if "axis from the walk is known to" in r:  # a walk alone: the other planes carry flexion
        return "flexion axis known only roughly", (
            f"add a seated calibration: extend the {display} fully and let it flex back 5 times"
        )
    if ("axis" in r or "axes" in r) and any(k in r for k in AXIS_WORDS):
        return "axis", bend
    if "forward direction from the walk" in r or "forward direction is from the" in r:
        # the hint was refuted and the walk replaced it (segments.grades): placing the sensor
        # again cannot help; flexion is determined when the thigh tilts little over the
        # recording (grades.HEADING_BOUND_DEG), its other planes stay weak in a stand and walk
        cause = f"forward direction of the {where} sensor from the walk"
        if "can move flexion" in r:  # flexion weak: the thigh tilted far (sitting down)
            return cause, (
                "record only the stand and the walk (no sitting down) for a determined "
                "flexion; the other planes stay weak in a stand-and-walk recording"
            )
        if "turns" in r:  # the walk did not set off straight ahead right after the stand
            return cause, (
                "set off walking straight ahead right after the stand: the first steps give "
                "the pelvis's forward direction to within 5-10°, the turns only to 5-25°"
            )
        return cause, (
            "a stand and a walk cannot do better: the steps next to the stand (the first after "
            "it, or the last before it) give the pelvis's forward direction to within 5-10°"
        )
    if "forward direction" in r or "one measured axis" in r:
        return (
            f"forward direction of the {where} sensor",
            f"place the {where} sensor exactly as the protocol says",
        )
    if "nominal placement only" in r or "has no calibration" in r:
        return f"{where} sensor not calibrated", "record the calibration: stand still 5 s first"
    if "flagged" in r:
        return f"calibration of the {where} sensor flagged", "repeat the calibration"
    return "calibration", "see the calibration page"


def missing_lines(view: SessionView) -> list[str]:
    """One line per joint with an angle that is not ``determined``: which angles, their grade
    and short cause, and the single most useful remedy (for sensors that look swapped in the
    map, else for the worst of them):
    ``'Right knee: flexion-extension not determined (axis) — walk 10 straight steps at an even
    pace.'``; one per joint left out for a segment with no sensor (``'Right hip: not measured
    (no sensor on the pelvis) — …'``); plus one line for trunk compensation from a thorax that
    is not determined."""
    lines = []
    for joint in view.joints():
        rows = [r for r in grade_rows(view) if r.joint == joint.name]
        bad = [r for r in rows if not is_determined(r.grade)]
        if not bad:
            continue
        groups: dict[tuple[str, str], list[str]] = {}
        worst = max(bad, key=lambda r: r.grade == NOT_DETERMINED)
        for r in sorted(bad, key=lambda r: r.grade != NOT_DETERMINED):
            cause = cause_and_remedy(view, joint.name, r.reason)[0]
            groups.setdefault((r.grade, cause), []).append(angle_title(joint.type, r.angle))
        what = "; ".join(
            f"{' and '.join(angles) if len(angles) < 3 else 'all angles'} {grade} ({cause})"
            for (grade, cause), angles in groups.items()
        )
        # sensors that look swapped in the map come first: the map fixed, every angle changes
        swapped = [c for r in bad for c in r.reason.split("; ") if "look swapped" in c]
        remedy = cause_and_remedy(view, joint.name, (swapped or [worst.reason])[0])[1]
        lines.append(f"{joint_title(joint)}: {what} — {remedy}.")
    for joint, segments in view.unmeasured:
        names = " and ".join(segment_title(view.protocol, s) for s in segments)
        lines.append(
            f"{joint_title(joint)}: not measured (no sensor on the {names}) — strap one "
            f"{'there' if len(segments) == 1 else 'on each'} to measure it."
        )
    trunk, why = segment_grade(view, THORAX)
    if view.metrics.trunk_compensation and not is_determined(trunk):
        lines.append(f"Trunk compensation: {trunk} ({why}) — record the calibration.")
    return lines


def weak_lines(view: SessionView, joint: str) -> list[str]:
    """Descriptions of a joint's ``weak`` ranges for its page, one sentence per task and reason,
    not compared with the normal range: ``'Right hip flexion-extension range -13 to 41° and
    ab-adduction range -13 to 5° during walk (weak: <reason>).'``."""
    groups: dict[tuple[str, str], list[RomRow]] = {}
    for r in rom_rows(view):
        if r.joint == joint and r.grade == WEAK:
            groups.setdefault((r.task, r.reason), []).append(r)
    out = []
    for (task, reason), rows in groups.items():
        side, name = _joint_words(rows[0].joint_type, rows[0].joint, rows[0].side)
        parts = [
            f"{angle_title(r.joint_type, r.angle)} range "
            f"{span(r.typical_min_deg, r.typical_max_deg)}"
            for r in rows
        ]
        ranges = ", ".join(parts[:-1]) + " and " + parts[-1] if len(parts) > 1 else parts[0]
        text = f"{side} {name} {ranges} during {task_name(task)}".strip()
        out.append(graded(text[0].upper() + text[1:] + ".", WEAK, reason))
    return out


def quality_notes(view: SessionView) -> list[str]:
    """Sentences on data and calibration problems, most important first (calibration, clocks
    the sync could not check, a sensor the map names that the recording lacks, saturation,
    magnetic disturbance, then gaps, the longest loss first); empty when all is well."""
    notes: list[str] = []
    gaps: list[tuple[float, str]] = []
    bad = sorted({r.segment for r in calibration_rows(view) if not r.segment_ok})
    if bad:
        notes.append(
            f"Calibration of {', '.join(bad)} needs attention (see the calibration page); "
            "angles involving it are less certain."
        )
    unchecked = unchecked_clocks(view)
    walks = {t.name for t in view.protocol.tasks if t.is_gait}
    if unchecked:
        legs = " and the gait numbers comparing the legs are withheld" if walks else ""
        notes.append(
            f"Clock{'s' if len(unchecked) > 1 else ''} of {', '.join(unchecked)} not "
            "synchronised (no reliable timing in the recording, see 'Sensor clocks'): taken as "
            "recorded, so the angles between sensors not timed against each other are weak at "
            f"best where they turn fast{legs} (an offset moves an angle by 3° per 10 ms at "
            "300°/s); sensors that share one clock: run with --no-clock-sync."
        )
    notes += list(beyond_anatomy(view).values())
    g = view.session.results.gait
    if g is not None and not g.ok and walks:  # the gait pages went missing with no word why
        spans = ", ".join(f"{task_name(k)} {a:.0f}–{b:.0f} s"
                          for k, (a, b) in view.blocks().items() if k in walks)  # fmt: skip
        notes.append(
            f"No gait analysis: {g.status.removeprefix('no gait: ')}"
            + (f" in the walk found at {spans}" if spans else "")
            + "; check that the walk is where the recording has it (a task's time_range)."
        )
    for entry in view.session.metadata.get("map_unmatched", []):
        segment = f" ({entry['segment']})" if entry.get("segment") else ""
        notes.append(
            f"The sensor map's '{entry['key']}'{segment} named no sensor in the recording; "
            "angles that need it are left out."
        )
    for q in quality_rows(view):
        if q.gaps_kept:
            text = (
                f"Sensor {q.sensor} lost {q.gaps_kept_s:.1f} s of data in "
                f"{q.gaps_kept} gap(s); no angles are reported there."
            )
            gaps.append((q.gaps_kept_s, text))
        if q.saturated_samples:
            notes.append(
                f"Sensor {q.sensor} reached its measuring range on {q.saturated_samples} "
                "samples; fast movements there may be underestimated."
            )
        if np.isfinite(q.mag_disturbed_pct) and q.mag_disturbed_pct > 20:
            notes.append(
                f"The magnetic field near sensor {q.sensor} was disturbed "
                f"{q.mag_disturbed_pct:.0f}% of the time (metal or electronics nearby)."
            )
    # the longest loss first: the findings keep two notes (a thigh's 360 s went unsaid
    # behind a pelvis's 0.6 s, listed first as its sensor came first)
    return notes + [text for _, text in sorted(gaps, key=lambda g: -g[0])]


def unchecked_clocks(view: SessionView) -> list[str]:
    """The sensors whose clock the sync could check against no other (their fit ``not
    reliable``, or too little shared movement: kept as recorded, following their reference's),
    in the sync's order; none when the session was not synchronised (``--no-clock-sync``: the
    user takes the clocks as one) or the vendor's synchronisation was kept. A part of the body
    on a clock of its own (``not linked``, the legs without a pelvis sensor) is said where it
    matters, by the numbers across the legs withheld."""
    sync = view.session.results.clock_sync
    fits = sync.fits.values() if sync is not None else []
    return [f.sensor for f in fits if not f.timed and not f.status.startswith(NOT_LINKED)]


#: how far (deg) an angle may pass the joint's anatomical range before it is called beyond it:
#: the ranges are those of the average adult, and skin motion adds a few degrees
ANATOMY_TOLERANCE_DEG = 10.0


def beyond_anatomy(view: SessionView) -> dict[str, str]:
    """``{angle column: sentence}`` for every angle (not graded not determined) that passed the
    joint's anatomical range (the protocol's ``normative.range_of_motion``, e.g. elbow flexion
    -10 to 145°) by more than :data:`ANATOMY_TOLERANCE_DEG` in a task: no joint moves so, the
    sensors or their calibration do (a sensor slipped, the wrong segment or side). Such an
    angle states no finding (:func:`findings`)."""
    out: dict[str, str] = {}
    for r in rom_rows(view) if view.metrics is not None else []:
        limits = normal_range(view.protocol, "range_of_motion", r.column)
        if limits is None or r.grade == NOT_DETERMINED or r.column in out:
            continue
        lo, hi = limits
        past = [x for x in (r.min_deg, r.max_deg) if np.isfinite(x)
                and not lo - ANATOMY_TOLERANCE_DEG <= x <= hi + ANATOMY_TOLERANCE_DEG]  # fmt: skip
        if past:
            worst = max(past, key=lambda x: max(lo - x, x - hi))
            out[r.column] = (
                f"{angle_words(view, r.joint, r.angle)} reached {worst:.0f}° during "
                f"{task_name(r.task)}, beyond the joint's anatomical range {span(lo, hi)}: "
                "check the sensors' placement and the calibration; no finding is stated from "
                "this angle."
            )
    return out


def accuracy_sentence(angle: str, entry: dict[str, Any], joint_type: str = "") -> str:
    """``'flexion-extension: ±2° (RMSE 1.4°, worst 1.9°)'``; ``joint_type`` names the angle
    (default: the first clinical type that has it)."""
    rmse = float(entry.get("rmse_deg", np.nan))
    worst = float(entry.get("max_rmse_deg", np.nan))
    if not joint_type:
        known = (t.name for t in JOINT_TYPES.values() if t.angle_names and angle in t.angle_names)
        joint_type = next(known, "")
    name = angle_title(joint_type, angle)
    text = f"{name}: ±{entry_bound(entry):.0f}° (RMSE {rmse:.1f}°"
    # two decimals: a worst case of 1.04° is rounded up to ±2°, and "1.0" would not show why
    text += f", worst case {worst:.2f}°" if np.isfinite(worst) else ""
    dropped, runs = int(entry.get("not_determined", 0)), int(entry.get("runs", 0))
    if dropped:  # those runs' angle was not drawn: its error is not one a reader meets
        text += f"; not determined in {dropped} of {dropped + runs} runs, which are not counted"
    return text + ")"


def real_accuracy_sentence(angle: str, entry: dict[str, Any], joint_type: str) -> str:
    """``'flexion-extension: ±2° (offset-free RMSE 1.8° median, worst 1.9° over 5 recordings;
    2.0° with the offset; graded determined in 3 of 5)'``: a ``real`` figure of
    ``accuracy.yaml`` (median and worst offset-free RMSE over real recordings against an
    optical reference); ``angle`` ``rotation_from_rest`` is the joint's rotation away from the
    rest pose."""
    rmse = float(entry.get("rmse_deg", np.nan))
    worst = float(entry.get("max_rmse_deg", np.nan))
    runs = int(entry.get("runs", 0))
    name = (
        "rotation away from the rest pose (any direction)"
        if angle == "rotation_from_rest"
        else angle_title(joint_type, angle)
    )
    text = (
        f"{name}: ±{entry_bound(entry):.0f}° (offset-free RMSE {rmse:.1f}° median, "
        f"worst {worst:.1f}° over {runs} recordings"
    )
    if "with_offset_deg" in entry:
        text += f"; {float(entry['with_offset_deg']):.1f}° with the offset"
    if "determined" in entry:
        text += f"; graded determined in {int(entry['determined'])} of {runs}"
    return text + ")"
