"""Xsens DOT CSV reader: header, 60 Hz µs clock with 32-bit wrap, quaternion and free acc."""

import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab import rotations
from motionlab.errors import InputError
from motionlab.io import detect_format, dot, read_any, xsens

FIXTURE = DATA / "dot" / "RFemur_20210820_202113_840_excerpt.csv"


def _one(path, options=None):
    rec = read_any(path, options)
    assert rec.format == "dot"
    return rec.sensors[0]


def test_fixture_rate_channels_and_header():
    s = _one(FIXTURE)
    assert s.n_samples == 200
    assert s.rate_hz == pytest.approx(60.0, abs=0.01)
    # 16 667 µs, 16 667 µs, 16 666 µs … a 60 Hz clock in whole µs
    assert np.diff(s.time).max() - np.diff(s.time).min() <= 2e-6
    assert s.time[0] == pytest.approx(3343.444552)
    assert s.serial == "ydt" and s.vendor == "Xsens DOT"
    assert s.channels == ["quat"] and s.acc is None and s.gyr is None
    assert s.extra["free_acc"].shape == (200, 3)
    assert s.source_units == {"quat": "1", "free_acc": "m/s^2"}
    assert s.attrs["nominal_rate_hz"] == 60.0
    assert s.attrs["header"]["FilterProfile"] == "General"
    np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", s.quat[1:], s.quat[:-1]) > 0)
    raw = np.genfromtxt(FIXTURE, delimiter=",", skip_header=12)
    np.testing.assert_allclose(s.quat, rotations.normalize(raw[:, 2:6]), atol=1e-12)
    np.testing.assert_allclose(s.extra["free_acc"], raw[:, 6:9])


def test_detected_by_content():
    head = FIXTURE.read_bytes()
    assert dot.sniff(FIXTURE, head)
    assert not xsens.sniff(FIXTURE, head)
    x = DATA / "xsens" / "MT46_01-000_00B42D4D.txt"
    assert not dot.sniff(x, x.read_bytes())
    assert detect_format(FIXTURE) == "dot"


def _synthetic(tmp_path, ticks, extra_cols="", extra_vals=""):
    head = "sep=,\nDeviceTag:,knee\nOutputRate:,60Hz\n\n"
    head += "PacketCounter,SampleTimeFine,Quat_W,Quat_X,Quat_Y,Quat_Z" + extra_cols + "\n"
    rows = "".join(f"{k},{t},1,0,0,0{extra_vals}\n" for k, t in enumerate(ticks))
    p = tmp_path / "dot.csv"
    p.write_text(head + rows)
    return p


def test_sample_time_fine_wraps_at_2_32_microseconds(tmp_path):
    ticks = (2**32 - 50_000 + 16_667 * np.arange(8)) % 2**32
    s = _one(_synthetic(tmp_path, ticks))
    assert s.attrs["clock_wraps"] == 1
    np.testing.assert_allclose(np.diff(s.time), 0.016667, atol=1e-9)
    assert s.serial == "knee"


def test_euler_and_raw_inertial_columns(tmp_path):
    head = "sep=,\nDeviceTag:,e\n\nPacketCounter,SampleTimeFine,Euler_X,Euler_Y,Euler_Z,"
    head += "Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z\n"
    rows = "".join(f"{k},{1000 + 16667 * k},0,0,90,0,0,9.81,0,0,180\n" for k in range(4))
    p = tmp_path / "e.csv"
    p.write_text(head + rows)
    s = _one(p)
    # yaw 90°: sensor x points north (ENU y)
    np.testing.assert_allclose(rotations.rotate(s.quat[0], [1.0, 0, 0]), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(s.gyr[0], [0, 0, np.pi])
    assert s.source_units["gyr"] == "deg/s"


def test_errors(tmp_path):
    p = _synthetic(tmp_path, [10, 20, 30], ",FreeAcc_X,FreeAcc_Y,FreeAcc_Z", ",NaN,NaN,NaN")
    with pytest.raises(InputError) as err:
        read_any(p)
    assert "FreeAcc_X" in err.value.where
    lines = FIXTURE.read_text().splitlines()
    lines[20] = lines[20].replace(",", ";")
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines))
    with pytest.raises(InputError) as err:
        read_any(bad)
    assert err.value.where == "line 21"
    assert err.value.line().endswith("1 columns, expected 10 — is the delimiter ';'?")


@needs_shared
def test_shared_dot_files():
    for name, n in (
        ("RFemur_20210820_202113_840.csv", 380),
        ("RTibia_20210820_202113_825.csv", 381),
    ):
        s = _one(SHARED / "formats" / "dot" / name)
        assert s.n_samples == n + 1
        assert s.rate_hz == pytest.approx(60.0, abs=0.01)
        assert s.duration_s == pytest.approx(n / 60.0, abs=1e-3)
        np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-12)


RATE_QUANTITIES = DATA / "dot" / "femur_rate_quantities_excerpt.csv"


def test_rate_quantities_export_is_read_in_si_units():
    """The DOT app's 2024 "Inertial data mode – rate quantities (with mag)" export: raw acc
    (m/s²), gyr (deg/s → rad/s) and mag (a.u.), no orientation; the label is the DeviceTag."""
    s = _one(RATE_QUANTITIES)
    raw = np.genfromtxt(RATE_QUANTITIES, delimiter=",", skip_header=12)
    assert s.n_samples == 200 and s.label == "Femur" and s.serial == "Femur"
    assert s.quat is None and s.channels == ["acc", "gyr", "mag"]
    np.testing.assert_allclose(s.acc, raw[:, 2:5])
    np.testing.assert_allclose(s.gyr, np.radians(raw[:, 5:8]))
    np.testing.assert_allclose(s.mag, raw[:, 8:11] * 50.0)
    assert s.source_units == {"acc": "m/s^2", "gyr": "deg/s", "mag": "a.u."}
    np.testing.assert_allclose(s.time - s.time[0], (raw[:, 1] - raw[0, 1]) * 1e-6, atol=1e-9)
    # seated at the start: gravity along the thigh sensor's z, about 1 g
    assert 9.5 < np.linalg.norm(s.acc[:20].mean(axis=0)) < 10.1


def test_the_recording_date_comes_from_start_time_and_reaches_the_report():
    """The DOT app's ``StartTime: ,2021-08-20_20:21:13_839 GMT+8`` is the day the recording was
    made: the ingest keeps it (``metadata["recorded"]``) and the report's session date is it
    when the sensor map gives none."""
    from motionlab.ingest import ingest
    from motionlab.io.clock import recording_date

    assert _one(FIXTURE).attrs["recorded"] == "2021-08-20"
    assert ingest([FIXTURE]).metadata["recorded"] == "2021-08-20"
    assert recording_date("2025-02-13 11:44:29") == "2025-02-13"
    assert recording_date("2024/12/9_17:31") == "2024-12-09"
    for stamp in ("Unknown", "", "2021-13-40_10:00", "20210820", "12021-08-20", None, 7):
        assert recording_date(stamp) is None, stamp
