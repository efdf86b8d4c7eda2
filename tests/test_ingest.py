"""Ingest: clock repair, gaps, resampling, quality checks, sensor map, common origin, provenance."""

import importlib
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab import qc, rotations, timebase
from motionlab.errors import InputError
from motionlab.ingest import ingest, unmatched_keys
from motionlab.io import Recording
from motionlab.sensor_map import load_sensor_map
from motionlab.session import MarkerSet, SensorStream, load_session, save_session, sha256_file

# the module, not the function ``motionlab.ingest`` that the package exports under its name
ingest_module = importlib.import_module("motionlab.ingest")


def stream(t, label="s1", serial="", **channels) -> SensorStream:
    t = np.asarray(t, dtype=float)
    return SensorStream(label=label, time=t, serial=serial, **channels)


def ramp(t):
    """acc = [t, 2t, 9.81]: linear in time, so linear interpolation is exact."""
    return np.column_stack([t, 2 * t, np.full_like(t, 9.81)])


# ----------------------------------------------------------------------------- clock repair


def test_exact_duplicates_dropped():
    t = np.array([0.0, 0.01, 0.01, 0.02, 0.03])
    s = stream(t, acc=ramp(t))
    out, rep = timebase.repair_clock(s)
    np.testing.assert_array_equal(out.time, [0.0, 0.01, 0.02, 0.03])
    np.testing.assert_array_equal(out.acc, ramp(out.time))
    assert rep["duplicates_dropped"] == 1


def test_duplicate_stamp_with_other_values_refused():
    t = np.array([0.0, 0.01, 0.01, 0.02])
    acc = ramp(t)
    acc[2, 0] = 5.0
    with pytest.raises(InputError, match="data row 3") as e:
        timebase.repair_clock(stream(t, acc=acc), "a.csv")
    assert "a.csv" in e.value.line()


def test_swapped_rows_reordered():
    t = np.array([0.0, 0.01, 0.03, 0.02, 0.04])
    s = stream(t, acc=ramp(t), extra={"flag": np.array([0, 1, 3, 2, 4])})
    out, rep = timebase.repair_clock(s)
    np.testing.assert_array_equal(out.time, [0.0, 0.01, 0.02, 0.03, 0.04])
    np.testing.assert_array_equal(out.acc[:, 0], out.time)  # the values moved with their stamps
    np.testing.assert_array_equal(out.extra["flag"], [0, 1, 2, 3, 4])
    assert rep["reordered"] == 1


def test_single_glitch_restamped():
    t = np.array([0.0, 0.01, 0.02, 7.5, 0.04, 0.05])
    out, rep = timebase.repair_clock(stream(t, acc=ramp(t)))
    np.testing.assert_allclose(out.time, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
    assert rep["restamped"] == 1


def test_two_backward_steps_refused():
    t = np.array([0.0, 0.02, 0.01, 0.03, 0.05, 0.04, 0.06])
    with pytest.raises(InputError, match=r"data row 3: time goes backwards at 2 places"):
        timebase.repair_clock(stream(t, acc=ramp(t)))


def test_nan_stamps_dropped():
    t = np.array([0.0, 0.01, np.nan, 0.03])
    out, rep = timebase.repair_clock(stream(t, acc=ramp(np.nan_to_num(t))))
    np.testing.assert_array_equal(out.time, [0.0, 0.01, 0.03])
    assert rep["nan_time_dropped"] == 1


# ----------------------------------------------------------------------------- gaps


def test_short_gap_filled_linear_and_slerp_long_gap_kept():
    t = np.round(np.arange(0, 1.0, 0.01), 10)
    keep = np.ones(len(t), bool)
    keep[20:24] = False  # 4 samples missing: interval 0.19 → 0.24 (0.05 s), filled
    keep[50:70] = False  # 20 missing: 0.49 → 0.70 (0.21 s), kept
    t = t[keep]
    angle = 2.0 * t  # rotation about z at 2 rad/s
    quat = rotations.from_axis_angle([0, 0, 1], angle)
    s = stream(t, acc=ramp(t), quat=quat, extra={"moving": t > 0.3})
    out, rep = timebase.fill_short_gaps(s, gap_max=0.1)
    assert rep["gaps_filled"] == 1 and rep["samples_filled"] == 4
    assert rep["dropped_samples"] == 24
    assert rep["gaps"] == [[pytest.approx(0.49), pytest.approx(0.70)]]
    assert rep["filled_spans_s"] == [[pytest.approx(0.19), pytest.approx(0.24)]]
    new = np.isin(np.round(out.time, 6), [0.2, 0.21, 0.22, 0.23])
    assert new.sum() == 4 and len(out.time) == len(t) + 4
    np.testing.assert_allclose(out.acc[new], ramp(out.time[new]), atol=1e-12)
    np.testing.assert_allclose(rotations.angle(out.quat[new]), 2.0 * out.time[new], atol=1e-12)
    assert not out.extra["moving"][new].any()  # held from the previous sample
    old = ~new
    np.testing.assert_array_equal(out.acc[old], s.acc)  # recorded samples untouched
    np.testing.assert_array_equal(out.quat[old], s.quat)


def test_no_gaps_returns_stream_unchanged():
    t = np.arange(100) / 100.0
    s = stream(t, acc=ramp(t))
    out, rep = timebase.fill_short_gaps(s, 0.1)
    assert out is s and rep["dropped_samples"] == 0 and rep["gaps"] == []


# ----------------------------------------------------------------------------- resampling


def test_resample_common_clock_and_nan_in_long_gap():
    t = 0.0033 + np.arange(0, 3.0, 1 / 285.7)
    t = t[(t < 1.0) | (t > 1.5)]
    f = 1.3  # Hz, well below the new Nyquist frequency
    gyr = np.column_stack([np.sin(2 * np.pi * f * t)] * 3)
    q = rotations.from_axis_angle([1, 0, 0], 0.5 * t)
    out = timebase.resample(stream(t, gyr=gyr, quat=q), 100.0)
    k = np.round(out.time * 100)
    np.testing.assert_allclose(out.time, k / 100, atol=1e-12)  # on k/rate
    assert out.time[0] >= t[0] and out.time[-1] <= t[-1]
    inside = (out.time > t[t < 1.0][-1]) & (out.time < t[t > 1.5][0])
    assert inside.sum() == 51  # 1.00 … 1.50 s
    assert np.isnan(out.gyr[inside]).all() and np.isnan(out.quat[inside]).all()
    ok = ~inside & (out.time > 0.1) & (out.time < 2.9) & (np.abs(out.time - 1.25) > 0.4)
    np.testing.assert_allclose(out.gyr[ok, 0], np.sin(2 * np.pi * f * out.time[ok]), atol=2e-3)
    np.testing.assert_allclose(rotations.angle(out.quat[ok]), 0.5 * out.time[ok], atol=1e-9)


def test_resample_removes_aliasing():
    t = np.arange(0, 4.0, 1e-3)  # 1000 Hz
    x = np.sin(2 * np.pi * 2.0 * t) + np.sin(2 * np.pi * 310.0 * t)  # 310 Hz would alias to 10 Hz
    out = timebase.resample(stream(t, gyr=np.column_stack([x, x, x])), 100.0)
    mid = (out.time > 0.5) & (out.time < 3.5)
    err = out.gyr[mid, 0] - np.sin(2 * np.pi * 2.0 * out.time[mid])
    assert np.max(np.abs(err)) < 0.02


# ----------------------------------------------------------------------------- quality checks


def _rest(n=500, rate=100.0, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    acc = np.array([0.1, 0.2, 9.79]) + 0.02 * rng.standard_normal((n, 3))
    gyr = 0.01 * rng.standard_normal((n, 3))
    mag = np.array([0.0, 20.0, -40.0]) + 0.5 * rng.standard_normal((n, 3))
    return t, acc, gyr, mag


def test_qc_clean_recording_has_no_flags():
    t, acc, gyr, mag = _rest()
    acc = np.round(acc, 2)  # quantised: runs of identical values that are not a range limit
    out = qc.check_stream(stream(t, acc=acc, gyr=gyr, mag=mag), 0.1)
    assert not any(out["flags"].values()), out["flags"]
    assert out["rate_hz"] == pytest.approx(100.0)
    assert out["acc_rest_norm"] == pytest.approx(np.linalg.norm([0.1, 0.2, 9.79]), abs=0.01)


def test_qc_jitter_in_ms():
    rng = np.random.default_rng(2)
    dt = 0.01 + 0.0005 * rng.standard_normal(5000)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    out = qc.check_stream(stream(t, acc=ramp(t)), 0.1)
    assert out["jitter_ms"] == pytest.approx(0.5, rel=0.05)
    assert not out["flags"]["irregular_sampling"]


def test_qc_saturation_flat_tops():
    t = np.arange(1000) / 100.0
    w = 40.0 * np.sin(2 * np.pi * 0.5 * t)
    gyr = np.column_stack([np.clip(w, -34.9, 34.9), np.zeros_like(t), np.zeros_like(t)])
    out = qc.check_stream(stream(t, gyr=gyr), 0.1)
    assert out["flags"]["gyr_saturated"]
    expected = np.sum(np.abs(w) >= 34.9)
    assert out["saturated_samples"]["gyr"] == expected


def test_qc_gyro_in_deg_per_s_and_acc_in_g():
    t, acc, gyr, mag = _rest()
    gyr[200:220, 2] = 60.0  # a 60 rad/s burst: that is a rate in deg/s
    out = qc.check_stream(stream(t, acc=acc / 9.81, gyr=gyr, mag=mag * 10), 0.1)
    f = out["flags"]
    assert f["gyr_looks_like_deg_s"] and f["acc_looks_like_g"] and f["mag_norm_out_of_range"]
    assert not f["acc_norm_implausible"]
    one = gyr.copy()
    one[:, 2] = 0.0
    one[200, 2] = 60.0  # a single spike is not sustained
    assert not qc.check_stream(stream(t, gyr=one), 0.1)["flags"]["gyr_looks_like_deg_s"]


def test_qc_time_stamps_against_the_headers_rate():
    """A DOT export whose SampleTimeFine was in ms, not µs (a femur at 58824 Hz beside its
    60-Hz tibia, 0.05 s long): the header's OutputRate said 60 Hz and nothing was said."""
    t, acc, gyr, mag = _rest()  # 100 Hz
    s = stream(t, acc=acc, gyr=gyr)
    s.attrs["nominal_rate_hz"] = 100.0
    assert not qc.check_stream(s, 0.1)["flags"]["header_rate_mismatch"]
    fast = stream(t / 1000.0, acc=acc, gyr=gyr)
    fast.attrs["nominal_rate_hz"] = 100.0
    fast.qc = qc.check_stream(fast, 0.1)
    assert fast.qc["flags"]["header_rate_mismatch"]
    assert any("header says 100 Hz" in d for d in qc.doubts(fast))
    assert "header_rate_mismatch" not in qc.check_stream(stream(t, acc=acc), 0.1)["flags"]


def test_qc_mag_assumed_scale_is_not_judged():
    t, acc, gyr, mag = _rest()
    s = stream(t, mag=mag * 10)
    s.attrs["mag_scale_assumed"] = True
    assert "mag_norm_out_of_range" not in qc.check_stream(s, 0.1)["flags"]


def test_qc_nan_spans_and_packets():
    t, acc, gyr, mag = _rest()
    gyr[100:110] = np.nan
    gyr[300, 1] = np.nan
    counter = (np.arange(len(t)) + 65530) % 65536
    counter = np.delete(counter, [10, 11, 12])  # three packets lost across the wrap
    keep = np.delete(np.arange(len(t)), [10, 11, 12])
    s = stream(t[keep], gyr=gyr[keep], extra={"packet_counter": counter})
    out = qc.check_stream(s, 0.1)
    assert out["dropped_packets"] == 3 and out["flags"]["dropped_packets"]
    assert out["nan_spans"]["gyr"] == [[1.0, 1.09], [3.0, 3.0]]
    assert out["flags"]["nan_spans"]


# ----------------------------------------------------------------------------- ingest


@pytest.fixture
def fake_files(tmp_path, monkeypatch):
    """Two files: one with two sensors on an absolute clock, one with a marker set."""
    a, b = tmp_path / "imus.bin", tmp_path / "optical.bin"
    a.write_bytes(b"imu file")
    b.write_bytes(b"optical file")
    t1 = 1000.0 + np.arange(0, 2.0, 0.01)
    t2 = 1000.5 + np.arange(0, 2.0, 0.01)
    tm = 1000.2 + np.arange(0, 1.0, 0.005)
    recs = {
        a: Recording(
            sensors=[
                stream(t1, "thigh", "00B421AF", acc=ramp(t1 - 1000), gyr=np.zeros((200, 3))),
                stream(t2, "shank", "00B421ED", acc=ramp(t2 - 1000), gyr=np.zeros((200, 3))),
            ],
            metadata={"device": "test"},
            format="fake",
        ),
        b: Recording(
            markers=[MarkerSet("optical", tm, ["M1"], positions=np.zeros((200, 1, 3)))],
            format="fake",
        ),
    }
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    return a, b


def test_ingest_common_origin_map_and_provenance(fake_files, tmp_path):
    m = tmp_path / "map.yaml"
    m.write_text(
        "subject: {id: P1, height_m: 1.8}\nsession: {date: 2024-05-02}\n"
        "sensors:\n  00b421ed: {segment: shank, side: Right, label: shank_r}\n"
        "  thigh: {segment: thigh, side: L}\n"
    )
    s = ingest(list(fake_files), m, command="motionlab ingest test")
    assert list(s.sensors) == ["thigh", "shank_r"]
    assert s.metadata["time_origin_s"] == 1000.0
    assert s.metadata["subject"] == {"id": "P1", "height_m": 1.8}
    assert s.metadata["session"] == {"date": "2024-05-02"}
    sh = s.sensors["shank_r"]
    assert (sh.segment, sh.side, sh.serial) == ("shank", "r", "00B421ED")
    assert s.sensors["thigh"].side == "l"
    assert sh.time[0] == pytest.approx(0.5) and sh.attrs["start_s"] == 1000.5
    assert s.markers["optical"].time[0] == pytest.approx(0.2)
    np.testing.assert_allclose(sh.acc, ramp(sh.time), atol=1e-9)
    assert sh.qc["flags"]["gaps"] is False and sh.qc["rate_hz"] == pytest.approx(100.0)
    p = s.provenance[-1]
    assert p["command"] == "motionlab ingest test"
    assert p["parameters"]["gap_max_s"] == 0.1
    assert p["inputs"] == {str(f): sha256_file(f) for f in [*fake_files, m]}
    assert p["software"].startswith("motionlab ")


def test_ingest_rate_puts_everything_on_one_clock(fake_files):
    s = ingest(list(fake_files), rate=50.0)
    for x in [*s.sensors.values(), *s.markers.values()]:
        np.testing.assert_allclose(x.time * 50, np.round(x.time * 50), atol=1e-9)
    assert s.sensors["shank"].time[0] == pytest.approx(0.5)


def test_map_naming_absent_sensor(fake_files, tmp_path):
    """A key that names no sensor here is kept as a warning (a study's map names a device one
    recording lacks), with its line and segment; a map none of whose keys names a sensor is the
    wrong map: an error naming its first key and what is there."""
    m = tmp_path / "map.yaml"
    m.write_text("sensors:\n  thigh: {segment: thigh}\n  00B4FFFF: {segment: foot, side: r}\n")
    session = ingest(list(fake_files), m)
    assert session.metadata["map_unmatched"] == [
        {"key": "00B4FFFF", "line": 3, "segment": "foot_r"}
    ]
    (line,) = unmatched_keys(session)
    assert line.startswith("sensor map key '00B4FFFF' (line 3, foot_r) names no sensor")
    assert "00B421AF" in line and "\n" not in line
    assert session.sensors["thigh"].segment == "thigh"  # the keys that match still apply
    m.write_text("sensors:\n  00B4FFFE: {segment: thigh}\n  00B4FFFF: {segment: foot}\n")
    with pytest.raises(InputError) as e:
        ingest(list(fake_files), m)
    assert e.value.where == "line 2, key sensors.00B4FFFE"
    assert "no key of the map names one" in e.value.line() and "00B421AF" in e.value.line()


@pytest.mark.parametrize(
    "text, key",
    [
        ("sensors:\n  a: {segment: shank, side: up}\n", "sensors.a.side"),
        ("sensors:\n  a: {segment: shank, colour: red}\n", "sensors.a.colour"),
        ("sensor:\n  a: {segment: shank}\n", "sensor"),
        ("sensors:\n  a: {label: x}\n  b: {label: x}\n", "sensors.b.label"),
        ("subject: P1\n", "subject"),
        # a length in cm, or not a number: the gait analysis left it out without a word
        ("subject: {id: P1, height_m: 178}\n", "subject.height_m"),
        ('sensors:\n  a: {label: "x\\ny"}\n', "sensors.a.label"),  # printed on two lines
        ("reader: {format: xsens, rate_hz: 60, mag_feild_ut: 48}\n", "reader.mag_feild_ut"),
        ("subject:\n  thigh_m: 0.4\n  shank_m: tall\n", "subject.shank_m"),
        # two sensors on one segment (a side copied wrong): one of them was analysed, silently
        (
            "sensors:\n  a: {segment: thigh, side: r}\n  b: {segment: thigh_r}\n",
            "sensors.b.segment",
        ),
    ],
)
def test_map_errors_name_the_key(tmp_path, text, key):
    m = tmp_path / "map.yaml"
    m.write_text(text)
    with pytest.raises(InputError) as e:
        load_sensor_map(m)
    assert e.value.where.endswith(f"key {key}")


def test_map_keys_stay_text(tmp_path):
    m = tmp_path / "map.yaml"
    m.write_text("sensors:\n  00123456: {side: left}\n  0x1F: {}\n")
    smap = load_sensor_map(m)
    assert list(smap.sensors) == ["00123456", "0x1F"]


def test_all_nan_channel_refused(fake_files, monkeypatch):
    t = np.arange(10) / 100
    rec = Recording(sensors=[stream(t, "x", gyr=np.full((10, 3), np.nan), acc=ramp(t))])
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: rec)
    with pytest.raises(InputError, match="channel gyr holds no usable numbers"):
        ingest([fake_files[0]])


def test_axis_without_usable_numbers_refused(fake_files, monkeypatch, tmp_path):
    """An axis of ±inf only, or of 1e308 only (the others numbers), was taken and left that
    axis NaN or beyond any sensor for the whole recording; it is refused like an all-NaN
    column, by the ingest and by the reader."""
    t = np.arange(10) / 100
    acc = ramp(t)
    acc[:, 1] = np.inf
    gyr = np.zeros((10, 3))
    gyr[:, 2] = 1e308
    for channels, match in [
        ({"acc": acc, "gyr": np.zeros((10, 3))}, r"channel acc .* in axis y \(all NaN, ±inf"),
        ({"acc": ramp(t), "gyr": gyr}, r"channel gyr holds no usable numbers in axis z"),
    ]:
        rec = Recording(sensors=[stream(t, "x", **channels)])
        monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None, rec=rec: rec)
        with pytest.raises(InputError, match=match):
            ingest([fake_files[0]])
    monkeypatch.undo()
    p = tmp_path / "inf.csv"
    write_xio(p, t, np.zeros((10, 3)), np.column_stack([np.full(10, np.inf), np.ones((10, 2))]))
    with pytest.raises(InputError, match=r"column 'Accelerometer X \(g\)': .*has no values"):
        ingest([p])


def test_free_acceleration_beyond_any_sensor_is_refused_or_doubted(fake_files, monkeypatch):
    """The vendor's free acceleration (``extra["free_acc"]``, DOT and Xsens exports) is checked
    like the accelerometer: an axis of 1e308 only is refused, one 1e308 sample is a doubt."""
    t = np.arange(200) / 100
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (200, 1))
    for row, refused in [(slice(None), True), (50, False)]:
        free = np.zeros((200, 3))
        free[row, 0] = 1e308
        s = stream(t, "x", quat=quat)
        s.extra["free_acc"] = free
        rec = Recording(sensors=[s])
        monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None, rec=rec: rec)
        if refused:
            with pytest.raises(InputError, match=r"channel free_acc holds no usable numbers in "):
                ingest([fake_files[0]])
            continue
        got = next(iter(ingest([fake_files[0]]).sensors.values()))
        assert got.qc["implausible_share"] == {"free_acc": 1 / 200}
        assert "in free_acc 0.5 % of the rows: damaged?" in qc.doubts(got)[0]


def write_xio(path, t, gyr_dps, acc_g):
    head = "Time (s)," + ",".join(f"Gyroscope {a} (deg/s)" for a in "XYZ") + ","
    head += ",".join(f"Accelerometer {a} (g)" for a in "XYZ")
    np.savetxt(path, np.column_stack([t, gyr_dps, acc_g]), delimiter=",", header=head,
               comments="", fmt="%.9g")  # fmt: skip


def test_ingest_xio_files_end_to_end(tmp_path):
    rng = np.random.default_rng(3)
    files = []
    for k, start in enumerate([0.0, 0.37]):
        t = start + np.arange(0, 5.0, 0.01)
        keep = np.ones(len(t), bool)
        keep[100:103] = False  # a short gap, filled
        keep[300:340] = False  # a long gap, kept
        gyr = rng.normal(size=(len(t), 3)) * 10
        write_xio(tmp_path / f"s{k}.csv", t[keep], gyr[keep], np.tile([0, 0, 1.0], (keep.sum(), 1)))
        files.append(tmp_path / f"s{k}.csv")
    before = [(f.read_bytes(), f.stat().st_mtime_ns) for f in files]
    s = ingest(files)
    assert [(f.read_bytes(), f.stat().st_mtime_ns) for f in files] == before
    s1 = s.sensors["s1"]
    assert s1.time[0] == pytest.approx(0.37)
    assert s1.qc["gaps_filled"] == 1 and s1.qc["samples_filled"] == 3
    assert s1.qc["gaps"] == [[pytest.approx(0.37 + 2.99), pytest.approx(0.37 + 3.40)]]
    assert s1.source_units["gyr"] == "deg/s"
    assert s1.qc["acc_rest_norm"] == pytest.approx(9.80665)
    out = tmp_path / "session.h5"
    save_session(s, out)
    back = load_session(out)
    np.testing.assert_array_equal(back.sensors["s1"].gyr, s1.gyr)
    assert back.sensors["s1"].qc == s1.qc


@needs_shared
def test_ingest_real_xsens_and_xio():
    f = SHARED / "formats"
    s = ingest([f / "xsens/MT_012005D6_031-000_00B421AF.txt", f / "xio/sensor_data.csv"])
    xs = s.sensors["00B421AF"]
    assert xs.qc["rate_hz"] == pytest.approx(100.0)
    assert xs.qc["acc_rest_norm"] == pytest.approx(9.81, abs=0.1)
    # the only finding is the assumption the reader made: the magnetometer's a.u. scale
    assert [k for k, v in xs.qc["flags"].items() if v] == ["mag_scale_assumed"]
    xio = s.sensors["sensor_data"]
    assert xio.source_units["gyr"] == "deg/s"
    assert not xio.qc["flags"]["gyr_looks_like_deg_s"]
    assert 20 < xio.qc["mag_norm_ut"] < 70


def test_info_json_and_text(tmp_path):
    from click.testing import CliRunner

    from motionlab.cli import main

    t = np.arange(0, 3.0, 0.01)
    t = t[(t < 1.0) | (t > 1.5)]
    write_xio(tmp_path / "a.csv", t, np.zeros((len(t), 3)), np.tile([0, 0, 1.0], (len(t), 1)))
    out = str(tmp_path / "s.h5")
    assert CliRunner().invoke(main, ["ingest", str(tmp_path / "a.csv"), "-o", out]).exit_code == 0
    r = CliRunner().invoke(main, ["info", out, "--json"])
    assert r.exit_code == 0
    import json

    a = json.loads(r.stdout)["sensors"][0]
    assert a["label"] == "a" and a["n_samples"] == len(t) and a["channels"] == ["acc", "gyr"]
    assert a["rate_hz"] == pytest.approx(100.0) and a["duration_s"] == pytest.approx(2.99)
    assert a["units"] == {"time": "s", "acc": "m/s^2", "gyr": "rad/s"}
    assert a["gaps"] == [[pytest.approx(0.99), pytest.approx(1.51)]]
    assert a["flags"]["gaps"] is True and a["flags"]["acc_saturated"] is False
    text = CliRunner().invoke(main, ["info", out]).stdout
    assert "gaps kept as missing: 0.99–1.51 s" in text and "qc flags: dropped_samples, gaps" in text
    assert f"motionlab ingest {tmp_path / 'a.csv'} -o {out}" in text


def test_unrelated_clocks_are_flagged(fake_files, monkeypatch):
    t = np.arange(0, 1.0, 0.01)
    recs = {
        fake_files[0]: Recording(sensors=[stream(1.55e9 + t, "unix", acc=ramp(t))]),
        fake_files[1]: Recording(sensors=[stream(t, "zero", acc=ramp(t))]),
    }
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    s = ingest(list(fake_files))
    assert s.metadata["clocks_unrelated"] is True
    assert s.metadata["start_spread_s"] == pytest.approx(1.55e9)
    assert s.sensors["unix"].attrs["start_s"] == 1.55e9


def test_related_clocks_are_not_flagged(fake_files):
    s = ingest(list(fake_files))
    assert s.metadata["clocks_unrelated"] is False
    assert s.metadata["start_spread_s"] == pytest.approx(0.5)


def test_doubts_name_inf_values_and_rows_without_time(tmp_path):
    """An inf sample (1e308 g is inf in m/s²) was counted nowhere, and rows with a NaN time
    were dropped without a word: both are doubts the ingest prints."""
    t = np.arange(200) / 100.0
    acc = np.tile([0.0, 0.0, 1.0], (200, 1))
    acc[50, 0] = 1e308
    t[[10, 20]] = np.nan
    write_xio(tmp_path / "s.csv", t, np.zeros((200, 3)), acc)
    s = next(iter(ingest([tmp_path / "s.csv"]).sensors.values()))
    assert s.qc["implausible_share"] == {"acc": 1 / 198}
    assert [d.split(" — ")[0] for d in qc.doubts(s)] == [
        "values beyond what a sensor measures (1e308, ±inf) in acc 0.505 % of the rows: damaged?",
        "2 rows without a time stamp (NaN) dropped",
    ]


def test_reader_keys_cover_every_reader_option():
    """The sensor map refuses a reader key no reader takes; each one a reader takes is let
    through (the generic reader's column map, Xsens and x-IMU3 ``mag_field_ut``)."""
    from motionlab.io import generic
    from motionlab.sensor_map import READER_KEYS

    assert set(READER_KEYS) == generic._TOP_KEYS | generic._SENSOR_KEYS | {"mag_field_ut"}


def test_a_gyroscope_reading_zeros_while_the_sensor_turns_is_refused(tmp_path):
    """A dead gyroscope exported as zeros beside an accelerometer that sees gravity turn by 90°
    (the sensor tilted over 2 s): refused in one line naming the file, the sensor and the channel.
    The same zeros on a sensor whose gravity does not turn (a noiseless still sensor, or a spin
    about the vertical) pass: they may be true."""
    t = np.arange(400) / 100.0
    tilt = np.clip(t - 1.0, 0.0, 2.0) * np.pi / 4  # 0 → 90° over 1-3 s
    acc = np.column_stack([np.sin(tilt), np.zeros_like(t), np.cos(tilt)])  # in g
    write_xio(tmp_path / "dead.csv", t, np.zeros((400, 3)), acc)
    with pytest.raises(InputError) as err:
        ingest([tmp_path / "dead.csv"])
    line = err.value.line()
    assert (
        line.startswith("dead.csv sensor ") and "channel gyr: channel gyr reads (0, 0, 0)" in line
    )
    assert "gravity turn by 90°" in line and "record with the gyroscope on" in line
    write_xio(tmp_path / "still.csv", t, np.zeros((400, 3)), np.tile([0.0, 0.0, 1.0], (400, 1)))
    assert ingest([tmp_path / "still.csv"]).sensors


def test_an_apdm_format7_file_keeps_its_unix_clock_against_a_trc(tmp_path):
    """docs/ingest.md's own example, an APDM Format=7 export beside optical frames from 0 s,
    was laid on one time axis as if simultaneous: the reader had subtracted its first Unix
    stamp. It keeps the Unix time now, so the clocks are told unrelated, and the date."""
    data = Path(__file__).parent / "data"
    s = ingest([data / "apdm" / "apdm_format7.csv", data / "c3d" / "markers_20frames.trc"])
    assert s.metadata["clocks_unrelated"] is True
    assert s.metadata["start_spread_s"] == pytest.approx(1550879504.438281, abs=1e-3)
    assert s.sensors["Lumbar"].attrs["recorded"] == "2019-02-22"


def test_one_device_in_two_files_is_named_as_such(fake_files, monkeypatch, tmp_path):
    """Two exports of one Xsens recording (comma and semicolon, DeviceId 00B42D4B) were told to
    be given their own labels by serial, then, with such a map, to be keyed by serial: a map
    cannot tell one device apart from itself. Now the refusal says it is one device; two
    devices that share a label are still told to take their own."""
    t = np.arange(0, 1.0, 0.01)
    recs = {
        fake_files[0]: Recording(sensors=[stream(t, "00B42D4B", "00B42D4B", acc=ramp(t))]),
        fake_files[1]: Recording(sensors=[stream(t, "00B42D4B", "00B42D4B", acc=ramp(t))]),
    }
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    with pytest.raises(InputError, match="device 00B42D4B also comes from .*recording once"):
        ingest(list(fake_files))
    smap = tmp_path / "map.yaml"
    smap.write_text("sensors:\n  00B42D4B: {segment: thigh, side: r}\n")
    with pytest.raises(InputError, match="names device 00B42D4B in both .*recording once"):
        ingest(list(fake_files), smap)
    recs[fake_files[1]].sensors[0] = stream(t, "00B42D4B", "00B4AAAA", acc=ramp(t))
    with pytest.raises(InputError, match="sensor label '00B42D4B' also comes from .*own label"):
        ingest(list(fake_files))


def test_info_says_where_a_late_stream_starts(fake_files, monkeypatch, tmp_path):
    """DOT streams that began 55 min after an Xsens one showed their durations only: nothing
    told that the files do not overlap."""
    from click.testing import CliRunner

    from motionlab.cli import main
    from motionlab.session import save_session

    t = np.arange(0, 1.0, 0.01)
    recs = {
        fake_files[0]: Recording(sensors=[stream(t, "early", acc=ramp(t))]),
        fake_files[1]: Recording(sensors=[stream(3300.0 + t, "late", acc=ramp(t))]),
    }
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    save_session(ingest(list(fake_files)), tmp_path / "s.h5")
    text = CliRunner().invoke(main, ["info", str(tmp_path / "s.h5")]).stdout
    assert "starts at 3300.00 s of the session" in text and text.count("starts at") == 1


def test_an_accelerometer_and_gyroscope_of_zeros_say_the_accelerometer_reads_zeros(tmp_path):
    """Both channels exported as zeros: 'channel gyr reads (0, 0, 0) ... while the
    accelerometer sees gravity turn by nan°' (the mean of zeros normalised), then a unit remedy
    for |a| = 0. Now one line that the accelerometer reads zeros."""
    from click.testing import CliRunner

    from motionlab.cli import main

    rows = "".join(f"{k / 100:.2f},0,0,0,0,0,0\n" for k in range(400))
    (tmp_path / "z.csv").write_text(
        "Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
        "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)\n" + rows
    )
    result = CliRunner().invoke(main, ["ingest", str(tmp_path / "z.csv"), "-o",
                                       str(tmp_path / "s.h5")])  # fmt: skip
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [
        "error: z.csv sensor z: |a| at rest is 0: the accelerometer reads zeros, it was off or "
        "not recorded — record with the accelerometer on, or export its channel again"
    ]


def test_an_accelerometer_in_m_s2_read_as_g_says_so(tmp_path):
    """The x-io excerpt with its accelerometer written in m/s² under its '(g)' header: the line
    asked whether the columns were the gyroscope's; |a| at rest is 9.81 times gravity."""
    from click.testing import CliRunner

    from motionlab.cli import main

    lines = (DATA / "xio" / "sensor_data_excerpt.csv").read_text().splitlines()
    rows = [c[:4] + [f"{float(v) * 9.80665:.6f}" for v in c[4:7]] + c[7:]
            for c in (line.split(",") for line in lines[1:])]  # fmt: skip
    (tmp_path / "x.csv").write_text("\n".join([lines[0], *map(",".join, rows)]) + "\n")
    result = CliRunner().invoke(main, ["ingest", str(tmp_path / "x.csv"), "-o",
                                       str(tmp_path / "s.h5")])  # fmt: skip
    assert result.exit_code == 2, result.output
    (line,) = result.stderr.splitlines()
    assert "(read as g), 9.81 times gravity: the accelerometer is in m/s², read as g" in line
    assert "acc: {unit: m/s^2}" in line


@pytest.mark.parametrize(
    ("label", "said"),
    [  # each crashed: a NUL (h5py: "VLEN strings do not support embedded NULLs"), "." (an
        # HDF5 group of that name exists), a non-UTF-8 folder name in the report (matplotlib),
        # 70 000 characters (the report's wrapping for minutes)
        ("Ba\x00ck", "holds control or undecodable characters"),
        (".", "is only dots"),
        ("Ch\udce4ir", "holds control or undecodable characters"),
        ("x" * 70000, "is 70000 characters long"),
    ],
)
def test_a_device_name_that_cannot_name_a_sensor_is_one_line(fake_files, monkeypatch, label, said):
    t = np.arange(0, 1.0, 0.01)
    recs = {fake_files[0]: Recording(sensors=[stream(t, label, acc=ramp(t))])}
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    with pytest.raises(InputError, match=f"{said}: it cannot name a sensor .*sensor map") as err:
        ingest([fake_files[0]])
    assert len(str(err.value)) < 400 and "\n" not in str(err.value)


def test_time_stamps_in_another_unit_than_the_header_rate_are_refused(fake_files, monkeypatch):
    """A DOT export's SampleTimeFine in ms (read as µs) gave 58 823 Hz against the header's
    60 Hz: a warning, then the clock sync crashed (arrays of different lengths)."""
    t = np.arange(0, 3263) / 58823.5
    recs = {fake_files[0]: Recording(sensors=[stream(t, "Femur", acc=ramp(t))])}
    recs[fake_files[0]].sensors[0].attrs["nominal_rate_hz"] = 60.0
    monkeypatch.setattr(ingest_module, "read_any", lambda p, options=None: recs[p])
    with pytest.raises(InputError, match="give 5.882e.04 Hz, the file's header says 60 Hz .*unit"):
        ingest([fake_files[0]])
    recs[fake_files[0]].sensors[0] = stream(np.arange(0, 600) / 66.0, "Femur", acc=ramp(t[:600]))
    recs[fake_files[0]].sensors[0].attrs["nominal_rate_hz"] = 60.0  # 10 % off: a warning
    assert ingest([fake_files[0]]).sensors["Femur"].qc["flags"]["header_rate_mismatch"]


@pytest.mark.parametrize(
    ("options", "said"),
    [  # '--rate 0' said "--gap-max 0.1 must be ≥ 0 and --rate 0.0 > 0"; NaN was taken
        ({"rate": 0.0}, "rate=0 Hz is not a sampling rate"),
        ({"rate": float("inf")}, "rate=inf Hz is not a sampling rate"),
        ({"gap_max": -1.0}, "gap_max=-1 s is not a gap"),
        ({"gap_max": float("nan")}, "gap_max=nan s is not a gap"),
    ],
)
def test_rate_and_gap_options_are_checked_each_on_its_own(fake_files, options, said):
    with pytest.raises(InputError, match=said):
        ingest([fake_files[0]], **options)
    assert ingest([fake_files[0]], gap_max=float("inf")).sensors  # every gap interpolated
