"""OpenSim/OpenSense quaternion .sto: reading, writing, round trip, errors."""

from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.io import detect_format, opensim, read_any

TASKS = DATA / "opensim" / "myComplexTasksTrial_orientations.sto"
NO_RATE = DATA / "opensim" / "imuOrientations.sto"


def test_read_fixture():
    assert detect_format(TASKS) == "opensim"
    rec = read_any(TASKS)
    labels = ["pelvis_imu", "tibia_r_imu", "femur_r_imu", "tibia_l_imu", "femur_l_imu"]
    assert [s.label for s in rec.sensors] == labels + ["calcn_l_imu", "calcn_r_imu"]
    assert rec.metadata["nominal_rate_hz"] == 100.0
    for s in rec.sensors:
        assert s.channels == ["quat"] and s.quat.shape == (6, 4)
        assert s.rate_hz == pytest.approx(100.0, rel=1e-9)
        assert (
            "Z up" in s.attrs["earth_frame"]
            and "sensor_to_opensim_rotations" in (s.attrs["earth_frame"])
        )
        np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(
        rec.sensors[0].quat[0],
        [0.5064886386335554, 0.4915562864138964, -0.5355653906346357, 0.4636932052300068],
    )
    np.testing.assert_array_equal(rec.sensors[0].time, np.arange(6) * 0.01)


def test_read_without_datarate():
    rec = read_any(NO_RATE)
    assert len(rec.sensors) == 8 and "nominal_rate_hz" not in rec.metadata
    assert rec.sensors[0].rate_hz == pytest.approx(100.0)


def test_write_read_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    time = np.arange(250) / 100.0 + 12.34
    quats = {f"imu_{k}": rot.normalize(rng.normal(size=(250, 4))) for k in range(3)}
    quats["imu_1"][17] = np.nan  # a gap survives the trip
    path = tmp_path / "out.sto"
    opensim.write_sto(path, time, quats)
    lines = path.read_text().splitlines()
    assert lines[:5] == [
        "DataRate=100.000000",
        "DataType=Quaternion",
        "version=3",
        "OpenSimVersion=4.1",
        "endheader",
    ]
    assert lines[5].split("\t") == ["time", "imu_0", "imu_1", "imu_2"]
    assert lines[6 + 17].split("\t")[2] == "NaN,NaN,NaN,NaN"
    back = opensim.read(path)
    np.testing.assert_array_equal(back.sensors[0].time, time)
    for s in back.sensors:
        np.testing.assert_array_equal(s.quat, quats[s.label])  # bit-exact, NaN included
    with pytest.raises(InputError, match="output exists"):
        opensim.write_sto(path, time, quats)
    opensim.write_sto(path, time[:2], {"a": quats["imu_0"][:2]}, force=True)
    assert len(opensim.read(path).sensors) == 1


def test_rewrite_real_file_keeps_values(tmp_path):
    rec = opensim.read(TASKS)
    out = tmp_path / "copy.sto"
    opensim.write_sto(out, rec.sensors[0].time, {s.label: s.quat for s in rec.sensors})
    again = opensim.read(out)
    for a, b in zip(rec.sensors, again.sensors, strict=True):
        assert a.label == b.label
        np.testing.assert_array_equal(a.quat, b.quat)


def test_write_errors(tmp_path):
    t = np.arange(3) * 0.01
    with pytest.raises(InputError, match=r"expected \(3, 4\)"):
        opensim.write_sto(tmp_path / "a.sto", t, {"x": np.zeros((3, 3))})
    with pytest.raises(InputError, match="names without tab or comma"):
        opensim.write_sto(tmp_path / "a.sto", t, {"a,b": np.zeros((3, 4))})
    with pytest.raises(InputError, match="no orientations"):
        opensim.write_sto(tmp_path / "a.sto", t, {})
    assert not (tmp_path / "a.sto").exists()


def _variant(tmp_path: Path, edit) -> Path:
    lines = TASKS.read_text().splitlines()
    path = tmp_path / "v.sto"
    path.write_text("\n".join(edit(lines)) + "\n")
    return path


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda ls: [ln for ln in ls if ln != "endheader"], "no 'endheader'"),
        (lambda ls: ls[:7] + [ls[7].replace("0.49", "abc", 1)] + ls[8:], r"line 8 column"),
        (lambda ls: ls[:8] + [ls[8].replace(",", ";", 1)] + ls[9:], r"line 9.*expected w,x,y,z"),
        (lambda ls: ls[:9] + [ls[9][:120]], r"line 10.*cells, expected 8"),
        (lambda ls: ls[:1] + ["DataType=double"] + ls[2:], r"line 2.*DataType=double"),
        (lambda ls: ls[:5], "no column names"),
        (lambda ls: ["DataRate=fast"] + ls[1:], r"line 1.*DataRate=fast"),
    ],
)
def test_read_errors(tmp_path, edit, match):
    path = _variant(tmp_path, edit)
    with pytest.raises(InputError, match=match):
        opensim.read(path)
    assert detect_format(path) == "opensim"  # still recognised, so the error names the problem


@needs_shared
def test_shared_sto_files():
    files = sorted((SHARED / "formats" / "opensim").glob("*.sto"))
    assert len(files) == 3
    for path in files:
        rec = read_any(path)
        assert rec.format == "opensim" and len(rec.sensors) >= 7
        for s in rec.sensors:
            assert s.rate_hz == pytest.approx(100.0, rel=1e-6)
            np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-9)
    big = opensim.read(SHARED / "formats" / "opensim" / files[0].name)
    assert big.sensors[0].n_samples == 401 and big.sensors[0].time[0] == 678.0
