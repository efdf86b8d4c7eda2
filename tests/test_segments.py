"""Sensor-to-segment calibration on a synthetic knee session with known mountings.

The session is fused (:func:`motionlab.stages.fuse`, the default estimator 6-D) before it is
calibrated, as a user would; each sensor's ``quat`` holds its true orientation.
"""

import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab import stages
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import compose, decompose
from motionlab.protocol import load_protocol
from motionlab.segments import calibrate_segments, orientations_sha256, segment_orientations
from motionlab.segments.frames import lm_fit, wahba
from motionlab.segments.functional import functional_axis
from motionlab.segments.heading import apply_heading, heading_from_hinge
from motionlab.segments.hinge import hinge_axes
from motionlab.segments.sensors import sensor_quats
from motionlab.session import SensorStream, Session

RATE = 100.0
G = 9.81
STANDING = rot.from_matrix(np.column_stack([[0.0, 1, 0], [0.0, 0, 1], [1.0, 0, 0]]))
Z = np.array([0.0, 0.0, 1.0])


def smooth_step(t, t0, t1):
    s = np.clip((t - t0) / (t1 - t0), 0, 1)
    return s * s * (3 - 2 * s)


def knee_truth(seed=0):
    """Segment → earth quaternions of a knee protocol session (100 Hz) and its step times."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 44, 1 / RATE)
    sit = smooth_step(t, 3, 5) - smooth_step(t, 36, 38)  # sit down at 3-5 s, stand up at 36-38
    hip = np.radians(90) * sit
    knee = {"r": np.radians(90) * sit, "l": np.radians(90) * sit}
    wobble = {}
    for side, (t0, t1) in {"r": (9, 19), "l": (22, 32)}.items():
        on = (t > t0) & (t < t1)
        knee[side] = knee[side] - np.where(on, np.radians(40) * (1 - np.cos(np.pi * (t - t0))), 0)
        # slightly non-planar movement: 2° of ad/abduction and rotation with the flexion
        wobble[side] = np.where(on, np.radians(2) * np.sin(np.pi * (t - t0)), 0)
    # task after standing up: walking-like knee motion with known ab/adduction and rotation
    task = t > 39
    truth_angles = {}
    seg_q = {"pelvis": np.tile(STANDING, (len(t), 1))}
    for side in "rl":
        hip_q = compose(np.column_stack([-hip, 0 * t, 0 * t]), "knee", "r")  # +z about pelvis
        thigh = rot.mul(seg_q["pelvis"], hip_q)
        fl = knee[side] + np.where(task, np.radians(30) * (1 - np.cos(2 * np.pi * t)), 0)
        ad = wobble[side] + np.where(task, np.radians(5) * np.sin(2 * np.pi * t), 0)
        ro = wobble[side] + np.where(task, np.radians(8) * np.sin(2 * np.pi * t + 1), 0)
        ang = np.column_stack([fl, ad, ro])
        truth_angles[side] = ang
        seg_q[f"thigh_{side}"] = thigh
        seg_q[f"shank_{side}"] = rot.mul(thigh, compose(ang, "knee", side))
    steps = {
        "standing": (0.5, 2.5),
        "sitting": (5.5, 8.5),
        "knee_flexion_r": (9, 19),
        "knee_flexion_l": (22, 32),
    }
    return t, seg_q, truth_angles, steps, rng


def body_rates(t, q):
    """Angular velocity (N, 3) in the body frame of a quaternion series."""
    dq = rot.mul(rot.conj(q[:-1]), q[1:])
    w = rot.to_rotvec(dq) / np.diff(t)[:, None]
    return np.vstack([w, w[-1]])


def knee_session(seed=0, max_err_deg=30.0):
    t, seg_q, truth, steps, rng = knee_truth(seed)
    protocol = load_protocol("knee")
    session, mounts = Session(), {}
    for seg, q_seg in seg_q.items():
        n = protocol.segments[seg].nominal_mounting().T  # segment → sensor
        direction = rng.normal(size=3)
        angle = np.radians(max_err_deg) * rng.uniform(0.5, 1.0)
        err = rot.to_matrix(rot.from_axis_angle(direction, angle))
        m = n @ err
        mounts[seg] = rot.from_matrix(m)
        q_sensor = rot.mul(q_seg, rot.conj(mounts[seg]))
        acc = rot.rotate(rot.conj(q_sensor), G * Z) + rng.normal(0, 0.05, (len(t), 3))
        gyr = body_rates(t, q_sensor) + rng.normal(0, 0.01, (len(t), 3))
        session.sensors[seg] = SensorStream(label=seg, time=t, acc=acc, gyr=gyr, segment=seg)
        session.sensors[seg].quat = q_sensor  # the true orientation
    stages.fuse(session)
    return session, protocol, mounts, truth, steps, t


def test_knee_calibration_recovers_mountings_and_steps():
    session, protocol, mounts, _, steps, _ = knee_session()
    cal = calibrate_segments(session, protocol)
    for name, (t0, t1) in steps.items():
        found = cal.steps[name]
        assert found[0] >= t0 - 1.0 and found[1] <= t1 + 1.0, (name, found)
    assert cal.steps["hip_flexion_r"] is None
    for seg, res in cal.segments.items():
        err = np.degrees(rot.angle(rot.mul(rot.conj(mounts[seg]), res.mounting)))
        limit = 2.0 if res.method == "procrustes" else 40.0
        assert err < limit, (seg, err, res.method)
        assert res.quality.min_rho > 0.9
    assert cal.segments["shank_r"].method == "procrustes"
    assert cal.segments["pelvis"].method == "single_axis"


def test_heading_ties_are_found_once_at_calibration():
    """The calibration stores each joint's heading ties with the SHA-256 of each segment's
    orientations; the angles apply them to those orientations (the same segment frames as
    finding them again), also when given only some segments, and shifted ties turn the distal
    segment by the shift; a joint whose sensor orientations differ finds its ties anew."""
    session, protocol, *_ = knee_session(seed=2)
    cal = calibrate_segments(session, protocol)
    quats = sensor_quats(session, protocol)
    assert cal.headings.sha256 == {s: orientations_sha256(*tq) for s, tq in quats.items()}
    assert set(cal.headings.joints) == set(protocol.joints)
    stored = segment_orientations(protocol, cal, quats)
    fresh = segment_orientations(protocol, dataclasses.replace(cal, headings=None), quats)
    for seg, (_, q) in fresh.items():
        assert np.array_equal(stored[seg][1], q), seg
    name, ties = next((k, v) for k, v in cal.headings.joints.items() if len(v.times))
    joint = protocol.joints[name]
    cal.headings.joints[name] = dataclasses.replace(ties, deltas=ties.deltas + np.radians(10.0))
    shifted = segment_orientations(protocol, cal, quats)[joint.distal][1]
    turn = np.degrees(rot.angle(rot.mul(shifted, rot.conj(stored[joint.distal][1]))))
    np.testing.assert_allclose(turn, 10.0, atol=1e-6)
    # the joint's two segments alone (as the gait and metrics stages ask): still the stored ties
    pair = {s: quats[s] for s in (joint.proximal, joint.distal)}
    alone = segment_orientations(protocol, cal, pair)[joint.distal][1]
    np.testing.assert_allclose(rot.angle(rot.mul(alone, rot.conj(shifted))), 0.0, atol=1e-9)
    # other orientations of the distal sensor (another estimator): the ties are found anew
    t, q = quats[joint.distal]
    other = dict(quats) | {joint.distal: (t, rot.mul(q, rot.from_rotvec(np.array([0, 1e-6, 0]))))}
    anew = segment_orientations(protocol, cal, other)[joint.distal][1]
    turn = np.degrees(rot.angle(rot.mul(anew, rot.conj(stored[joint.distal][1]))))
    assert np.max(turn) < 0.01  # not the 10° shift of the stored ties


def test_knee_angles_after_calibration_and_heading_alignment():
    session, protocol, _, truth, _, t = knee_session(seed=1)
    cal = calibrate_segments(session, protocol)
    # 6-D fusion: each sensor has its own heading; the calibration must align them
    quats = {
        seg: (s.time, apply_heading(s.quat, np.radians(40.0 * i - 60)))
        for i, (seg, s) in enumerate(session.sensors.items())
    }
    seg_q = segment_orientations(protocol, cal, quats)
    for side in "rl":
        got = decompose(seg_q[f"thigh_{side}"][1], seg_q[f"shank_{side}"][1], "knee", side)
        err = np.degrees(np.sqrt(np.mean((got - truth[side])[t > 39] ** 2, axis=0)))
        assert np.all(err < [1.0, 2.0, 2.0]), (side, err)
    # without calibration the sensors' axes give cross-talk and offsets
    raw = segment_orientations(protocol, None, quats, align_heading=False)
    got = decompose(raw["thigh_r"][1], raw["shank_r"][1], "knee", "r")
    assert np.degrees(np.sqrt(np.mean((got - truth["r"]) ** 2, axis=0))).max() > 10


def test_missing_step_is_input_error():
    session, protocol, *_ = knee_session()
    for s in session.sensors.values():  # cut the recording before the left knee movement
        keep = s.time < 20.5
        s.time, s.acc, s.gyr = s.time[keep], s.acc[keep], s.gyr[keep]
    with pytest.raises(InputError, match="knee_flexion_l.*not found"):
        calibrate_segments(session, protocol)


def test_time_range_override():
    session, protocol, *_ = knee_session()
    protocol.calibration[2].time_range = (10.0, 18.0)
    cal = calibrate_segments(session, protocol)
    assert cal.steps["knee_flexion_r"] == [10.0, 18.0]


def test_functional_axis_svd_and_reliability():
    rng = np.random.default_rng(2)
    t = np.arange(0, 10, 0.01)
    axis = rot.normalize(np.array([0.3, -0.8, 0.5]))
    w = 3 * np.sin(np.pi * t)[:, None] * axis + rng.normal(0, 0.006, (len(t), 3))  # Ricci eq. 6.14
    v, rho, n = functional_axis(w)
    assert abs(v @ axis) > np.cos(np.radians(0.2)) and rho > 0.99 and n < len(t)
    # repetitions about three orthogonal axes: ρ near 1/3
    mix = np.vstack([3 * np.sin(np.pi * t)[:, None] * e for e in np.eye(3)])
    assert functional_axis(mix)[1] < 0.36


def test_procrustes_matches_lm_and_truth():
    rng = np.random.default_rng(4)
    m_true = rot.to_matrix(rot.normalize(rng.normal(size=4)))
    r = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0, 1, 0]])
    v = r @ m_true.T + rng.normal(0, 0.02, (4, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    w = np.array([0.9, 0.98, 0.7, 0.6])
    m = wahba(v, r, w)
    m_lm, iters = lm_fit(v, r, w, q0=rot.from_matrix(m_true.T) + 0.1)
    assert np.degrees(rot.angle(rot.from_matrix(m.T @ m_true))) < 3
    assert np.degrees(rot.angle(rot.from_matrix(m.T @ m_lm))) < 0.1 and iters < 30


def test_seel_hinge_axes_and_heading_from_hinge():
    rng = np.random.default_rng(5)
    t = np.arange(0, 20, 0.01)
    # thigh moves arbitrarily, shank = thigh ⊗ flexion about the segment z (a hinge)
    rv = np.column_stack([0.6 * np.sin(0.7 * t), 0.4 * np.sin(1.3 * t + 1), 0.8 * np.sin(0.9 * t)])
    q_thigh = rot.from_rotvec(rv)
    flex = np.radians(40) * (1 - np.cos(2.1 * t))
    q_shank = rot.mul(q_thigh, compose(np.column_stack([flex, 0 * t, 0 * t]), "knee", "r"))
    m1 = rot.normalize(rng.normal(size=4))
    m2 = rot.normalize(rng.normal(size=4))  # segment → sensor mountings
    g1 = body_rates(t, rot.mul(q_thigh, rot.conj(m1))) + rng.normal(0, 0.01, (len(t), 3))
    g2 = body_rates(t, rot.mul(q_shank, rot.conj(m2))) + rng.normal(0, 0.01, (len(t), 3))
    j1_true, j2_true = rot.rotate(m1, Z), rot.rotate(m2, Z)
    j1, j2, res = hinge_axes(g1, g2, prior1=j1_true, prior2=j2_true + 0.5)
    assert np.degrees(np.arccos(j1 @ j1_true)) < 1.0
    assert np.degrees(np.arccos(j2 @ j2_true)) < 1.0
    # heading: turn the shank's earth frame by 35° and recover it from the hinge axis
    q_shank_6d = apply_heading(q_shank, np.radians(35))
    delta = heading_from_hinge(q_thigh, q_shank_6d, Z, Z)
    assert abs(np.degrees(delta) + 35) < 0.5


def test_hinge_fit_on_active_samples_with_the_analytic_jacobian(monkeypatch):
    """The fit uses at most MAX_SAMPLES moving samples and Seel's analytic Jacobian, and lands
    within 0.1° of the plain fit over every sample with a finite-difference Jacobian."""
    import scipy.optimize

    from motionlab.segments import hinge

    rng = np.random.default_rng(6)
    t = np.arange(0, 80, 0.01)
    on = smooth_step(t, 10, 11) - smooth_step(t, 69, 70)  # 10 s still at both ends
    rv = on[:, None] * np.column_stack(
        [0.6 * np.sin(0.7 * t), 0.4 * np.sin(1.3 * t + 1), 0.8 * np.sin(0.9 * t)]
    )
    q_thigh = rot.from_rotvec(rv)
    flex = np.radians(40) * (1 - np.cos(2.1 * t)) * on
    q_shank = rot.mul(q_thigh, compose(np.column_stack([flex, 0 * t, 0 * t]), "knee", "r"))
    m1, m2 = rot.normalize(rng.normal(size=(2, 4)))
    g1 = body_rates(t, rot.mul(q_thigh, rot.conj(m1))) + rng.normal(0, 0.01, (len(t), 3))
    g2 = body_rates(t, rot.mul(q_shank, rot.conj(m2))) + rng.normal(0, 0.01, (len(t), 3))
    j1_true, j2_true = rot.rotate(m1, Z), rot.rotate(m2, Z)

    calls = []
    real = scipy.optimize.least_squares

    def spy(fun, x0, jac="2-point", **kw):
        calls.append((len(fun(x0)), callable(jac)))
        if callable(jac):  # the analytic Jacobian agrees with finite differences
            num = scipy.optimize.approx_fprime(x0, lambda x: fun(x)[7], 1e-7)
            assert np.allclose(jac(x0)[7], num, atol=1e-4)
        return real(fun, x0, jac=jac, **kw)

    monkeypatch.setattr(hinge, "least_squares", spy)
    j1, j2, _ = hinge.hinge_axes(g1, g2, prior1=j1_true, prior2=j2_true)
    moving = np.sum(np.maximum(np.linalg.norm(g1, axis=1), np.linalg.norm(g2, axis=1)) > 0.1)
    assert all(jac and n <= hinge.MAX_SAMPLES for n, jac in calls)
    assert len(g1) - moving > 1500  # the rests were there to leave out

    def plain(x):  # Seel's residual over every sample
        a, b = hinge._unit(x[0], x[1]), hinge._unit(x[2], x[3])
        return np.linalg.norm(np.cross(g1, a), axis=1) - np.linalg.norm(np.cross(g2, b), axis=1)

    x0 = np.array([*hinge._angles(j1_true), *hinge._angles(j2_true)])
    ref = real(plain, x0, method="lm").x
    for j, r in ((j1, hinge._unit(ref[0], ref[1])), (j2, hinge._unit(ref[2], ref[3]))):
        assert np.degrees(np.arccos(min(1.0, abs(j @ r)))) < 0.1
    assert np.degrees(np.arccos(j2 @ j2_true)) < 1.0
