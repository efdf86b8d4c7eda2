"""Shipped protocols load; a broken protocol names the key and the line."""

from pathlib import Path

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import JOINT_ANGLE_NAMES
from motionlab.kinematics.joint_types import JOINT_TYPES
from motionlab.protocol import PACKAGED, axis_vector, list_protocols, load_protocol


def test_all_shipped_protocols_are_there():
    assert {"knee", "elbow", "lumbar", "upper_body_children"} <= set(list_protocols())


@pytest.mark.parametrize("name", list_protocols())
def test_shipped_protocol_loads_and_is_complete(name):
    p = load_protocol(name)
    assert p.title and p.purpose and p.source and p.metrics
    for seg in p.segments.values():
        assert seg.placement, seg.name
        m = seg.nominal_mounting()
        np.testing.assert_allclose(m.T @ m, np.eye(3))
    assert any(s.kind == "static" for s in p.calibration)
    # every required segment gets a vertical axis and at least one more axis, so its frame is fixed
    # (a stand-and-move protocol, without functional steps, takes the others from its tasks)
    stand_and_move = not any(s.kind == "functional" for s in p.calibration)
    for seg in (s for s in p.segments.values() if s.required and not stand_and_move):
        axes = [s.vertical_axis[seg.name] for s in p.calibration if seg.name in s.vertical_axis]
        axes += [s.axis[seg.name] for s in p.calibration if seg.name in s.axis]
        dirs = {tuple(np.abs(axis_vector(a))) for a in axes}
        assert len(dirs) >= 2 or name == "knee" and seg.name == "pelvis", (name, seg.name, axes)
    for joint in p.joints.values():
        assert joint.type in JOINT_ANGLE_NAMES
        assert joint.side or not JOINT_TYPES[joint.type].sided
    for task, ranges in p.normative.items():
        for col in ranges:
            assert col.endswith("_deg"), (task, col)


def test_knee_protocol_contents():
    p = load_protocol("knee")
    assert set(p.joints) == {"knee_r", "knee_l"}
    names = [s.name for s in p.calibration]
    assert names[:4] == ["standing", "sitting", "knee_flexion_r", "knee_flexion_l"]
    assert p.calibration[2].repetitions == 5
    assert all(s.optional for s in p.calibration if s.name.startswith("hip"))
    assert {t.name for t in p.tasks} == {"gait", "squat", "sit_to_stand"}
    assert p.thresholds["varus_thrust_deg"] == 3.0


def test_children_protocol_has_ricci_movements_and_reliabilities():
    p = load_protocol("upper_body_children")
    names = [s.name for s in p.calibration]
    assert names == [
        "supine",
        "thorax_rotation",
        "thorax_flexion",
        "arm_abduction",
        "arm_flexion",
        "arm_flexion_bar",
        "pronation",
        "elbow_flexion_bar",
    ]
    assert p.calibration[6].reference_rho["forearm_r"] == 0.89


def _write(tmp_path, text):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    return path


def _broken(tmp_path, old, new):
    text = (PACKAGED / "knee.yaml").read_text()
    assert old in text
    return _write(tmp_path, text.replace(old, new, 1))


def test_unknown_segment_names_key_and_line(tmp_path):
    path = _broken(tmp_path, "proximal: thigh_r", "proximal: femur_r")
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1) if "femur_r" in t)
    with pytest.raises(InputError) as err:
        load_protocol(path)
    msg = str(err.value)
    assert "joints.knee_r.proximal" in msg and f"line {line}" in msg and "femur_r" in msg


def test_bad_axis_names_key(tmp_path):
    path = _broken(tmp_path, "axis: {shank_r: -z}", "axis: {shank_r: -w}")
    with pytest.raises(InputError, match=r"calibration\[2\].axis.shank_r.*'-w'"):
        load_protocol(path)


def test_missing_key_and_bad_type(tmp_path):
    path = _broken(tmp_path, "    duration_s: 5\n", "    duration_s: five\n")
    with pytest.raises(InputError, match=r"line \d+, key calibration\[0\].duration_s.*five"):
        load_protocol(path)
    path = _write(tmp_path, "name: x\njoints: {}\n")
    with pytest.raises(InputError, match="segments.*missing"):
        load_protocol(path)


@pytest.mark.parametrize("value", ["-5", "0", "1000000000000"])
def test_a_step_duration_out_of_range_is_refused(tmp_path, value):
    """The hostile-input audit's protocols with a step of -5 s or 10¹² s ran; 'five' and inf
    were refused."""
    path = _broken(tmp_path, "    duration_s: 5\n", f"    duration_s: {value}\n")
    with pytest.raises(InputError, match=r"key calibration\[0\].duration_s: is .* s — give a "
                       r"duration above 0 s, at most 86400 s"):  # fmt: skip
        load_protocol(path)


def test_yaml_syntax_error_names_line(tmp_path):
    path = _write(tmp_path, "name: knee\nsegments:\n  thigh_r: {side: r\n  shank_r: {}\n")
    with pytest.raises(InputError, match=r"bad.yaml line \d+: not valid YAML"):
        load_protocol(path)


def test_bad_reference_rho_segment(tmp_path):
    src = (PACKAGED / "upper_body_children.yaml").read_text()
    src = src.replace("reference_rho: {thorax: 0.84}", "reference_rho: {torso: 0.84}", 1)
    path = _write(tmp_path, src)
    with pytest.raises(InputError, match="reference_rho.*torso"):
        load_protocol(path)


def test_task_time_range_and_step_options(tmp_path):
    path = _broken(tmp_path, "{name: gait, kind: gait, duration_s: 60,",
                   "{name: gait, kind: gait, duration_s: 60, time_range: [95, 150.5],")  # fmt: skip
    p = load_protocol(path)
    assert p.tasks[0].time_range == (95.0, 150.5) and "time_range" not in p.tasks[0].options
    assert p.calibration[2].axis_method == "svd"
    path = _broken(tmp_path, "{name: gait, kind: gait, duration_s: 60,",
                   "{name: gait, kind: gait, duration_s: 60, time_range: [150, 95],")  # fmt: skip
    with pytest.raises(InputError, match=r"line \d+, key tasks\[0\].time_range"):
        load_protocol(path)
    path = _broken(tmp_path, "    repetitions: 5\n    duration_s: 15\n    instructions: \"still",
                   "    repetitions: 5\n    duration_s: 15\n    axis_method: seel\n"
                   "    instructions: \"still")  # fmt: skip
    with pytest.raises(InputError, match=r"line \d+, key calibration\[2\].axis_method.*'seel'"):
        load_protocol(path)


def test_a_folder_named_like_a_packaged_protocol_does_not_hide_it(tmp_path, monkeypatch):
    """An earlier run's output folder ``knee`` in the working folder: ``--protocol knee`` is
    still the packaged protocol; a folder given as a protocol of no packaged name is refused."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "knee").mkdir()
    assert load_protocol("knee").name == load_protocol(PACKAGED / "knee.yaml").name
    (tmp_path / "mine").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        load_protocol("mine")
    (tmp_path / "walk").write_text("not: [a protocol")  # a file of the name is read, as given
    with pytest.raises(InputError, match="walk"):
        load_protocol("walk")


def test_the_help_examples_paths_into_protocols_work_outside_the_repository(tmp_path, monkeypatch):
    """``run --help`` writes ``--map protocols/examples/trunk_map.yaml`` and ``--protocol
    protocols/examples/ring_rig.yaml``: outside the repository they said "no such sensor map
    file". A relative path into ``protocols/`` that does not exist is the installed copy; one
    that exists is read as given."""
    from motionlab.protocol import packaged_copy
    from motionlab.sensor_map import load_sensor_map

    monkeypatch.chdir(tmp_path)
    smap = load_sensor_map("protocols/examples/trunk_map.yaml")
    assert smap.path == PACKAGED / "examples" / "trunk_map.yaml"
    assert load_protocol("protocols/examples/ring_rig.yaml").name == "ring_rig"
    assert packaged_copy("protocols/examples/none.yaml") is None
    assert packaged_copy("elsewhere/trunk_map.yaml") is None
    mine = tmp_path / "protocols" / "examples" / "trunk_map.yaml"
    mine.parent.mkdir(parents=True)
    mine.write_text("sensors: {Back: {segment: pelvis}}\n")
    assert packaged_copy("protocols/examples/trunk_map.yaml") is None
    assert load_sensor_map("protocols/examples/trunk_map.yaml").path == Path(
        "protocols/examples/trunk_map.yaml"
    )


@pytest.mark.parametrize(
    ("old", "new", "expect"),
    [  # each ran before: '' and '.' as internal errors (an HDF5 group or attribute without a
        # name), 'knee/flex' wrote a session that 'info' and 'report' then could not read
        ("name: knee_flexion_r\n", "name: ''\n", r"calibration\[2\].name: name '' is empty"),
        ("name: knee_flexion_r\n", "name: knee/flex\n", r"calibration\[2\].name: .* holds '/'"),
        ("  knee_r: {type", "  '.': {type", r"joints\..: name '.' is empty or only dots"),
        ("  thigh_r:\n", "  thigh/r:\n", r"segments.thigh/r: name 'thigh/r' holds '/'"),
        ("{name: gait, kind: gait,", "{name: '', kind: gait,", r"tasks\[0\].name: name ''"),
        # two tasks or steps of one name: one's results were kept under the other's
        ("{name: squat, kind: squat,", "{name: gait, kind: squat,",
         r"tasks\[1\].name: name 'gait' is given twice \(tasks\[0\] too\)"),
        ("name: sitting\n", "name: standing\n", r"calibration\[1\].name: .* given twice"),
        ("repetitions: 5, duration_s: 30", "repetitions: -5, duration_s: 30",
         r"tasks\[1\].repetitions: is -5 — give a count between 0 and"),
        # a normal range of a task or column that does not exist was never shown, silently
        ("  gait:\n    knee_flexion_deg", "  giat:\n    knee_flexion_deg",
         r"normative.giat: names no task of the protocol — did you mean 'gait'"),
        ("    knee_flexion_deg: [0, 65]", "    knee_flex_deg: [0, 65]",
         r"normative.gait.knee_flex_deg: names no angle column .* did you mean"),
    ],
)  # fmt: skip
def test_names_that_cannot_name_results_are_refused(tmp_path, old, new, expect):
    path = _broken(tmp_path, old, new)
    with pytest.raises(InputError, match=expect):
        load_protocol(path)


def test_a_number_in_e_notation_without_a_point_says_how_to_write_it(tmp_path):
    """YAML 1.1 reads 1e3 as text: 'is str '1e3', expected float — fix the value' did not say
    what was wrong with it."""
    path = _broken(tmp_path, "duration_s: 60,", "duration_s: 1e3,")
    with pytest.raises(InputError, match=r"is text '1e3': YAML reads .* e.g. 1.0e3"):
        load_protocol(path)


def test_a_misspelt_metric_is_refused_with_the_names_it_may_be(tmp_path):
    """'cross_talks' in ``metrics`` switched the cross-talk off without a word."""
    from motionlab.kinematics.metrics import OUT_OF_PLANE
    from motionlab.protocol import METRICS

    assert set(OUT_OF_PLANE) <= set(METRICS)
    path = _broken(tmp_path, "cross_talk, varus_thrust", "cross_talks, varus_thrust")
    with pytest.raises(InputError) as err:
        load_protocol(path)
    assert "key metrics: unknown metric 'cross_talks'" in err.value.line()
    assert "cross_talk" in err.value.line().split("—")[-1]


@pytest.mark.parametrize("value, expect", [("0", 0.0), ("12.5", 12.5), (None, None)])
def test_a_protocol_sets_the_angles_low_pass(tmp_path, value, expect):
    """``angle_lowpass_hz``: a rig has no skin to wobble (its protocol keeps the angles as
    computed); without the key the stage's default (6 Hz) applies."""
    text = (PACKAGED / "knee.yaml").read_text()
    path = _write(tmp_path, text + (f"angle_lowpass_hz: {value}\n" if value else ""))
    assert load_protocol(path).angle_lowpass_hz == expect
    assert load_protocol(PACKAGED / "examples" / "ring_rig.yaml").angle_lowpass_hz == 0.0


@pytest.mark.parametrize("value, what", [("-6", "is -6: not a cut-off"),
                                         ("six", "'six' is not a number"),
                                         (".nan", "not a finite number")])  # fmt: skip
def test_a_bad_angles_low_pass_is_refused_with_its_line(tmp_path, value, what):
    text = (PACKAGED / "knee.yaml").read_text()
    path = _write(tmp_path, text + f"angle_lowpass_hz: {value}\n")
    line = len(path.read_text().splitlines())
    with pytest.raises(InputError, match=rf"line {line}, key angle_lowpass_hz.*{what}"):
        load_protocol(path)
