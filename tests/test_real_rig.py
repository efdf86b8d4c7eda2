"""The RING rig recording (../shared, not shipped: skipped without it) through the generic reader
and the optical joint-angle helpers; plus the helpers on hand-made poses (always run)."""

import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, SHARED

from motionlab.io import generic
from motionlab.kinematics.joint_angles import decompose
from motionlab.protocol import load_protocol
from motionlab.sensor_map import load_sensor_map
from motionlab.validation.joint_reference import (
    agreement_metrics,
    fit_clock_offset,
    read_orientation_csv,
)

# MOTIONLAB_SHARED points at the shared folder from a checkout that has no ../shared beside it
RING = Path(os.environ.get("MOTIONLAB_SHARED", SHARED)) / "datasets" / "ring" / "trial1"
needs_ring = pytest.mark.skipif(not RING.is_dir(), reason="../shared/datasets/ring is not present")
MAP = ROOT / "motionlab" / "protocols" / "examples" / "ring_map.yaml"
PROTOCOL = MAP.with_name("ring_rig.yaml")
HINGES = (("seg2", "seg3", "x"), ("seg3", "seg4", "y"), ("seg4", "seg5", "z"))


@needs_ring
@pytest.mark.parametrize("name", ["imu_rigid.csv", "imu_nonrigid.csv"])
def test_ring_imu_file_reads_five_sensors_at_40_hz(name):
    rec = generic.read(RING / name, load_sensor_map(MAP).reader)
    assert [s.label for s in rec.sensors] == ["seg1", "seg2", "seg3", "seg4", "seg5"]
    for s in rec.sensors:
        assert len(s.time) == 2650 and s.rate_hz == pytest.approx(40.0)
        assert s.channels == ["acc", "gyr", "mag"] and s.source_units["mag"] == "a.u."
        assert 9.0 < np.median(np.linalg.norm(s.acc[:40], axis=1)) < 10.5  # resting, m/s²


@needs_ring
def test_ring_optical_hinge_angles_are_finite_over_most_samples():
    t, q = read_orientation_csv(RING / "omc.csv")
    assert list(q) == ["seg1", "seg2", "seg3", "seg4", "seg5"]
    assert 1 / np.median(np.diff(t)) == pytest.approx(30.0)
    for prox, dist, axis in HINGES:
        a = np.degrees(decompose(q[prox], q[dist], "hinge", axis=axis)[:, 0])
        assert np.isfinite(a).mean() > 0.8
        assert np.nanmax(a) - np.nanmin(a) > 30  # the hinge moves


def test_clock_offset_and_agreement_on_a_shifted_signal():
    t_a = np.arange(0, 20, 1 / 40)
    t_b = np.arange(0, 20, 1 / 30)
    f = lambda t: np.sin(1.3 * t) + 0.5 * np.sin(3.1 * t + 1)  # noqa: E731
    b = f(t_b - 0.037)  # the event at t on clock a is at t + 0.037 on clock b
    b[100:130] = np.nan
    offset, r = fit_clock_offset(t_a, f(t_a), t_b, b)
    assert offset == pytest.approx(0.037, abs=0.0015) and r > 0.999
    m = agreement_metrics(-(f(t_a) + 2.0), f(t_a))
    assert m["flipped"] and m["r"] < -0.99
    assert m["rmse_offset_free_deg"] == pytest.approx(0.0, abs=1e-9)
    assert m["mean_diff_deg"] == pytest.approx(2.0)  # after the flip


def test_ring_protocol_follows_the_rig_and_the_rest_loads(tmp_path):
    doc = yaml.safe_load(PROTOCOL.read_text(encoding="utf-8"))
    assert doc["joints"] == {
        "ball12": {"type": "ball", "proximal": "seg1", "distal": "seg2", "sequence": "ZXY"},
        "hinge23": {"type": "hinge", "proximal": "seg2", "distal": "seg3", "axis": "x"},
        "hinge34": {"type": "hinge", "proximal": "seg3", "distal": "seg4", "axis": "y"},
        "hinge45": {"type": "hinge", "proximal": "seg4", "distal": "seg5", "axis": "z"},
    }
    protocol = load_protocol(PROTOCOL)
    assert list(protocol.segments) == ["seg1", "seg2", "seg3", "seg4", "seg5"]
    assert all(s.sensor_axes == ("x", "y", "z") for s in protocol.segments.values())
    assert protocol.calibration == []  # no reference pose: every axis from the movement
    assert [t.name for t in protocol.tasks] == ["motion"]
    sensors = load_sensor_map(MAP).sensors
    assert {k: v.segment for k, v in sensors.items()} == {s: s for s in protocol.segments}
