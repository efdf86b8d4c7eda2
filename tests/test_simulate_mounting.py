"""Sensors anywhere on the segment, soft tissue that follows the segment's acceleration, the loose
preset, and the stand-and-move protocols (walk, arm)."""

import numpy as np
import pytest
from click.testing import CliRunner

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.protocol import load_protocol
from motionlab.simulate import _uniform_rotation, simulate
from motionlab.simulate.body import Body

LEGS = ("thigh_r", "thigh_l", "shank_r", "shank_l")


def _walk(seed, preset="typical", **kw):
    """24 s of the walk protocol: 11 s standing (rests and the standing step), 10 s of gait."""
    return simulate("walk", 24.0, seed, preset, rate_hz=50.0, **kw)


@pytest.fixture(scope="module")
def loose():
    return _walk(5, "loose", mounting="random")


@pytest.fixture(scope="module")
def typical_motion():
    return _walk(5, "typical", mounting="random", soft_tissue="motion")


def _gait(truth):
    step = truth.step("walk")
    return (truth.time > step["start_s"] + 2.0) & (truth.time < step["end_s"] - 2.0)


def test_random_mountings_differ_across_sensors_and_seeds_and_repeat(loose):
    _, truth = loose
    q = np.array([s["mounting"] for s in truth.sensors.values()])
    pairs = [(i, j) for i in range(len(q)) for j in range(i + 1, len(q))]
    assert min(np.degrees(rot.angle_between(q[i], q[j])) for i, j in pairs) > 5.0
    _, again = _walk(5, "loose", mounting="random", calibration=False)
    _, other = _walk(6, "loose", mounting="random", calibration=False)
    body = Body()
    for seg, s in truth.sensors.items():
        np.testing.assert_array_equal(s["mounting"], again.sensors[seg]["mounting"])
        np.testing.assert_array_equal(s["site"], again.sensors[seg]["site"])
        assert np.degrees(rot.angle_between(s["mounting"], other.sensors[seg]["mounting"])) > 1.0
        # on the skin of its segment: along it and around it, not at the nominal site
        if seg != "pelvis":
            assert -body.segment_length(seg) < s["site"][1] < 0.0
            assert 0.02 < np.hypot(s["site"][0], s["site"][2]) < 0.10
        assert np.isclose(np.linalg.norm(s["normal"]), 1.0)


def test_uniform_rotations_have_zero_mean_matrix():
    rng = np.random.default_rng(0)
    m = rot.to_matrix(np.array([_uniform_rotation(rng) for _ in range(4000)])).mean(axis=0)
    assert np.abs(m).max() < 0.05  # Haar measure: E[R] = 0


def test_surface_mounting_lies_flat_on_the_skin():
    _, truth = _walk(2, "clean", mounting="surface", calibration=False)
    for s in truth.sensors.values():
        z_sensor = rot.rotate(s["mounting"], np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(z_sensor, s["normal"], atol=1e-12)


def test_nominal_default_keeps_the_older_truth_layout():
    _, truth = simulate("walk", 20.0, 1, "typical", rate_hz=25.0)
    assert "mounting" not in truth.config and "soft_tissue" not in truth.config
    assert "slip_deg" not in truth.config["error_model"]
    assert all("wobble" not in s for s in truth.sensors.values())


def test_sensor_orientation_is_segment_mounting_wobble(loose):
    _, truth = loose
    for seg, s in truth.sensors.items():
        q_seg, p_seg = truth.segments[seg]["orientation"], truth.segments[seg]["position"]
        q = rot.mul(rot.mul(q_seg, s["mounting"]), s["wobble"])
        assert np.degrees(rot.angle_between(q, s["orientation"])).max() < 1e-9
        p = p_seg + rot.rotate(q_seg, s["site"] + s["displacement"])
        assert np.abs(p - s["position"]).max() < 1e-12
        # the sensor's own angles are not the segment's: it moves on the segment
        assert np.degrees(rot.angle(s["wobble"])).max() > 0.5


def test_soft_tissue_amplitude_in_gait_typical_and_loose(typical_motion, loose):
    gait = _gait(typical_motion[1])
    peak = {}
    for name, (_, truth) in (("typical", typical_motion), ("loose", loose)):
        peak[name] = {
            seg: np.degrees(rot.angle(truth.sensors[seg]["wobble"][gait])).max() for seg in LEGS
        }
        first = truth.time < truth.step("standing")["end_s"]
        for s in truth.sensors.values():  # at rest before any movement the sensor sits still
            assert np.degrees(rot.angle(s["wobble"][first])).max() < 1e-6
            assert np.abs(s["displacement"][first]).max() < 1e-9
    typ = np.array(list(peak["typical"].values()))
    # documented (signals.py, README): typical ≈ 1-3° in gait (peaks 0.5-4°), loose about 3x
    assert 0.5 < np.median(typ) < 3.0 and typ.min() > 0.3 and typ.max() < 5.0
    for seg in LEGS:
        assert peak["loose"][seg] > 2.0 * peak["typical"][seg]
    d = np.abs(typical_motion[1].sensors["shank_r"]["displacement"][gait]).max()
    assert 2e-4 < d < 0.01  # a few mm


def test_walk_protocol_stands_then_walks(typical_motion):
    session, truth = typical_motion
    assert load_protocol("walk").segments["pelvis"].required is False
    steps = [(s["name"], s["kind"]) for s in truth.steps]
    assert steps == [("standing", "static"), ("walk", "gait")]
    walk = truth.step("walk")
    assert walk["start_s"] >= 8.0
    for s in session.sensors.values():
        gyr = np.linalg.norm(s.gyr, axis=1)
        assert gyr[s.time < walk["start_s"] - 0.1].max() < 0.1  # ≥ 8 s of quiet standing
    shank = session.sensors["shank_r"]
    assert np.linalg.norm(shank.gyr, axis=1)[shank.time > walk["start_s"] + 3].max() > 2.0


def test_arm_protocol_free_movement_covers_flexion_and_pronation():
    _, truth = simulate("arm", 60.0, 1, "clean", rate_hz=20.0, soft_tissue="impacts")
    task = truth.step("free_movement")
    assert task["generator"] == "free_arm"
    m = (truth.time > task["start_s"]) & (truth.time < task["end_s"])
    for side in "rl":
        flex = truth.joint_angles[f"elbow_{side}_flexion_deg"][m]
        pro = truth.joint_angles[f"elbow_{side}_pronation_deg"][m]
        assert flex.min() < 25 and flex.max() > 115
        assert pro.min() < -40 and pro.max() > 40
        # the upper arm moves too: its long axis turns away from vertical in many directions
        y = rot.rotate(truth.segments[f"upperarm_{side}"]["orientation"][m], [0.0, 1.0, 0.0])
        assert np.degrees(np.arccos(np.clip(-y[:, 2], -1, 1))).max() > 45


def test_cli_mounting_and_loose_preset(tmp_path):
    out, truth = tmp_path / "walk.h5", tmp_path / "truth.h5"
    args = ["simulate", "--protocol", "walk", "--duration", "18", "--rate", "25", "-o", str(out),
            "--truth", str(truth), "--mounting", "random", "--preset", "loose"]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(main, [*args[:-4], "--mounting", "anywhere", "--force"])
    assert res.exit_code == 2 and res.output.startswith("error: --mounting")
