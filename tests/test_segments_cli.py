"""``motionlab calibrate`` and ``motionlab angles`` on a synthetic knee session."""

import numpy as np
import pandas as pd
from click.testing import CliRunner
from test_segments import knee_session

from motionlab.cli import main
from motionlab.results import FusionEntry
from motionlab.session import load_session, save_session


def test_calibrate_then_angles_cli(tmp_path):
    session, _, _, truth, _, t = knee_session(seed=3)
    for s in session.sensors.values():
        session.results.fusion[s.label] = FusionEntry("vendor", s.quat)
    path = tmp_path / "s.h5"
    save_session(session, path)
    runner = CliRunner()
    res = runner.invoke(main, ["calibrate", str(path), "--protocol", "knee"])
    assert res.exit_code == 0, res.output
    assert "knee_flexion_r" in res.output and "shank_r" in res.output
    cal = load_session(path).results.calibration
    assert cal.segments["shank_l"].method == "procrustes"
    again = runner.invoke(main, ["calibrate", str(path), "--protocol", "knee"])
    assert again.exit_code == 2 and "--force" in again.output
    csv = tmp_path / "angles.csv"
    res = runner.invoke(main, ["angles", str(path), "--csv", str(csv)])
    assert res.exit_code == 0, res.output
    df = pd.read_csv(csv)
    assert list(df.columns[:4]) == [
        "time_s",
        "knee_r_flexion_deg",
        "knee_r_adduction_deg",
        "knee_r_rotation_deg",
    ]
    task = df["time_s"].to_numpy() > 39
    err = df.loc[task, "knee_l_flexion_deg"] - np.degrees(truth["l"][t > 39, 0])
    assert np.sqrt(np.mean(err**2)) < 1.0
    assert "knee_l_rotation_deg" in load_session(path).results.angles.data


def test_angles_needs_calibration(tmp_path):
    session, *_ = knee_session()
    path = tmp_path / "s.h5"
    save_session(session, path)
    res = CliRunner().invoke(main, ["angles", str(path)])
    assert res.exit_code == 2 and "motionlab calibrate" in res.output


def test_a_walk_without_a_stand_says_what_is_missing_in_one_line(tmp_path):
    from motionlab.protocol import load_protocol
    from motionlab.simulate import simulate

    session, _ = simulate(load_protocol("walk"), 20.0, 0, "clean", calibration=False, rest_s=0.5)
    path = tmp_path / "walk.h5"
    save_session(session, path)
    res = CliRunner().invoke(main, ["calibrate", str(path), "--protocol", "walk"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1
    assert "calibration step 'standing' (static) not found" in lines[0]
    assert "the recording holds movement" in lines[0]


def test_sensors_strapped_any_way_round_calibrate_without_a_placement_warning(tmp_path):
    """The walk protocol's sensors go 'anywhere, any orientation' (``any_orientation``): random
    mountings calibrate with no 'points up … the protocol says' warning (one per sensor
    before), and ``run`` says what ``calibrate`` says."""
    from motionlab.protocol import load_protocol
    from motionlab.simulate import simulate

    session, _ = simulate(load_protocol("walk"), 30.0, 1, "clean", mounting="random")
    path = tmp_path / "walk.h5"
    save_session(session, path)
    assert CliRunner().invoke(main, ["fuse", str(path)]).exit_code == 0
    res = CliRunner().invoke(main, ["calibrate", str(path), "--protocol", "walk"])
    assert res.exit_code == 0, res.output
    warnings = [x for x in res.output.splitlines() if x.startswith("warning:")]
    assert not any("points up" in w for w in warnings), warnings
    # flexion from the walk's principal axes; the other planes carry up to sin 5° of it
    assert "knee_r       angles: determined, not determined, not determined" in res.output
    # run shows the same warnings while it reports its progress (the stage path it shares)
    res = CliRunner().invoke(
        main, ["run", str(path), "--protocol", "walk", "-o", str(tmp_path / "out")]
    )
    assert res.exit_code == 0, res.output
    assert [x for x in res.output.splitlines() if x.startswith("warning:")] == warnings
