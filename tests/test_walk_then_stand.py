"""A recording that ends with its stand (walk or move the arms, stop, stand still, stop the
recording): the ``walk`` and ``arm`` protocols take the stand after the movement when none
comes before it."""

from __future__ import annotations

import numpy as np
import pytest
from test_short_walk import _rmse, _skin_one_clock, _streams

from motionlab.errors import InputError
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.segments.steps import task_window
from motionlab.simulate import simulate
from motionlab.timebase import take


def _without_the_first_stand(seed: int, cut_s: float = 9.5, protocol: str = "walk"):
    """A simulated stand-and-walk (45 s: stand 3-8 s, walk 11-42 s, standing still from about
    42 s; ``arm``: free arm movement in place of the walk) cut to start at ``cut_s``: a short
    rest, the movement, then the stand."""
    session, truth = simulate(load_protocol(protocol), 45.0, seed, _skin_one_clock(),
                              mounting="random", knee_model="anatomical")  # fmt: skip
    for label, stream in session.sensors.items():
        session.sensors[label] = take(stream, np.flatnonzero(stream.time >= cut_s))
    prepare_sensors(session)
    return session, truth


@pytest.mark.parametrize("seed", [0, 1])
def test_a_stand_after_the_walk_calibrates_it(seed):
    """Refused before ("the rest at 42.2-44.5 s has no walk after it"). Now the stand is found
    after the walk, the walk is the task, the knees' flexion is ``determined`` and the pelvis
    faces the way the last steps went. Measured here (one clock, low-passed as the metrics take
    it), seeds 0 / 1: knee flexion 1.2 / 1.4° (r), 1.2 / 1.0° (l), hip flexion 0.9 / 1.2° (r),
    0.8 / 0.6° (l); the same recordings with their stand before the walk in the table below
    (docs/kinematics.md, "A walk that ends with its stand")."""
    session, truth = _without_the_first_stand(seed)
    proto = load_protocol("walk")
    analyse(session, PipelineOptions(proto, progress=False, clock_sync=False))
    cal = session.results.calibration
    walk = truth.step("walk")
    assert cal.steps["standing"][0] > walk["end_s"]
    assert "forward direction is taken from the last steps of the walk" in " ".join(cal.warnings)
    for side in "rl":
        assert cal.grades[f"knee_{side}"].grades[0] == "determined"
        assert _rmse(session, truth, f"knee_{side}_flexion_deg") < 2.0
        assert _rmse(session, truth, f"hip_{side}_flexion_deg") < 2.0


def test_a_stand_after_free_arm_movement_calibrates_the_elbows():
    """The ``arm`` protocol likewise (the hands in the lap at the end would leave the elbows
    ``not determined``: ``arm_sides.pose_hanging``): the elbows are graded and measured as
    with the same recording's stand first. Measured (seed 1, one clock, 45 s): elbow flexion
    2.33 / 0.90° (right / left; 2.31 / 0.97° with the stand first), grades alike; with own
    clocks, 80 s, seeds 0-5: within -1.1 to +0.2° of the stand first."""
    arm = load_protocol("arm")
    runs = []
    for cut in (True, False):
        if cut:
            session, truth = _without_the_first_stand(1, protocol="arm")
        else:
            session, truth = simulate(arm, 45.0, 1, _skin_one_clock(), mounting="random",
                                      knee_model="anatomical")  # fmt: skip
            prepare_sensors(session)
        analyse(session, PipelineOptions(arm, progress=False, clock_sync=False))
        runs.append((session, truth))
    (cut, truth), (full, _) = runs
    assert cut.results.calibration.steps["standing"][0] > truth.step("free_movement")["end_s"]
    assert set(cut.results.metrics.blocks) == {"free_movement"}
    for side in "rl":
        name, col = f"elbow_{side}", f"elbow_{side}_flexion_deg"
        assert cut.results.calibration.grades[name] == full.results.calibration.grades[name]
        assert (
            _rmse(cut, truth, col, "free_movement") < _rmse(full, truth, col, "free_movement") + 0.3
        )


def test_the_tasks_lie_after_the_stand_or_before_one_that_ends_the_walk():
    """After the stand where the walk follows it; before it where nothing (or a shift under
    2 s) moves after it; after it where neither side moves (the tasks then refuse as before); a
    protocol with functional steps keeps its order."""
    walk = load_protocol("walk")
    stand = {"standing": (2.0, 5.0)}
    assert task_window(_streams([(6.0, 19.0)]), walk, stand) == (5.0, np.inf)
    end = {"standing": (15.0, 19.0)}
    assert task_window(_streams([(1.0, 14.0)]), walk, end) == (-np.inf, 15.0)
    assert task_window(_streams([(1.0, 14.0), (19.2, 19.8)]), walk, end) == (-np.inf, 15.0)
    assert task_window(_streams([]), walk, end) == (19.0, np.inf)
    knee = load_protocol("knee")
    steps = {s.name: None for s in knee.calibration} | {"standing": (15.0, 19.0)}
    assert task_window(_streams([(1.0, 14.0)]), knee, steps) == (19.0, np.inf)


def test_a_rest_with_no_walk_beside_it_is_still_no_stand():
    """A recording that is all rest but a short shift: refused in one line that names the
    rest and that no walk lies beside it."""
    session, _ = _without_the_first_stand(0, cut_s=40.0)
    with pytest.raises(InputError, match="no walk after or before it|too short|not found"):
        analyse(session, PipelineOptions(load_protocol("walk"), progress=False, clock_sync=False))


def test_the_run_says_where_it_found_the_stand(tmp_path):
    """``motionlab run`` on such a recording completes, and its screen says where the stand
    was found (after the walk) and which task it analysed (the walk before it)."""
    from click.testing import CliRunner

    from motionlab.cli import main
    from motionlab.session import save_session

    session, _ = _without_the_first_stand(0)
    save_session(session, tmp_path / "walk.h5")
    res = CliRunner().invoke(
        main, ["run", str(tmp_path / "walk.h5"), "--protocol", "walk", "--no-clock-sync",
               "-o", str(tmp_path / "out"), "--quiet"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "calibration: 5/5 segments ok (standing 42-44 s)" in res.output, res.output
    assert "tasks: walk 11-42 s" in res.output, res.output
    assert "taken from the last steps of the walk" in res.output
