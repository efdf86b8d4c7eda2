"""Optional calibration steps recorded with sensors strapped any way round, and the task blocks
after optional steps that were recorded but not accepted.

The knee protocol simulated with every sensor at a random orientation and place on its segment
(``mounting="random"``): the straight-leg hip flexions are recorded, but their axes are not the
nominal placement's. The step finder used to refuse them (optional steps), so the shank's
flexion axis came from the seated knee flexion, turned by the tibia's screw-home rotation
(12-13° on the simulated knee: ab/adduction 4-5° SD off in the walk, the varus thrust read 2°
low, graded ``determined``); it now accepts them by their axes as the stand and the sitting
measured them. Steps recorded but not accepted still happen (a knee bent in the swing), and the
task finder used to take them, joined, for the walk (``bench/task_finding.py``: all 10 seeds,
the gait window 57-92 s for a true 95-147 s, the squat on the walk, no stride in the gait
block): the tests of that take the steps found less the hip flexions.
"""

import numpy as np
import pytest

from motionlab import stages
from motionlab.errors import InputError
from motionlab.protocol import load_protocol
from motionlab.segments import streams_of
from motionlab.segments.steps import blocks, calibration_stretches, find_steps, find_tasks, walking
from motionlab.simulate import simulate


@pytest.fixture(scope="module")
def knee():
    return load_protocol("knee")


@pytest.fixture(scope="module")
def recording(knee):
    """A knee session (the duration ``bench/task_finding.py`` simulates), sensors at random,
    its streams and the steps found less the hip flexions (recorded, not accepted)."""
    session, truth = simulate(knee, 207.0, seed=0, preset="clean", rate_hz=50.0, mounting="random")
    streams = streams_of(session, knee)
    steps = dict(find_steps(streams, knee), hip_flexion_r=None, hip_flexion_l=None)
    return streams, truth, steps, session


def test_optional_steps_are_found_by_their_axes_as_measured(knee, recording):
    """The straight-leg hip flexions of sensors strapped any way round: found where they were
    recorded, by their axes against the stand's and the sitting's verticals in each sensor."""
    streams, truth, _, _ = recording
    steps = find_steps(streams, knee)
    for name in ("hip_flexion_r", "hip_flexion_l"):
        true = truth.step(name)
        assert steps[name] is not None, name
        assert min(_share(steps[name], (true["start_s"], true["end_s"]))) > 0.8, name


def _share(window, true) -> tuple[float, float]:
    """(share of the true span the window covers, share of the window that is the true span)."""
    inter = max(0.0, min(window[1], true[1]) - max(window[0], true[0]))
    return inter / (true[1] - true[0]), inter / (window[1] - window[0])


def test_optional_steps_not_accepted_are_not_taken_for_the_tasks(knee, recording):
    streams, truth, steps, _ = recording
    after = max(v[1] for v in steps.values() if v is not None)
    tasks = find_tasks(streams, knee, after_s=after, steps=steps)
    for task in knee.tasks:
        true = truth.step(task.name)
        cover, purity = _share(tasks[task.name], (true["start_s"], true["end_s"]))
        assert cover > 0.9 and purity > 0.9, (task.name, tasks[task.name], true)


def test_the_stretches_of_steps_not_found_follow_the_protocol_order(knee, recording):
    """Each hip flexion takes its own movement; with the right one found (as on seed 8 of the
    bench), only the left one's movement is left out of the tasks."""
    streams, truth, steps, _ = recording
    after = steps["knee_flexion_l"][1]
    usable = [b for b in blocks(streams) if b.start >= after]
    claimed = calibration_stretches(usable, knee, steps, streams)
    assert [s.name for s, _ in claimed] == ["hip_flexion_r", "hip_flexion_l"]
    for step, block in claimed:
        true = truth.step(step.name)
        assert min(_share((block.start, block.end), (true["start_s"], true["end_s"]))) > 0.8
    hip_r = truth.step("hip_flexion_r")
    found = dict(steps, hip_flexion_r=(hip_r["start_s"], hip_r["end_s"]))
    usable = [b for b in usable if b.start >= hip_r["end_s"]]
    assert [s.name for s, _ in calibration_stretches(usable, knee, found, streams)] == [
        "hip_flexion_l"
    ]


def test_a_walk_is_never_one_leg_moving(knee, recording):
    """Without the steps (the finder as it was), the two hip flexions are the movement where the
    order puts the walk: one line naming the task and what moved instead, not a walk window
    without a stride."""
    streams, _, steps, _ = recording
    with pytest.raises(InputError) as err:
        find_tasks(streams, knee, after_s=steps["knee_flexion_l"][1], suggest=False)
    msg = err.value.line()
    assert "task 'gait' (gait) not found" in msg
    assert "only the right leg moves" in msg and "only the left leg moves" in msg
    assert "time_range" in msg and "\n" not in msg


def test_the_walk_is_where_both_legs_move(recording):
    """The walk protocol on the same recording after the seated knee flexions: its one task
    shares every movement after them, and its window starts with the walk, not with the hip
    flexions (one leg moving) before it."""
    streams, truth, steps, _ = recording
    walk = load_protocol("walk")
    mine = {s: v for s, v in streams.items() if s in walk.segments}
    window = find_tasks(mine, walk, after_s=steps["knee_flexion_l"][1])["walk"]
    assert abs(window[0] - truth.step("gait")["start_s"]) < 1.0
    moves = [b for b in blocks(mine) if b.moving and b.end - b.start > 10.0]
    assert [walking(b) for b in moves] == [False, False, False, False, True, True, True]
    assert np.isclose(window[1], moves[-1].end)


def test_the_metrics_stage_finds_the_walk_and_its_strides(knee, recording):
    """Through the stages as ``motionlab run`` chains them: the gait block is the walk and the
    gait analysis keeps its strides (before: the hip flexions, 'no stride passed the checks')."""
    _, truth, _, session = recording
    stages.fuse(session)
    stages.calibrate(session, knee)
    stages.angles(session, knee)
    stages.metrics(session, knee)
    true = truth.step("gait")
    cover, purity = _share(
        session.results.metrics.spans()["gait"], (true["start_s"], true["end_s"])
    )
    assert cover > 0.9 and purity > 0.9
    assert session.results.gait.ok and session.results.gait.strides.kept.sum() > 40
