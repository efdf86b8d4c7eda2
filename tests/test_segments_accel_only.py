"""Accelerometer-only elbow angles (Lee 2012 model) against a known sagittal-plane movement."""

import numpy as np
import pytest

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


def test_a_carrying_angle_held_from_the_stand_is_not_read_as_flexion():
    """Lee's model fixes the carrying angle at 0°: a straight elbow with 12° of valgus read as
    12° of flexion, and its pronation 70-90° off (simulated elbows, below 20° of flexion). With
    the stand's carrying angle in the model the angles come back, for any upper-arm pose."""
    from motionlab.kinematics.accel_only import stand_carrying

    rng = np.random.default_rng(3)
    n = 3000
    t = np.linspace(0, 30, n)
    phase = rng.uniform(0, 6)
    upper = np.radians([70, 40, 50]) * np.sin(np.outer(t, [0.21, 0.13, 0.17]) + [phase, 0, 0])
    flex = np.radians(5 + 60 * (1 - np.cos(0.5 * t)))
    pron = np.radians(50) * np.sin(0.35 * t)
    carrying = np.radians(12.0)
    for side in "rl":
        q_u = compose(upper, "elbow", side)
        truth = np.column_stack([flex, np.full(n, carrying), pron])
        q_f = rot.mul(q_u, compose(truth, "elbow", side))
        up_u, up_f = rot.rotate(rot.conj(q_u), UP), rot.rotate(rot.conj(q_f), UP)
        got = elbow_from_gravity(up_u, up_f, side, carrying)
        observable = np.abs(np.sin(flex)) > 0.2  # away from the straight elbow's pronation lock
        err = np.degrees(np.abs(got - truth))
        assert err[:, 0].max() < 0.5 and err[observable, 2].max() < 0.5, (side, err.max(axis=0))
        straight = compose(np.column_stack([np.zeros(50), np.full(50, carrying), np.zeros(50)]),
                           "elbow", side)  # fmt: skip
        hanging = np.tile(UP, (50, 1))  # the stand: upper arm vertical, elbow straight
        found = stand_carrying(hanging, rot.rotate(rot.conj(straight), UP), side)
        assert np.degrees(found) == pytest.approx(12.0, abs=1e-6)
        lee = elbow_from_gravity(hanging, rot.rotate(rot.conj(straight), UP), side)
        assert np.degrees(np.abs(lee[:, 0])).min() > 10  # the carrying angle read as flexion
