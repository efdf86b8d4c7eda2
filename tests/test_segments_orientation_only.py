"""Sensors with only an orientation (OpenSense .sto, Xsens DOT, a vendor's fusion) calibrate
from the gravity and angular velocity their orientation implies."""

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import signals_from_orientation
from motionlab.kinematics.session_angles import session_angles
from motionlab.protocol import load_protocol
from motionlab.segments import calibrate_segments
from motionlab.simulate import simulate


def test_signals_from_orientation_match_a_still_and_a_turning_sensor():
    t = np.arange(0.0, 2.0, 0.01)
    q = rot.from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.5 * t)  # 0.5 rad/s about sensor y
    _, acc, gyr = signals_from_orientation(t, q)
    np.testing.assert_allclose(gyr, np.tile([0.0, 0.5, 0.0], (len(t), 1)), atol=1e-9)
    # gravity seen in the sensor frame, +9.81 along "up"
    np.testing.assert_allclose(acc[0], [0.0, 0.0, 9.81], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(acc, axis=1), 9.81)


def test_walk_from_vendor_orientations_only():
    protocol = load_protocol("walk")
    session, truth = simulate(protocol, 40.0, 2, "clean", mounting="random")
    for label, s in session.sensors.items():  # keep only the orientation, as a .sto has
        q = rot.resample(truth.time, truth.sensors[label]["orientation"], s.time)
        session.sensors[label] = type(s)(label=label, time=s.time, quat=q, segment=s.segment,
                                         side=s.side)  # fmt: skip
    cal = calibrate_segments(session, protocol)
    assert cal.grades["knee_r"].grades[0] == "determined"
    table = session_angles(session, protocol, cal)
    col = "knee_r_flexion_deg"
    ref = np.interp(table["time_s"], truth.time, truth.joint_angles[col])
    moving = ref > 5.0
    assert np.sqrt(np.mean((table[col] - ref)[moving] ** 2)) < 2.0
