"""Calibration files: exact round trip, application to a stream, validation of broken files."""

import json

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.sensorcal import (
    ChannelCalibration,
    SensorCalibration,
    apply_calibration,
    apply_calibration_dir,
    calibration_path,
    find_calibration,
    load_calibration,
    save_calibration,
)
from motionlab.session import SensorStream


def example(serial: str = "00B421AF") -> SensorCalibration:
    rng = np.random.default_rng(0)
    return SensorCalibration(
        serial=serial,
        channels={
            "gyr": ChannelCalibration(rng.normal(0, 0.01, 3), np.eye(3), "rest-windows"),
            "mag": ChannelCalibration(
                rng.normal(0, 10, 3),
                np.eye(3) + rng.normal(0, 0.05, (3, 3)),
                "ellipsoid",
                quality={"coverage": 0.83, "offset_sd": np.array([0.1, 0.2, 0.3])},
            ),
        },
        noise={"gyr": {"white_density": [1e-4, 2e-4, np.float64(3e-4)], "rate_random_walk": None}},
        vendor="xsens",
    )


def stream(serial: str = "00B421AF", n: int = 50) -> SensorStream:
    rng = np.random.default_rng(1)
    return SensorStream(
        label="shank_r",
        time=np.arange(n) / 100.0,
        acc=rng.normal(size=(n, 3)),
        gyr=rng.normal(size=(n, 3)),
        mag=rng.normal(size=(n, 3)),
        serial=serial,
    )


def test_yaml_round_trip_is_exact(tmp_path):
    cal = example()
    path = save_calibration(cal, tmp_path / "calibration")  # the folder is created
    assert path == tmp_path / "calibration" / "00B421AF.yaml"
    back = load_calibration(path)
    for ch in ("gyr", "mag"):
        assert np.array_equal(back.channels[ch].offset, cal.channels[ch].offset)
        assert np.array_equal(back.channels[ch].matrix, cal.channels[ch].matrix)
        assert back.channels[ch].method == cal.channels[ch].method
        assert back.channels[ch].date == cal.channels[ch].date
    assert back.channels["mag"].quality["offset_sd"] == [0.1, 0.2, 0.3]
    assert back.noise == {"gyr": {"white_density": [1e-4, 2e-4, 3e-4], "rate_random_walk": None}}
    assert back.serial == "00B421AF" and back.vendor == "xsens"
    assert find_calibration(tmp_path / "calibration", "00B421AF").channels.keys() == {"gyr", "mag"}
    assert find_calibration(tmp_path / "calibration", "other") is None


def test_json_files_are_read_and_existing_files_need_force(tmp_path):
    cal = example()
    (tmp_path / "00B421AF.json").write_text(json.dumps(cal.to_dict()))
    back = find_calibration(tmp_path, "00B421AF")
    assert np.array_equal(back.channels["mag"].matrix, cal.channels["mag"].matrix)
    save_calibration(cal, tmp_path)
    with pytest.raises(InputError, match="force=True") as err:  # the argument, not the flag
        save_calibration(cal, tmp_path)
    assert err.value.arguments == ("force",)
    save_calibration(cal, tmp_path, force=True)


def test_serial_is_made_safe_for_file_names(tmp_path):
    assert calibration_path(tmp_path, "IMU 3/left").name == "IMU_3_left.yaml"


def test_apply_corrects_the_recorded_channels_and_keeps_the_input():
    cal, s = example(), stream()
    raw_mag = s.mag.copy()
    out = apply_calibration(s, cal)
    c = cal.channels["mag"]
    assert np.allclose(out.mag, (raw_mag - c.offset) @ c.matrix.T)
    assert np.allclose(out.gyr, s.gyr - cal.channels["gyr"].offset)
    assert np.array_equal(out.acc, s.acc)  # no accelerometer calibration in the file
    assert np.array_equal(s.mag, raw_mag) and "calibration" not in s.attrs
    assert out.attrs["calibration"]["serial"] == "00B421AF"
    assert set(out.attrs["calibration"]["channels"]) == {"gyr", "mag"}
    with pytest.raises(InputError, match="already calibrated"):
        apply_calibration(out, cal)


def test_apply_refuses_another_device_or_nothing_to_do():
    with pytest.raises(InputError, match="serial"):
        apply_calibration(stream(serial="OTHER"), example())
    bare = SensorStream(label="x", time=np.arange(3.0), acc=np.zeros((3, 3)), serial="00B421AF")
    with pytest.raises(InputError, match="covers none"):
        apply_calibration(bare, example())


def test_apply_a_folder_by_serial(tmp_path):
    save_calibration(example(), tmp_path)
    streams = {"shank_r": stream(), "thigh_r": stream(serial="NOFILE")}
    done, notes = apply_calibration_dir(streams, tmp_path, ["shank_r", "thigh_r"])
    assert set(done) == {"shank_r"} and "no calibration" in notes["thigh_r"]
    # the files looked for named: the folder held another set's ("00B421AF.yaml")
    with pytest.raises(InputError, match="holds no calibration .*looked for NOFILE.yaml"):
        apply_calibration_dir(streams, tmp_path, ["thigh_r"])
    with pytest.raises(InputError, match="no such calibration folder"):
        apply_calibration_dir(streams, tmp_path / "missing", ["shank_r"])


@pytest.mark.parametrize(
    "edit, where",
    [
        (lambda d: d.update(format="something"), "key format"),
        (lambda d: d["channels"]["mag"].update(matrix=[[1, 0], [0, 1]]), "key channels.mag.matrix"),
        (lambda d: d["channels"]["mag"].update(matrix=np.zeros((3, 3)).tolist()), "singular"),
        (lambda d: d["channels"]["gyr"].update(offset=[0, "a", 0]), "key channels.gyr.offset"),
        (lambda d: d["channels"]["gyr"].update(unit="deg/s"), "key channels.gyr.unit"),
        (lambda d: d["channels"].update(baro={}), "key channels.baro"),
        (lambda d: d.update(serial=""), "key serial"),
        (lambda d: d.update(version=99), "key version"),
        # these crashed fuse, run and sensorcal with an internal error
        (lambda d: d.update(version="abc"), "key version"),
        (lambda d: d.update(version=[1]), "key version"),
        (lambda d: d.update(version=1.5), "key version"),
        (lambda d: d["channels"]["gyr"].update(quality=[1, 2, 3]), "key channels.gyr.quality"),
        (lambda d: d["channels"]["gyr"].update(quality="abc"), "key channels.gyr.quality"),
    ],
)
def test_broken_files_name_the_key(tmp_path, edit, where):
    data = example().to_dict()
    edit(data)
    path = tmp_path / "x.json"
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=where) as err:
        load_calibration(path)
    assert "x.json" in err.value.line()


def test_unparsable_file_names_the_line(tmp_path):
    path = tmp_path / "x.yaml"
    path.write_text("format: motionlab-sensor-calibration\nchannels: [unclosed\n")
    with pytest.raises(InputError, match="line"):
        load_calibration(path)
    with pytest.raises(InputError, match="no such"):
        load_calibration(tmp_path / "missing.yaml")


def test_billion_laughs_calibration_file_is_refused(tmp_path):
    lol = '"lol", ' * 8 + '"lol"'
    levels = zip("abcdefgh", "bcdefghi", strict=True)
    nested = "".join(f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in levels)
    text = f"a: &a [{lol}]\n" + nested
    path = tmp_path / "x.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match="alias"):
        load_calibration(path)


def test_a_serial_less_sensor_is_filed_by_its_files_label_not_the_maps(tmp_path):
    """APDM's ``Upper`` has no serial; mapped to ``thigh_r`` its calibration was filed as
    ``thigh_r.yaml`` (and printed as "serial thigh_r"), which the same file ingested without
    that map never found. It is filed by the name its file gives it."""
    from motionlab.ingest import ingest
    from motionlab.sensorcal import calibration_key

    csv = tmp_path / "imu.csv"
    rows = ["t,ax,ay,az,gx,gy,gz"] + [f"{k / 100:.2f},0,0,9.81,0.01,0,0" for k in range(300)]
    csv.write_text("\n".join(rows) + "\n")
    reader = (
        "reader:\n  format: generic\n  time: t\n  sensors:\n"
        "    - {label: Upper, acc: {columns: [ax, ay, az], unit: m/s^2},"
        " gyr: {columns: [gx, gy, gz], unit: rad/s}}\n"
    )
    (tmp_path / "plain.yaml").write_text("sensors:\n  Upper: {segment: thigh, side: r}\n" + reader)
    (tmp_path / "mapped.yaml").write_text(
        "sensors:\n  Upper: {segment: thigh, side: r, label: thigh_r}\n" + reader
    )
    mapped = ingest([csv], tmp_path / "mapped.yaml").sensors["thigh_r"]
    plain = ingest([csv], tmp_path / "plain.yaml").sensors["Upper"]
    assert mapped.serial == "" and calibration_key(mapped) == calibration_key(plain) == "Upper"


def test_sensorcal_refuses_a_file_under_this_name_holding_another_serial(tmp_path):
    """A file filed under this sensor's serial but holding another's: sensorcal --force wrote
    this sensor's bias into it, under the other serial, for fuse to apply to that device."""
    from motionlab.sensorcal.stage import merge

    other = example("OTHER-99")
    with pytest.raises(InputError, match="holds serial OTHER-99, the sensor is 00B421AF"):
        merge(other, stream(), [], "rec.csv", force=True, path=tmp_path / "00B421AF.yaml")
