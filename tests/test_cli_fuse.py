"""``motionlab fuse``: results stored per sensor, atomic write-back, errors as one line."""

import numpy as np
import pytest
from click.testing import CliRunner
from fusion_signals import constant_rotation

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.session import SensorStream, Session, load_session, save_session


@pytest.fixture
def session_file(tmp_path):
    ses = Session()
    for i, label in enumerate(("shank_r", "thigh_r")):
        sig = constant_rotation(seconds=10.0, seed=i)
        t = np.arange(len(sig["gyr"])) / sig["rate"]
        ses.sensors[label] = SensorStream(
            label=label, time=t, acc=sig["acc"], gyr=sig["gyr"], mag=sig["mag"]
        )
        ses.sensors[label].attrs["truth"] = sig["quat"].tolist()
    ses.sensors["baro"] = SensorStream(label="baro", time=np.arange(10) / 10.0)
    path = tmp_path / "session.h5"
    save_session(ses, path)
    return path


def test_fuse_stores_a_result_per_sensor(session_file):
    args = ["fuse", str(session_file), "--filter", "madgwick", "--param", "beta=0.2"]
    out = CliRunner().invoke(main, [*args, "--magnetometer"])  # 9-D: the truth's heading
    assert out.exit_code == 0, out.output
    ses = load_session(session_file)
    fusion = ses.results.fusion
    assert set(fusion) == {"shank_r", "thigh_r"}
    res = fusion["shank_r"]
    assert res.name == "madgwick" and res.params["beta"] == 0.2
    truth = np.array(ses.sensors["shank_r"].attrs["truth"])
    assert np.degrees(rot.angle_between(res.quat[-300:], truth[-300:])).max() < 3.0
    assert res.rest.dtype == bool and res.mag_disturbed.shape == (1000,)
    assert ses.provenance[-1]["parameters"]["filter"] == "madgwick"
    assert "skipped" in out.output


def test_existing_result_needs_force_and_output_file(session_file, tmp_path):
    runner = CliRunner()
    args = ["fuse", str(session_file), "--filter", "mahony", "--sensor", "thigh_r"]
    assert runner.invoke(main, args).exit_code == 0
    again = runner.invoke(main, args)
    assert again.exit_code == 2 and "--force" in again.output
    assert runner.invoke(main, [*args, "--force"]).exit_code == 0
    target = tmp_path / "out.h5"
    assert runner.invoke(main, [*args, "--force", "-o", str(target)]).exit_code == 0
    assert load_session(target).results.fusion["thigh_r"].gyro_bias is not None
    exists = runner.invoke(
        main, ["fuse", str(session_file), "--sensor", "shank_r", "-o", str(target)]
    )
    assert exists.exit_code == 2 and "output exists" in exists.output


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--filter", "nope"], "unknown estimator"),
        (["--filter", "madgwick", "--param", "beta"], "key=value"),
        (["--filter", "madgwick", "--param", "gamma=1"], "no parameter gamma"),
        (["--filter", "madgwick", "--param", "beta=fast"], "not a float"),
        (["--sensor", "ankle"], "no sensor ankle"),
        (["--sensor", "baro"], "no gyroscope"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(session_file, extra, message):
    before = session_file.read_bytes()
    out = CliRunner().invoke(main, ["fuse", str(session_file), *extra])
    assert out.exit_code == 2
    assert message in out.output and "Traceback" not in out.output
    assert session_file.read_bytes() == before


def test_list_prints_every_estimator():
    out = CliRunner().invoke(main, ["fuse", "--list"])
    assert out.exit_code == 0
    for name in ("madgwick", "mahony", "liu_gn", "adaptive_cf"):
        assert f"{name}:" in out.output
    assert "beta = 0.1 rad/s" in out.output


@pytest.mark.parametrize("extra", [[], ["--no-magnetometer"]])
def test_fuses_6d_by_default_as_run_does(session_file, extra):
    out = CliRunner().invoke(main, ["fuse", str(session_file), *extra])
    assert out.exit_code == 0, out.output
    assert "6-D" in out.output
    assert "not been clock-synchronised: run 'motionlab sync" in out.output
    ses = load_session(session_file)
    assert all(e.magnetometer is False for e in ses.results.fusion.values())
    assert ses.provenance[-1]["parameters"]["magnetometer"] is False


def test_run_unknown_filter_is_refused_before_work(tmp_path, session_file):
    out = CliRunner().invoke(
        main, ["run", "--protocol", "knee", str(session_file), "--filter", "nope", "-o",
               str(tmp_path / "out")],
    )  # fmt: skip
    assert out.exit_code == 2 and "unknown estimator 'nope'" in out.output
    assert not (tmp_path / "out").exists()
