"""A check that cannot be fooled: over degraded sessions, no finding, score or red value comes from
a weak or undetermined input, and no mean from fewer than 3 steady strides (issue 27).

One simulated walk (stand, then walk with turns; pelvis, thighs, shanks) is analysed once per
module; the degraded cases are built from it: its pelvis has no measured forward direction (its
frame is one measured axis and the placement hint: hips and pelvis weak), a knee whose hinge axis
the movement contradicts (its flexion forced ``not determined``), a pelvis not calibrated at all
(regraded by :func:`motionlab.segments.grades.grade_joints`), a walk cut to two strides, a walk
cut around one turn, and the shank sensors swapped left for right (analysed again). The same
checks run over the real recordings in ``shared/datasets/human`` when present.

:func:`problems` reads only what the report prints (the findings, the rendered summary, gait and
joint pages: their texts, red cells and drawn curves) and the grades, strides and events behind
them, so that it holds whatever the implementation.
"""

import copy
import re
from dataclasses import replace

import matplotlib
import numpy as np
import pytest
from conftest import SHARED

from motionlab.protocol import load_protocol
from motionlab.report.model import grade_rows, load_view, segment_grade
from motionlab.report.pdf import FLAG_COLOUR, RC, Document
from motionlab.report.sentences import angle_words, findings
from motionlab.results import StrideTable

MIN = 3  # steady strides per side (and paired steps) before a number is given
HUMAN = SHARED / "datasets" / "human"
GPS_NUMBER = re.compile(r"GPS: right \d|overall \d+\.\d°|GPS \d+\.\d deg")


def _analysed(seed: int = 0, swap: bool = False):
    from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
    from motionlab.simulate import simulate

    proto = load_protocol("walk")
    session, _ = simulate(proto, 40.0, seed, "clean", rate_hz=60.0, gait="normal")
    if swap:  # the right shank's sensor data under the left shank's label and back
        a, b = session.sensors["shank_r"], session.sensors["shank_l"]
        for attr in ("time", "acc", "gyr", "mag", "quat"):
            va, vb = getattr(a, attr), getattr(b, attr)
            setattr(a, attr, vb)
            setattr(b, attr, va)
    prepare_sensors(session)
    analyse(session, PipelineOptions(proto, progress=False, clock_sync=False))
    return session


@pytest.fixture(scope="module")
def walk():
    return _analysed()


def _regait(session, start: float, end: float):
    """The session with its walk block cut to ``start``-``end`` s and gait analysed again."""
    from motionlab.kinematics.gait import analyse_gait

    ses = copy.deepcopy(session)
    blocks = ses.results.metrics.blocks
    blocks["walk"] = replace(blocks["walk"], start_s=float(start), end_s=float(end))
    ses.results.gait = analyse_gait(ses, load_protocol("walk"))
    return ses


def _force(session, joint: str, k: int, grade: str, reason: str):
    ses = copy.deepcopy(session)
    entry = ses.results.calibration.grades[joint]
    entry.grades[k], entry.reasons[k] = grade, reason
    return ses


def _pelvis_nominal(session):
    from motionlab.segments.grades import grade_joints

    ses = copy.deepcopy(session)
    cal = ses.results.calibration
    cal.segments["pelvis"] = replace(cal.segments["pelvis"], method="nominal")
    cal.grades = grade_joints(load_protocol("walk"), cal)
    return ses


# --------------------------------------------------------------------------------- the check


def _paired_steps(strides: StrideTable) -> int:
    """Pairs of consecutive steps (onto the right, then onto the left) inside one steady bout,
    counted from the stride table's events alone: every stride that bounds a step is kept."""
    side = np.asarray(strides.side, str)
    start = np.asarray(strides.start_s, float)
    kept = np.asarray(strides.kept, bool)
    stride = np.asarray(strides.stride_time_s, float)
    end = start + stride

    def bout(s: str, t: float) -> bool:
        """The other side's last stride starting before ``t`` is kept and runs past ``t``."""
        o = (side != s) & (start < t)
        if not o.any():
            return False
        j = np.flatnonzero(o)[np.argmax(start[o])]
        return bool(kept[j] and end[j] >= t - 1e-9)

    n = 0
    for i in np.flatnonzero((side == "r") & kept):
        nxt = (side == "l") & (start > start[i])
        if not nxt.any() or not bout("r", start[i]):
            continue
        j = np.flatnonzero(nxt)[np.argmin(start[nxt])]
        n += bool(kept[j] and start[j] < end[i] and bout("l", start[j]))
    return n


def _red_rows(fig) -> list[tuple[str, str, float]]:
    """``(row text, red text, x)`` of every red (flagged) cell on a page."""
    red = [t for t in fig.texts if t.get_color() == FLAG_COLOUR and t.get_text().strip()]
    out = []
    for t in red:
        y = t.get_position()[1]
        row = [u for u in fig.texts if abs(u.get_position()[1] - y) < 1e-6]
        row.sort(key=lambda u: u.get_position()[0])
        out.append((" | ".join(u.get_text() for u in row), t.get_text(), t.get_position()[0]))
    return out


def _header_x(fig, name: str) -> float | None:
    for t in fig.texts:
        if t.get_text() == name and t.get_weight() == "bold":
            return t.get_position()[0]
    return None


def _cells(fig, x: float | None) -> list[str]:
    """The texts of one right-aligned table column (its header's x) on a page."""
    if x is None:
        return []
    return [t.get_text() for t in fig.texts if abs(t.get_position()[0] - x) < 1e-6]


def _row(fig, label: str) -> str:
    """The texts of the table row that starts with ``label``, joined."""
    for t in fig.texts:
        if t.get_text().startswith(label):
            y = t.get_position()[1]
            row = [u for u in fig.texts if abs(u.get_position()[1] - y) < 1e-6]
            return " | ".join(u.get_text() for u in sorted(row, key=lambda u: u.get_position()[0]))
    return ""


def _variable_grades(view) -> dict[str, str]:
    """``{'r_hip_flexion': grade, ...}`` of the GPS's variables, straight from the grades."""
    out = {}
    for r in grade_rows(view):
        j = view.protocol.joints[r.joint]
        if j.type in ("hip", "knee") and f"{j.type}_{r.angle}" in (
            "hip_flexion",
            "hip_adduction",
            "hip_rotation",
            "knee_flexion",
        ):
            out[f"{j.side}_{j.type}_{r.angle}"] = r.grade
    cal = view.session.results.calibration
    if "pelvis" in view.protocol.segments and cal is not None and "pelvis" in cal.segments:
        out["pelvis"] = segment_grade(view, "pelvis")[0]
    return out


def _pages(view, joints: bool):
    from motionlab.report.pages_gait import gait_report_pages
    from motionlab.report.pages_joint import joint_pages
    from motionlab.report.pages_summary import summary_page

    with matplotlib.rc_context(RC):
        doc = Document("motionlab report · test", "subject X")
        summary_page(doc, view)
        gait_report_pages(doc, view)
        if joints:
            joint_pages(doc, view)
    return doc.pages


def problems(session, joints: bool = True) -> list[str]:
    """Everything the report says that its inputs do not allow (empty: the report obeys)."""
    view = load_view(session)
    out = []
    bad = {(r.joint, r.angle): r.grade for r in grade_rows(view)}
    bad = {k: g for k, g in bad.items() if g != "determined"}
    items = findings(view)
    # 1. findings only from determined planes (a weak or undetermined angle is never a bullet)
    for (joint, angle), grade in bad.items():
        words = angle_words(view, joint, angle).lower()
        out += [f"finding from a {grade} angle: {f}" for f in items if words in f.lower()]
        j = view.protocol.joints[joint]
        if j.type == "knee" and angle == "adduction":
            side = {"r": "right", "l": "left"}[j.side]
            out += [f"varus thrust from a {grade} plane: {f}" for f in items
                    if f.lower().startswith(f"{side} knee varus thrust")]  # fmt: skip
    # 2. symmetry only from planes determined on both sides
    for f in items:
        if "differs between sides" in f:
            for (joint, angle), grade in bad.items():
                j = view.protocol.joints[joint]
                words = angle_words(view, joint, angle).lower().split(" ", 1)[1]
                if f.lower().startswith(words):
                    out.append(f"symmetry from a {grade} angle: {f}")
    pages = _pages(view, joints)
    from motionlab.report.pdf import page_text

    text = "\n".join(page_text(p) for p in pages)
    g = session.results.gait
    if g is not None and g.ok:
        # 3. GPS only when every variable is determined and each side has enough strides
        grades = _variable_grades(view)
        weak = sorted(k for k, v in grades.items() if v != "determined")
        kept = np.asarray(g.strides.kept, bool)
        side = np.asarray(g.strides.side, str)
        few = [s for s in "rl" if np.sum(kept & (side == s)) < MIN]
        if (weak or few) and GPS_NUMBER.search(text):
            out.append(f"GPS printed with {weak or few} not determined or too few strides")
        # 4. spatio-temporal: no mean from fewer than MIN strides, no asymmetry from fewer
        # than MIN paired steps, no red value without enough strides
        pairs = _paired_steps(g.strides)
        for p in pages:
            if "spatio-temporal" not in " ".join(t.get_text() for t in p.texts):
                continue
            xs = {s: _header_x(p, n) for s, n in (("r", "right"), ("l", "left"))}
            for row, _cell, x in _red_rows(p):
                s = "r" if xs["r"] is not None and abs(x - xs["r"]) < 1e-6 else "l"
                if "asymmetry" in row and pairs < MIN:
                    out.append(f"red asymmetry from {pairs} paired steps: {row}")
                elif "asymmetry" not in row and np.sum(kept & (side == s)) < MIN:
                    out.append(f"red value from {np.sum(kept & (side == s))} strides: {row}")
            for s in "rl":
                n = int(np.sum(kept & (side == s)))
                cells = [c for c in _cells(p, xs[s]) if "±" in c]
                if n < MIN and cells:
                    out.append(f"means printed from {n} strides ({s}): {cells[0]}")
            asym = _row(p, "step-time asymmetry")
            if pairs < MIN and re.search(r"\d+\.\d", asym):
                out.append(f"asymmetry printed from {pairs} paired steps: {asym}")
    # 5. red cells of the joint pages only on determined rows
    for p in pages:
        for row, _cell, _ in _red_rows(p):
            if "weak" in row.split(" | ")[-1] or "not determined" in row.split(" | ")[-1]:
                out.append(f"red value of a graded angle: {row}")
    # 6. an undetermined plane is not drawn as a curve
    for p in pages:
        for ax in p.axes:
            if "not determined" in ax.get_title(loc="left") or (
                "not determined" in ax.get_title() and "right" not in ax.get_title()
            ):
                drawn = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 2]
                if drawn:
                    out.append(f"curve drawn for an undetermined plane: {ax.get_title(loc='left')}")
    return out


# --------------------------------------------------------------------------------- the cases


def test_pelvis_without_forward_direction(walk):
    grades = {r.column: r.grade for r in grade_rows(load_view(walk))}
    assert grades["hip_r_adduction_deg"] != "determined"  # the case is what it says
    assert problems(walk) == []


def test_knee_with_a_wrong_axis(walk):
    why = "hinge axis from movement: the axis differs by up to 35° between parts of the movement"
    ses = _force(walk, "knee_r", 0, "not determined", why)
    assert problems(ses) == []
    view = load_view(ses)
    from motionlab.report.sentences import missing_lines

    line = next(m for m in missing_lines(view) if m.startswith("Right knee"))
    assert line.startswith("Right knee: flexion-extension not determined (axis)"), line
    assert line.endswith(" — walk 10 straight steps at an even pace."), line


def test_what_to_repeat_lists_the_angles_left_weak_or_not_determined(walk):
    """The calibration page said "none: every segment was calibrated within the quality
    limits" under "what to repeat next time" beside a weak lumbar rotation whose remedy the
    summary gave: the joints with such angles are listed there too, with the same remedy."""
    from motionlab.report.pages_quality import repeat_lines
    from motionlab.report.sentences import missing_lines

    why = "hinge axis from movement: the axis differs by up to 35° between parts of the movement"
    view = load_view(_force(walk, "knee_r", 0, "not determined", why))
    lines = repeat_lines(view, view.session.results.calibration)
    assert set(missing_lines(view)) <= set(lines)
    assert any(x.startswith("Right knee: flexion-extension not determined") for x in lines)
    assert not any(x.startswith("none") for x in lines)


def test_a_two_axis_fit_whose_parts_disagree_is_an_axis_problem(walk):
    """The real full-body elbows ('the axes differ by up to 10° between parts of the movement',
    a two-axis fit) were told only 'see the calibration page': the plural missed the axis
    words. They are an axis problem, with its movement as the remedy."""
    from motionlab.report.sentences import cause_and_remedy

    why = "hinge axis from movement: the axes differ by up to 10° between parts of the movement"
    cause, remedy = cause_and_remedy(load_view(walk), "knee_r", why)
    assert (cause, remedy) == ("axis", "walk 10 straight steps at an even pace")


def test_a_pelvis_forward_direction_from_the_walk_is_not_told_to_move_the_sensor(walk):
    """The real full-body walker's hips (pelvis forward direction from the walk's turns, as it was
    before the first steps came first) were
    told 'place the pelvis sensor exactly as the protocol says', under a walk protocol whose
    pelvis goes 'anywhere, any orientation': a new placement cannot help there."""
    from motionlab.report.sentences import missing_lines

    ses = _force(walk, "hip_r", 0, "weak", "pelvis's forward direction from the walk may be 20° "
                 "off, which can move flexion by 5° where thigh_r tilts 82°")  # fmt: skip
    turns = "pelvis's forward direction is from the walk's turns (often 5-25° off)"
    for k in (1, 2):
        ses = _force(ses, "hip_r", k, "weak", turns)
    line = next(m for m in missing_lines(load_view(ses)) if m.startswith("Right hip"))
    assert line.startswith("Right hip: all angles weak (forward direction of the pelvis sensor "
                           "from the walk) — record only the stand and the walk"), line  # fmt: skip
    assert "exactly as the protocol says" not in line


def test_a_determined_hip_flexion_is_not_told_to_avoid_sitting_down(walk):
    """A stand and a walk with no sitting down (hip flexion determined, the other planes weak
    from the walk's forward direction) was told 'record only the stand and the walk (no
    sitting down) for a determined flexion': it had done exactly that."""
    from motionlab.report.sentences import missing_lines

    ses = _force(walk, "hip_r", 0, "determined", "")
    start = "pelvis's forward direction is from the first steps of the walk (about 5-10° off)"
    for k in (1, 2):
        ses = _force(ses, "hip_r", k, "weak", start)
    line = next(m for m in missing_lines(load_view(ses)) if m.startswith("Right hip"))
    assert line.startswith("Right hip: ab-adduction and internal-external rotation weak"), line
    assert "sitting down" not in line and "cannot do better" in line, line


def test_a_forward_direction_from_the_turns_is_told_to_set_off_straight_ahead(walk):
    """Where the pelvis's forward direction came from the walk's turns (the walk did not set off
    straight ahead right after the stand), the remedy says to: the first steps give it to
    5-10°, the turns only to 5-25° (segments/walk_forward.py)."""
    from motionlab.report.sentences import missing_lines

    ses = _force(walk, "hip_r", 0, "determined", "")
    turns = "pelvis's forward direction is from the walk's turns (often 5-25° off)"
    for k in (1, 2):
        ses = _force(ses, "hip_r", k, "weak", turns)
    line = next(m for m in missing_lines(load_view(ses)) if m.startswith("Right hip"))
    assert "set off walking straight ahead right after the stand" in line, line


def test_pelvis_not_calibrated(walk):
    ses = _pelvis_nominal(walk)
    assert (
        load_view(ses).session.results.calibration.grades["hip_r"].grades == ["not determined"] * 3
    )
    assert problems(ses) == []


def test_two_strides_only(walk):
    kept = walk.results.gait.strides
    start = np.asarray(kept.start_s)[np.asarray(kept.kept, bool)]
    ses = _regait(walk, start[0] - 0.3, start[0] + 2.6)
    g = ses.results.gait
    assert g.ok and 0 < np.sum(g.strides.kept) <= 2 * (MIN - 1)
    assert problems(ses, joints=False) == []


def test_one_turn(walk):
    strides = walk.results.gait.strides
    turn = np.asarray(strides.start_s)[np.asarray(strides.reason, str) == "turn"]
    ses = _regait(walk, turn[0] - 6.0, turn[0] + 6.0)
    assert problems(ses, joints=False) == []


def test_a_sensor_swapped_gets_no_report_but_one_line():
    """The shanks' sensors swapped between the legs: no report is made of them (a knee would
    extend 35° past its straight stand, :mod:`motionlab.segments.gait_axes`), the calibration
    refuses the map in one line naming both (:mod:`motionlab.segments.walk_checks`)."""
    from motionlab.errors import InputError

    with pytest.raises(InputError) as exc:
        _analysed(swap=True)
    line = str(exc.value)
    assert "\n" not in line and "look swapped left for right" in line
    assert "shank_r's sensor shank_r" in line and "shank_l's sensor shank_l" in line


DOT_PROTOCOL = """
name: knee1
title: "One knee: a Xsens DOT on the thigh and one on the shank, seated start, then movement"
segments:
  thigh_r: {side: r, placement: "right thigh, any orientation"}
  shank_r: {side: r, placement: "right shank, any orientation"}
calibration:
  - {name: sitting, kind: static, pose: sitting, duration_s: 1, time_range: [0.0, 1.0],
     vertical_axis: {thigh_r: x, shank_r: y}}
joints:
  knee_r: {type: knee, proximal: thigh_r, distal: shank_r, side: r, sequence: ZXY}
tasks:
  - {name: movement, kind: knee_flexion, time_range: [5.0, 30.0]}
normative:
  movement: {knee_flexion_deg: [0, 130]}
"""


@pytest.mark.skipif(not (HUMAN / "imt_dot").is_dir(), reason="shared data absent")
def test_real_dot_knee(tmp_path):
    """Xsens DOT knee_tracking1 (thigh and shank, 60 Hz), its first 30 s, through ingest."""
    from motionlab.ingest import ingest
    from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors

    folder = HUMAN / "imt_dot" / "knee_tracking1"
    (tmp_path / "knee1.yaml").write_text(DOT_PROTOCOL)
    (tmp_path / "map.yaml").write_text(
        "sensors:\n  Femur: {segment: thigh, side: r}\n  Tibia: {segment: shank, side: r}\n"
    )
    session = ingest([folder / "femur.csv", folder / "tibia.csv"], tmp_path / "map.yaml")
    for s in session.sensors.values():
        keep = s.time < 30.0
        s.time = s.time[keep]
        for c in ("acc", "gyr", "mag", "quat"):
            if getattr(s, c) is not None:
                setattr(s, c, getattr(s, c)[keep])
    prepare_sensors(session)
    proto = load_protocol(tmp_path / "knee1.yaml")
    analyse(session, PipelineOptions(proto, progress=False, clock_sync=False))
    assert problems(session) == []


@pytest.mark.skipif(not (HUMAN / "qmt_full_body").is_dir(), reason="shared data absent")
def test_real_full_body_walk():
    from scipy.io import loadmat

    from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
    from motionlab.session import SensorStream, Session

    mat = loadmat(HUMAN / "qmt_full_body" / "full_body_example_data.mat",
                  squeeze_me=True, struct_as_record=False)  # fmt: skip
    names = {"hip": "pelvis", "upper_leg_right": "thigh_r", "upper_leg_left": "thigh_l",
             "lower_leg_right": "shank_r", "lower_leg_left": "shank_l"}  # fmt: skip
    t = np.asarray(mat["t"], float)
    session = Session(metadata={"subject": {"id": "qmt", "height_m": 1.75}})
    for src, label in names.items():
        s = mat[src]
        seg, _, side = label.partition("_")
        session.sensors[label] = SensorStream(
            label, t, acc=np.asarray(s.acc, float), gyr=np.asarray(s.gyr, float),
            quat=np.asarray(s.quat, float), segment=seg, side=side,
        )  # fmt: skip
    prepare_sensors(session)
    analyse(session, PipelineOptions(load_protocol("walk"), progress=False, clock_sync=False))
    assert problems(session) == []


def _calibration_row(**kw):
    from motionlab.report.model import CalibrationRow

    base = {
        "segment": "thorax", "sensor": "Back", "method": "procrustes", "step": "trunk_movement",
        "kind": "movement", "rho": 0.29, "reference_rho": float("nan"), "residual_deg": 0.0,
        "used": True, "hinge_check_deg": float("nan"), "segment_ok": True, "verdict": "determined",
    }  # fmt: skip
    return CalibrationRow(**{**base, **kw})


def test_calibration_table_judges_a_movement_axis_by_its_own_check():
    """A seated trunk's flexion axis (one block of bending and turning: ρ 0.29) was drawn red
    against the functional steps' ρ ≥ 0.60 beside 'Segment ok' and a determined grade; it is
    red only when its own check found it weak, and its 'ρ wanted' is that check's verdict."""
    from motionlab.report.pages_quality import calibration_cells

    cells, flags = calibration_cells(_calibration_row())
    assert cells[3] == "0.290" and cells[4] == "determined" and not (flags[3] or flags[4])
    _, flags = calibration_cells(_calibration_row(verdict="weak"))
    assert flags[4] and not flags[3]
    cells, flags = calibration_cells(_calibration_row(kind="functional", verdict=None))
    assert cells[4] == "≥ 0.60" and flags[3]  # a protocol step keeps its floor


def test_a_hinge_fits_axis_shows_its_verdict_and_no_made_up_rho(walk):
    """The knees' flexion axes from the walk are weighted 0.9 (determined) or 0.6 in the frame
    fit by their verdict, the pelvis's forward from the walk 0.6; the calibration table
    printed that weight as the axis' "ρ", a number no movement measured. Their rows now have
    no ρ, their verdict in 'ρ wanted'."""
    from motionlab.report.model import calibration_rows
    from motionlab.report.pages_quality import calibration_cells

    rows = [r for r in calibration_rows(load_view(walk)) if r.step.startswith("movement:")]
    assert rows and all(np.isnan(r.rho) for r in rows)
    for r in rows:
        cells, _ = calibration_cells(r)
        assert cells[3] == "-" and cells[4] == r.verdict


def test_a_movement_axis_step_is_named_in_words():
    """The step column printed the records' keys, 'movement:knee r:0' and 'movement:turns',
    wrapped over two lines; it names the joint whose movement gave the axis, or the walk."""
    from motionlab.report.pages_quality import step_words

    walk = load_protocol("walk").joints
    assert step_words("movement:knee_r:0", walk) == "movement (right knee)"
    assert step_words("movement:knee_l", walk) == "movement (left knee)"
    assert step_words("movement:turns", walk) == "the walk (forward)"
    assert step_words("knee_flexion_l") == "knee flexion l"
    assert step_words("movement:wrist_x:1") == "movement (wrist x)"


def test_calibration_table_does_not_flag_the_residual_of_an_axis_left_out():
    """The knee's movement axis left out of the shank's fit (the hip-flexion step measured it
    better) keeps its residual as information, not in red beside 'In fit: no'."""
    from motionlab.report.pages_quality import calibration_cells

    row = _calibration_row(kind="functional", verdict=None, rho=0.96, residual_deg=19.0)
    assert calibration_cells(replace(row, used=False))[1][5] is False
    assert calibration_cells(row)[1][5] is True


@pytest.mark.parametrize("pelvis", [True, False])
def test_the_stride_curves_have_their_key_and_axis_labels(walk, pelvis):
    """The stride-curve page had no key for its colours (given only on the page before) and no
    x-axis label. With 7 curves the key takes the spare cell, with an even number it goes below
    the last row; either way the page lays out cleanly."""
    from motionlab.report.pages_gait import curve_page
    from motionlab.report.pdf import layout_problems

    ses = copy.deepcopy(walk)
    if not pelvis:  # hips and knees only: 4 curves
        for side in ses.results.gait.curves.values():
            for k in [k for k in side if k.startswith("pelvis")]:
                del side[k]
    with matplotlib.rc_context(RC):
        doc = Document("motionlab report · test", "subject X")
        curve_page(doc, load_view(ses))
        (page,) = doc.pages
        assert layout_problems(page) == []
        keys = [t.get_text() for ax in page.axes if ax.get_legend() for t in
                ax.get_legend().get_texts()]  # fmt: skip
        assert keys == ["right (mean ± SD)", "left (mean ± SD)", "normative mean ± SD"]
        drawn = [ax for ax in page.axes if ax.get_lines()]
        assert drawn and all(ax.get_xlabel() == "% of stride" for ax in drawn)


def test_a_segment_whose_frame_is_not_determined_is_no_ok_segment():
    """The real full-body arm's thorax passed its quality checks, but its frame (one measured
    axis, the placement hint contradicted) was not determined: the calibration table and the
    run summary said "ok" beside a trunk compensation "not determined" for that very reason."""
    from motionlab.report.model import _segment_ok
    from motionlab.results import SegmentQuality, SegmentRecord

    passed = SegmentQuality(ok=True, messages=[], min_rho=0.99)
    one_axis = SegmentRecord(np.array([1.0, 0, 0, 0]), "single_axis", quality=passed)
    assert _segment_ok("thorax", one_axis)  # one axis and the hint: weak, still usable
    contradicted = SegmentRecord(
        np.array([1.0, 0, 0, 0]), "single_axis", quality=passed, hint_contradicted=True
    )
    assert not _segment_ok("thorax", contradicted)
    assert not _segment_ok(
        "thorax", SegmentRecord(np.array([1.0, 0, 0, 0]), "nominal", quality=passed)
    )


def test_cycles_counted_on_an_undetermined_angle_are_withheld():
    """The real full-body arm's elbows showed "Cycles 5" on rows that all said "not determined":
    the repetitions are counted on the elbow's flexion, which the recording did not determine.
    A walk's knees and hips count their leg's strides (the shank's gyroscope) and keep them."""
    from motionlab.protocol import load_protocol
    from motionlab.report.model import cycles_counted

    arm, walk = load_protocol("arm"), load_protocol("walk")
    elbow, free = arm.joints["elbow_r"], arm.tasks[0]
    nd = {"elbow_r_flexion_deg": ("not determined", "")}
    assert not cycles_counted(free, elbow, nd)
    assert cycles_counted(free, elbow, {"elbow_r_flexion_deg": ("weak", "")})
    knee_nd = {"knee_r_flexion_deg": ("not determined", "")}
    assert cycles_counted(walk.tasks[0], walk.joints["knee_r"], knee_nd)


def test_a_flag_needs_the_value_beyond_its_own_uncertainty():
    """The demo's healthy knee was told its varus thrust of 3.3° (SD 0.3, 9 strides) was above
    the 3° flagged, "linked to progression of medial knee osteoarthritis", with an adduction
    the report itself gives as ±2°; its elbow was told of trunk compensation for a 10.2° lean
    against a 10° limit. A flag now needs the value beyond the limit by more than its margin,
    and a thrust is said within its limit only below it by more than that margin."""
    import types

    from motionlab.protocol import load_protocol
    from motionlab.report.model import accuracy_bound, thrust_above, thrust_within, trunk_above
    from motionlab.report.normative import load_accuracy
    from motionlab.results import TrunkAngleStats

    view = types.SimpleNamespace(protocol=load_protocol("knee"))
    on_file = load_accuracy()["protocols"]["knee"]["knee_adduction"]  # the page's figure
    bound = accuracy_bound(view, "knee", "adduction")
    assert bound == np.ceil(max(on_file["rmse_deg"], on_file["max_rmse_deg"])) >= 2.0

    def stance(mean, sd, n):
        return types.SimpleNamespace(varus_thrust_mean_deg=mean, varus_thrust_sd_deg=sd,
                                     strides=n, threshold_deg=3.0)  # fmt: skip

    assert not thrust_above(view, "knee_r", stance(3.3, 0.3, 9))
    assert not thrust_above(view, "knee_r", stance(2.9 + bound, 0.5, 20))  # margin 0.22 + bound
    assert thrust_above(view, "knee_r", stance(3.3 + bound, 0.5, 20))
    # "within" the same way: a simulated knee read 2.3° (27 strides) for a true 4.1°
    assert not thrust_within(view, "knee_r", stance(2.3, 0.5, 27))
    assert not thrust_within(view, "knee_r", stance(3.0 - bound, 0.5, 27))  # margin 0.19 + bound
    assert thrust_within(view, "knee_r", stance(2.7 - bound, 0.5, 27))
    walk = types.SimpleNamespace(protocol=load_protocol("walk"))  # knee adduction: none on file
    assert not thrust_above(walk, "knee_r", stance(9.0, 0.5, 20))
    assert not thrust_within(walk, "knee_r", stance(0.0, 0.5, 20))
    assert not trunk_above(TrunkAngleStats(10.2, 0.0, 10.2, 90.0, 10.0))
    assert trunk_above(TrunkAngleStats(12.5, 0.0, 12.5, 40.0, 10.0))


def test_a_joint_with_no_sensor_is_said_not_measured_on_the_summary(walk):
    """A walk recorded without its pelvis sensor (or with one leg only) listed the knees on the
    summary and said nothing of the hips the protocol names: now each such joint has its line
    under 'Weak or not determined in this recording', naming the segment without a sensor."""
    from motionlab.report.sentences import missing_lines

    ses = copy.deepcopy(walk)
    assert not any(m.startswith(("Right hip: not measured", "Left knee: not measured"))
                   for m in missing_lines(load_view(ses)))  # fmt: skip
    for label in ("pelvis", "thigh_l", "shank_l"):
        del ses.sensors[label]
    view = load_view(ses)
    assert [j.name for j in view.joints()] == ["knee_r"]
    lines = missing_lines(view)
    assert (
        "Right hip: not measured (no sensor on the pelvis) — strap one there to measure it."
        in lines
    )
    assert ("Left knee: not measured (no sensor on the left thigh and left shank) — strap one on "
            "each to measure it.") in lines  # fmt: skip


def test_clocks_the_sync_could_not_check_are_said_among_the_findings(walk):
    """The real 16-IMU walk (one radio clock, which its files do not show): every joint-centre
    and heel-strike fit was refused, each sensor kept its recorded clock and the knees were
    graded as if the clocks were known to agree; nothing on the summary said the angles assume
    it. A sensor the sync could not check is named in one quality note, which says what it
    does to the grades and the gait numbers (segments.grades.clock_graded); an applied fit, a
    vendor's clock kept, a part on its own clock (said by the withheld numbers across the legs)
    or no sync at all (--no-clock-sync) add none."""
    from motionlab.clocksync.stage import VENDOR_KEPT
    from motionlab.report.sentences import quality_notes
    from motionlab.results import NOT_LINKED, ClockFit, ClockSync

    def with_fits(*statuses):
        ses = copy.deepcopy(walk)
        sensors = ("thigh_r", "thigh_l", "shank_r")[: len(statuses)]
        fits = {s: ClockFit("pelvis", s, 0.0, 0.0, 20.0, 1e-3, 1e-6, np.nan, 0.0, status, "network")
                for s, status in zip(sensors, statuses, strict=True)}  # fmt: skip
        ses.results.clock_sync = ClockSync(fits)
        return [n for n in quality_notes(load_view(ses)) if "not synchronised (" in n]

    refused = "not reliable: the shared joint centre fits poorly (residual 0.76 m/s²)"
    assert with_fits(refused, "applied", "not enough shared movement") == [
        "Clocks of thigh_r, shank_r not synchronised (no reliable timing in the recording, see "
        "'Sensor clocks'): taken as recorded, so the angles between sensors not timed against "
        "each other are weak at best where they turn fast and the gait numbers comparing the "
        "legs are withheld (an offset moves an angle by 3° per 10 ms at 300°/s); sensors that "
        "share one clock: run with --no-clock-sync."
    ]
    assert with_fits("applied", "consistent with one clock") == []
    assert with_fits(f"{VENDOR_KEPT} (one time column); the data's fit said: {refused}") == []
    assert with_fits(f"{NOT_LINKED}: no sensor joins it to pelvis") == []
    assert with_fits() == []  # nothing synced
    # a protocol without a walk has no gait numbers to withhold (a lumbar report said it had)
    ses = copy.deepcopy(walk)
    fit = ClockFit("pelvis", "thorax", 0.0, 0.0, 20.0, 1e-3, 1e-6, np.nan, 0.0, refused, "network")
    ses.results.clock_sync = ClockSync({"thorax": fit})
    view = replace(load_view(ses), protocol=load_protocol("lumbar_seated"))
    (note,) = [n for n in quality_notes(view) if "not synchronised (" in n]
    assert "turn fast (an offset moves" in note and "gait" not in note


def test_results_json_names_the_joints_not_measured(walk):
    """results.json (programs) said nothing of a joint with no sensor, where the report, the
    CSV tables and the study table now do."""
    from motionlab.export import results_json

    assert "not_measured" not in results_json(walk)
    ses = copy.deepcopy(walk)
    del ses.sensors["pelvis"]
    assert results_json(ses)["not_measured"] == {
        "hip_r": {"segments": ["pelvis"], "reason": "not measured: no pelvis sensor"},
        "hip_l": {"segments": ["pelvis"], "reason": "not measured: no pelvis sensor"},
    }


def test_a_walks_cycles_get_the_gait_band_and_a_weak_angle_no_normal(walk):
    """The walk protocol's knee cycles were drawn against a hatched range (the knee protocol's
    'gait' task had the normal curve), the weak hip ab-adduction and rotation against the normal
    range they are not compared with, and the key named a normal curve no panel drew."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from motionlab.report.pages_joint import cycle_band, draw_cycle

    view = load_view(walk)
    assert cycle_band(view, "walk", "knee", "flexion") is not None
    joints = view.protocol.joints
    ax = Figure().add_subplot()
    assert draw_cycle(ax, view, joints["knee_r"], "walk", "flexion", "knee_r_flexion_deg") == "band"
    ses = _force(walk, "hip_r", 1, "weak", "pelvis's forward direction from the first steps")
    ax = Figure().add_subplot()
    hip = joints["hip_r"]
    assert draw_cycle(ax, load_view(ses), hip, "walk", "adduction", "hip_r_adduction_deg") == ""
    assert not ax.patches


def test_the_summary_says_what_to_record_for_a_shank_axis_or_a_sensor_half_a_turn_off():
    """The two grades of sensors strapped any way round (segments.grades) in a clinician's
    words: the knee's off-axis angles weak for want of the straight-leg swings, and a frame
    whose axis nothing in the recording signs."""
    import types

    from motionlab.protocol import load_protocol
    from motionlab.report.sentences import cause_and_remedy
    from motionlab.segments.grades import _coupled_axis_grade, _unsigned

    knee = load_protocol("knee")
    segs = {"shank_r": types.SimpleNamespace(axes={"knee_flexion_r": types.SimpleNamespace(
        in_fit=True, kind="functional")})}  # fmt: skip
    grade, reason = _coupled_axis_grade(knee, knee.joints["knee_r"], segs)
    assert grade == "weak"
    cause, remedy = cause_and_remedy(types.SimpleNamespace(protocol=knee), "knee_r", reason)
    assert cause == "shank axis from the knee's own flexion"
    assert remedy.startswith("record the optional straight-leg swings (standing, holding")
    elbow = types.SimpleNamespace(protocol=load_protocol("elbow"))
    cause, remedy = cause_and_remedy(
        elbow, "elbow_l", _unsigned("upperarm_l", ["shoulder_flexion_l"])
    )
    assert cause == "which way the left upperarm sensor sits"
    assert remedy.startswith("strap the left upperarm sensor as the protocol places it")
