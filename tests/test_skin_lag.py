"""The upper arm's skin lag undone in the angles (:mod:`motionlab.segments.skin_lag`)."""

import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.protocol import load_protocol
from motionlab.results import HingeFit, SegmentCalibration, SegmentRecord, TwoAxisFit
from motionlab.rotations import twist_angle
from motionlab.segments.grades import grade_joints
from motionlab.segments.skin_lag import covers, lag_undone, undo_lag

X, Y, Z = np.eye(3)
RATE = 100.0


def _turn(axis: np.ndarray, deg) -> np.ndarray:
    return rot.from_axis_angle(axis, np.radians(np.atleast_1d(np.asarray(deg, float))))


def test_the_twist_of_a_swing_then_a_twist_is_the_twist():
    """``q = swing · twist``, the swing about an axis across ``y``: the twist comes back, for
    either sign of the quaternion; a pure swing has none."""
    swing = _turn(np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0), 40.0)
    q = rot.mul(swing, _turn(Y, 30.0))
    assert np.degrees(twist_angle(q, Y)) == pytest.approx([30.0])
    assert np.degrees(twist_angle(-q, Y)) == pytest.approx([30.0])
    assert np.degrees(twist_angle(swing, Y)) == pytest.approx([0.0], abs=1e-9)


def test_a_twist_past_half_a_turn_is_unwrapped():
    deg = np.linspace(0.0, 300.0, 61)
    assert np.degrees(twist_angle(_turn(Y, deg), Y)) == pytest.approx(deg)


def _arm(follow: float):
    """An upper arm that hangs in a 2-s stand, then swings out by up to 70° and twists by ±60°
    about its own long axis while the whole body turns 90° about the vertical; the skin sensor's
    segment frame follows ``follow`` of the twist. ``(t, trunk, humerus, skin)``."""
    t = np.arange(0.0, 20.0, 1.0 / RATE)
    ramp = np.clip(t - 2.0, 0.0, None)
    body = _turn(Z, 90.0 * np.clip(ramp / 10.0, 0.0, 1.0))  # the trunk turns in the room
    hang = _turn(X, 90.0)  # the segment's y (long axis) up, as in the stand
    swing = _turn(np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0), 70.0 * np.sin(0.3 * ramp) ** 2)
    twist = 60.0 * np.sin(0.9 * ramp)
    base = rot.mul(rot.mul(body, hang), swing)
    humerus = rot.mul(base, _turn(Y, twist))
    skin = rot.mul(base, _turn(Y, follow * twist))
    return t, body, humerus, skin


def _deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(rot.angle(rot.mul(rot.conj(a), b)))


def test_the_twist_the_skin_missed_is_added_back_against_the_trunk():
    """The skin follows 0.6 of a ±60° twist (24° missed) while the arm swings out and the body
    turns: with the trunk's orientation (in a frame of its own: the 6-D sensors' headings
    differ) the humerus comes back exactly; against the room the body's turn would be read as
    twist."""
    t, body, humerus, skin = _arm(0.6)
    assert _deg(skin, humerus).max() == pytest.approx(24.0, abs=0.1)
    trunk_frame = rot.mul(_turn(Z, 35.0), rot.mul(body, _turn(X, 20.0)))  # any mounting, heading
    back = undo_lag(t, skin, (0.0, 1.5), 0.6, (t, trunk_frame))
    assert _deg(back, humerus).max() < 1e-6
    still = undo_lag(t, skin, (0.0, 1.5), 0.6, (t, rot.IDENTITY[None].repeat(len(t), 0)))
    assert _deg(still, humerus).max() > 30.0  # the room is no anchor for the skin


def test_a_sensor_that_follows_is_left_as_it_is():
    t, body, humerus, skin = _arm(1.0)
    back = undo_lag(t, skin, (0.0, 1.5), 1.0, (t, body))
    assert _deg(back, humerus).max() < 1e-6


def test_a_trunk_sensor_that_missed_the_stand_gives_nothing_back():
    """A thorax recording that starts after the stand (or a stand with no sample) has no pose to
    take the twist from: the calibration names no anchor and the angles are left as they are."""
    t, body, humerus, skin = _arm(0.6)
    late = (t[t > 3.0], body[t > 3.0])
    assert covers((t, body), (0.0, 1.5)) and not covers(late, (0.0, 1.5))
    assert not covers(None, (0.0, 1.5)) and not covers((t, body), None)
    assert np.array_equal(undo_lag(t, skin, (0.0, 1.5), 0.6, late), skin)
    assert np.array_equal(undo_lag(t, skin, (30.0, 31.0), 0.6, (t, body)), skin)


def _fit(**kw) -> TwoAxisFit:
    return TwoAxisFit("elbow_r", Z, Z, 0.0, 0.0, 0.0, "measured", "anatomy",
                      verdict="determined", **kw)  # fmt: skip


def test_only_a_measured_lag_with_a_trunk_sensor_is_undone():
    assert lag_undone(_fit(axial_follow=0.7, lag_anchor="thorax"))
    assert not lag_undone(_fit(axial_follow=0.7))  # no trunk sensor
    assert not lag_undone(_fit(lag_anchor="thorax"))  # no lag fitted
    assert not lag_undone(_fit(axial_follow=1.0, lag_anchor="thorax"))


def test_the_anchor_is_stored_with_the_fit_and_named_in_the_grade():
    fit = _fit(axial_follow=0.66, lag_anchor="thorax")
    assert HingeFit.from_tree(fit.to_tree()).lag_anchor == "thorax"
    assert "lag_anchor" not in _fit(axial_follow=0.66).to_tree()  # as stored before it existed
    protocol = load_protocol("arm")
    protocol.joints = {"elbow_r": protocol.joints["elbow_r"]}
    segs = {s: SegmentRecord(rot.IDENTITY, "primary_secondary")
            for s in ("upperarm_r", "forearm_r")}  # fmt: skip
    for anchor, words in (("thorax", "twist against the thorax"), ("", "the rest goes into")):
        cal = SegmentCalibration(
            "arm", segments=segs, hinges={"elbow_r": dataclasses.replace(fit, lag_anchor=anchor)}
        )
        grades = grade_joints(protocol, cal)["elbow_r"]
        assert grades.grades[1:] == ["weak", "weak"]
        assert words in grades.reasons[1], grades.reasons[1]


def test_a_simulated_arm_with_a_thorax_sensor_loses_the_skin_lag_off_its_elbow_angles():
    """``arm`` protocol, skin preset (the upper-arm skin follows 0.55-0.85 of the humerus'
    twist), random mountings, one clock, seed 2: the fit finds the lag and the thorax sensor
    anchors it; the carrying angle and pronation come closer to the truth on both sides
    (measured: right 3.20 → 1.80° and 4.33 → 3.76°, left 7.24 → 4.79° and 4.86 → 2.92°), and
    flexion, which the lag enters only through the carrying angle, moves by hundredths."""
    from motionlab import stages
    from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
    from motionlab.simulate import simulate
    from motionlab.simulate.errors import get_preset

    preset = get_preset("skin")
    preset = dataclasses.replace(preset, timing=dataclasses.replace(
        preset.timing, clock_offset_sigma_s=0.0, clock_drift_sigma=0.0))  # fmt: skip
    protocol = load_protocol("arm")
    session, truth = simulate(protocol, 40.0, 2, preset, mounting="random",
                              knee_model="anatomical")  # fmt: skip
    prepare_sensors(session)
    analyse(session, PipelineOptions(protocol, progress=False, clock_sync=False))
    cols = [f"elbow_{s}_{a}_deg" for s in "rl" for a in ("flexion", "carrying", "pronation")]

    def rmse() -> np.ndarray:
        ang = session.results.angles.columns()
        moving = ang["time_s"] > truth.step("standing")["end_s"] + 2.0
        out = []
        for c in cols:
            err = ang[c] - np.interp(ang["time_s"], truth.time, truth.joint_angles[c])
            out.append(np.sqrt(np.nanmean(err[moving] ** 2)))
        return np.array(out)

    hinges = session.results.calibration.hinges
    assert all(f.lag_anchor == "thorax" and f.axial_follow < 0.9 for f in hinges.values())
    undone = rmse()
    for fit in hinges.values():
        fit.lag_anchor = ""
    stages.angles(session, force=True)
    kept = rmse()
    off_axis = [1, 2, 4, 5]
    assert np.all(undone[off_axis] < 0.9 * kept[off_axis]), (undone, kept)
    assert np.all(np.abs(undone[[0, 3]] - kept[[0, 3]]) < 0.2), (undone, kept)


def test_the_calibration_page_says_what_was_given_back():
    """The hinge table's words on the skin lag: given back against the thorax, not given back
    without one, and a fit the angles do not use (not determined, axes from no segment) named
    as such."""
    from motionlab.report.pages_quality import _skin_lag

    joint = load_protocol("arm").joints["elbow_r"]
    fit = _fit(axial_follow=0.77, lag_anchor="thorax")
    cal = SegmentCalibration("arm", hinges={"elbow_r": fit})
    assert "follows 0.77 of its segment's twist" in _skin_lag(fit, joint, cal)
    assert "given back in the angles from its twist against the thorax" in _skin_lag(
        fit, joint, cal
    )
    alone = dataclasses.replace(fit, lag_anchor="")
    assert "not given back (no thorax sensor" in _skin_lag(alone, joint, cal)
    unused = dataclasses.replace(fit, verdict="not determined")
    cal_unused = SegmentCalibration("arm", hinges={"elbow_r": unused})
    assert "which the angles do not use" in _skin_lag(unused, joint, cal_unused)
    assert _skin_lag(_fit(), joint, cal) == ""  # no lag fitted
