"""Xsens MT Manager text reader: layouts, delimiters, orientation conventions, clocks, errors."""

import shutil

import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab import rotations
from motionlab.errors import InputError
from motionlab.io import detect_format, read_any, xsens

XS = DATA / "xsens"
G = 9.81

HEADER_2022 = """// General information:
//  MT Manager version: 2022.2.0
// Device information:
//  DeviceId: 00B4AAAA
// Coordinate system: {frame}
"""


def _one(path, options=None):
    rec = read_any(path, options)
    assert rec.format == "xsens"
    assert len(rec.sensors) == 1
    return rec.sensors[0]


def test_fixtures_rates_serials_channels():
    expect = {
        "MT2022_ACC_00B42D4B.txt": (100.0, "00B42D4B", ["acc"]),
        "MT46_01-000_00B42D4D.txt": (100.0, "00B42D4D", ["acc", "gyr", "quat"]),
        "MT_01200454_000-000_00B40DE4.txt": (100.0, "00B40DE4", ["acc", "gyr", "mag", "quat"]),
        "MT_012005D6_031-000_00B421AF_excerpt.txt": (
            100.0,
            "00B421AF",
            ["acc", "gyr", "mag", "quat"],
        ),
        "MT_012005D6-000_sit_to_stand-000_00B421ED_excerpt.txt": (40.0, "00B421ED", ["quat"]),
    }
    for name, (rate, serial, channels) in expect.items():
        s = _one(XS / name)
        assert s.rate_hz == pytest.approx(rate, rel=1e-9), name
        assert s.serial == serial
        assert s.vendor == "Xsens"
        assert s.channels == channels
        assert s.time.dtype == np.float64
        assert np.all(np.diff(s.time) > 0)


def test_time_from_packet_counter_keeps_dropped_packets():
    s = _one(XS / "MT_012005D6-000_sit_to_stand-000_00B421ED_excerpt.txt")
    # first rows: 35166, 35167, 35168, 35170 (one packet lost) at 40 Hz
    assert s.time[:4] == pytest.approx(np.array([35166, 35167, 35168, 35170]) / 40.0)
    assert s.attrs["time_source"] == "PacketCounter"
    assert "rate_assumed" not in s.attrs


def test_2022_export_without_rate_line_assumes_100_hz_and_says_so():
    s = _one(XS / "MT2022_ACC_00B42D4B.txt")
    assert s.attrs["rate_assumed"] is True
    assert any("assumed" in n for n in s.attrs["notes"])
    s60 = _one(XS / "MT2022_ACC_00B42D4B.txt", {"rate_hz": 60})
    assert s60.rate_hz == pytest.approx(60.0)
    assert "rate_assumed" not in s60.attrs
    with pytest.raises(InputError, match="rate_hz"):
        read_any(XS / "MT2022_ACC_00B42D4B.txt", {"rate_hz": -1})


def test_four_delimiters_give_identical_data():
    names = ["MAT_COMMA", "MAT_SEMICOLON", "MAT_SPACE"]
    ref = _one(XS / "MT2022_ACC_GYRO_ROT_ALL_TAB_NAN_00B42D4B.txt")
    for n in names:
        s = _one(XS / f"MT2022_ACC_GYRO_ROT_{n}_00B42D4B.txt")
        np.testing.assert_array_equal(s.time, ref.time)
        # the tab/NaN file has Acc_X of its first row blanked out
        assert np.isnan(ref.acc[0, 0]) and not np.isnan(s.acc[0, 0])
        np.testing.assert_array_equal(s.acc[1:], ref.acc[1:])
        np.testing.assert_array_equal(s.gyr, ref.gyr)
        assert rotations.angle_between(s.quat, ref.quat).max() < np.radians(0.01)


def test_quaternion_matrix_euler_agree_in_one_export():
    s = _one(XS / "MT2022_ACC_GYRO_ROT_ALL_TAB_NAN_00B42D4B.txt")
    assert s.attrs["orientation_source"] == "quaternion"
    assert s.attrs["orientation_agreement_deg"] < 0.01
    # independently: build each representation by hand from the file's numbers
    tab = np.genfromtxt(XS / "MT2022_ACC_GYRO_ROT_ALL_TAB_NAN_00B42D4B.txt", skip_header=13)
    q = rotations.normalize(tab[:, 12:16])
    roll, pitch, yaw = np.radians(tab[:, 16:19]).T
    c, s_ = np.cos, np.sin
    rz = np.array(
        [[c(yaw), -s_(yaw), 0 * yaw], [s_(yaw), c(yaw), 0 * yaw], [0 * yaw, 0 * yaw, 1 + 0 * yaw]]
    )
    ry = np.array(
        [
            [c(pitch), 0 * pitch, s_(pitch)],
            [0 * pitch, 1 + 0 * pitch, 0 * pitch],
            [-s_(pitch), 0 * pitch, c(pitch)],
        ]
    )
    rx = np.array(
        [
            [1 + 0 * roll, 0 * roll, 0 * roll],
            [0 * roll, c(roll), -s_(roll)],
            [0 * roll, s_(roll), c(roll)],
        ]
    )
    r_euler = np.einsum("ijn,jkn,kln->nil", rz, ry, rx)
    mat = tab[:, 19:28].reshape(-1, 3, 3).transpose(0, 2, 1)  # file order: Mat[1][1], Mat[2][1], …
    np.testing.assert_allclose(rotations.to_matrix(q), mat, atol=2e-5)
    np.testing.assert_allclose(r_euler, mat, atol=2e-5)
    assert rotations.angle_between(s.quat, q).max() < 1e-9


def test_orientation_maps_sensor_gravity_to_enu_up():
    """At near-rest the measured specific force, rotated to earth, points up (+z ENU)."""
    for name in (
        "MT_012005D6_031-000_00B421AF_excerpt.txt",
        "MT2022_ACC_GYRO_ROT_EULER_TAB_00B42D4F.txt",
        "MT46_01-000_00B42D4D.txt",
    ):  # (00B40DE4 is turning at 0.4 rad/s: not at rest)
        s = _one(XS / name)
        up = rotations.rotate(s.quat, s.acc)
        med = np.nanmedian(up, axis=0)
        assert med[2] == pytest.approx(G, abs=0.35), name
        assert np.hypot(med[0], med[1]) < 0.6, name
        norms = np.linalg.norm(s.quat, axis=1)
        np.testing.assert_allclose(norms, 1.0, atol=1e-12)


def test_units_and_magnetometer_scale():
    s = _one(XS / "MT_01200454_000-000_00B40DE4.txt")
    assert s.source_units == {"acc": "m/s^2", "gyr": "rad/s", "mag": "a.u.", "quat": "1"}
    assert s.attrs["mag_scale_assumed"] is True
    raw = np.genfromtxt(XS / "MT_01200454_000-000_00B40DE4.txt", skip_header=13)[:, 7:10]
    np.testing.assert_allclose(s.mag, raw * xsens.DEFAULT_MAG_FIELD_UT)
    s40 = _one(XS / "MT_01200454_000-000_00B40DE4.txt", {"mag_field_ut": 40})
    np.testing.assert_allclose(s40.mag, raw * 40)
    np.testing.assert_allclose(np.linalg.norm(s.mag, axis=1), 47.0, rtol=0.05)


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_sample_time_fine_wraps_at_2_32(tmp_path):
    ticks = (2**32 - 250 + 100 * np.arange(10)) % 2**32  # 10 kHz ticks, 100 Hz, wraps once
    rows = "".join(f"{k}\t{t}\t0\t0\t9.81\n" for k, t in enumerate(ticks))
    head = HEADER_2022.format(frame="ENU") + "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\n"
    s = _one(_write(tmp_path, "w.txt", head + rows))
    assert s.attrs["time_source"] == "SampleTimeFine"
    assert s.attrs["clock_wraps"] == 1
    np.testing.assert_allclose(np.diff(s.time), 0.01, atol=1e-12)
    assert s.time[0] == pytest.approx((2**32 - 250) / 1e4)
    assert s.serial == "00B4AAAA"


def test_packet_counter_wraps_at_2_16(tmp_path):
    pc = (65530 + np.arange(12)) % 65536
    head = "// Update Rate: 50.0Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"
    rows = "".join(f"{p:05d}\t0\t0\t9.81\n" for p in pc)
    s = _one(_write(tmp_path, "p.txt", head + rows))
    np.testing.assert_allclose(np.diff(s.time), 0.02)
    assert s.attrs["clock_wraps"] == 1


def test_an_older_export_names_its_counter_counter(tmp_path):
    """Older MT Software exports (MTx, MTi-G) call the sample counter ``Counter``; such a file
    had been refused for lack of a time column. Its serial comes from the file name."""
    pc = (65534 + np.arange(6)) % 65536
    head = "// Start Time: Unknown\n// Update Rate: 100.0Hz\nCounter\tAcc_X\tAcc_Y\tAcc_Z\tRoll\n"
    rows = "".join(f"{p:05d}\t0\t0\t9.81\t0\n" for p in pc)
    s = _one(_write(tmp_path, "MT_00300556-000_00300556.txt", head + rows))
    np.testing.assert_allclose(np.diff(s.time), 0.01)
    assert s.attrs["time_source"] == "Counter" and s.attrs["clock_wraps"] == 1
    assert s.serial == "00300556"


def test_ned_export_is_rotated_to_enu(tmp_path):
    head = HEADER_2022.format(frame="NED")
    head += "PacketCounter,Acc_X,Acc_Y,Acc_Z,Quat_q0,Quat_q1,Quat_q2,Quat_q3,"
    head += "FreeAcc_X,FreeAcc_Y,FreeAcc_Z\n"
    rows = "".join(f"{k},0,0,-9.81,1,0,0,0,1,2,3\n" for k in range(5))
    s = _one(_write(tmp_path, "ned.txt", head + rows), {"rate_hz": 100})
    # identity in NED: sensor x = north, y = east, z = down
    ex, ey, ez = rotations.rotate(s.quat[0], np.eye(3))
    np.testing.assert_allclose(ex, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(ey, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(ez, [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(s.extra["free_acc"][0], [2, 1, -3])  # (N, E, D) → (E, N, U)


def test_sniff_by_content_not_name(tmp_path):
    src = XS / "MT2022_ACC_GYRO_ROT_MAT_COMMA_00B42D4B.txt"
    renamed = tmp_path / "recording.csv"
    shutil.copy(src, renamed)
    assert detect_format(renamed) == "xsens"
    for other in (DATA / "dot" / "RFemur_20210820_202113_840_excerpt.csv",
                  DATA / "xio" / "sensor_data_excerpt.csv"):  # fmt: skip
        assert not xsens.sniff(other, other.read_bytes()[:65536])


# ------------------------------------------------------------------------------ errors


def _lines(name):
    return (XS / name).read_text().splitlines()


def test_truncated_last_line_is_dropped_with_a_note(tmp_path):
    lines = _lines("MT46_01-000_00B42D4D.txt")
    lines[-1] = lines[-1][:30]
    s = _one(_write(tmp_path, "t_00B42D4D.txt", "\n".join(lines) + "\n"))
    assert s.n_samples == 4
    assert any("truncated last line" in n for n in s.attrs["notes"])


def test_short_middle_line_names_the_line(tmp_path):
    lines = _lines("MT46_01-000_00B42D4D.txt")
    lines[6] = lines[6][:30]
    p = _write(tmp_path, "m.txt", "\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_any(p)
    assert err.value.where == "line 7"
    assert "columns, expected 16" in err.value.message


def test_text_in_numeric_column_names_line_and_column(tmp_path):
    lines = _lines("MT2022_ACC_GYRO_ROT_MAT_COMMA_00B42D4B.txt")
    fields = lines[15].split(",")
    fields[7] = "abc"
    lines[15] = ",".join(fields)
    with pytest.raises(InputError) as err:
        read_any(_write(tmp_path, "x.txt", "\n".join(lines)))
    assert err.value.where == "line 16"
    assert "'Acc_Y'" in err.value.message and "'abc'" in err.value.message


def test_header_only_and_nan_only_channel(tmp_path):
    lines = _lines("MT2022_ACC_00B42D4B.txt")
    with pytest.raises(InputError, match="no data rows"):
        read_any(_write(tmp_path, "h.txt", "\n".join(lines[:13]) + "\n"))
    rows = [ln.split("\t") for ln in lines[13:]]
    for r in rows:
        r[7] = "NaN"
    text = "\n".join(lines[:13] + ["\t".join(r) for r in rows])
    with pytest.raises(InputError) as err:
        read_any(_write(tmp_path, "n.txt", text))
    assert "Acc_Y" in err.value.where and "acc" in err.value.message


def test_missing_time_column(tmp_path):
    p = _write(tmp_path, "nt.txt", "// Update Rate: 100Hz\nAcc_X\tAcc_Y\tAcc_Z\n1\t2\t3\n")
    with pytest.raises(InputError, match="no time column"):
        read_any(p)


# ------------------------------------------------------------------------------ ../shared


@needs_shared
def test_all_shared_xsens_files():
    folder = SHARED / "formats" / "xsens"
    files = sorted(folder.glob("*.txt"))
    assert len(files) == 13
    for f in files:
        s = _one(f)
        want = 40.0 if "sit_to_stand" in f.name else 100.0
        assert s.rate_hz == pytest.approx(want, rel=1e-9), f.name
        assert s.serial == f.stem[-8:]
        if s.quat is not None:
            np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1)[~np.isnan(s.quat[:, 0])], 1)
    big = _one(folder / "MT_012005D6_031-000_00B421AF.txt")
    assert big.n_samples == 3369
    up = np.median(rotations.rotate(big.quat, big.acc), axis=0)
    assert up[2] == pytest.approx(G, abs=0.2) and np.hypot(*up[:2]) < 0.3
    sts = _one(folder / "MT_012005D6-000_sit_to_stand-000_00B421ED.txt")
    gaps = np.diff(sts.time)
    assert gaps.min() == pytest.approx(0.025) and gaps.max() > 0.025  # dropped packets kept


def test_time_from_utc_fields(tmp_path):
    head = "PacketCounter\tUTC_Nano\tUTC_Year\tUTC_Month\tUTC_Day\tUTC_Hour\tUTC_Minute"
    head += "\tUTC_Second\tUTC_Valid\tAcc_X\tAcc_Y\tAcc_Z\n"
    text = (
        "1\t995000000\t2021\t12\t31\t23\t59\t59\t7\t0\t0\t9.81\n"
        "2\t5000000\t2022\t1\t1\t0\t0\t0\t7\t0\t0\t9.81\n"
        "3\t15000000\t2022\t1\t1\t0\t0\t0\t7\t0\t0\t9.81\n"
    )
    s = _one(_write(tmp_path, "u.txt", "// Update Rate: 100Hz\n" + head + text))
    assert s.attrs["time_source"] == "UTC"
    assert s.time[0] == pytest.approx(1640995199.995, abs=1e-6)
    np.testing.assert_allclose(np.diff(s.time), 0.01, atol=1e-6)


def test_session_round_trip_keeps_reader_output(tmp_path):
    from motionlab.session import Session, load_session, save_session

    s = _one(XS / "MT_012005D6_031-000_00B421AF_excerpt.txt")
    save_session(Session(sensors={s.label: s}), tmp_path / "s.h5")
    back = load_session(tmp_path / "s.h5").sensors[s.label]
    np.testing.assert_array_equal(back.quat, s.quat)
    assert back.attrs == s.attrs and back.source_units == s.source_units


def test_a_legacy_start_time_dates_the_recording_and_unknown_does_not(tmp_path):
    """MT Manager 4.x writes ``// Start Time: Unknown`` unless the time was set: a date there is
    the day of the recording (``attrs["recorded"]``); ``Unknown`` gives none."""
    src = XS / "MT_012005D6_031-000_00B421AF_excerpt.txt"
    assert "recorded" not in read_any(src).sensors[0].attrs
    text = src.read_text(encoding="utf-8").replace(
        "// Start Time: Unknown", "// Start Time: 2018-03-14 10:12:11"
    )
    dated = tmp_path / src.name
    dated.write_text(text, encoding="utf-8")
    assert read_any(dated).sensors[0].attrs["recorded"] == "2018-03-14"
