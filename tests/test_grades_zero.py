"""A hinge angle is ``determined`` only when its zero is measured too: both segment frames whole
(:func:`motionlab.segments.grades.grade_joints`)."""

from pathlib import Path

import pytest

from motionlab import rotations as rot
from motionlab.protocol import load_protocol
from motionlab.results import AxisMeasurement, HingeFit, SegmentCalibration, SegmentRecord
from motionlab.segments.grades import grade_joints

RIG = Path(__file__).resolve().parents[1] / "motionlab/protocols/examples/ring_rig.yaml"
Z = rot.IDENTITY[1:]
MEASURED = AxisMeasurement("hinge34", "movement", "hinge", Z, Z, 0.9, used=True)


def _calibration(seg4_method: str) -> SegmentCalibration:
    """hinge34 (seg3-seg4, axis y) with its axis fitted from movement (``determined``)."""
    segs = {
        "seg3": SegmentRecord(
            rot.IDENTITY, "procrustes", {"hinge23": MEASURED, "hinge34": MEASURED}
        ),
        "seg4": SegmentRecord(rot.IDENTITY, seg4_method, {"hinge34": MEASURED}),
    }
    fit = HingeFit("hinge34", Z, Z, 0.0, 0.0, 0.0, "measured", "anatomy", verdict="determined")
    return SegmentCalibration("ring_rig", segments=segs, hinges={"hinge34": fit})


def _hinge34(method: str) -> tuple[str, str]:
    protocol = load_protocol(RIG)
    protocol.joints = {"hinge34": protocol.joints["hinge34"]}
    g = grade_joints(protocol, _calibration(method))["hinge34"]
    return g.grades[0], g.reasons[0]


@pytest.mark.parametrize("method", ["procrustes", "primary_secondary"])
def test_a_hinge_between_two_whole_frames_is_determined(method):
    assert _hinge34(method) == ("determined", "")


def test_a_hinge_whose_zero_is_a_placement_hint_is_weak_and_says_why():
    grade, reason = _hinge34("single_axis")
    assert grade == "weak"
    assert reason.startswith("its zero is seg4's placement hint")


@pytest.mark.parametrize("follow", [float("nan"), 0.95, 0.66])
def test_an_upper_arm_sensor_that_lags_the_humerus_leaves_carrying_and_pronation_weak(follow):
    """The arm protocol's elbow from a determined two-axis fit: flexion stays determined; the
    carrying angle and pronation are weak where the fit found the upper-arm sensor following
    less than 0.9 of the humerus' axial rotation (the rest turns up in them), and say so."""
    from motionlab.results import TwoAxisFit

    protocol = load_protocol("arm")
    protocol.joints = {"elbow_r": protocol.joints["elbow_r"]}
    segs = {s: SegmentRecord(rot.IDENTITY, "primary_secondary", {"m": MEASURED})
            for s in ("upperarm_r", "forearm_r")}  # fmt: skip
    fit = TwoAxisFit("elbow_r", Z, Z, 0.0, 0.0, 0.0, "measured", "anatomy",
                     verdict="determined", axial_follow=follow)  # fmt: skip
    cal = SegmentCalibration("arm", segments=segs, hinges={"elbow_r": fit})
    g = grade_joints(protocol, cal)["elbow_r"]
    assert g.grades[0] == "determined"
    if follow < 0.9:
        assert g.grades[1:] == ["weak", "weak"]
        assert "upperarm_r's sensor follows 0.66" in g.reasons[1]
    else:
        assert g.grades[1:] == ["determined", "determined"], g.reasons
