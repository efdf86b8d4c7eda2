"""Simulator physics: gyro integration, gravity at rest, magnetic field, joint angles, lever arm."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import decompose
from motionlab.protocol import CalibrationStep, Joint, Protocol, Segment, Task, list_protocols
from motionlab.simulate import simulate
from motionlab.simulate.body import Body
from motionlab.simulate.chain import segment_poses
from motionlab.simulate.timeline import plan

G = 9.81


def knee_protocol() -> Protocol:
    segs = {
        "pelvis": Segment("pelvis", landmarks=["LASI", "RASI"]),
        "thigh_r": Segment("thigh_r", "r", landmarks=["RGT", "RLE", "RME"]),
        "shank_r": Segment("shank_r", "r", sensor_axes=("-z", "y", "x"), landmarks=["RLM"]),
        "thigh_l": Segment("thigh_l", "l"),
        "shank_l": Segment("shank_l", "l"),
    }
    return Protocol(
        name="knee_test",
        segments=segs,
        joints={
            "knee_r": Joint("knee_r", "knee", "thigh_r", "shank_r", "r"),
            "knee_l": Joint("knee_l", "knee", "thigh_l", "shank_l", "l"),
        },
        calibration=[
            CalibrationStep(
                "standing", "static", 5.0, pose="standing", vertical_axis={"thigh_r": "y"}
            ),
            CalibrationStep(
                "knee_flex_r",
                "functional",
                10.0,
                instructions="seated",
                segments=["shank_r"],
                axis={"shank_r": "-z"},
                repetitions=5,
            ),
        ],  # fmt: skip
        tasks=[Task("gait", "gait", 30.0), Task("squat", "squat", 10.0, 3)],
    )


@pytest.fixture(scope="module")
def clean():
    """60 s of the knee protocol, no sensor errors, at 400 Hz."""
    return simulate(knee_protocol(), 60.0, 1, "clean", rate_hz=400.0)


def test_gyro_integrates_to_the_true_orientation(clean):
    session, truth = clean
    for label, s in session.sensors.items():
        q = truth.sensors[label]["orientation"]
        q_int = rot.integrate_gyro(q[0], s.gyr, np.diff(s.time))
        err = np.degrees(rot.angle_between(q_int, q))
        assert err[-1] < 0.05, (label, err[-1])
        assert s.time[-1] == pytest.approx(60.0)


def test_accelerometer_at_rest_reads_gravity(clean):
    session, truth = clean
    step = truth.step("standing")
    still = (truth.time >= step["start_s"]) & (truth.time <= step["end_s"])
    for label, s in session.sensors.items():
        q = truth.sensors[label]["orientation"][still]
        expected = rot.rotate(rot.conj(q), [0.0, 0.0, G])
        assert np.abs(s.acc[still] - expected).max() < 1e-6
        assert np.abs(s.gyr[still]).max() < 1e-9
        assert np.linalg.norm(s.acc[still], axis=1) == pytest.approx(G, abs=1e-6)


def test_magnetometer_norm_and_dip(clean):
    session, truth = clean
    for label, s in session.sensors.items():
        b = rot.rotate(truth.sensors[label]["orientation"], s.mag)
        assert np.linalg.norm(s.mag, axis=1) == pytest.approx(50.0, abs=1e-9)
        dip = np.degrees(np.arctan2(-b[:, 2], np.hypot(b[:, 0], b[:, 1])))
        assert dip == pytest.approx(60.0, abs=1e-9)
        assert np.abs(b[:, 0]).max() < 1e-9  # magnetic north is +y


def test_joint_angles_match_segment_orientations(clean):
    _, truth = clean
    for side in "rl":
        q_p = truth.segments[f"thigh_{side}"]["orientation"]
        q_d = truth.segments[f"shank_{side}"]["orientation"]
        angles = np.degrees(decompose(q_p, q_d, "knee", side))
        for i, name in enumerate(("flexion", "adduction", "rotation")):
            stored = truth.joint_angles[f"knee_{side}_{name}_deg"]
            assert np.abs(angles[:, i] - stored).max() < 1e-9
    flex = truth.joint_angles["knee_r_flexion_deg"]
    gait = truth.step("gait")
    walk = (truth.time > gait["start_s"] + 5) & (truth.time < gait["end_s"] - 5)
    assert 55 < flex[walk].max() < 70 and flex[walk].min() < 8  # gait-like knee flexion
    assert np.abs(truth.joint_angles["knee_r_adduction_deg"][walk]).max() < 6
    assert np.abs(truth.joint_angles["knee_r_rotation_deg"][walk]).max() < 11


def test_specific_force_matches_second_derivative_of_position(clean):
    session, truth = clean
    dt = truth.time[1] - truth.time[0]
    for label, s in session.sensors.items():
        p = truth.sensors[label]["position"]
        a = (-p[4:] + 16 * p[3:-1] - 30 * p[2:-2] + 16 * p[1:-3] - p[:-4]) / (12 * dt**2)
        q = truth.sensors[label]["orientation"][2:-2]
        f = rot.rotate(rot.conj(q), a + [0.0, 0.0, G])
        err = np.abs(f - s.acc[2:-2]).max()
        dyn = np.abs(s.acc - rot.rotate(rot.conj(truth.sensors[label]["orientation"]),
                                        [0.0, 0.0, G])).max()  # fmt: skip
        assert dyn > 2.0  # the sensor really accelerates
        assert err < 1e-3, (label, err)


def test_feet_stay_on_the_floor_in_squats_and_sitting():
    body = Body(1.6)
    tl = plan(knee_protocol(), body, 60.0, seed=1)
    sq = next(s for s in tl.steps() if s["name"] == "squat")
    t = np.linspace(sq["start_s"], sq["end_s"], 500)
    poses = segment_poses(body, tl.channels(t), ["foot_r", "foot_l", "thigh_r"])
    for foot in ("foot_r", "foot_l"):
        z = poses[foot][1][:, 2]
        assert np.abs(z - 0.039 * 1.6).max() < 2e-3  # knee coupling tilts the shank slightly
    thigh_height = poses["thigh_r"][1][:, 2]
    assert thigh_height.min() < 0.53 * 1.6 - 0.2  # a real squat: the hips drop 20 cm or more


def test_static_steps_are_still_and_in_protocol_order(clean):
    _, truth = clean
    names = [s["name"] for s in truth.steps]
    assert names == ["standing", "knee_flex_r", "gait", "squat"]
    starts = [s["start_s"] for s in truth.steps]
    assert starts == sorted(starts) and truth.steps[-1]["end_s"] <= 60.0
    step = truth.step("standing")
    still = (truth.time >= step["start_s"]) & (truth.time <= step["end_s"])
    q = truth.segments["shank_r"]["orientation"][still]
    assert np.degrees(rot.angle_between(q, q[:1])).max() < 1e-9


def test_gait_walks_through_the_room_and_turns():
    session, truth = simulate(knee_protocol(), 50.0, 2, "clean", calibration=False)
    p = truth.segments["pelvis"]["position"]
    assert np.ptp(p[:, 0]) > 3.0 or np.ptp(p[:, 1]) > 3.0
    heading = np.unwrap(np.arctan2(*rot.rotate(truth.segments["pelvis"]["orientation"],
                                                [1.0, 0, 0])[:, 1::-1].T))  # fmt: skip
    assert np.ptp(heading) > np.pi  # the magnetometer matters


def test_wobble_keeps_integration_exact():
    proto = knee_protocol()
    proto.segments = {k: v for k, v in proto.segments.items() if k == "shank_r"}
    proto.joints = {}
    from motionlab.simulate.errors import Preset

    session, truth = simulate(proto, 45.0, 4, Preset("wobbly", wobble_deg=2.0), rate_hz=400.0)
    s = session.sensors["shank_r"]
    q = truth.sensors["shank_r"]["orientation"]
    q_seg = truth.segments["shank_r"]["orientation"]
    q_mount = rot.mul(rot.conj(q_seg), q)
    assert np.degrees(rot.angle_between(q_mount, q_mount[:1])).max() > 0.5  # it wobbles
    err = np.degrees(rot.angle_between(rot.integrate_gyro(q[0], s.gyr, 1 / 400.0), q))
    assert err[-1] < 0.05


@pytest.mark.parametrize("name", list_protocols())
def test_shipped_protocols_simulate(name):
    session, truth = simulate(name, 240.0, 0, "clean", rate_hz=50.0)
    assert set(session.sensors) == set(truth.sensors)
    assert truth.joint_angles and all(np.isfinite(v).all() for v in truth.joint_angles.values())
    assert all(s["end_s"] <= 240.0 for s in truth.steps)
