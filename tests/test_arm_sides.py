"""Arms swapped left for right in the sensor map (:mod:`motionlab.segments.arm_sides`): an elbow
whose carrying angle reads varus in the stand is not a determined angle of that side."""

from __future__ import annotations

import dataclasses

import pytest

from motionlab.binding import sensor_for_segment
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.results import JointGrades
from motionlab.segments import arm_sides
from motionlab.simulate import simulate

OPTIONS = PipelineOptions(protocol="arm", progress=False)


def _arms_swapped(session):
    """Each arm's sensors given the other arm's segments, as a map that swapped the sides."""
    for a, b in (("upperarm_r", "upperarm_l"), ("forearm_r", "forearm_l")):
        la, lb = sensor_for_segment(session, a), sensor_for_segment(session, b)
        sa, sb = session.sensors[la], session.sensors[lb]
        session.sensors[la] = dataclasses.replace(sa, segment=sb.segment, side=sb.side)
        session.sensors[lb] = dataclasses.replace(sb, segment=sa.segment, side=sa.side)
    return session


@pytest.fixture(scope="module")
def mapped_and_swapped():
    """The ``arm`` protocol on skin, random mountings, seed 0 (40 s), analysed as mapped and with
    the arms' sensors swapped left for right."""
    out = []
    for swap in (False, True):
        session, _ = simulate("arm", 40.0, 0, "skin", mounting="random", knee_model="anatomical")
        if swap:
            _arms_swapped(session)
        prepare_sensors(session)
        analyse(session, OPTIONS)
        out.append(session)
    return out


def test_arms_swapped_left_for_right_leave_no_determined_elbow(mapped_and_swapped):
    """As mapped the left elbow is ``determined`` on all three angles and the stand's carrying
    angle reads valgus; with the arms swapped the same elbow, now read as the right one, was
    ``determined`` with its carrying angle and pronation turned (measured −10.7° and the
    pronation's sign). It is ``weak``, saying why, and the warning names its sensors."""
    mapped, swapped = mapped_and_swapped
    cal = mapped.results.calibration
    assert cal.grades["elbow_l"].grades == ["determined"] * 3
    assert not any("varus" in w for w in cal.warnings)
    cal = swapped.results.calibration
    for name, g in cal.grades.items():
        assert "determined" not in g.grades, name
    assert all("look swapped left for right" in r for r in cal.grades["elbow_r"].reasons)
    ua, fa = (sensor_for_segment(swapped, s) for s in ("upperarm_r", "forearm_r"))
    assert any(
        w.startswith("elbow_r: the carrying angle reads") and f"are {ua} and {fa} on the right" in w
        for w in cal.warnings
    )
    # the report's summary gives the map's remedy
    from motionlab.report.model import load_view
    from motionlab.report.sentences import missing_lines

    (right,) = [
        line for line in missing_lines(load_view(swapped)) if line.startswith("Right elbow")
    ]
    assert right.endswith("— check the sensor map: the right arm's sensors on the right arm's "
                          "segments, the left's on the left.")  # fmt: skip


def test_the_stand_reads_the_carrying_angle_with_its_sign_turned(mapped_and_swapped):
    from motionlab.segments import segment_orientations
    from motionlab.segments.sensors import sensor_quats

    protocol = load_protocol("arm")
    read = []
    for session in mapped_and_swapped:
        cal = session.results.calibration
        seg_q = segment_orientations(protocol, cal, sensor_quats(session, protocol))
        read.append(arm_sides.pose_carrying(protocol, cal, seg_q))
    (step, left), (_, right_swapped) = read[0]["elbow_l"], read[1]["elbow_r"]
    assert step == "standing"
    assert 5.0 < left < 20.0
    assert right_swapped == pytest.approx(-left, abs=0.5)


def test_only_a_found_axis_reading_varus_beyond_the_threshold_lowers_the_grades():
    protocol = load_protocol("arm")
    det, nd = (
        JointGrades(["determined"] * 3, [""] * 3),
        JointGrades(["not determined"] * 3, ["x"] * 3),
    )
    limit = arm_sides.CARRYING_VARUS_DEG
    graded = {"elbow_r": det, "elbow_l": det}
    near = {"elbow_r": ("standing", -limit + 0.1), "elbow_l": ("standing", 12.0)}
    assert arm_sides.side_graded(graded, near) == graded
    assert arm_sides.side_warnings(None, protocol, graded, near) == []
    varus = {"elbow_r": ("standing", -limit - 0.1), "elbow_l": ("standing", -9.0)}
    both = arm_sides.side_graded(graded, varus)
    assert all(g.grades == ["weak"] * 3 for g in both.values())
    assert "reads 9° varus in the standing pose" in both["elbow_l"].reasons[0]
    (line,) = arm_sides.side_warnings(None, protocol, graded, varus)
    assert line.startswith("both elbows read varus in the standing pose (elbow_r 5°, elbow_l 9°)")
    assert "swap the sides of the arm sensors" in line
    # an elbow whose axis was not found reads its carrying angle from a hint: no evidence
    assert arm_sides.side_graded({"elbow_r": nd}, varus) == {"elbow_r": nd}


def test_one_arm_is_enough_for_its_elbow():
    """A clinic measures the affected arm: the ``arm`` protocol refused a recording of one arm
    ("no sensor on segment 'upperarm_l'") as the walk no longer refuses one leg. Its elbow is
    measured; the other is "not measured" in the report, not an error."""
    from motionlab.report.model import load_view
    from motionlab.report.sentences import missing_lines

    session, _ = simulate("arm", 40.0, 0, "skin", mounting="random", knee_model="anatomical")
    for label in [k for k, s in session.sensors.items() if s.segment.endswith("_r")]:
        del session.sensors[label]
    prepare_sensors(session)
    analyse(session, OPTIONS)
    assert list(session.results.calibration.grades) == ["elbow_l"]
    assert session.results.calibration.grades["elbow_l"].grades[0] == "determined"
    assert [c for c in session.results.angles.columns() if c.startswith("elbow_r")] == []
    lines = missing_lines(load_view(session))
    assert any(line.startswith("Right elbow: not measured (no sensor on the") for line in lines)


def test_a_stand_with_the_forearms_hanging_passes(mapped_and_swapped):
    """As mapped, each forearm's long axis (the fit's pronation axis) hangs within the
    carrying angle of the vertical in the stand (simulated seeds 0-9: 7.7-14.1°)."""
    mapped, _ = mapped_and_swapped
    hanging = arm_sides.pose_hanging(mapped, load_protocol("arm"), mapped.results.calibration)
    assert hanging and set(hanging) <= {"elbow_r", "elbow_l"}  # not for a fit not determined
    assert all(5.0 < deg < 20.0 for _, deg in hanging.values()), hanging
    assert not any("from hanging" in w for w in mapped.results.calibration.warnings)


def test_hands_in_the_lap_taken_for_the_stand_leave_the_elbows_not_determined(monkeypatch):
    """The recording starts seated with the hands in the lap (elbows at 90°) and no stand: that
    rest was the stand, every elbow angle's zero 90° off (flexion 70-111° RMSE), graded
    ``weak`` with a warning that the arms looked swapped. Now the forearms lie 80-81° from
    hanging there: every elbow angle is ``not determined``, a warning says what to record, and
    the swapped-arms warning is not given."""
    from motionlab.simulate import motion, tasks

    def seated(body, name, posture=motion.posture):
        row = posture(body, name)
        if name == "sitting":
            for side in "rl":
                row[motion.CH[f"elbow_{side}_0"]] = 90.0 * motion.DEG
        return row

    monkeypatch.setattr(motion, "posture", seated)
    monkeypatch.setattr(tasks, "posture", seated)
    arm = load_protocol("arm")
    lap = dataclasses.replace(arm.calibration[0], pose="sitting", instructions="hands in the lap")
    session, _ = simulate(dataclasses.replace(arm, calibration=[lap]), 40.0, 1, "skin",
                          mounting="random", knee_model="anatomical")  # fmt: skip
    prepare_sensors(session)
    analyse(session, OPTIONS)
    cal = session.results.calibration
    hanging = arm_sides.pose_hanging(session, arm, cal)  # elbows whose fit found the axes
    assert hanging and all(deg > 60.0 for _, deg in hanging.values()), hanging
    for name in ("elbow_r", "elbow_l"):
        assert cal.grades[name].grades == ["not determined"] * 3
    for name in hanging:
        assert "from hanging in the standing pose" in cal.grades[name].reasons[0]
        assert any(w.startswith(f"{name}: the forearm lies") and "hands in the lap" in w
                   for w in cal.warnings)  # fmt: skip
    assert not any("swapped" in w for w in cal.warnings)
