"""``motionlab sensorcal`` and ``motionlab fuse --calibration`` on a recording with known errors."""

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from sensorcal_signals import measure, random_poses, trajectory

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.segments import corrected_acc
from motionlab.sensorcal import apply_calibration, load_calibration
from motionlab.session import SensorStream, Session, load_session, save_session

RNG = np.random.default_rng(42)
GYR_BIAS = np.radians([2.0, -1.0, 1.5])
ACC_GAIN = (np.eye(3) + np.tril(RNG.normal(0, 0.01, (3, 3)), -1)) @ np.diag(
    1 + RNG.normal(0, 0.01, 3)
)
ACC_BIAS = RNG.normal(0, 0.15, 3)
SOFT = np.eye(3) + (lambda a: (a + a.T) / 2)(RNG.normal(0, 0.05, (3, 3)))
HARD = np.array([15.0, -8.0, 5.0])


@pytest.fixture(scope="module")
def recording():
    """12 static poses (3 s each) then 60 s of tumbling, 100 Hz, with sensor errors."""
    t, q, w = trajectory(random_poses(12, seed=3), hold=3.0, move=1.5, tumble=60.0)
    sig = measure(
        q, w, seed=4, gyr_bias=GYR_BIAS, acc_gain=ACC_GAIN, acc_bias=ACC_BIAS,
        mag_gain=SOFT, mag_offset=HARD,
    )  # fmt: skip
    return t, q, sig


@pytest.fixture
def session_file(tmp_path, recording):
    t, _, sig = recording
    ses = Session()
    ses.sensors["shank_r"] = SensorStream(label="shank_r", time=t, serial="SIM 001", **sig)
    ses.sensors["baro"] = SensorStream(label="baro", time=t[:10])
    path = tmp_path / "session.h5"
    save_session(ses, path)
    return path


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_auto_calibration_recovers_every_channel(session_file, tmp_path):
    caldir = tmp_path / "calibration"
    out = run("sensorcal", session_file, "--sensor", "shank_r", "-o", caldir)
    assert out.exit_code == 0, out.output
    assert "coverage" in out.output and "multipos" in out.output and "deg/s" in out.output
    cal = load_calibration(caldir / "SIM_001.yaml")
    assert cal.serial == "SIM 001" and cal.source == "session.h5#shank_r"
    gyr, acc, mag = (cal.channels[ch] for ch in ("gyr", "acc", "mag"))
    assert np.abs(gyr.offset - GYR_BIAS).max() < np.radians(0.01)
    assert acc.method == "multiposition-norm"
    assert np.abs(acc.offset - ACC_BIAS).max() < 5e-3
    assert np.abs(acc.matrix @ ACC_GAIN - np.eye(3)).max() < 1e-3
    assert np.abs(mag.offset - HARD).max() < 0.1
    assert np.allclose(
        np.linalg.svd(mag.matrix @ SOFT, compute_uv=False), mag.quality["norm"] / 50.0, rtol=2e-3
    )
    assert mag.quality["coverage"] > 0.5
    # a second run must not silently replace it
    again = run("sensorcal", session_file, "--sensor", "shank_r", "--kind", "gyro", "-o", caldir)
    assert again.exit_code == 2 and "--force" in again.output
    forced = run(
        "sensorcal", session_file, "--sensor", "shank_r", "--kind", "gyro", "-o", caldir, "--force"
    )
    assert forced.exit_code == 0
    assert set(load_calibration(caldir / "SIM_001.yaml").channels) == {"gyr", "acc", "mag"}


def test_acc_ellipsoid_and_mag_with_a_known_field(session_file, tmp_path):
    args = ["--kind", "acc", "--kind", "mag", "--field-norm", "50", "-o", tmp_path / "cal"]
    out = run("sensorcal", session_file, "--sensor", "shank_r", *args)
    assert out.exit_code == 0, out.output
    cal = load_calibration(tmp_path / "cal" / "SIM_001.yaml")
    acc, mag = cal.channels["acc"], cal.channels["mag"]
    assert acc.method == "ellipsoid" and set(cal.channels) == {"acc", "mag"}
    assert np.abs(acc.offset - ACC_BIAS).max() < 0.01
    assert np.allclose(np.linalg.svd(acc.matrix @ ACC_GAIN, compute_uv=False), 1.0, atol=2e-3)
    assert mag.quality["norm"] == 50.0
    assert np.abs(mag.matrix - np.linalg.inv(SOFT)).max() < 2e-3  # symmetric soft iron: exact


def test_fuse_applies_the_calibration_by_serial(session_file, tmp_path, recording):
    caldir = tmp_path / "cal"
    assert run("sensorcal", session_file, "--sensor", "shank_r", "-o", caldir).exit_code == 0
    raw = tmp_path / "raw.h5"
    fused = run("fuse", session_file, "--filter", "madgwick", "--sensor", "shank_r", "-o", raw)
    assert fused.exit_code == 0, fused.output
    out = run(
        "fuse", session_file, "--filter", "madgwick", "--sensor", "shank_r", "--calibration", caldir
    )
    assert out.exit_code == 0, out.output
    assert "calibrated (gyr, acc, mag)" in out.output
    ses = load_session(session_file)
    entry = ses.results.fusion["shank_r"]
    assert entry.sensor_calibration.serial == "SIM 001"
    assert list(entry.sensor_calibration.channels) == ["gyr", "acc", "mag"]
    assert all(isinstance(c.method, str) for c in entry.sensor_calibration.channels.values())
    _, q_true, sig = recording
    assert np.array_equal(ses.sensors["shank_r"].gyr, sig["gyr"])  # the data stay as recorded
    # the segment calibration's accelerometer is the one the fusion saw (madgwick: no bias states)
    seen = apply_calibration(ses.sensors["shank_r"], load_calibration(next(caldir.iterdir())))
    assert np.abs(corrected_acc(ses, "shank_r") - seen.acc).max() < 1e-12
    assert np.abs(corrected_acc(ses, "shank_r") - sig["acc"]).max() > 0.05
    assert ses.provenance[-1]["parameters"]["calibration"] == str(caldir)

    def error_deg(q):  # orientation error over the tumble, heading offset removed
        tail = slice(-4000, None)
        d = rot.mul(q[tail], rot.conj(q_true[tail]))
        return np.degrees(rot.angle(rot.mul(rot.conj(rot.mean(d)), d))).mean()

    err_cal = error_deg(entry.quat)
    err_raw = error_deg(load_session(raw).results.fusion["shank_r"].quat)
    assert err_cal < 3.0 and err_cal < err_raw / 2


def test_allan_kind_on_a_static_recording(tmp_path):
    rng = np.random.default_rng(7)
    n, rate = 12_000, 100.0  # 2 min
    static = SensorStream(
        label="imu",
        time=np.arange(n) / rate,
        gyr=GYR_BIAS + rng.normal(0, 0.002, (n, 3)),
        acc=[0, 0, 9.81] + rng.normal(0, 0.01, (n, 3)),
        serial="S2",
    )
    ses = Session(sensors={"imu": static})
    save_session(ses, tmp_path / "still.h5")
    out = run(
        "sensorcal", tmp_path / "still.h5", "--kind", "allan", "--kind", "gyro", "-o",
        tmp_path / "cal",
    )  # fmt: skip
    assert out.exit_code == 0, out.output
    assert "deg/sqrt(h)" in out.output and "allan acc" in out.output
    data = yaml.safe_load((tmp_path / "cal" / "S2.yaml").read_text())
    white = np.array(data["noise"]["gyr"]["white_density"])
    assert np.allclose(white, 0.002 / np.sqrt(rate), rtol=0.05)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--sensor", "knee"], "no sensor knee"),
        (["--sensor", "shank_r", "--kind", "acc", "--kind", "multipos"], "choose one"),
        (["--sensor", "baro", "--kind", "gyro"], "has no gyr"),
        (["--sensor", "shank_r", "--kind", "allan"], "at rest"),
        (["--sensor", "shank_r", "--gravity", "-1"], "positive"),
    ],
)
def test_bad_requests_exit_2_with_one_line(session_file, tmp_path, args, message):
    out = run("sensorcal", session_file, *args, "-o", tmp_path / "cal")
    assert out.exit_code == 2 and message in out.output
    assert len(out.output.strip().splitlines()) == 1
    assert not (tmp_path / "cal").exists()


def test_vendor_file_without_serial_is_filed_by_label(tmp_path, data_dir):
    # 3 s of a real x-io recording lying still: a gyroscope bias, nothing else
    out = run("sensorcal", data_dir / "xio" / "sensor_data_excerpt.csv", "-o", tmp_path)
    assert out.exit_code == 0, out.output
    assert "mag       skipped" in out.output and "multipos  skipped" in out.output
    cal = load_calibration(tmp_path / "sensor_data_excerpt.yaml")
    assert set(cal.channels) == {"gyr"}
    assert np.abs(cal.channels["gyr"].offset).max() < np.radians(0.5)
    assert cal.channels["gyr"].quality["rest_s"] >= 2.5


def test_bad_files_exit_2(tmp_path, session_file):
    notafolder = tmp_path / "file.txt"
    notafolder.write_text("x")
    out = run("sensorcal", session_file, "-o", notafolder)
    assert out.exit_code == 2 and "folder" in out.output
    out = run("sensorcal", tmp_path / "missing.h5", "-o", tmp_path / "cal")
    assert out.exit_code == 2 and "no such file" in out.output
    # only movement: nothing can be calibrated
    ses = load_session(session_file)
    moving = ses.sensors["shank_r"]
    for ch in ("time", "gyr", "acc", "mag"):
        setattr(moving, ch, getattr(moving, ch)[-500:])
    save_session(ses, tmp_path / "moving.h5")
    out = run("sensorcal", tmp_path / "moving.h5", "--sensor", "shank_r", "-o", tmp_path / "cal")
    assert out.exit_code == 2 and "no calibration is possible" in out.output
    # NaN in the data
    ses = load_session(session_file)
    ses.sensors["shank_r"].gyr[500] = np.nan
    save_session(ses, tmp_path / "nan.h5")
    out = run(
        "sensorcal",
        tmp_path / "nan.h5",
        "--sensor",
        "shank_r",
        "--kind",
        "gyro",
        "-o",
        tmp_path / "c",
    )
    assert out.exit_code == 2 and "NaN" in out.output
