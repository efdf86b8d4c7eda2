"""Joint-angle signs with hand-made poses on both sides (docs/conventions.md)."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import (
    JOINT_ANGLE_NAMES,
    column_name,
    compose,
    decompose,
    joint_angles,
)
from motionlab.protocol import Joint

# Standing pose, subject facing north: segment x (anterior) = north, y (up) = up, z (right) = east.
STANDING = np.column_stack([[0.0, 1, 0], [0.0, 0, 1], [1.0, 0, 0]])


def frame(x, y, z) -> np.ndarray:
    """Segment → earth quaternion of a distal frame given by its axes in proximal coordinates."""
    m = np.column_stack([x, y, z]).astype(float)
    assert np.allclose(m.T @ m, np.eye(3), atol=1e-12) and np.linalg.det(m) > 0
    return rot.from_matrix(STANDING @ m)[None]


def angles_deg(x, y, z, joint_type, side):
    q_prox = rot.from_matrix(STANDING)[None]
    return np.degrees(decompose(q_prox, frame(x, y, z), joint_type, side))[0]


c30, s30 = np.cos(np.radians(30)), np.sin(np.radians(30))
c10, s10 = np.cos(np.radians(10)), np.sin(np.radians(10))
c15, s15 = np.cos(np.radians(15)), np.sin(np.radians(15))
c60, s60 = np.cos(np.radians(60)), np.sin(np.radians(60))

# (joint, side, distal axes in proximal coordinates, expected clinical angles in degrees)
POSES = [
    # knee flexion 30°: the foot moves backward, the shank's long axis leans forward
    ("knee", "r", ([c30, -s30, 0], [s30, c30, 0], [0, 0, 1]), [30, 0, 0]),
    ("knee", "l", ([c30, -s30, 0], [s30, c30, 0], [0, 0, 1]), [30, 0, 0]),
    # knee varus 10°: the foot moves medially (left for the right leg, right for the left leg)
    ("knee", "r", ([1, 0, 0], [0, c10, s10], [0, -s10, c10]), [0, 10, 0]),
    ("knee", "l", ([1, 0, 0], [0, c10, -s10], [0, s10, c10]), [0, 10, 0]),
    # knee internal rotation 15°: the shank's anterior axis turns medially
    ("knee", "r", ([c15, 0, -s15], [0, 1, 0], [s15, 0, c15]), [0, 0, 15]),
    ("knee", "l", ([c15, 0, s15], [0, 1, 0], [-s15, 0, c15]), [0, 0, 15]),
    # elbow flexion 90°: the forearm points forward, palm up
    ("elbow", "r", ([0, 1, 0], [-1, 0, 0], [0, 0, 1]), [90, 0, 0]),
    ("elbow", "l", ([0, 1, 0], [-1, 0, 0], [0, 0, 1]), [90, 0, 0]),
    # elbow carrying angle (valgus) 10°: the wrist moves laterally
    ("elbow", "r", ([1, 0, 0], [0, c10, -s10], [0, s10, c10]), [0, 10, 0]),
    ("elbow", "l", ([1, 0, 0], [0, c10, s10], [0, -s10, c10]), [0, 10, 0]),
    # elbow pronation 60°: the palm (anterior axis) turns medially
    ("elbow", "r", ([c60, 0, -s60], [0, 1, 0], [s60, 0, c60]), [0, 0, 60]),
    ("elbow", "l", ([c60, 0, s60], [0, 1, 0], [-s60, 0, c60]), [0, 0, 60]),
    # lumbar flexion 30°: the thorax's top moves forward
    ("lumbar", "", ([c30, -s30, 0], [s30, c30, 0], [0, 0, 1]), [30, 0, 0]),
    # lumbar lateral bending 10° to the right: the thorax's top moves right
    ("lumbar", "", ([1, 0, 0], [0, c10, s10], [0, -s10, c10]), [0, 10, 0]),
    # lumbar axial rotation 15° to the left: the thorax's front turns left
    ("lumbar", "", ([c15, 0, -s15], [0, 1, 0], [s15, 0, c15]), [0, 0, 15]),
]


@pytest.mark.parametrize("joint_type, side, axes, expected", POSES)
def test_sign_table_hand_made_poses(joint_type, side, axes, expected):
    np.testing.assert_allclose(angles_deg(*axes, joint_type, side), expected, atol=1e-9)


def test_opposite_movements_give_negative_angles():
    # knee hyperextension 10° on the right: the foot moves forward
    ext = angles_deg([c10, s10, 0], [-s10, c10, 0], [0, 0, 1], "knee", "r")
    np.testing.assert_allclose(ext, [-10, 0, 0], atol=1e-9)
    # knee valgus on the left: the foot moves laterally (left, -z)
    valgus = angles_deg([1, 0, 0], [0, c10, s10], [0, -s10, c10], "knee", "l")
    np.testing.assert_allclose(valgus, [0, -10, 0], atol=1e-9)
    # lumbar bending to the left and rotation to the right
    left_bend = angles_deg([1, 0, 0], [0, c10, -s10], [0, s10, c10], "lumbar", "")
    np.testing.assert_allclose(left_bend, [0, -10, 0], atol=1e-9)


@pytest.mark.parametrize("joint_type", ["knee", "elbow"])
def test_left_is_mirror_of_right(joint_type):
    rng = np.random.default_rng(3)
    mirror = np.diag([1.0, 1.0, -1.0])
    angles = rng.uniform(-0.5, 0.5, (50, 3))
    m_right = rot.to_matrix(compose(angles, joint_type, "r"))
    m_left = mirror @ m_right @ mirror  # reflect through the sagittal plane
    q_prox = np.tile(rot.from_matrix(STANDING), (50, 1))
    q_left = rot.mul(q_prox, rot.from_matrix(m_left))
    np.testing.assert_allclose(decompose(q_prox, q_left, joint_type, "l"), angles, atol=1e-9)


@pytest.mark.parametrize(
    "joint_type, side",
    [("knee", "r"), ("knee", "l"), ("elbow", "r"), ("elbow", "l"), ("lumbar", "")],
)
def test_compose_is_inverse_of_decompose(joint_type, side):
    rng = np.random.default_rng(7)
    angles = rng.uniform(-1.2, 1.2, (200, 3))
    angles[:, 1] = rng.uniform(-1.2, 1.2, 200)
    q_prox = rot.normalize(rng.normal(size=(200, 4)))
    q_dist = rot.mul(q_prox, compose(angles, joint_type, side))
    np.testing.assert_allclose(decompose(q_prox, q_dist, joint_type, side), angles, atol=1e-9)


def test_column_names_and_convenience():
    assert column_name("knee", "r", "flexion") == "knee_r_flexion_deg"
    assert column_name("lumbar", "", "axial_rotation") == "lumbar_axial_rotation_deg"
    joint = Joint(name="elbow_l", type="elbow", proximal="upperarm_l", distal="forearm_l", side="l")
    q_prox = np.tile(rot.from_matrix(STANDING), (2, 1))
    q_dist = rot.mul(q_prox, compose(np.radians([[45, 5, 20], [90, 0, -30]]), "elbow", "l"))
    out = joint_angles(q_prox, q_dist, joint)
    assert list(out) == [f"elbow_l_{n}_deg" for n in JOINT_ANGLE_NAMES["elbow"]]
    np.testing.assert_allclose(out["elbow_l_pronation_deg"], [20, -30], atol=1e-9)


def test_bad_joint_or_side_is_input_error():
    from motionlab.errors import InputError

    q = rot.from_matrix(STANDING)[None]
    with pytest.raises(InputError, match="side"):
        decompose(q, q, "knee", "")
    with pytest.raises(InputError, match="joint type"):
        decompose(q, q, "wrist", "r")


@pytest.mark.parametrize("joint_type, side", [("knee", "l"), ("elbow", "r"), ("lumbar", "")])
def test_missing_orientations_give_nan_rows(joint_type, side):
    angles = np.radians([[30.0, 5.0, -10.0], [60.0, -3.0, 12.0], [90.0, 2.0, 20.0]])
    q_prox = np.tile(rot.from_matrix(STANDING), (3, 1))
    q_dist = rot.mul(q_prox, compose(angles, joint_type, side))
    q_prox[1] = np.nan  # proximal sample lost
    q_dist[2] = 0.0  # distal sample not a rotation
    out = decompose(q_prox, q_dist, joint_type, side)
    assert np.isnan(out[1:]).all()
    np.testing.assert_allclose(out[0], angles[0], atol=1e-9)
    assert np.isnan(decompose(np.full((2, 4), np.nan), q_dist[:2], joint_type, side)).all()
