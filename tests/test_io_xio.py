"""x-io style CSV reader: units taken from the column names, converted to SI."""

import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab.errors import InputError
from motionlab.io import detect_format, read_any, xio
from motionlab.units import STANDARD_GRAVITY

FIXTURE = DATA / "xio" / "sensor_data_excerpt.csv"


def _one(path):
    rec = read_any(path)
    assert rec.format == "xio"
    return rec.sensors[0]


def test_fixture_units_and_rate():
    s = _one(FIXTURE)
    raw = np.genfromtxt(FIXTURE, delimiter=",", skip_header=1)
    assert s.n_samples == 300
    assert s.rate_hz == pytest.approx(99.2, abs=0.1)
    np.testing.assert_array_equal(s.time, raw[:, 0])
    np.testing.assert_allclose(s.gyr, np.radians(raw[:, 1:4]))
    np.testing.assert_allclose(s.acc, raw[:, 4:7] * STANDARD_GRAVITY)
    np.testing.assert_allclose(s.mag, raw[:, 7:10])
    assert s.source_units == {"time": "s", "gyr": "deg/s", "acc": "g", "mag": "uT"}
    # the board lies still at the start: |acc| ≈ g, |gyr| ≈ 0 rad/s, |mag| a plausible field
    assert np.linalg.norm(s.acc[:100], axis=1).mean() == pytest.approx(9.81, rel=0.01)
    assert np.linalg.norm(s.gyr[:100], axis=1).max() < 0.02
    assert 25 < np.linalg.norm(s.mag, axis=1).mean() < 65


def test_detected_by_content_and_other_units(tmp_path):
    assert detect_format(FIXTURE) == "xio"
    p = tmp_path / "imu.txt"
    p.write_text(
        "Timestamp (ms),Gyroscope X (rad/s),Gyroscope Y (rad/s),Gyroscope Z (rad/s),"
        "Accelerometer X (m/s^2),Accelerometer Y (m/s^2),Accelerometer Z (m/s^2),"
        "Barometer (hPa)\n0,1,2,3,0,0,9.8,1013\n10,1,2,3,0,0,9.8,1013\n"
    )
    assert xio.sniff(p, p.read_bytes())
    s = _one(p)
    np.testing.assert_allclose(s.time, [0.0, 0.01])
    np.testing.assert_allclose(s.gyr[0], [1, 2, 3])
    np.testing.assert_allclose(s.extra["barometer_hpa"], [1013, 1013])
    assert s.mag is None


def test_errors_name_the_column(tmp_path):
    p = tmp_path / "u.csv"
    p.write_text(
        "Time (s),Gyroscope X (furlong),Gyroscope Y (furlong),Gyroscope Z (furlong),"
        "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)\n0,1,2,3,0,0,1\n"
    )
    with pytest.raises(InputError) as err:
        read_any(p)
    assert "furlong" in err.value.message and "gyroscope" in err.value.where
    lines = FIXTURE.read_text().splitlines()
    lines[50] = lines[50].replace("0.", "O.", 1)
    p.write_text("\n".join(lines))
    with pytest.raises(InputError) as err:
        read_any(p)
    assert err.value.where == "line 51"


@needs_shared
def test_shared_xio_file():
    s = _one(SHARED / "formats" / "xio" / "sensor_data.csv")
    assert s.n_samples == 13514
    assert s.rate_hz == pytest.approx(99.2, abs=0.05)
    raw_max = 365.3  # deg/s, the file's largest |gyroscope| value, about 6.37 rad/s
    assert np.abs(s.gyr).max() == pytest.approx(np.radians(raw_max), rel=0.01)
    assert np.median(np.linalg.norm(s.acc, axis=1)) == pytest.approx(9.81, rel=0.01)
