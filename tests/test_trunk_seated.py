"""The lumbar_seated protocol (segments/trunk_axes.py) on a simulated seated session: a rest
anywhere, the trunk's three planes in one continuous block; the trunk's lean against a chair;
recordings without a rest refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.kinematics.joint_angles import decompose
from motionlab.pipeline import PipelineOptions, analyse
from motionlab.session import SensorStream
from motionlab.simulate import simulate
from motionlab.timebase import take

PLANES = ("flexion", "lateral_bending", "axial_rotation")
OPTIONS = PipelineOptions(protocol="lumbar_seated", progress=False, clock_sync=False)


@pytest.fixture(scope="module")
def seated():
    """A seated session (50 Hz, typical sensors): rest, sitting still, one continuous block of
    flexion, lateral bending and rotation, then everyday movement; and its truth."""
    return simulate("lumbar_seated", duration=40, seed=2, preset="typical", rate_hz=50)


def _crop(session, t0: float, t1: float):
    """The session with every sensor cut to ``[t0, t1]`` s (a recording started late or
    stopped early)."""
    s = dataclasses.replace(session, sensors=dict(session.sensors))
    for label, stream in s.sensors.items():
        s.sensors[label] = take(stream, np.flatnonzero((stream.time >= t0) & (stream.time <= t1)))
    s.results = type(session.results)()
    return s


def _errors(session, truth) -> dict[str, np.ndarray]:
    """Per plane the error (deg) over the trunk block, with the truth's zero at the rest."""
    cols = session.results.angles.columns()
    t = cols["time_s"]
    rest = session.results.calibration.steps["rest"]
    block = truth.step("trunk_movement")
    inside = (t >= block["start_s"]) & (t <= block["end_s"])
    at_rest = (t >= rest[0]) & (t <= rest[1])
    out = {}
    for plane in PLANES:
        ref = np.interp(t, truth.time, truth.joint_angles[f"lumbar_{plane}_deg"])
        out[plane] = (cols[f"lumbar_{plane}_deg"] - (ref - ref[at_rest].mean()))[inside]
    return out


def test_seated_continuous_trunk_movement_gives_the_lumbar_angles(seated):
    session, truth = seated
    session = _crop(session, 0.0, 1e9)
    analyse(session, OPTIONS)
    cal = session.results.calibration
    assert cal.grades["lumbar"]["grades"] == ["determined"] * 3
    rest = cal.steps["rest"]
    assert rest[1] - rest[0] >= 1.0
    err = _errors(session, truth)
    rmse = {p: float(np.sqrt(np.mean(e**2))) for p, e in err.items()}
    # measured (seed 2, 50 Hz): 1.1 / 1.4 / 0.9°, within the 1.5° per plane; seed 2
    # rests standing, the other seeds rest seated with the thorax flexed 10° and reach 6° in
    # lateral bending (bench/seated_trunk_sim.py, docs/kinematics.md), hence the looser bound
    assert rmse["flexion"] < 1.5 and rmse["axial_rotation"] < 1.5
    assert rmse["lateral_bending"] < 2.0


def test_a_recording_that_starts_moving_and_rests_only_at_the_end(seated):
    session, truth = seated
    block = truth.step("trunk_movement")
    late = _crop(session, block["start_s"] + 2.0, 1e9)  # started in the middle of the block
    analyse(late, OPTIONS)
    rest = late.results.calibration.steps["rest"]
    assert rest[0] > block["end_s"]  # the only rest left is after the movement
    assert np.isfinite(late.results.angles.columns()["lumbar_flexion_deg"]).all()


def test_no_rest_is_one_line_naming_the_protocol_and_the_remedy(tmp_path):
    from tests import ximu3_export as xe

    imu = xe.write(tmp_path, xe.export_files(seconds=4.0))  # both turning at 30°/s throughout
    (tmp_path / "map.yaml").write_text(
        "sensors:\n  Back: {segment: thorax}\n  Chest: {segment: pelvis}\n"
    )
    res = CliRunner().invoke(
        main, ["run", str(imu), "--map", str(tmp_path / "map.yaml"), "--protocol",
               "lumbar_seated", "-o", str(tmp_path / "out"), "--quiet"],
    )  # fmt: skip
    assert res.exit_code == 2, res.output
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1
    assert "lumbar_seated.yaml" in line and "no rest" in line and "30°/s" in line
    assert "sitting or standing still" in line


def test_the_trunk_leans_against_a_still_chair(seated):
    session, truth = seated
    block = truth.step("trunk_movement")
    session = _crop(session, 0.0, block["end_s"] + 2.0)  # seated: rest, then the trunk block
    pelvis = session.sensors[next(k for k, s in session.sensors.items() if s.segment == "pelvis")]
    mount = rot.from_axis_angle(np.array([1.0, 2.0, 0.5]) / np.sqrt(5.25), 1.1)  # any way up
    g = rot.rotate(rot.conj(mount), np.array([0.0, 0.0, 9.81]))
    rng = np.random.default_rng(0)
    n = pelvis.n_samples
    session.sensors["chair"] = SensorStream(
        "chair", pelvis.time.copy(), acc=g + 0.02 * rng.standard_normal((n, 3)),
        gyr=0.002 * rng.standard_normal((n, 3)), segment="chair",
    )  # fmt: skip
    analyse(session, OPTIONS)
    cols = session.results.angles.columns()
    assert session.results.calibration.grades["trunk_chair"]["grades"][2] == "determined"
    t = cols["time_s"]
    rest = session.results.calibration.steps["rest"]
    q = rot.resample(truth.time, truth.segments["thorax"]["orientation"], t)
    at_rest = (t >= rest[0]) & (t <= rest[1])
    q0 = rot.mean(rot.make_continuous(q[at_rest]))
    # the truth: the thorax against its own rest pose, the chair being still
    want = np.degrees(decompose(np.broadcast_to(q0, q.shape), q, "lumbar"))
    inside = (t >= block["start_s"]) & (t <= block["end_s"])
    forward = cols["trunk_lean_forward_deg"][inside]
    sideways = cols["trunk_lean_sideways_deg"][inside]
    assert forward.max() > 40  # the simulated forward bend
    assert np.sqrt(np.mean((forward - want[inside, 0]) ** 2)) < 2.0
    assert np.sqrt(np.mean((sideways - want[inside, 1]) ** 2)) < 3.0


def test_the_lumbar_protocol_refusing_a_seated_recording_names_lumbar_seated(seated):
    from motionlab import stages
    from motionlab.errors import InputError

    session, _ = seated
    session = _crop(session, 0.0, 1e9)
    stages.fuse(session)
    with pytest.raises(InputError, match="the shipped protocol 'lumbar_seated' fits"):
        stages.calibrate(session, "lumbar")
