"""The gyroscope's unit against the accelerometer's tilt (``qc.gyr_scale``): a slowly moving
gyroscope in °/s read as rad/s stays under the 35 rad/s check, and is refused by ``motionlab
ingest`` because its rotation does not match how the accelerometer sees gravity turn."""

import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import SHARED, generic_reader, needs_shared

from motionlab import qc
from motionlab.cli import main
from motionlab.simulate import simulate

DEG = math.pi / 180


@pytest.fixture(scope="module")
def seated():
    """A seated trunk session at 50 Hz (``lumbar_seated``: sitting still, flexion, lateral
    bending and rotation, everyday movement): ``label -> (t, acc m/s², gyr rad/s)``."""
    session, _ = simulate("lumbar_seated", duration=40.0, seed=0, rate_hz=50.0)
    return {k: (s.time, s.acc, s.gyr) for k, s in session.sensors.items()}


def write_recording(folder, name, t, acc, gyr, gyr_unit):
    """``name.csv`` (columns t, ax..az m/s², gx..gz as given) and a map that reads the
    gyroscope in ``gyr_unit``; returns the ingest's arguments."""
    csv = folder / f"{name}.csv"
    np.savetxt(csv, np.column_stack([t, acc, gyr]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz")  # fmt: skip
    reader = generic_reader()
    reader["gyr"]["unit"] = gyr_unit
    reader["label"] = name
    (folder / "map.yaml").write_text(yaml.safe_dump({"reader": reader}))
    return [str(csv), "--map", str(folder / "map.yaml"), "-o", str(folder / "s.h5")]


def ingest(args):
    return CliRunner().invoke(main, ["ingest", *args])


def assert_refused(result, folder, *words):
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert not (folder / "s.h5").exists()


def test_slow_deg_s_read_as_rad_s_is_refused(tmp_path, seated):
    t, acc, gyr = seated["pelvis"]
    deg = np.degrees(gyr)
    assert np.linalg.norm(deg, axis=1).max() < qc.GYR_MAX_PLAUSIBLE  # the old check is silent
    result = ingest(write_recording(tmp_path, "pelvis", t, acc, deg, "rad/s"))
    assert_refused(result, tmp_path, "error: pelvis.csv sensor pelvis: the gyroscope (read as "
                   "rad/s) turns", "is it in °/s? — check the export's gyroscope unit",
                   "gyr: {unit: deg/s}")  # fmt: skip


def test_slow_deg_s_read_as_deg_s_passes(tmp_path, seated):
    t, acc, gyr = seated["pelvis"]
    result = ingest(write_recording(tmp_path, "pelvis", t, acc, np.degrees(gyr), "deg/s"))
    assert result.exit_code == 0, result.output
    assert "gyroscope" not in result.stderr


@pytest.mark.parametrize("label", ["pelvis", "thorax"])
def test_rad_s_passes_with_its_scale_near_one(tmp_path, seated, label):
    t, acc, gyr = seated[label]
    result = ingest(write_recording(tmp_path, label, t, acc, gyr, "rad/s"))
    assert result.exit_code == 0, result.output
    assert "gyroscope" not in result.stderr
    found = qc.gyr_scale(t, acc, gyr)
    assert 0.9 < found["scale"] < 1.1 and 0.9 < found["axes_free_scale"] < 1.1
    misread = qc.gyr_scale(t, acc, gyr / DEG)  # the scale that explains the tilt: π/180
    assert 0.9 * DEG < misread["scale"] < 1.1 * DEG and misread["deg_s_fit"] > 1000


def test_rad_s_read_as_deg_s_is_refused(tmp_path, seated):
    t, acc, gyr = seated["thorax"]
    result = ingest(write_recording(tmp_path, "thorax", t, acc, gyr, "deg/s"))
    assert_refused(result, tmp_path, "(read as deg/s) turns", "is it in rad/s?",
                   "gyr: {unit: rad/s}")  # fmt: skip


def test_a_gyroscope_turns_at_least_as_far_as_its_sensor_tilts():
    """``turn_ratio``: a simulated knee session's thigh turns about as far as it tilts (more:
    it also turns about the vertical), and 57 times less with a rad/s gyroscope read as °/s,
    which is then refused whatever the fit says."""
    session, _ = simulate("knee", duration=120.0, seed=1, rate_hz=50.0)
    s = session.sensors["thigh_r"]
    as_read = qc.gyr_scale(s.time, s.acc, s.gyr)
    assert as_read["tilt_deg"] >= qc.SCALE_TURN_TILT_DEG and 1.0 < as_read["turn_ratio"] < 1.5
    misread = qc.gyr_scale(s.time, s.acc, s.gyr * DEG)
    assert misread["turn_ratio"] == pytest.approx(as_read["turn_ratio"] * DEG, rel=1e-6)
    misread["rad_s_fit"] = 1.0  # as a moving limb's linear acceleration leaves it
    assert qc.gyr_unit_finding(misread) == "rad_s"


@needs_shared
def test_real_knee_recording_with_its_gyroscope_57_times_too_small_is_refused(tmp_path):
    """The hostile-input audit: a DOT thigh recording whose gyroscope was written in rad/s under
    its °/s header went through the ingest with no flag (the fit: 3.7 times better in rad/s,
    under the 4 of a doubt)."""
    from motionlab.io import read_any

    s = read_any(SHARED / "datasets/human/imt_dot/knee_tracking1/femur.csv").sensors[0]
    t, acc = s.time - s.time[0], s.acc
    result = ingest(write_recording(tmp_path, "femur", t, acc, s.gyr, "deg/s"))
    assert_refused(result, tmp_path, "turns", "× less than the tilt")
    result = ingest(write_recording(tmp_path, "femur", t, acc, np.degrees(s.gyr), "deg/s"))
    assert result.exit_code == 0 and "gyroscope" not in result.stderr, result.output


def test_accelerometer_axes_in_another_order_are_not_a_unit(seated):
    """The axes-free scale (a free 3×3 map) does not move when the accelerometer's columns are
    permuted, and no unit is blamed; the same with the gyroscope in °/s is still °/s."""
    t, acc, gyr = seated["pelvis"]
    plain = qc.gyr_scale(t, acc, gyr)
    for swapped in (acc[:, [1, 2, 0]], acc[:, [1, 0, 2]], acc * [-1, 1, 1]):
        found = qc.gyr_scale(t, swapped, gyr)
        assert found["axes_free_scale"] == pytest.approx(plain["axes_free_scale"], rel=1e-6)
        assert found["scale"] < 0.5 and qc.gyr_unit_finding(found) == ""
        assert qc.gyr_unit_finding(qc.gyr_scale(t, swapped, gyr / DEG)) == "deg_s"


def test_still_sensor_with_a_drifting_bias_is_not_deg_s():
    """A still sensor, bias drifting by 1°/s over 5 minutes: π/180 explains the (absent) tilt
    about 4.5 times better than rad/s, because it claims less, but rad/s misses it by a tenth
    of a degree: no finding. Without the miss guard this would be a doubt."""
    rng = np.random.default_rng(1)
    t = np.arange(30000) / 100.0
    acc = np.array([0.3, -0.2, 9.8]) + rng.normal(0, 0.02, (len(t), 3))
    bias = np.radians([0.5, -0.3, 0.2]) + np.outer(t / t[-1], np.radians([1.0, -1.0, 1.0]))
    gyr = bias + rng.normal(0, 0.002, (len(t), 3))
    found = qc.gyr_scale(t, acc, gyr)
    assert found["deg_s_fit"] > qc.SCALE_DOUBT and found["miss_deg"]["as_read"] < 0.5
    assert qc.gyr_unit_finding(found) == ""


def test_too_short_or_damaged_gives_no_verdict():
    t = np.arange(6) / 50.0
    assert qc.gyr_scale(t, np.tile([0, 0, 9.81], (6, 1)), np.zeros((6, 3))) is None
    t = np.arange(500) / 50.0
    acc = np.tile([0, 0, 9.81], (500, 1))
    assert qc.gyr_scale(t, acc, np.full((500, 3), np.nan)) is None
    assert qc.gyr_unit_finding(None) == ""


TRUNK_CHAIR = "datasets/trunk/Aag/trunkmovement_ls/imu/x-IMU3 93E8-5410-EC7B-D38B (UDP)"
QMT = "datasets/human/qmt_full_body/full_body_example_data.mat"


def real_excerpts() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Slow real stretches, gyroscope in °/s: a person's lower back as they sit down (qmt full
    body, 100 Hz, 13-21 s from its start, under 14 °/s) and the x-IMU3 on the wheelchair of a trunk
    trial (50 Hz, 8 s, under 27 °/s): ``name -> (t s, acc m/s², gyr °/s)``."""
    import scipy.io as sio

    from motionlab.io import read_any

    m = sio.loadmat(SHARED / QMT, squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float) - m["t"][0]
    keep = (t >= 13.0) & (t < 21.0)
    back = m["lower_back"]
    out = {"lower_back": (t[keep], np.asarray(back.acc)[keep], np.degrees(back.gyr[keep]))}
    s = read_any(SHARED / TRUNK_CHAIR).sensors[0]
    keep = (s.time >= 3686.0) & (s.time < 3694.0)
    out["wheelchair"] = (s.time[keep], s.acc[keep], np.degrees(s.gyr[keep]))
    return out


@needs_shared
def test_real_slow_excerpts_deg_s_read_as_rad_s_are_refused(tmp_path):
    for name, (t, acc, deg) in real_excerpts().items():
        assert np.linalg.norm(deg, axis=1).max() < qc.GYR_MAX_PLAUSIBLE
        folder = tmp_path / name
        folder.mkdir()
        assert_refused(ingest(write_recording(folder, name, t, acc, deg, "rad/s")), folder,
                       f"sensor {name}", "is it in °/s?")  # fmt: skip
        result = ingest(write_recording(folder, name, t, acc, deg, "deg/s"))
        assert result.exit_code == 0 and "gyroscope" not in result.stderr, result.output


def found(deg_s_fit=1.0, rad_s_fit=1.0, free=1.0, miss=20.0):
    """A hand-made ``qc["gyr_scale"]``: the fits, the axes-free scale, the miss as read (°)."""
    return {"scale": free, "axes_free_scale": free, "deg_s_fit": deg_s_fit,
            "rad_s_fit": rad_s_fit, "tilt_deg": 100.0, "windows": 50,
            "miss_deg": {"as_read": miss, "deg_s": miss / math.sqrt(deg_s_fit),
                         "rad_s": miss / math.sqrt(rad_s_fit), "none": miss}}  # fmt: skip


@pytest.mark.parametrize(
    "kwargs, finding",
    [
        ({"deg_s_fit": 12.0, "free": 0.02}, "deg_s"),
        ({"deg_s_fit": 6.0, "free": 0.02}, "deg_s?"),
        ({"deg_s_fit": 3.9, "free": 0.02}, ""),  # under 4: no doubt
        ({"deg_s_fit": 12.0, "free": 0.5}, "axes?"),  # fits on the same axes only
        ({"deg_s_fit": 12.0, "free": 0.02, "miss": 4.0}, ""),  # misses by < 5°: no evidence
        ({"deg_s_fit": 0.01, "rad_s_fit": 12.0, "free": 60.0, "miss": 4.0}, "rad_s"),
        ({"deg_s_fit": 0.01, "rad_s_fit": 12.0, "free": 3.0}, "axes?"),
        ({"turn": 0.02}, "rad_s"),  # turned 50 times less than it tilted, whatever the fit
        ({"turn": 0.02, "tilt": 60.0}, ""),  # too little tilt to tell
        ({"turn": 0.3}, ""),
    ],
)
def test_verdict_thresholds(kwargs, finding):
    f = found(**{k: v for k, v in kwargs.items() if k not in ("turn", "tilt")})
    f["turn_ratio"], f["tilt_deg"] = kwargs.get("turn", 1.2), kwargs.get("tilt", 100.0)
    assert qc.gyr_unit_finding(f) == finding


def test_doubt_is_one_warning_line():
    from motionlab.session import SensorStream

    s = SensorStream(label="x", time=np.arange(3.0), source_units={"gyr": "rad/s"})
    s.qc = {"flags": {}, "gyr_scale": found(deg_s_fit=6.0, free=0.02)}
    (line,) = qc.doubts(s)
    assert line.startswith("the gyroscope (read as rad/s) turns 50× more than the tilt")
    assert "by 20° per 0.5 s (RMS), by 8.2° in °/s: is it in °/s? — check the export's" in line
    s.qc["gyr_scale"] = found(deg_s_fit=12.0, free=0.5)
    assert "its unit, or axes that are not the accelerometer's?" in qc.doubts(s)[0]


@pytest.mark.parametrize(("scale", "unit"), [(1 / DEG, "deg/s"), (DEG, "rad/s")])
def test_a_gyroscope_57_times_off_its_own_unit_is_not_asked_if_it_is_in_that_unit(
    tmp_path, seated, scale, unit
):
    """Degrees per second read as °/s that still turn 57× too far (converted twice) were told
    '(a gyroscope in °/s read as °/s turns 57.3×) ... is it in °/s?', which they were."""
    t, acc, gyr = seated["thorax"]
    gyr = gyr * scale * (1 / DEG if unit == "deg/s" else 1.0)
    result = ingest(write_recording(tmp_path, "thorax", t, acc, gyr, unit))
    assert_refused(result, tmp_path, f"(read as {unit}) turns", "57.3× is the step between "
                   "rad/s and °/s", "converted between °/s and rad/s twice, or not at all? — "
                   f"check the gyroscope's values against its unit ({unit})")  # fmt: skip
    assert "is it in" not in result.stderr
