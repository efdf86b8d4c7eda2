"""Orientation-only recordings through ``run`` to knee angles: OpenSense's own ``.sto`` (a single
calibration pose, OpenSense-style single-pose calibration), an Xsens DOT pair, and a simulated
session round-tripped through ``export --to sto`` and ``ingest``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import SHARED, needs_shared
from test_pipeline import PROTOCOL

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.kinematics.angle_filter import smoothed_table
from motionlab.kinematics.session_angles import session_angles
from motionlab.protocol import load_protocol
from motionlab.segments import calibrate_segments
from motionlab.session import SensorStream, Session, load_session, save_session
from motionlab.simulate import simulate

RKNEE = """\
name: rknee
title: "Right knee from orientations (stand, then move)"
segments:
  thigh_r: {side: r}
  shank_r: {side: r}
calibration:
  - {name: standing, kind: static, pose: standing, duration_s: 1,
     vertical_axis: {thigh_r: y, shank_r: y}}
joints:
  knee_r: {type: knee, proximal: thigh_r, distal: shank_r, side: r}
tasks:
  - {name: movement, kind: free, duration_s: 3}
"""
STO_MAP = """\
sensors:
  femur_r_imu: {segment: thigh, side: r}
  tibia_r_imu: {segment: shank, side: r}
"""
DOT_MAP = """\
sensors:
  ydt: {segment: thigh, side: r}
  yxt: {segment: shank, side: r}
"""
FLEX = "knee_r_flexion_deg"


def _cli(*args) -> str:
    res = CliRunner().invoke(main, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res.output


def _run_real(tmp_path, files, map_text) -> tuple[Session, str]:
    (tmp_path / "rknee.yaml").write_text(RKNEE)
    (tmp_path / "map.yaml").write_text(map_text)
    _cli("ingest", *files, "--map", tmp_path / "map.yaml", "-o", tmp_path / "in.h5")
    out = _cli("run", "--protocol", tmp_path / "rknee.yaml", tmp_path / "in.h5",
               "-o", tmp_path / "out", "--quiet")  # fmt: skip
    return load_session(tmp_path / "out" / "session.h5"), out


@needs_shared
def test_opensense_calibration_pose_sto_gives_knee_angles_by_single_pose(tmp_path):
    sto = SHARED / "formats" / "opensim" / "imuOrientations.sto"
    ses, out = _run_real(tmp_path, [sto], STO_MAP)
    cal = ses.results.calibration
    assert cal.single_pose == "standing"
    assert cal.steps == {"standing": [0.0, 0.01]}  # the whole recording (2 samples)
    assert cal.grades["knee_r"].grades == ["weak", "weak", "weak"]
    single = [w for w in cal.warnings if "single-pose" in w]
    assert len(single) == 1 and "OpenSense-style" in single[0] and "sensor_axes hint" in single[0]
    assert "single-pose calibration (OpenSense-style)" in out
    angles = ses.results.angles.columns()
    np.testing.assert_allclose(angles["time_s"], [0.0, 0.01])
    for col in (FLEX, "knee_r_adduction_deg", "knee_r_rotation_deg"):
        assert np.all(np.isfinite(angles[col]))
        assert np.max(np.abs(angles[col])) < 0.5  # the pose is the angles' zero, by definition
    for seg in ("thigh_r", "shank_r"):  # the segment's vertical axis points up in the pose
        q_mount = np.asarray(cal.segments[seg].mounting)
        q_sensor = ses.sensors[cal.segments[seg].sensor].quat
        y_earth = rot.rotate(rot.mul(q_sensor, q_mount), np.tile([0.0, 1.0, 0.0], (2, 1)))
        assert np.degrees(np.arccos(np.clip(y_earth[:, 2], -1, 1))).max() < 0.1
        assert cal.segments[seg].method == "single_axis"


def test_a_short_recording_of_raw_signals_is_still_refused(tmp_path):
    """Only sensors carrying an orientation take the single-pose path."""
    (tmp_path / "rknee.yaml").write_text(RKNEE)
    protocol = load_protocol(tmp_path / "rknee.yaml")
    t = np.arange(0.0, 0.5, 0.01)
    ses = Session()
    for label, seg in (("T", "thigh"), ("S", "shank")):
        ses.sensors[label] = SensorStream(
            label=label, time=t, acc=np.tile([0.0, 9.81, 0.0], (len(t), 1)),
            gyr=np.zeros((len(t), 3)), segment=seg, side="r",
        )  # fmt: skip
    with pytest.raises(InputError, match="the recording lasts 0.49 s"):
        calibrate_segments(ses, protocol)


def test_a_single_pose_is_read_from_the_orientation_the_angles_take(tmp_path):
    """An APDM recording of 3 samples, raw signals beside the vendor's quaternions, read its
    own pose as 20° of lateral bending: the pose was read from the vendor's orientations, the
    angles from the 6-D fusion 10° off them. Both now come from the fused orientation."""
    from motionlab import stages
    from motionlab.results import FusionEntry

    (tmp_path / "rknee.yaml").write_text(RKNEE)
    protocol = load_protocol(tmp_path / "rknee.yaml")
    t = np.arange(0.0, 0.03, 0.01)
    x = np.array([1.0, 0.0, 0.0])
    upright = np.tile(rot.from_axis_angle(x, np.pi / 2), (len(t), 1))  # sensor y up
    off = np.tile(rot.from_axis_angle(x, np.radians(10.0)), (len(t), 1))
    ses = Session()
    for label, seg in (("T", "thigh"), ("S", "shank")):
        ses.sensors[label] = SensorStream(
            label=label, time=t, acc=rot.rotate(rot.conj(upright), np.tile([0, 0, 9.81], (3, 1))),
            gyr=np.zeros((len(t), 3)), quat=rot.mul(off, upright) if label == "S" else upright,
            segment=seg, side="r",
        )  # fmt: skip
        ses.results.fusion[label] = FusionEntry(name="smoother", quat=upright)
    cal = stages.calibrate(ses, protocol)
    assert cal.single_pose == "standing"
    table = stages.angles(ses, protocol).columns()
    for col in (FLEX, "knee_r_adduction_deg", "knee_r_rotation_deg"):
        assert np.max(np.abs(table[col])) < 0.1, col  # the pose is the angles' zero (was 10°)


@needs_shared
def test_xsens_dot_pair_gives_knee_angles(tmp_path):
    dot = SHARED / "formats" / "dot"
    files = [next(dot.glob("RFemur_*.csv")), next(dot.glob("RTibia_*.csv"))]
    ses, _ = _run_real(tmp_path, files, DOT_MAP)
    cal = ses.results.calibration
    assert cal.single_pose is None  # 6 s: stand and movement are found
    assert cal.steps["standing"] is not None
    assert cal.grades["knee_r"].grades[0] == "weak"
    flex = ses.results.angles.columns()[FLEX]
    assert np.all(np.isfinite(flex))
    # measured 0-65.5°: the DOTs' own orientations turn the shank 65.7° away from the stand at
    # most, a figure no axis choice moves (Seel's axis gave 1-35° before the walk's principal
    # axes, segments/gait_axes.py)
    assert -5.0 < np.min(flex) < 5.0 and 55.0 < np.max(flex) < 70.0


@pytest.fixture(scope="module")
def sto_round_trip(tmp_path_factory):
    """A simulated right-knee session with a gap in the thigh sensor, run, exported to .sto and
    the .sto ingested."""
    root = tmp_path_factory.mktemp("sto_trip")
    (root / "knee.yaml").write_text(yaml.safe_dump(PROTOCOL))
    (root / "map.yaml").write_text(STO_MAP)
    session, _ = simulate(root / "knee.yaml", 30.0, 3, "typical", rate_hz=50.0,
                          mounting_max_deg=5.0)  # fmt: skip
    save_session(session, root / "sim.h5")
    _cli("run", "--protocol", root / "knee.yaml", root / "sim.h5", "-o", root / "out",
         "--no-clock-sync", "--quiet")  # fmt: skip
    _cli("export", root / "out" / "session.h5", "--to", "sto", "-o", root / "o.sto")
    _cli("ingest", root / "o.sto", "--map", root / "map.yaml", "-o", root / "sto.h5")
    return root


def test_sto_round_trip_reproduces_the_fused_angles(sto_round_trip):
    root = sto_round_trip
    original = load_session(root / "out" / "session.h5")
    ingested = load_session(root / "sto.h5")
    # the gap, as rows left out (NaN rows read back were refused): a step in the stamps
    assert all(np.isfinite(s.quat).all() for s in ingested.sensors.values())
    assert any(np.diff(s.time).max() > 0.1 for s in ingested.sensors.values())
    origin = ingested.metadata["time_origin_s"]  # ingest starts the clock at the first stamp
    for label, s in ingested.sensors.items():
        ingested.sensors[label] = dataclasses.replace(s, time=s.time + origin)
    protocol = load_protocol(root / "knee.yaml")
    # low-passed as the stored angles are, each run of samples on its own (the .sto's gap is
    # a step in the stamps, the original's NaN rows)
    table = smoothed_table(session_angles(ingested, protocol, original.results.calibration))
    ref = original.results.angles.columns()
    t = table["time_s"]
    shared = np.isin(np.round(t * 1e6), np.round(ref["time_s"] * 1e6))
    assert shared.mean() > 0.99  # the .sto keeps the time stamps
    assert t[0] == pytest.approx(ref["time_s"][0], abs=1e-9)
    assert t[-1] == pytest.approx(ref["time_s"][-1], abs=1e-9)
    for col in (FLEX, "knee_r_adduction_deg", "knee_r_rotation_deg"):
        diff = table[col] - np.interp(t, ref["time_s"], ref[col])
        assert np.max(np.abs(diff)) < 0.1, col  # measured 0.0007° (rotation), 4e-6° (flexion)


def test_run_on_the_sto_alone_matches_the_fused_knee_flexion(sto_round_trip):
    """The orientation-only calibration (gravity and rates from the orientation) against the
    original's from the raw signals: flexion RMS difference measured 2.3° (max 7.3° at the
    peaks) over 61° of range, the same range to 0.005°."""
    root = sto_round_trip
    _cli("run", "--protocol", root / "knee.yaml", root / "sto.h5", "-o", root / "out_sto",
         "--quiet")  # fmt: skip
    ses = load_session(root / "out_sto" / "session.h5")
    assert ses.results.calibration.single_pose is None
    assert {e.name for e in ses.results.fusion.values()} <= {"vendor"}
    ref = load_session(root / "out" / "session.h5").results.angles.columns()
    got = ses.results.angles.columns()
    t = got["time_s"] + ses.metadata["time_origin_s"]
    diff = got[FLEX] - np.interp(t, ref["time_s"], ref[FLEX])
    assert np.sqrt(np.mean(diff**2)) < 3.5
    assert abs(np.ptp(got[FLEX]) - np.ptp(ref[FLEX])) < 1.0  # measured 0.005°
