"""Rest/movement blocks, calibration steps and task blocks with short rests and skipped steps.

Hand-made gyroscope signals test the hysteresis and the rest lengths; simulated knee sessions
(the simulator's default rests, 2 s rests, and a session without the optional hip flexions)
test the steps and tasks against the simulator's truth.
"""

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.protocol import load_protocol
from motionlab.segments import streams_of
from motionlab.segments.steps import blocks, find_steps, find_tasks
from motionlab.simulate import simulate

RATE = 100.0


def movement(t, t0, reps, period, pause, peak, ramp=0.3):
    """Rate (rad/s) of ``reps`` repetitions of ``period`` s (easing in and out) with ``pause`` s
    between them; the whole movement starts and stops within ``ramp`` s. Returns the rate and
    the movement's end (s)."""
    out = np.zeros(len(t))
    for k in range(reps):
        x = np.clip((t - t0 - k * (period + pause)) / period, 0.0, 1.0)
        out += np.sin(np.pi * x) ** 2
    end = t0 + reps * period + (reps - 1) * pause
    edge = np.clip(np.minimum(t - t0, end - t) / ramp, 0.0, 1.0)
    return peak * np.maximum(out, 0.3) * edge, end


def test_two_second_rests_split_and_pauses_between_repetitions_do_not():
    """Three movements of four repetitions (0.8 s pauses between them, where the rate eases to
    0.3 of its peak or below, then stops), 2 s apart; one sensor has an uncalibrated 0.2 rad/s
    bias (11°/s), both sensor noise."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 60, 1 / RATE)
    truth, rate, t0 = [], np.zeros(len(t)), 5.0
    for _ in range(3):
        r, end = movement(t, t0, 4, 2.0, 0.8, 1.2)
        rate += r
        truth.append((t0, end))
        t0 = end + 2.0
    axis = np.array([0.0, 0.6, 0.8])
    streams = {}
    for seg, bias in (("thigh", [0.12, -0.16, 0.0]), ("shank", [0.0, 0.0, 0.0])):
        gyr = rate[:, None] * axis + np.asarray(bias) + rng.normal(0, 0.01, (len(t), 3))
        acc = np.tile([0.0, 9.81, 0.0], (len(t), 1)) + rng.normal(0, 0.05, (len(t), 3))
        streams[seg] = (t, acc, gyr)
    found = blocks(streams)
    moving = [b for b in found if b.moving]
    assert len(moving) == 3
    for b, (a, e) in zip(moving, truth, strict=True):
        assert abs(b.start - a) < 0.3 and abs(b.end - e) < 0.3
    assert all(b.rate["thigh"] < 0.03 for b in found if not b.moving)  # the bias is no movement


def test_a_short_stand_before_a_long_walk_is_a_rest():
    """A 5-s stand, then 10 minutes of walking whose quietest moments still turn at 0.25 rad/s
    (a leg never stops in a stride): the gyroscope bias comes from the quietest seconds, the
    stand's, not from the quietest tenth of the recording, which is walking (issue 23: the
    stand was not found)."""
    rng = np.random.default_rng(1)
    t = np.arange(0, 610, 1 / 50.0)
    walking = t >= 8.0
    stride = 2.0 * np.pi * t / 1.1
    rate = np.where(walking, 0.25 + 2.0 * np.sin(stride / 2.0) ** 2, 0.0)
    gyr = rate[:, None] * np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.01, (len(t), 3))
    acc = np.tile([0.0, 9.81, 0.0], (len(t), 1)) + rng.normal(0, 0.05, (len(t), 3))
    found = blocks({"thigh": (t, acc, gyr)})
    assert not found[0].moving and found[0].end > 6.5
    assert found[1].moving and abs(found[1].start - 8.0) < 0.5


@pytest.fixture(scope="module")
def knee():
    return load_protocol("knee")


def test_default_rests_knee_session_steps_and_tasks(knee):
    """``motionlab simulate --protocol knee --duration 150`` (3 s rests): every step and task."""
    session, truth = simulate(knee, 150.0, seed=0, rate_hz=50.0)
    streams = streams_of(session, knee)
    steps = find_steps(streams, knee)
    for step in truth.steps:  # a change of pose (2 s) may come right before a block
        found = (
            steps.get(step["name"])
            or find_tasks(streams, knee, steps["hip_flexion_l"][1])[step["name"]]
        )
        if step["kind"] != "static":
            assert -2.5 < found[0] - step["start_s"] < 0.5 and abs(found[1] - step["end_s"]) < 0.5


def test_two_second_rests_in_a_simulated_session(knee):
    session, truth = simulate(knee, 150.0, seed=1, rate_hz=50.0, rest_s=2.0)
    streams = streams_of(session, knee)
    steps = find_steps(streams, knee)
    tasks = find_tasks(streams, knee, after_s=steps["hip_flexion_l"][1])
    for step in truth.steps:
        found = steps.get(step["name"]) or tasks[step["name"]]
        if step["kind"] != "static":
            assert -2.5 < found[0] - step["start_s"] < 0.5 and abs(found[1] - step["end_s"]) < 0.5


def test_optional_steps_not_recorded_are_not_matched(knee, tmp_path):
    """Without the hip flexions in the recording, the gait (both legs moving, the knee flexing)
    must not be taken for them, and the tasks keep their blocks."""
    text = knee.path.read_text()
    cut = text[text.index("  - name: hip_flexion_r") : text.index("joints:")]
    path = tmp_path / "knee_no_hip.yaml"
    path.write_text(text.replace(cut, ""))
    session, truth = simulate(load_protocol(path), 130.0, seed=2, rate_hz=50.0)
    streams = streams_of(session, knee)
    steps = find_steps(streams, knee)
    assert steps["hip_flexion_r"] is None and steps["hip_flexion_l"] is None
    tasks = find_tasks(streams, knee, after_s=steps["knee_flexion_l"][1])
    for name, (_, b) in tasks.items():
        assert abs(b - truth.step(name)["end_s"]) < 0.5


def _stand_then_walk(up_axis: int):
    """10 s still (each sensor's ``up_axis`` up), then 30 s of movement of every segment."""
    t = np.arange(0, 40, 1 / RATE)
    rate, _ = movement(t, 10.0, 20, 1.2, 0.1, 2.0)
    up = np.zeros(3)
    up[up_axis] = 9.81
    streams = {}
    for k, seg in enumerate(("pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l")):
        gyr = rate[:, None] * np.roll([0.0, 0.0, 1.0], k % 2)
        streams[seg] = (t, np.tile(up, (len(t), 1)), gyr)
    return streams


def test_all_missing_steps_named_at_once_with_what_the_recording_holds(knee):
    with pytest.raises(InputError) as err:
        find_steps(_stand_then_walk(up_axis=1), knee)
    msg = err.value.line()
    # (the walk may pass for the right knee's flexion: a required step is not checked for other
    # segments keeping still, as a trunk flexion carries the arms)
    for step in ("'sitting' (static)", "'knee_flexion_l' (functional)"):
        assert step in msg
    assert "'standing'" not in msg  # found
    assert "rest 0.0-" in msg and "movement 10.0-" in msg
    assert "pointing up in the first still moment" in msg and "pelvis +y, thigh_r +y" in msg
    assert "'walk'" in msg  # the shipped protocol that fits a stand and a walk


def test_too_few_task_blocks_name_the_shipped_protocol_that_fits(knee):
    """A stand and a walk run with the knee protocol whose steps were found (here: given as
    its first second) but whose three tasks are not there: the line names 'walk', which fits
    (its stand and its one task), as a missing step's line does."""
    with pytest.raises(InputError) as err:
        find_tasks(_stand_then_walk(up_axis=1), knee, after_s=1.0)
    msg = err.value.line()
    assert "found 1 movement block(s) after the calibration for 3 task(s)" in msg
    assert "the shipped protocol 'walk' fits this recording" in msg
    with pytest.raises(InputError) as err:
        find_tasks(_stand_then_walk(up_axis=1), knee, after_s=1.0, suggest=False)
    assert "fits this recording" not in err.value.line()


def test_a_still_pose_alone_is_named_as_such():
    """OpenSense keeps its calibration pose (a few seconds still) apart from the movement: such
    a recording finds its stand but no task, and the line says that the movement is missing."""
    t = np.arange(0, 4, 1 / RATE)
    streams = {
        seg: (t, np.tile([0.0, 9.81, 0.0], (len(t), 1)), np.zeros((len(t), 3)))
        for seg in ("pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l")
    }
    walk = load_protocol("walk")
    assert find_steps(streams, walk)["standing"] is not None
    with pytest.raises(InputError) as err:
        find_tasks(streams, walk)
    msg = err.value.line()
    assert "found 0 movement block(s)" in msg and "rest 0.0-4.0 s" in msg
    assert "one still pose with no movement" in msg and "recording of the movement" in msg


def test_a_recording_without_a_rest_says_no_shipped_protocol_fits_and_why():
    t = np.arange(0, 30, 1 / RATE)
    rate, _ = movement(t, -1.0, 30, 1.2, 0.1, 2.0)  # moving from the first sample to the last
    streams = {
        seg: (t, np.tile([0.0, 9.81, 0.0], (len(t), 1)), rate[:, None] * [0.0, 0.0, 1.0])
        for seg in ("pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l")
    }
    with pytest.raises(InputError) as err:
        find_steps(streams, load_protocol("walk"))
    msg = err.value.line()
    assert "'standing' (static) not found" in msg and "the recording holds movement 0.0-" in msg
    assert "no shipped protocol fits a recording without a rest" in msg
    assert "record the standing pose held still for 5 s before or after the walk" in msg


def test_a_contradicted_hint_gives_one_warning_and_the_data_is_used(knee):
    warnings: list[str] = []
    with pytest.raises(InputError):  # the seated steps are still missing
        find_steps(_stand_then_walk(up_axis=0), knee, warnings)
    assert len(warnings) == 5  # one per segment of the standing pose
    assert (
        "thigh_r: sensor +x points up in the standing pose, the protocol says +y; using the data"
        in warnings
    )


def test_a_sensor_that_may_sit_any_way_round_is_no_warning():
    """The walk protocol's sensors go 'anywhere, any orientation': the real full-body walk and
    arm reports listed every sensor that did not point as the default hint under 'what to
    repeat next time'. A segment marked any_orientation gives no such warning."""
    walk = load_protocol("walk")
    assert all(s.any_orientation for s in walk.segments.values())
    warnings: list[str] = []
    find_steps(_stand_then_walk(up_axis=0), walk, warnings)
    assert not any("points up in the" in w for w in warnings), warnings


def test_a_nan_span_in_one_sensor_does_not_hide_the_rests_and_movements():
    streams = _stand_then_walk(up_axis=1)
    t, acc, gyr = streams["thigh_r"]
    acc, gyr = acc.copy(), gyr.copy()
    acc[2000:2100] = np.nan  # 1 s of lost samples in the walk
    gyr[2000:2100] = np.nan
    streams["thigh_r"] = (t, acc, gyr)
    found = blocks(streams)
    assert [b.moving for b in found if b.end - b.start > 1.0] == [False, True, False]
    assert np.allclose(found[0].up["thigh_r"], [0.0, 1.0, 0.0])


def _walk_sit_walk_protocol(tmp_path, sit_s: float):
    """The shipped ``walk`` protocol with three tasks: walk, sit still ``sit_s`` s, walk."""
    text = load_protocol("walk").path.read_text()
    text = text.replace(
        "tasks:\n",
        "tasks:\n"
        "  - {name: walk_before, kind: gait, duration_s: 20}\n"
        f"  - {{name: sitting, kind: static, duration_s: {sit_s}}}\n",
        1,
    ).replace("name: walk\n", "name: walk_sit_walk\n", 1)
    path = tmp_path / "walk_sit_walk.yaml"
    path.write_text(text)
    return load_protocol(path)


def test_a_held_task_takes_the_rest_and_the_moves_around_it_stay_apart(tmp_path):
    """Stand 0-5 s, walk 5-25 s, sit down 28-29.5 s (a short move), sit still 29.5-90 s,
    get up and walk 90-120 s: the sitting task is the long rest (its middle), not the short
    move of sitting down, and each walk is its own movement block."""
    t = np.arange(0, 125, 1 / RATE)
    rate = movement(t, 5.0, 16, 1.2, 0.05, 2.0)[0] + movement(t, 90.0, 24, 1.2, 0.05, 2.0)[0]
    rate += movement(t, 28.0, 1, 1.5, 0.0, 1.0)[0]
    streams = {
        seg: (t, np.tile([0.0, 9.81, 0.0], (len(t), 1)), rate[:, None] * [0.0, 0.0, 1.0])
        for seg in ("pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l")
    }
    protocol = _walk_sit_walk_protocol(tmp_path, 60)
    tasks = find_tasks(streams, protocol, after_s=4.0)
    assert list(tasks) == ["walk_before", "sitting", "walk"]
    assert abs(tasks["walk_before"][0] - 5.0) < 0.5 and abs(tasks["walk_before"][1] - 25.0) < 0.5
    assert 29.5 <= tasks["sitting"][0] < 30.5 and 88.5 < tasks["sitting"][1] <= 90.0
    assert abs(tasks["walk"][0] - 90.0) < 0.5
    with pytest.raises(InputError) as err:  # a held task longer than any rest
        find_tasks(streams, _walk_sit_walk_protocol(tmp_path, 200), after_s=4.0)
    assert "found no rest of at least 100.0 s for the held task 'sitting'" in err.value.line()
