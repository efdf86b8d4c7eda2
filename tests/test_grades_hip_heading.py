"""A hip whose pelvis took its forward direction from the walk: flexion is graded by what that
heading's doubt can do to it, ``θ (1 - cos e)``, ab/adduction and rotation stay ``weak``
(:func:`motionlab.segments.grades.grade_joints`)."""

from dataclasses import replace

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import decompose
from motionlab.protocol import load_protocol
from motionlab.results import AxisMeasurement, HingeFit, SegmentCalibration, SegmentRecord
from motionlab.segments.grades import HEADING_BOUND_DEG, grade_joints

Y, Z = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
MEASURED = AxisMeasurement("walk", "movement", "hinge", Z, Z, 0.9, used=True)
GRAVITY = AxisMeasurement("standing", "static", "gravity", Y, Y, 0.99, used=True)


def _calibration(forward: str, tilt_deg: float, knee: str = "determined") -> SegmentCalibration:
    """pelvis: gravity and a forward direction by ``forward``; thigh_r and shank_r measured
    whole; knee_r fitted from the walk with the thigh tilting ``tilt_deg``."""
    turns = AxisMeasurement("movement:turns", "movement", forward, Y, Y, 0.5, used=True)
    segs = {
        "pelvis": SegmentRecord(rot.IDENTITY, "primary_secondary", {"s": GRAVITY, "t": turns}),
        "thigh_r": SegmentRecord(rot.IDENTITY, "primary_secondary", {"s": GRAVITY, "k": MEASURED}),
        "shank_r": SegmentRecord(rot.IDENTITY, "primary_secondary", {"s": GRAVITY, "k": MEASURED}),
    }
    z = np.array([0.0, 0.0, 1.0])
    fit = HingeFit("knee_r", z, z, 0.0, 0.0, 0.0, "measured", "anatomy", (60.0, 0.0),
                   verdict=knee, method="principal", witness_deg=2.0,
                   proximal_tilt_deg=tilt_deg)  # fmt: skip
    return SegmentCalibration("walk", segments=segs, hinges={"knee_r": fit})


def _hip(cal: SegmentCalibration) -> dict:
    protocol = load_protocol("walk")
    protocol.joints = {k: protocol.joints[k] for k in ("hip_r", "knee_r")}
    return grade_joints(protocol, cal)["hip_r"]


def test_a_walk_hip_flexion_is_determined_when_the_heading_doubt_moves_it_little():
    # 40° of thigh tilt, turns up to 20° off: at most 40 (1 - cos 20°) = 2.4° of flexion
    g = _hip(_calibration("turns", 40.0))
    assert g.grades == ["determined", "weak", "weak"]
    assert "turns" in g.reasons[1]


def test_a_hip_that_sits_down_keeps_its_flexion_weak_and_says_why():
    # sitting tilts the thigh 82°: 82 (1 - cos 20°) = 4.9°, more than 3°
    g = _hip(_calibration("turns", 82.0))
    assert g.grades == ["weak", "weak", "weak"]
    assert "20° off" in g.reasons[0] and "5°" in g.reasons[0]


def test_the_first_steps_are_trusted_further_than_the_turns():
    # walk start: up to 10° off; 82 (1 - cos 10°) = 1.2°
    assert _hip(_calibration("walk start", 82.0)).grades[0] == "determined"


def test_no_determined_knee_fit_no_bound():
    assert _hip(_calibration("turns", 40.0, knee="weak")).grades[0] == "weak"


@pytest.mark.parametrize("heading_deg", sorted(HEADING_BOUND_DEG.values()))
@pytest.mark.parametrize("flexion_deg", [20.0, 45.0, 60.0])
def test_a_frame_turned_about_the_vertical_moves_zxy_flexion_by_at_most_the_bound(
    heading_deg, flexion_deg
):
    """Flexion about a horizontal axis ``e`` from the pelvis frame's z, read as the hip's ZXY
    (x anterior, y up, z right): its flexion is off by no more than ``θ (1 - cos e)``."""
    e, theta = np.radians(heading_deg), np.radians(flexion_deg)
    q = rot.from_rotvec(theta * np.array([np.sin(e), 0.0, np.cos(e)]))
    z = abs(np.degrees(decompose(rot.IDENTITY, q, "hip", "r")[0, 0]))
    assert abs(z - flexion_deg) <= flexion_deg * (1.0 - np.cos(e)) + 1e-9
    assert abs(z - flexion_deg) > 0.2 * flexion_deg * (1.0 - np.cos(e))  # the bound is not loose


def test_a_thigh_with_one_measured_axis_and_a_contradicted_hint_leaves_the_hip_undetermined():
    """A thigh whose knee fit failed keeps only gravity; where the stand contradicted its
    placement hint, the hint's heading means nothing (a 74-s walk shortened to 14 s, seed 1:
    the left hip's flexion was 31° off and graded weak)."""
    cal = _calibration("turns", 40.0, knee="not determined")
    cal.segments["thigh_r"] = SegmentRecord(rot.IDENTITY, "single_axis", {"s": GRAVITY},
                                            hint_contradicted=True)  # fmt: skip
    g = _hip(cal)
    assert g.grades == ["not determined"] * 3
    assert g.reasons[0].startswith("thigh_r's frame")  # the cause first, then the pelvis'
    assert "contradict" in g.reasons[0] and "turns" in g.reasons[0]
    cal.segments["thigh_r"] = replace(cal.segments["thigh_r"], hint_contradicted=False)
    assert _hip(cal).grades == ["weak"] * 3
