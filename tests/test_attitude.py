"""Vector-attitude helpers recover a known attitude exactly from noise-free vectors."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import attitude

DIP = np.deg2rad(65.0)
M_REF = np.array([0.0, np.cos(DIP), -np.sin(DIP)])


@pytest.fixture
def poses():
    rng = np.random.default_rng(7)
    q = rot.normalize(rng.normal(size=(20, 4)))
    acc = rot.rotate(rot.conj(q), np.array([0.0, 0.0, 9.81]))
    mag = rot.rotate(rot.conj(q), 45.0 * M_REF)
    return q, acc, mag


def test_triad_recovers_attitude(poses):
    q, acc, mag = poses
    est = attitude.triad(acc, mag, attitude.UP, attitude.NORTH)
    assert np.max(rot.angle_between(est, q)) < 1e-10


def test_triad_single_pose_hand_computed():
    # sensor x points north, y west, z up: a +90° turn about up
    acc = np.array([0.0, 0.0, 9.81])
    mag = np.array([np.cos(DIP), 0.0, -np.sin(DIP)]) * 40
    est = attitude.triad(acc, mag, attitude.UP, attitude.NORTH)
    np.testing.assert_allclose(est, [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)], atol=1e-12)


def test_quest_recovers_attitude_with_three_vectors(poses):
    q, acc, mag = poses
    third = np.array([0.3, -0.5, 0.8])
    body = np.stack([acc, mag, rot.rotate(rot.conj(q), third)], axis=1)
    ref = np.broadcast_to(np.stack([attitude.UP, M_REF, third]), body.shape)
    est = attitude.quest(body, ref, np.array([2.0, 1.0, 0.5]))
    assert np.max(rot.angle_between(est, q)) < 1e-9
    one = attitude.quest(body[0], ref[0])
    assert rot.angle_between(one, q[0]) < 1e-9


def test_quest_weights_favour_the_trusted_vector():
    # two inconsistent observations: the heavier one is matched more closely
    body = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    ref = np.array([[0.0, 0.1, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    heavy = attitude.quest(body, ref, np.array([100.0, 1.0, 1.0]))
    light = attitude.quest(body, ref, np.array([0.01, 1.0, 1.0]))
    err = [
        np.linalg.norm(rot.rotate(q, body[0]) - ref[0] / np.linalg.norm(ref[0]))
        for q in (heavy, light)
    ]
    assert err[0] < 0.01 < err[1]


def test_gauss_newton_recovers_attitude_from_wrong_start(poses):
    q, acc, mag = poses
    start = rot.mul(q, rot.from_rotvec(np.array([0.6, -0.5, 0.7])))
    est = attitude.gauss_newton(acc, mag, start, iterations=8)
    assert np.max(rot.angle_between(est, q)) < 1e-9


def test_initial_orientation_with_and_without_mag(poses):
    q, acc, mag = poses
    est = attitude.initial_orientation(np.repeat(acc[:1], 5, 0), np.repeat(mag[:1], 5, 0))
    assert rot.angle_between(est, q[0]) < 1e-10
    tilt = attitude.initial_orientation(acc[:1])
    np.testing.assert_allclose(rot.rotate(tilt, acc[0] / 9.81), [0, 0, 1], atol=1e-12)
    upside_down = attitude.initial_orientation(np.array([[0.0, 0.0, -9.81]]))
    np.testing.assert_allclose(rot.rotate(upside_down, [0, 0, -1.0]), [0, 0, 1], atol=1e-12)


def test_parallel_vectors_are_an_input_error():
    with pytest.raises(InputError):
        attitude.triad([0, 0, 1.0], [0, 0, 2.0], attitude.UP, attitude.NORTH)
