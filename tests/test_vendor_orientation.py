"""``--orientation vendor``: the orientation the sensors carry drives the analysis."""

import numpy as np
from click.testing import CliRunner

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.protocol import load_protocol
from motionlab.session import load_session, save_session
from motionlab.simulate import simulate


def _walk_with_vendor_orientations(tmp_path, keep_raw: bool):
    session, truth = simulate(load_protocol("walk"), 40.0, 4, "clean", mounting="random")
    for label, s in list(session.sensors.items()):
        q = rot.resample(truth.time, truth.sensors[label]["orientation"], s.time)
        if keep_raw:
            s.quat = q
        else:
            session.sensors[label] = type(s)(label=label, time=s.time, quat=q,
                                             segment=s.segment, side=s.side)  # fmt: skip
    path = tmp_path / "walk.h5"
    save_session(session, path)
    return path, truth


def test_run_uses_the_vendor_orientation_when_asked(tmp_path):
    path, truth = _walk_with_vendor_orientations(tmp_path, keep_raw=True)
    out = tmp_path / "out"
    res = CliRunner().invoke(
        main,
        ["run", "--protocol", "walk", str(path), "-o", str(out), "--orientation", "vendor",
         "--no-clock-sync", "--quiet"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    ses = load_session(out / "session.h5")
    assert {e.name for e in ses.results.fusion.values()} == {"vendor"}
    for label, s in ses.sensors.items():
        np.testing.assert_array_equal(ses.results.fusion[label].quat, s.quat)
    angles = ses.results.angles.columns()
    col = "knee_l_flexion_deg"
    ref = np.interp(angles["time_s"], truth.time, truth.joint_angles[col])
    walking = ref > 5.0
    assert np.sqrt(np.mean((angles[col] - ref)[walking] ** 2)) < 2.0


def test_fuse_keeps_the_vendor_orientation_of_sensors_without_raw_signals(tmp_path):
    path, _ = _walk_with_vendor_orientations(tmp_path, keep_raw=False)
    res = CliRunner().invoke(main, ["fuse", str(path), "--orientation", "vendor"])
    assert res.exit_code == 0, res.output
    assert "vendor orientation kept" in res.output
    plain = CliRunner().invoke(main, ["fuse", str(path), "--force"])
    assert plain.exit_code == 2  # nothing to fuse without raw signals
