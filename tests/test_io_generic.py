"""Generic delimited text through a column map, and the shared text helpers' error messages."""

import numpy as np
import pytest
import yaml

from motionlab import rotations
from motionlab.errors import InputError
from motionlab.io import generic, read_any
from motionlab.io.clock import count_wraps, unwrap_counter
from motionlab.io.delimited import parse_table, read_lines

RNG = np.random.default_rng(7)


def _write(tmp_path, text, name="data.txt"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _two_sensor_file(tmp_path, n=50):
    """Two IMUs side by side, ';' delimited, decimal comma, two header rows, comments."""
    t_ms = 10.0 * np.arange(n)
    a = RNG.normal(0, 1, (n, 3)) + [0, 0, 1]  # g
    w = RNG.normal(0, 30, (n, 3))  # deg/s
    q = rotations.normalize(RNG.normal(size=(n, 4)))
    lines = [
        "# exported by a lab script",
        "// units: ms, g, deg/s",
        "time;thigh;;;;;;shank;;;",
        "ms;ax;ay;az;gx;gy;gz;qx;qy;qz;qw",
    ]
    for k in range(n):
        vals = [t_ms[k], *a[k], *w[k], *q[k, 1:], q[k, 0]]
        lines.append(";".join(f"{v:.9f}".replace(".", ",") for v in vals))
        if k == 10:
            lines.append("# a comment in the middle")
    return _write(tmp_path, "\n".join(lines) + "\n"), t_ms, a, w, q


MAP = """
format: generic
header_rows: 2
time: {column: "time ms", unit: ms}
sensors:
  - label: thigh
    serial: T1
    acc: {columns: [thigh ax, thigh ay, thigh az], unit: g}
    gyr: {columns: [4, 5, 6], unit: deg/s}
  - label: shank
    quat: {columns: [shank qx, shank qy, shank qz, shank qw], order: xyzw}
"""


def test_two_sensors_two_row_header_decimal_comma(tmp_path):
    p, t_ms, a, w, q = _two_sensor_file(tmp_path)
    rec = read_any(p, yaml.safe_load(MAP))
    assert rec.format == "generic"
    thigh, shank = rec.sensors
    assert (thigh.label, thigh.serial, shank.label) == ("thigh", "T1", "shank")
    np.testing.assert_allclose(thigh.time, t_ms / 1000)
    assert thigh.rate_hz == pytest.approx(100.0)
    np.testing.assert_allclose(thigh.acc, a * 9.80665, atol=1e-8)
    np.testing.assert_allclose(thigh.gyr, np.radians(w), atol=1e-9)
    assert thigh.source_units == {"acc": "g", "gyr": "deg/s"}
    assert rotations.angle_between(shank.quat, q).max() < 1e-7
    assert shank.channels == ["quat"]


def test_single_sensor_at_top_level_with_nominal_rate(tmp_path):
    text = "ax,ay,az\n" + "".join(f"{k},0,9.81\n" for k in range(20))
    s = read_any(
        _write(tmp_path, text),
        {"format": "generic", "rate_hz": 50, "acc": {"columns": [0, 1, 2], "unit": "m/s^2"}},
    )
    (s,) = s.sensors
    assert s.label == "data" and s.rate_hz == pytest.approx(50.0)
    np.testing.assert_allclose(s.acc[:, 0], np.arange(20))


def test_whitespace_delimiter_no_header_and_wrapping_ticks(tmp_path):
    ticks = (65536 - 30 + 10 * np.arange(10)) % 65536
    text = "".join(f"  {t}   0.1  0.2  0.3\n" for t in ticks)
    opts = {
        "format": "generic",
        "delimiter": "whitespace",
        "header_rows": 0,
        "time": {"column": 0, "unit": "ticks", "tick_hz": 1000, "wrap_bits": 16},
        "gyr": {"columns": [1, 2, 3], "unit": "rad/s"},
    }
    (s,) = read_any(_write(tmp_path, text), opts).sensors
    np.testing.assert_allclose(np.diff(s.time), 0.01)


def test_sniff_is_always_false(tmp_path):
    p = _write(tmp_path, "a,b,c\n1,2,3\n")
    assert not generic.sniff(p, p.read_bytes())


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (
            {
                "sensors": [
                    {"label": "x", "acc": {"columns": ["a", "b", "c"], "unit": "g"}, "colour": 1}
                ]
            },
            "sensors[0].colour",
        ),
        ({"sensors": [{"label": "x", "gyr": {"columns": ["a", "b", "c"]}}]}, "sensors[0].gyr.unit"),
        (
            {"sensors": [{"label": "x", "gyr": {"columns": ["a", "b", "nope"], "unit": "rad/s"}}]},
            "sensors[0].gyr.columns[2]",
        ),
        (
            {"sensors": [{"label": "x", "gyr": {"columns": ["a", "b", "c"], "unit": "g"}}]},
            "sensors[0].gyr.unit",
        ),
        (
            {
                "sensors": [
                    {"label": "a", "acc": {"columns": [0, 1, 2], "unit": "g"}},
                    {"acc": {"columns": [0, 1, 2], "unit": "g"}},
                ]
            },
            "sensors[1].label",
        ),
        (
            {"sensors": [{"label": "x", "quat": {"columns": [0, 1, 2], "order": "wxyz"}}]},
            "sensors[0].quat.columns",
        ),
        ({"time": {"column": "t", "unit": "fortnight"}}, "time.unit"),
        ({"time": None, "rate_hz": None}, "time"),
        ({"rate_hz": "fast", "time": None}, "rate_hz"),
        ({"delimiter": "|"}, "delimiter"),
        ({"header_rows": 3}, "header_rows"),
        ({"sensors": []}, "sensors"),
    ],
)
def test_invalid_maps_name_the_key(tmp_path, change, key):
    p = _write(tmp_path, "t,a,b,c\n0,1,2,3\n0.01,1,2,3\n")
    opts = {
        "format": "generic",
        "time": "t",
        "sensors": [{"label": "x", "acc": {"columns": ["a", "b", "c"], "unit": "g"}}],
    }
    opts.update(change)
    opts = {k: v for k, v in opts.items() if v is not None}
    with pytest.raises(InputError) as err:
        read_any(p, opts)
    assert err.value.where == f"column map key {key}"


def test_nan_only_channel_is_an_error(tmp_path):
    p = _write(tmp_path, "t,a,b,c\n0,1,,3\n0.01,1,NaN,3\n")
    opts = {"format": "generic", "time": "t", "acc": {"columns": ["a", "b", "c"], "unit": "g"}}
    with pytest.raises(InputError) as err:
        read_any(p, opts)
    assert err.value.where == "column 'b'"


# ------------------------------------------------------------------------------ text helpers


def _table(tmp_path, text, **kw):
    p = _write(tmp_path, text, "trial3.csv")
    return parse_table(p, read_lines(p), 0, **kw)


def test_wrong_delimiter_on_one_line_suggests_the_right_one(tmp_path):
    rows = ["t,a,b,c,d,e,f,g,h,i"] + [",".join(["1"] * 10)] * 5 + [";".join(["1"] * 10)]
    rows += [",".join(["1"] * 10)] * 3
    with pytest.raises(InputError) as err:
        _table(tmp_path, "\n".join(rows))
    assert err.value.line() == "trial3.csv line 7: 1 columns, expected 10 — is the delimiter ';'?"


def test_whole_file_with_unexpected_delimiter(tmp_path):
    with pytest.raises(InputError) as err:
        _table(tmp_path, "t;a;b\n1;2;3\n", delimiter=",")
    assert "is the delimiter ';'?" in err.value.line()


def test_text_in_numeric_column_and_header_only(tmp_path):
    with pytest.raises(InputError) as err:
        _table(tmp_path, "t\tacc x\n0\t1\n0.01\tn/a\n0.02\tabc\n")
    assert err.value.line() == (
        "trial3.csv line 4: 'abc' in numeric column 'acc x' — "
        "fix or delete the line, or check that the header matches the data"
    )
    with pytest.raises(InputError, match="no data rows"):
        _table(tmp_path, "t,a\n\n")


def test_truncated_last_line_dropped_middle_line_refused(tmp_path):
    t = _table(tmp_path, "t,a,b\n0,1,2\n1,1,2\n2,1")
    assert t.data.shape == (2, 3) and "truncated last line" in t.notes[0]
    with pytest.raises(InputError) as err:
        _table(tmp_path, "t,a,b\n0,1,2\n1,1\n2,1,2\n")
    assert err.value.where == "line 3" and "2 columns, expected 3" in err.value.message


def test_decimal_comma_detected_and_empty_fields_nan(tmp_path):
    t = _table(tmp_path, "a;b;c\n1,5;;-2,25\n3;NaN;4\n")
    assert t.delimiter == ";" and t.decimal == ","
    np.testing.assert_array_equal(t.data, [[1.5, np.nan, -2.25], [3, np.nan, 4]])


def test_unwrap_counter():
    c = np.array([65534, 65535, 0, 1, 5, 4])  # a wrap, a gap of 3, one step back
    np.testing.assert_array_equal(unwrap_counter(c, 16), [65534, 65535, 65536, 65537, 65541, 65540])
    assert count_wraps(c, 16) == 1
    big = np.array([2**32 - 1, 0, 1], dtype=np.uint32)
    np.testing.assert_array_equal(unwrap_counter(big, 32), [2**32 - 1, 2**32, 2**32 + 1])


def _rig_file(tmp_path, rate_line="# sampling frequency: 40", n=80):
    """Five IMUs in one comma file without a time column, in the layout of a multi-segment rig
    (``segN_acc_x`` …, gyro rad/s, magnetometer in arbitrary units); synthetic values."""
    rng = np.random.default_rng(3)
    names = [
        f"seg{s}_{ch}_{ax}" for s in range(1, 6) for ch in ("acc", "gyr", "mag") for ax in "xyz"
    ]
    data = rng.normal(size=(n, len(names)))
    lines = [rate_line, "# units are seconds/meters/radians/a.u.", ",".join(names)]
    lines += [",".join(f"{v:.9f}" for v in row) for row in data]
    return _write(tmp_path, "\n".join(lines) + "\n", "imu.csv"), names, data


def _rig_map(**top):
    sensors = [
        {
            "label": f"seg{s}",
            "acc": {"columns": [f"seg{s}_acc_{a}" for a in "xyz"], "unit": "m/s^2"},
            "gyr": {"columns": [f"seg{s}_gyr_{a}" for a in "xyz"], "unit": "rad/s"},
            "mag": {"columns": [f"seg{s}_mag_{a}" for a in "xyz"], "unit": "a.u."},
        }
        for s in range(1, 6)
    ]
    return {"format": "generic", "sensors": sensors, **top}


def test_five_sensors_rate_from_comment_and_mag_in_arbitrary_units(tmp_path):
    p, names, data = _rig_file(tmp_path)
    rec = read_any(p, _rig_map())
    assert [s.label for s in rec.sensors] == [f"seg{k}" for k in range(1, 6)]
    for k, s in enumerate(rec.sensors):
        assert len(s.time) == 80 and s.rate_hz == pytest.approx(40.0)
        np.testing.assert_allclose(s.time, np.arange(80) / 40.0)
        assert s.attrs["time_source"] == "comment line 1: 40.0 Hz"
        j = names.index(f"seg{k + 1}_gyr_x")
        np.testing.assert_allclose(s.gyr, data[:, j : j + 3], atol=1e-9)
        raw = data[:, j + 3 : j + 6]
        # direction kept, median norm at the assumed field, flagged so QC does not judge it
        cos = np.einsum("ij,ij->i", s.mag, raw) / np.linalg.norm(s.mag, axis=1)
        np.testing.assert_allclose(cos, np.linalg.norm(raw, axis=1), rtol=1e-9)
        assert np.median(np.linalg.norm(s.mag, axis=1)) == pytest.approx(50.0)
        assert s.source_units["mag"] == "a.u."
        assert s.attrs["mag_scale_assumed"] is True
        assert any("a.u." in note for note in s.attrs["notes"])


@pytest.mark.parametrize(
    "line, rate",
    [
        ("// fs=100", 100.0),
        ("# rate: 100 Hz", 100.0),
        ("# Sampling Rate (Hz): 128", 128.0),
        ("#sample_rate=62.5Hz", 62.5),
    ],
)
def test_rate_line_forms(tmp_path, line, rate):
    p, _, _ = _rig_file(tmp_path, line, n=20)
    s = read_any(p, _rig_map()).sensors[0]
    assert s.rate_hz == pytest.approx(rate)


def test_rate_in_map_wins_over_comment_and_missing_rate_is_an_error(tmp_path):
    p, _, _ = _rig_file(tmp_path, "# sampling frequency: 40", n=20)
    s = read_any(p, _rig_map(rate_hz=50)).sensors[0]
    assert s.rate_hz == pytest.approx(50.0) and s.attrs["time_source"] == "rate_hz 50.0"
    p, _, _ = _rig_file(tmp_path, "# recorded on a rig", n=20)
    with pytest.raises(InputError, match="no rate in a comment line"):
        read_any(p, _rig_map())


def test_arbitrary_units_only_for_the_magnetometer(tmp_path):
    p, _, _ = _rig_file(tmp_path, n=20)
    bad = _rig_map()
    bad["sensors"][0]["acc"]["unit"] = "a.u."
    with pytest.raises(InputError, match="acc cannot be in a.u."):
        read_any(p, bad)
    custom = _rig_map()
    custom["sensors"][0]["mag"]["field_ut"] = 40
    s = read_any(p, custom).sensors[0]
    assert np.median(np.linalg.norm(s.mag, axis=1)) == pytest.approx(40.0)
    wrong = _rig_map()
    wrong["sensors"][0]["gyr"]["field_ut"] = 40
    with pytest.raises(InputError, match="field_ut"):
        read_any(p, wrong)


def test_header_and_rows_ending_in_the_delimiter(tmp_path):
    """``t;ax;ay;az;``: a trailing delimiter is an empty last field, not a damaged line."""
    opts = {"format": "generic", "time": {"column": "t", "unit": "s"},
            "acc": {"columns": ["ax", "ay", "az"], "unit": "m/s^2"}}  # fmt: skip
    rows = [f"{k / 100};0;0;9.81{';' if k % 2 else ''}\n" for k in range(20)]
    (s,) = read_any(_write(tmp_path, "t;ax;ay;az;\n" + "".join(rows)), opts).sensors
    assert s.n_samples == 20 and s.acc[:, 2] == pytest.approx(9.81)
    assert np.diff(s.time) == pytest.approx(0.01)
    bad = "t;ax;ay;az;\n" + "".join(rows[:2]) + "0.5;1;2\n" + "".join(rows[2:])
    with pytest.raises(InputError, match="line 4: 3 columns, expected 4"):
        read_any(_write(tmp_path, bad), opts)
