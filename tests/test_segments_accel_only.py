"""Accelerometer-only elbow angles (Lee 2012 model) against a known sagittal-plane movement."""

import numpy as np

from motionlab import rotations as rot
from motionlab.kinematics.accel_only import elbow_from_gravity
from motionlab.kinematics.joint_angles import compose

UP = np.array([0.0, 1.0, 0.0])  # "up" in the standing segment frame


def test_elbow_from_gravity_recovers_flexion_and_pronation():
    t = np.linspace(0, 10, 2000)
    shoulder = np.radians(60) * (1 - np.cos(0.5 * t))  # upper-arm flexion in the sagittal plane
    arm_rot = np.radians(20) * np.sin(0.3 * t)  # rotation about the upper arm's long axis
    flex = np.radians(20 + 50 * (1 - np.cos(0.8 * t)))
    pron = np.radians(40) * np.sin(0.6 * t)
    for side in "rl":
        q_u = compose(np.column_stack([shoulder, 0 * t, arm_rot]), "elbow", side)
        truth = np.column_stack([flex, 0 * t, pron])
        q_f = rot.mul(q_u, compose(truth, "elbow", side))
        up_u = rot.rotate(rot.conj(q_u), UP)
        up_f = rot.rotate(rot.conj(q_f), UP)
        got = elbow_from_gravity(up_u, up_f, side)
        err = np.degrees(np.abs(got - truth)).max(axis=0)
        assert np.all(err < 0.5), (side, err)


def test_pronation_is_held_when_the_forearm_is_vertical():
    t = np.linspace(0, 1, 200)
    flex = np.where(t < 0.5, np.radians(60), 0.0)  # elbow straightens: forearm hangs vertical
    truth = np.column_stack([flex, 0 * t, np.full_like(t, np.radians(30))])
    q_f = compose(truth, "elbow", "r")
    got = elbow_from_gravity(np.tile(UP, (200, 1)), rot.rotate(rot.conj(q_f), UP), "r")
    np.testing.assert_allclose(np.degrees(got[:, 2]), 30, atol=1e-6)
