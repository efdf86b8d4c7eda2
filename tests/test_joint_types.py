"""The joint-type table: clinical signs, flexion axes, generic hinge and ball joints, and the
protocol errors about joints (each naming the key and the line)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import compose, decompose, joint_angles
from motionlab.kinematics.joint_types import (
    JOINT_TYPES,
    TAIT_BRYAN,
    angle_columns,
    angle_names,
    flexion_axis,
    joint_sequence,
    plane,
    split_column,
)
from motionlab.kinematics.out_of_plane import plane_index
from motionlab.protocol import Joint, axis_vector, load_protocol
from motionlab.report.pages_methods import decomposition_text

# The sign table as it was before the joint-type table (clinical = sign * ZXY Euler angle).
OLD_SIGNS = {
    "knee": {"r": (-1.0, 1.0, 1.0), "l": (-1.0, -1.0, -1.0)},
    "elbow": {"r": (1.0, -1.0, 1.0), "l": (1.0, 1.0, -1.0)},
    "lumbar": {"": (-1.0, 1.0, 1.0)},
}
OLD_NAMES = {
    "knee": ("flexion", "adduction", "rotation"),
    "elbow": ("flexion", "carrying", "pronation"),
    "lumbar": ("flexion", "lateral_bending", "axial_rotation"),
}
CLINICAL_SIDES = [("knee", "r"), ("knee", "l"), ("elbow", "r"), ("elbow", "l"), ("lumbar", "")]
IDENTITY = np.array([[1.0, 0.0, 0.0, 0.0]])


def same_rotation(p: np.ndarray, q: np.ndarray) -> bool:
    return bool(np.allclose(np.abs(np.sum(p * q, axis=-1)), 1.0, atol=1e-12))


# ------------------------------------------------------------------------------ the table


def test_clinical_types_keep_the_old_signs_names_and_sequence():
    for name, signs in OLD_SIGNS.items():
        jt = JOINT_TYPES[name]
        assert jt.clinical and jt.sequence == "ZXY" and jt.sequence_rule == "fixed"
        assert jt.signs == signs
        assert jt.angle_names == OLD_NAMES[name]
        assert jt.sided == (name != "lumbar")
    assert JOINT_TYPES["knee"].hinge and JOINT_TYPES["elbow"].hinge
    assert not JOINT_TYPES["lumbar"].hinge


def test_every_entry_is_complete():
    for name, jt in JOINT_TYPES.items():
        assert jt.name == name
        assert jt.sequence in TAIT_BRYAN
        assert len(jt.positive) == len(jt.titles) == 3
        assert all(len(s) == 3 and set(s) <= {-1.0, 1.0} for s in jt.signs.values())
        assert set(jt.signs) == ({"r", "l"} if jt.sided else {""})
        assert jt.sequence_rule in ("fixed", "axis", "any")
        assert jt.flexion_axis is None or jt.flexion_axis.lstrip("-") in "xyz"


@pytest.mark.parametrize("joint_type, side", CLINICAL_SIDES)
def test_flexion_axis_agrees_with_the_signs(joint_type, side):
    axis = JOINT_TYPES[joint_type].flexion_axis
    q = compose(np.radians([[10.0, 0.0, 0.0]]), joint_type, side)
    assert same_rotation(q, rot.from_axis_angle(axis_vector(axis), np.radians(10.0)))
    # and the sign the table's first entry gives: -z means clinical flexion = -Euler z angle
    assert (axis.startswith("-")) == (JOINT_TYPES[joint_type].signs[side][0] < 0)


def test_flexion_axis_of_a_joint():
    assert flexion_axis(Joint("k", "knee", "a", "b", "r")) == "-z"
    assert flexion_axis(Joint("e", "elbow", "a", "b", "l")) == "z"
    assert flexion_axis(Joint("h", "hinge", "a", "b", axis="-x")) == "-x"
    assert flexion_axis(Joint("s", "ball", "a", "b")) is None


# ------------------------------------------------------------------------------ hinge


@pytest.mark.parametrize(
    "axis, sequence", [("x", "XYZ"), ("y", "YZX"), ("z", "ZXY"), ("-z", "ZXY"), ("-x", "XYZ")]
)
def test_hinge_pure_rotation_about_its_axis(axis, sequence):
    joint = Joint("wrist", "hinge", "forearm", "hand", axis=axis)
    assert joint_sequence(joint) == sequence
    theta = np.radians([-70.0, -5.0, 0.0, 20.0, 95.0])
    q_dist = rot.from_axis_angle(np.tile(axis_vector(axis), (5, 1)), theta)
    q_prox = np.tile(IDENTITY, (5, 1))
    out = decompose(q_prox, q_dist, "hinge", sequence=None, axis=axis)
    np.testing.assert_allclose(out[:, 0], theta, atol=1e-12)
    np.testing.assert_allclose(out[:, 1:], 0.0, atol=1e-12)
    table = joint_angles(q_prox, q_dist, joint)
    assert list(table) == ["wrist_angle_deg", "wrist_off_axis_1_deg", "wrist_off_axis_2_deg"]
    np.testing.assert_allclose(table["wrist_angle_deg"], np.degrees(theta), atol=1e-9)
    # the hinge axis is the flexion axis: composing +10° is a +10° turn about it
    q = compose(np.radians([[10.0, 0.0, 0.0]]), "hinge", axis=axis)
    assert same_rotation(q, rot.from_axis_angle(axis_vector(axis), np.radians(10.0)))


def test_hinge_off_axis_angles_follow_the_sequence():
    rng = np.random.default_rng(5)
    angles = rng.uniform(-0.6, 0.6, (40, 3))
    for axis in ("x", "-y", "z"):
        q = compose(angles, "hinge", axis=axis)
        np.testing.assert_allclose(
            decompose(np.tile(IDENTITY, (40, 1)), q, "hinge", axis=axis), angles, atol=1e-9
        )
    joint = Joint("wrist", "hinge", "forearm", "hand", axis="y")
    assert [plane(joint, a) for a in angle_names(joint)] == ["transverse", "sagittal", "frontal"]
    assert plane_index(joint, "y") == 0 and plane_index(joint, "-x") == 2
    assert plane_index(joint, "xy") is None and plane_index("lumbar", "lateral_bending") == 1


# ------------------------------------------------------------------------------ ball


@pytest.mark.parametrize("sequence", ["YXZ", "XZY", "ZYX"])
def test_ball_decomposition_matches_scipy(sequence):
    rng = np.random.default_rng(11)
    euler = rng.uniform(-1.2, 1.2, (100, 3))
    q_rel = rot.from_scipy(Rotation.from_euler(sequence, euler))
    q_prox = rot.normalize(rng.normal(size=(100, 4)))
    q_dist = rot.mul(q_prox, q_rel)
    out = decompose(q_prox, q_dist, "ball", sequence=sequence)
    np.testing.assert_allclose(out, euler, atol=1e-9)
    joint = Joint("shoulder", "ball", "thorax", "upperarm_r", side="r", sequence=sequence)
    names = tuple(c.lower() for c in sequence)
    assert angle_names(joint) == names
    assert angle_columns(joint) == [(n, f"shoulder_{n}_deg") for n in names]
    assert plane(joint, "z") == "sagittal" and plane(joint, "x") == "frontal"


def test_ball_default_sequence_is_zxy():
    joint = Joint("hip", "ball", "pelvis", "thigh")
    assert joint_sequence(joint) == "ZXY"
    assert [c for _, c in angle_columns(joint)] == ["hip_z_deg", "hip_x_deg", "hip_y_deg"]


def test_clinical_columns_unchanged_and_split_back():
    knee = Joint("left_knee", "knee", "thigh_l", "shank_l", "l")
    assert [c for _, c in angle_columns(knee)] == [
        "knee_l_flexion_deg",
        "knee_l_adduction_deg",
        "knee_l_rotation_deg",
    ]
    lumbar = Joint("lumbar", "lumbar", "pelvis", "thorax")
    assert angle_columns(lumbar)[2] == ("axial_rotation", "lumbar_axial_rotation_deg")
    assert split_column("knee_r_flexion_deg") == ("knee_r", "flexion")
    assert split_column("lumbar_axial_rotation_deg") == ("lumbar", "axial_rotation")
    assert split_column("hinge3_off_axis_1_deg") == ("hinge3", "off_axis_1")
    assert split_column("shoulder_r_y_deg") == ("shoulder_r", "y")


def test_wrong_sequence_in_code_is_input_error():
    with pytest.raises(InputError, match="ZXY only"):
        decompose(IDENTITY, IDENTITY, "knee", "r", sequence="XYZ")
    with pytest.raises(InputError, match="starting with X"):
        compose(np.zeros((1, 3)), "hinge", axis="x", sequence="ZXY")
    with pytest.raises(InputError, match="needs axis"):
        compose(np.zeros((1, 3)), "hinge")


# ------------------------------------------------------------------------------ protocol


ARM = """name: arm
segments:
  thorax: {placement: sternum}
  upperarm_r: {side: r}
  forearm_r: {side: r}
  hand_r: {side: r}
joints:
  shoulder_r:
    type: ball
    proximal: thorax
    distal: upperarm_r
    sequence: YXZ
  elbow_r:
    type: elbow
    proximal: upperarm_r
    distal: forearm_r
    side: r
  wrist_r:
    type: hinge
    axis: -z
    proximal: forearm_r
    distal: hand_r
"""


def load_text(tmp_path, text):
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    return load_protocol(path)


def line_of(text: str, needle: str, after: str = "") -> int:
    lines = text.splitlines()
    start = next(i for i, t in enumerate(lines) if after in t) if after else 0
    return next(i for i, t in enumerate(lines[start:], start + 1) if needle in t)


def test_generic_joints_load_with_their_sequence_and_columns(tmp_path):
    p = load_text(tmp_path, ARM)
    assert p.joints["shoulder_r"].sequence == "YXZ"
    assert p.joints["elbow_r"].sequence == "ZXY" and p.joints["elbow_r"].axis is None
    assert p.joints["wrist_r"].axis == "-z" and p.joints["wrist_r"].sequence == "ZXY"
    assert angle_columns(p.joints["wrist_r"])[0] == ("angle", "wrist_r_angle_deg")
    text = decomposition_text(list(p.joints.values()))
    assert "intrinsic Y-X-Z" in text and "hinge axis -z" in text and "Z-X-Y" in text


def assert_error(tmp_path, text, key, line, *words):
    with pytest.raises(InputError) as err:
        load_text(tmp_path, text)
    msg = str(err.value)
    assert f"line {line}, key {key}" in msg, msg
    for w in words:
        assert w in msg, msg


@pytest.mark.parametrize("bad", ["ABC", "ZZX", "zxy", "ZXZ"])
def test_unknown_sequence_names_key_and_line(tmp_path, bad):
    text = ARM.replace("sequence: YXZ", f"sequence: {bad}")
    assert_error(tmp_path, text, "joints.shoulder_r.sequence", line_of(text, bad), repr(bad))


def test_clinical_type_with_another_sequence(tmp_path):
    text = ARM.replace("    side: r\n", "    side: r\n    sequence: XZY\n")
    line = line_of(text, "XZY")
    assert_error(tmp_path, text, "joints.elbow_r.sequence", line, "ZXY only", "'XZY'")


def test_hinge_without_axis_or_with_a_sequence_not_starting_with_it(tmp_path):
    text = ARM.replace("    axis: -z\n", "")
    assert_error(tmp_path, text, "joints.wrist_r.axis", line_of(text, "wrist_r:"), "needs axis")
    text = ARM.replace("    axis: -z\n", "    axis: -z\n    sequence: XYZ\n")
    assert_error(tmp_path, text, "joints.wrist_r.sequence", line_of(text, "XYZ"), "starting with Z")
    text = ARM.replace("    axis: -z\n", "    axis: w\n")
    assert_error(tmp_path, text, "joints.wrist_r.axis", line_of(text, "axis: w"), "'w'")


def test_axis_on_a_non_hinge_joint(tmp_path):
    text = ARM.replace("    side: r\n", "    side: r\n    axis: z\n")
    line = line_of(text, "axis: z")
    assert_error(tmp_path, text, "joints.elbow_r.axis", line, "takes no axis")


def test_two_joints_giving_one_column(tmp_path):
    text = ARM + "  elbow_again: {type: elbow, proximal: upperarm_r, distal: hand_r, side: r}\n"
    line = line_of(text, "elbow_again:")
    assert_error(
        tmp_path,
        text,
        "joints.elbow_again",
        line,
        "elbow_r_flexion_deg",
        "joints.elbow_r",
        f"line {line_of(text, 'elbow_r:')}",
    )
    # generic joints are named by the joint: two hinges of one side do not collide
    text = ARM + "  finger: {type: hinge, axis: z, proximal: forearm_r, distal: hand_r}\n"
    assert set(load_text(tmp_path, text).joints) == {"shoulder_r", "elbow_r", "wrist_r", "finger"}


def test_proximal_equals_distal(tmp_path):
    text = ARM.replace("    distal: hand_r\n", "    distal: forearm_r\n")
    line = line_of(text, "distal: forearm_r", after="wrist_r:")
    assert_error(tmp_path, text, "joints.wrist_r.distal", line, "forearm_r")


def test_sided_type_without_side(tmp_path):
    text = ARM.replace("    side: r\n", "")
    assert_error(tmp_path, text, "joints.elbow_r.side", line_of(text, "elbow_r:"), "needs a side")


# ------------------------------------------------------------------------------ ankle


@pytest.mark.parametrize("side, toes_left", [("r", 1.0), ("l", -1.0)])
def test_ankle_angles_of_a_hand_built_pose(side, toes_left):
    """A foot lifted 15° at the toes, its sole turned 8° towards the midline and its toes turned
    5° towards the midline reads dorsiflexion 15°, inversion 8°, internal rotation 5° on either
    side (ISB frames: x anterior, y up, z to the subject's right)."""
    lift = rot.from_axis_angle([0.0, 0.0, 1.0], np.radians(15.0))  # toes up about z
    # inversion: the foot's top tilts laterally (to the right for the right foot)
    tilt = rot.from_axis_angle([1.0, 0.0, 0.0], np.radians(8.0) * toes_left)
    turn = rot.from_axis_angle([0.0, 1.0, 0.0], np.radians(5.0) * toes_left)  # toes medially
    q_foot = rot.mul(rot.mul(lift, tilt), turn)[None]
    joint = Joint(f"ankle_{side}", "ankle", f"shank_{side}", f"foot_{side}", side)
    table = joint_angles(IDENTITY, q_foot, joint)
    assert list(table) == [f"ankle_{side}_dorsiflexion_deg", f"ankle_{side}_inversion_deg",
                           f"ankle_{side}_rotation_deg"]  # fmt: skip
    np.testing.assert_allclose([table[c][0] for c in table], [15.0, 8.0, 5.0], atol=1e-9)


def test_ankle_in_a_protocol(tmp_path):
    path = tmp_path / "ankle.yaml"
    path.write_text(
        "name: ankle\nsegments:\n  shank_r: {side: r}\n  foot_r: {side: r}\n"
        "joints:\n  ankle_r: {type: ankle, proximal: shank_r, distal: foot_r, side: r}\n"
    )
    protocol = load_protocol(path)
    assert [c for _, c in angle_columns(protocol.joints["ankle_r"])] == [
        "ankle_r_dorsiflexion_deg", "ankle_r_inversion_deg", "ankle_r_rotation_deg"
    ]  # fmt: skip
    joint = protocol.joints["ankle_r"]
    assert [plane(joint, a) for a in ("dorsiflexion", "inversion", "rotation")] == [
        "sagittal", "frontal", "transverse"
    ]  # fmt: skip
    assert plane_index(joint, "inversion") == 1


def test_trunk_lean_is_the_thorax_against_the_chair_with_lumbar_signs():
    """Written chair relative to thorax (YXZ), the angles are the thorax's against the chair:
    forward lean +, to the right +, turned to the left +, as the lumbar angles of the same
    rotation."""
    chair = np.array([[1.0, 0.0, 0.0, 0.0]])
    for axis, deg, want in ((np.array([0.0, 0.0, -1.0]), 20.0, ("forward", 20.0)),
                            (np.array([1.0, 0.0, 0.0]), 10.0, ("sideways", 10.0)),
                            (np.array([0.0, 1.0, 0.0]), 15.0, ("rotation", 15.0))):  # fmt: skip
        thorax = rot.from_axis_angle(axis, np.radians(deg))[None]
        lean = np.degrees(decompose(thorax, chair, "trunk_lean"))[0]
        names = JOINT_TYPES["trunk_lean"].angle_names
        got = dict(zip(names, lean, strict=True))
        assert got[want[0]] == pytest.approx(want[1], abs=1e-9)
        others = [v for k, v in got.items() if k != want[0]]
        assert np.allclose(others, 0.0, atol=1e-9)
    # a combined pose: the same three numbers as the lumbar decomposition of thorax vs chair
    thorax = compose(np.radians([[25.0, -8.0, 12.0]]), "lumbar")
    lumbar = np.degrees(decompose(chair, thorax, "lumbar"))[0]
    lean = np.degrees(decompose(thorax, chair, "trunk_lean"))[0]
    assert lean[::-1] == pytest.approx(lumbar, abs=1e-9)


def test_methods_text_names_only_the_conventions_and_cycles_of_the_protocol():
    """The seated trunk report's methods page spoke of the knee (Grood & Suntay), heel strikes
    and varus thrust: the conventions and the cycles are now those of the protocol's joints and
    tasks."""
    from motionlab.protocol import load_protocol

    def text(name: str) -> str:
        p = load_protocol(name)
        return decomposition_text(list(p.joints.values()), any(t.is_gait for t in p.tasks))

    seated = text("lumbar_seated")
    assert "ISB, Wu et al. 2002 for the lumbar spine" in seated
    assert not any(w in seated for w in ("Grood", "knee", "heel strike", "varus", "elbow"))
    walk = text("walk")
    assert "Grood & Suntay 1983 for the knee" in walk and "heel strike" in walk
    assert "elbow" not in walk
    assert "tables are the angles as computed" in walk  # a table stored before the low-pass
    p = load_protocol("walk")
    smooth = decomposition_text(list(p.joints.values()), True, 6.0)
    assert "low-passed at 6 Hz" in smooth and "tables are low-passed the same way" in smooth
    assert "low-passed at 3 Hz" in decomposition_text(list(p.joints.values()), True, 3.0)
