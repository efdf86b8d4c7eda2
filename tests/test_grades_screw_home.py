"""A knee whose shank took its flexion axis only from the knee's own flexion has ab/adduction and
rotation ``weak`` (:func:`motionlab.segments.grades._coupled_axis_grade`): the tibia turns about
its long axis as the knee leaves extension (screw-home), so the axis the seated knee flexion
gives the shank is turned by that rotation's mean over the movement (12-13° on the simulated
anatomical knee). The knee protocol's optional straight-leg hip flexions give the shank the axis
without it; when they are not recorded the grade says so and names them."""

import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab import stages
from motionlab.binding import sensor_for_segment
from motionlab.protocol import load_protocol
from motionlab.simulate import simulate


def _shank_z_error_deg(session, truth, shank: str) -> float:
    """Angle (deg) between the calibrated and the true flexion axis (z) of ``shank``."""
    m_true = truth.sensors[sensor_for_segment(session, shank)]["mounting"]
    q = rot.mul(m_true, np.asarray(session.results.calibration.segments[shank].mounting, float))
    z = np.array([0.0, 0.0, 1.0])
    return float(np.degrees(np.arccos(np.clip(rot.rotate(q, z) @ z, -1.0, 1.0))))


def _calibrated(recorded, knee, seed: int = 1):
    """A knee session simulated with the steps of ``recorded`` (anatomical knee), calibrated
    with the shipped ``knee`` protocol."""
    session, truth = simulate(
        recorded, 150.0, seed, preset="clean", rate_hz=50.0, knee_model="anatomical"
    )
    stages.prepare(session)
    stages.fuse(session)
    stages.calibrate(session, knee)
    return session, truth


@pytest.fixture(scope="module")
def knee():
    return load_protocol("knee")


def test_without_the_straight_leg_swings_the_knee_is_weak_off_its_flexion_axis(knee):
    without = dataclasses.replace(
        knee, calibration=[s for s in knee.calibration if not s.name.startswith("hip_flexion")]
    )
    session, truth = _calibrated(without, knee)
    cal = session.results.calibration
    assert cal.steps["hip_flexion_r"] is None and cal.steps["hip_flexion_l"] is None
    for side in "rl":
        grades = cal.grades[f"knee_{side}"]
        assert grades.grades == ["determined", "weak", "weak"], grades
        assert "screw-home" in grades.reasons[1]
        assert f"record 'hip_flexion_{side}'" in grades.reasons[1]
        # what the grade is for: the shank's axis turned by the screw-home rotation
        assert _shank_z_error_deg(session, truth, f"shank_{side}") > 6.0


def test_with_them_the_shank_takes_its_axis_from_the_swings(knee):
    session, truth = _calibrated(knee, knee)
    cal = session.results.calibration
    for side in "rl":
        assert cal.grades[f"knee_{side}"].grades == ["determined"] * 3
        assert cal.segments[f"shank_{side}"].axes[f"hip_flexion_{side}"].in_fit
        assert _shank_z_error_deg(session, truth, f"shank_{side}") < 2.0
