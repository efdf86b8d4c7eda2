"""The segment table (motionlab/kinematics/segment_types.py) and what reads it: the OpenSense IMU
names of an exported ``.sto``."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from motionlab.cli import main
from motionlab.export import imu_name
from motionlab.io import read_any
from motionlab.kinematics.segment_types import (
    SEGMENT_TYPES,
    kind_side,
    opensim_imu_name,
    segment_type,
)
from motionlab.protocol import load_protocol
from motionlab.session import save_session
from motionlab.simulate import simulate


def test_every_protocol_segment_has_a_kind():
    for name in ("knee", "walk", "elbow", "arm", "lumbar", "lumbar_seated",
                 "upper_body_children"):  # fmt: skip
        for seg in load_protocol(name).segments:
            kind, side = kind_side(seg)
            st = segment_type(kind)
            assert st is not None, (name, seg)
            assert st.sided == bool(side), (name, seg)


def test_kind_side_and_aliases():
    assert kind_side("upperarm_l") == ("upperarm", "l")
    assert kind_side("pelvis") == ("pelvis", "")
    assert segment_type("upper_arm") is SEGMENT_TYPES["upperarm"]
    assert segment_type("trunk") is SEGMENT_TYPES["thorax"]
    assert segment_type("tail") is None


@pytest.mark.parametrize(
    ("segment", "side", "name"),
    [
        ("upperarm_r", "", "humerus_r_imu"),  # the protocols' spelling (was the sensor label)
        ("upperarm", "left", "humerus_l_imu"),  # a sensor map's kind + side
        ("upper_arm_l", "", "humerus_l_imu"),
        ("forearm_l", "", "radius_l_imu"),
        ("shank_r", "", "tibia_r_imu"),
        ("foot", "r", "calcn_r_imu"),
        ("thorax", "", "torso_imu"),
        ("pelvis", "r", "pelvis_imu"),  # midline: no side
        ("lumbar", "", None),
        ("chair", "", None),
    ],
)
def test_opensim_imu_names(segment, side, name):
    assert opensim_imu_name(segment, side) == name
    assert imu_name("label7", segment, side) == (name or "label7")


def test_arm_session_exports_humerus_and_radius_imus(tmp_path):
    """An elbow session (both arms and the thorax) fused and exported to .sto: every sensor is
    named after its OpenSim body, as OpenSense's IMU placer needs."""
    session, _ = simulate("elbow", 18.0, 3, "clean", rate_hz=50.0, calibration=False)
    save_session(session, tmp_path / "arm.h5")
    runner = CliRunner()
    res = runner.invoke(main, ["fuse", str(tmp_path / "arm.h5"), "--filter", "madgwick"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "arm.sto"
    res = runner.invoke(main, ["export", str(tmp_path / "arm.h5"), "--to", "sto", "-o", str(out)])
    assert res.exit_code == 0, res.output
    names = sorted(s.label for s in read_any(out).sensors)
    assert names == ["humerus_l_imu", "humerus_r_imu", "radius_l_imu", "radius_r_imu",
                     "torso_imu"]  # fmt: skip
