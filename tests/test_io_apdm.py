"""APDM readers: CSV exports (Motion Studio, Mobility Lab Format=7) and the HDF5 layout."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import DATA, SHARED, assert_other_hdf5_refused, needs_shared

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.io import apdm, apdm_h5, detect_format, read_any

PENDULUM = DATA / "apdm" / "imuData01_1s.csv"
FORMAT7 = DATA / "apdm" / "apdm_format7.csv"


def _horizontal_heading_deg(stream) -> np.ndarray:
    """Azimuth of the horizontal magnetic field in the earth frame, from +y toward +x."""
    m = rot.rotate(stream.quat, stream.mag)
    return np.degrees(np.arctan2(m[:, 0], m[:, 1]))


def test_nwu_to_enu_by_hand():
    # a sensor whose axes coincide with NWU: its x axis points north, its y axis west
    q = apdm.nwu_to_enu(np.array([[1.0, 0, 0, 0]]))
    np.testing.assert_allclose(rot.rotate(q, [1.0, 0, 0])[0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rot.rotate(q, [0, 1.0, 0])[0], [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rot.rotate(q, [0, 0, 1.0])[0], [0, 0, 1], atol=1e-15)


def test_pendulum_export():
    assert detect_format(PENDULUM) == "apdm"
    rec = read_any(PENDULUM)
    assert [s.label for s in rec.sensors] == ["Static", "Upper", "Middle", "Lower"]
    assert rec.metadata["Test Name"] == "Pendulum Test 01"
    assert "Static/temperature" in rec.metadata["ignored_columns"]
    for s in rec.sensors:
        assert s.n_samples == 128 and s.vendor == "APDM"
        assert s.rate_hz == pytest.approx(128.0, rel=1e-9)
        assert s.attrs["nominal_rate_hz"] == 128.0
        assert s.source_units == {"acc": "m/s^2", "gyr": "rad/s", "mag": "uT", "time": "s"}
        assert s.time[0] == 0.007457625  # as written (s from the start of recording)
        np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-6)
        # gravity (specific force) points up in ENU
        up = rot.rotate(s.quat, s.acc)
        np.testing.assert_allclose(np.median(up, axis=0), [0, 0, 9.8], atol=0.15)
    static = rec.sensors[0]
    np.testing.assert_array_equal(static.acc[0], [0.102542184, 0.048829611, 9.804986382])
    np.testing.assert_allclose(static.time[1], 0.015270125, rtol=1e-12)
    # after NWU → ENU the horizontal magnetic field points to +y (magnetic north)
    assert np.abs(_horizontal_heading_deg(static)).max() < 2.0


def test_format7_export():
    assert detect_format(FORMAT7) == "apdm"
    rec = read_any(FORMAT7)
    assert [(s.label, s.serial) for s in rec.sensors] == [
        ("Lumbar", "5718"),
        ("Right Ankle", "5778"),
        ("Left Ankle", "5811"),
        ("Left Foot", "6570"),
        ("Chest", "6575"),
        ("Right Foot", "6833"),
    ]
    assert rec.metadata["format_version"] == "7"
    assert len(rec.metadata["ignored_columns"]) == 6  # one barometer per sensor
    lumbar = rec.sensors[0]
    # s since the Unix epoch (2019-02-22 23:51:44 UTC), so that a C3D from 0 s is unrelated
    np.testing.assert_allclose(
        lumbar.time - 1550879504.438281, [0.0, 0.007812, 0.015625], atol=1e-6
    )
    assert lumbar.attrs["start_unix_us"] == 1550879504438281
    assert lumbar.attrs["recorded"] == "2019-02-22"
    assert lumbar.source_units["gyr"] == "rad/s"
    np.testing.assert_array_equal(lumbar.gyr[0], [-0.928487, -0.085719, -0.059549])
    np.testing.assert_array_equal(lumbar.mag[0], [9.924619, 12.347788, -7.779168])
    for s in rec.sensors:
        np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-6)
        up = rot.rotate(s.quat, s.acc)  # the sensors move: up is the largest component
        assert up[:, 2].mean() > 8.0 and (up[:, 2] > np.abs(up[:, :2]).max(axis=1)).all()


def _write_lines(tmp_path: Path, lines: list[str], name: str = "x.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_csv_errors(tmp_path):
    lines = PENDULUM.read_text().splitlines()
    cut = lines[:20] + [lines[20][:200]] + lines[21:]
    with pytest.raises(InputError, match=r"line 21.*columns, expected 61"):
        apdm.read(_write_lines(tmp_path, cut))
    bad = lines[:10] + [lines[10].replace("0.", "x.", 1)] + lines[11:]
    with pytest.raises(InputError, match=r"line 11.*'x\."):
        apdm.read(_write_lines(tmp_path, bad))
    units = lines[:3] + [lines[3].replace("rad/s", "furlong/s", 1)] + lines[4:]
    with pytest.raises(InputError, match=r"line 4 column 5.*unknown unit 'furlong/s'"):
        apdm.read(_write_lines(tmp_path, units))
    with pytest.raises(InputError, match="no 'Time"):
        apdm.read(_write_lines(tmp_path, lines[:2]))
    f7 = FORMAT7.read_text().splitlines()
    with pytest.raises(InputError, match="header ends early"):
        apdm.read(_write_lines(tmp_path, f7[:2]))
    with pytest.raises(InputError, match="lines 1-3"):
        apdm.read(_write_lines(tmp_path, [f7[0] + ",extra"] + f7[1:]))


def test_format7_first_stamp_not_a_number(tmp_path):
    """A NaN first stamp is that row's alone: it made every time NaN and crashed on the
    start's conversion to an integer (ValueError, exit 1) before."""
    f7 = FORMAT7.read_text().splitlines()
    first = next(k for k, ln in enumerate(f7) if ln[:1].isdigit())
    f7[first] = "nan" + f7[first][f7[first].index(",") :]
    rec = apdm.read(_write_lines(tmp_path, f7))
    lumbar = rec.sensors[0]
    assert np.isnan(lumbar.time[0])
    np.testing.assert_allclose(lumbar.time[1:] - 1550879504.446093, [0.0, 0.007813], atol=1e-6)
    assert lumbar.attrs["start_unix_us"] == 1550879504446093
    for k in range(first, len(f7)):
        f7[k] = "nan" + f7[k][f7[k].index(",") :]
    with pytest.raises(InputError, match=r"lines 4-6 column 1: no row has a time stamp"):
        apdm.read(_write_lines(tmp_path, f7))


def test_sniff_by_content(tmp_path):
    renamed = tmp_path / "data.txt"
    renamed.write_bytes(PENDULUM.read_bytes())
    assert apdm.sniff(renamed, renamed.read_bytes()[:65536])
    assert not apdm.sniff(renamed, b"Time,Acc_X\n0,1\n")


def test_a_format7_export_behind_a_byte_order_mark_is_read(tmp_path):
    """An editor's UTF-8 byte-order mark before 'Format=7' made it an unknown file format (the
    other readers already skipped it)."""
    marked = tmp_path / "format7_bom.csv"
    marked.write_bytes(b"\xef\xbb\xbf" + FORMAT7.read_bytes())
    plain, read = read_any(FORMAT7), read_any(marked)
    assert [s.label for s in read.sensors] == [s.label for s in plain.sensors]
    assert np.array_equal(read.sensors[0].gyr, plain.sensors[0].gyr)


# ----------------------------------------------------------------------------------- HDF5


def _write_apdm_h5(path: Path, n: int = 50, rate: float = 128.0) -> dict:
    """An APDM .h5 file laid out as documented (format version 5), with known contents."""
    rng = np.random.default_rng(7)
    t0 = 1_600_000_000_000_000
    truth = {}
    with h5py.File(path, "w") as f:
        f.attrs["FileFormatVersion"] = 5
        for k, (case_id, label) in enumerate([("SI-000646", "Right Foot"), ("SI-000700", "")]):
            g = f.create_group(f"Sensors/{case_id}")
            time = t0 + np.round(np.arange(n) * 1e6 / rate).astype(np.uint64)
            g["Time"] = time
            acc = rng.normal(0, 1, (n, 3)) + [0, 0, 9.81]
            gyr = rng.normal(0, 0.1, (n, 3))
            mag = rng.normal(0, 1, (n, 3)) + [20, 0, -40]
            g["Accelerometer"] = acc
            g["Gyroscope"] = np.degrees(gyr) if k == 1 else gyr
            if k == 1:
                g["Gyroscope"].attrs["Units"] = np.bytes_("deg/s")
            g["Magnetometer"] = mag
            cfg = g.create_group("Configuration")
            cfg.attrs["Label 0"] = np.bytes_(label.encode() + b"\x00\x00")
            cfg.attrs["Sample Rate"] = np.array([rate])
            q = rot.normalize(rng.normal(size=(n, 4)))
            if k == 0:
                f[f"Processed/{case_id}/Orientation"] = q
            truth[case_id] = {"time": time, "acc": acc, "gyr": gyr, "mag": mag, "quat": q}
    return truth


def test_h5_layout_round_trip(tmp_path):
    path = tmp_path / "walk.h5"
    truth = _write_apdm_h5(path)
    assert detect_format(path) == "apdm_h5"
    rec = read_any(path)
    assert [(s.label, s.serial) for s in rec.sensors] == [
        ("Right Foot", "SI-000646"),
        ("SI-000700", "SI-000700"),
    ]
    for s in rec.sensors:
        want = truth[s.serial]
        np.testing.assert_allclose(s.time, want["time"] * 1e-6, rtol=0, atol=1e-6)
        assert s.attrs["start_unix_us"] == int(want["time"][0])
        assert s.attrs["nominal_rate_hz"] == 128.0
        assert s.rate_hz == pytest.approx(128.0, rel=1e-3)
        np.testing.assert_array_equal(s.acc, want["acc"])
        np.testing.assert_allclose(s.gyr, want["gyr"], rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(s.mag, want["mag"])
    foot, other = rec.sensors
    assert other.source_units["gyr"] == "deg/s" and other.quat is None
    np.testing.assert_allclose(foot.quat, apdm.nwu_to_enu(truth["SI-000646"]["quat"]))


def test_h5_errors(tmp_path):
    path = tmp_path / "bad.h5"
    _write_apdm_h5(path)
    with h5py.File(path, "a") as f:
        del f["Sensors/SI-000700/Time"]
    with pytest.raises(InputError, match="key /Sensors/SI-000700/Time"):
        apdm_h5.read(path)
    assert_other_hdf5_refused(tmp_path / "empty.h5", apdm_h5, "group /Sensors")
    short = tmp_path / "short.h5"
    _write_apdm_h5(short)
    with h5py.File(short, "a") as f:
        del f["Sensors/SI-000646/Magnetometer"]
        f["Sensors/SI-000646/Magnetometer"] = np.zeros((10, 3))
    with pytest.raises(InputError, match="10 samples but Time has 50"):
        apdm_h5.read(short)
    text = tmp_path / "not.h5"
    text.write_text("hello")
    with pytest.raises(InputError, match="not a readable HDF5"):
        apdm_h5.read(text)


# ------------------------------------------------------------------------------- real files


@needs_shared
def test_shared_apdm_files():
    rec = read_any(SHARED / "formats" / "apdm" / "imuData01.csv")
    assert len(rec.sensors) == 4
    for s in rec.sensors:
        assert s.n_samples == 1024
        assert s.rate_hz == pytest.approx(128.0, rel=1e-9)
        np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-6)
    heading = np.abs(_horizontal_heading_deg(rec.sensors[0]))
    assert np.median(heading) < 0.5 and heading.max() < 5.0
    rec7 = read_any(SHARED / "formats" / "apdm" / "apdm_format7.csv")
    assert len(rec7.sensors) == 6 and rec7.sensors[0].rate_hz == pytest.approx(128.0, rel=1e-3)


def test_h5_damaged_links_and_names_are_one_line(tmp_path):
    """h5py's words for damaged metadata (a dangling link: ``None``; a name that is not UTF-8:
    ``UnicodeDecodeError`` on every lookup) were exit 1; byte flips of the fixture made both."""
    path = tmp_path / "dangling.h5"
    _write_apdm_h5(path)
    with h5py.File(path, "a") as f:
        f["Sensors"]["SI-000999"] = h5py.SoftLink("/nowhere")
    with pytest.raises(InputError, match="SI-000999.*|is not a sensor group"):
        apdm_h5.read(path)
    path = tmp_path / "names.h5"
    _write_apdm_h5(path)
    with h5py.File(path, "a") as f:  # a name that is not UTF-8, as a flipped byte leaves it
        f.copy(f["Sensors/SI-000646"], f["Sensors"], name=b"SI-00064\xc8")
        f.copy(f["Processed/SI-000646"], f["Processed"], name=b"SI-00064\xc8")
    with pytest.raises(InputError, match="damaged"):
        apdm_h5.read(path)
