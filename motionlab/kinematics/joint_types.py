"""The table of joint types: every fact about a joint type in one place (:data:`JOINT_TYPES`).

A joint's angles come from the distal segment's orientation relative to the proximal one,
``R = R_proximal^T R_distal``, decomposed with an intrinsic Tait–Bryan ``sequence`` (three
different letters: ``"ZXY"`` means ``R = Rz(a) Rx(b) Ry(c)``: ``a`` about the proximal z axis,
``b`` about the floating axis, ``c`` about the distal y axis). The clinical angle is
``sign * (a, b, c)`` with the sign of the joint's side. Angles are in rad inside; the table has
only names, signs and words.

Kinds of joint types:

- **clinical** (knee, hip, elbow, lumbar): fixed names, signs and sequence (only their standard
  sequence is accepted); angle columns ``<type>_<side>_<angle>_deg`` (``knee_r_flexion_deg``), or
  ``<type>_<angle>_deg`` for midline types (``lumbar_flexion_deg``).
- **hinge**: the joint names its own axis (``axis: x|y|z|-x|-y|-z``, the same segment axis in the
  proximal and distal frames at the joint's zero pose). The sequence starts with that axis
  (default: the other two in cyclic order, x → XYZ, y → YZX, z → ZXY). Angles: ``angle`` about the
  hinge axis, positive turning about the given direction (so ``-z`` flips its sign);
  ``off_axis_1`` about the floating axis (the sequence's second letter) and ``off_axis_2`` about
  the distal third axis, both positive about the positive segment axis; they check how well the
  joint is a hinge.
- **ball**: three angles of any Tait–Bryan ``sequence`` (default ZXY), named by its letters
  (``ZXY`` → ``z``, ``x``, ``y``), signs +1. Proper Euler sequences (``ZXZ``) are refused: they
  are singular at the zero pose, where joints spend their time.

Generic (non-clinical) joints are named by the joint, not the type: ``<joint>_<angle>_deg``
(``hinge3_angle_deg``, ``shoulder_z_deg``), so several joints of one type never share a column.

Planes: in ISB segment frames (x anterior, y proximal, z right) a rotation about z moves in the
sagittal plane, about x in the frontal plane, about y in the transverse plane.

Adding a joint type: one :class:`JointType` entry in :data:`JOINT_TYPES` plus its test
(``tests/test_joint_types.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import permutations
from typing import Any

import numpy as np

from motionlab.errors import InputError

#: the six intrinsic Tait–Bryan sequences (three different axes)
TAIT_BRYAN = tuple("".join(p) for p in permutations("XYZ"))
#: anatomical plane of a rotation about each ISB segment axis
AXIS_PLANES = {"x": "frontal", "y": "transverse", "z": "sagittal"}
#: the default hinge sequence: the hinge axis, then the other two in cyclic order
HINGE_SEQUENCES = {"x": "XYZ", "y": "YZX", "z": "ZXY"}


@dataclass(frozen=True)
class JointType:
    """One joint type (see the module docstring). Tuples hold one item per angle, in
    decomposition order."""

    name: str
    #: angle names; ``None``: from the sequence's letters (ball)
    angle_names: tuple[str, str, str] | None
    #: standard intrinsic sequence; for ``sequence_rule == "axis"`` derived from the hinge axis
    sequence: str
    #: clinical angle = sign * Euler angle, per side (``""`` for midline or side-free types)
    signs: dict[str, tuple[float, float, float]]
    #: needs side l or r
    sided: bool
    #: anatomical plane of each angle; ``None``: from the sequence's axes
    planes: tuple[str, str, str] | None
    #: what a positive value means, for axis labels
    positive: tuple[str, str, str]
    #: display name of each angle
    titles: tuple[str, str, str]
    #: one dominant flexion axis (a functional step about it fits a hinge)
    hinge: bool
    #: segment axis the distal segment turns about (relative to the proximal one) when the first
    #: angle increases; ``None``: the joint's own ``axis`` (hinge) or no such axis
    flexion_axis: str | None
    #: columns keep the clinical ``<type>_<side>_<angle>_deg`` names
    clinical: bool
    #: ``"fixed"``: only :attr:`sequence`; ``"axis"``: starts with the joint's axis; ``"any"``
    sequence_rule: str
    #: display name of the joint type (``lumbar spine``)
    display: str
    #: flexes far one way from its reference pose and hardly the other (knee, elbow): the
    #: direction of its axis is told by anatomy when calibrated from movement
    flexes_one_way: bool = False
    #: a second axis fixed in the distal segment about which it turns too (the elbow's
    #: pronation about the forearm's long axis y): calibrated from movement as a two-axis joint
    twist_axis: str | None = None
    #: no hinge and no reference pose, so in 6-D its two segments' headings are tied by the
    #: shared joint centre's acceleration (generic ball joints; the hip keeps the stand's anchors:
    #: on simulated walks the centre tie turned the pelvis by 70-100°, while anchored at the
    #: stand the hip angles do not depend on which way the pelvis sensor faces)
    centre_heading: bool = False
    #: per angle, its coordinate in OpenSim's Rajagopal (2015) model (without the side suffix)
    #: and the sign from motionlab's angle to it; ``None`` where the model has none (see
    #: :func:`opensim_coordinates`)
    opensim: tuple[tuple[str, float] | None, ...] = ()
    #: Plug-in Gait's model output of the joint without its side letter (``KneeAngles``), and
    #: how many of its X, Y, Z are motionlab's angles in order, all signs +1 (see
    #: :mod:`motionlab.validation.model_angles`)
    plugin_gait: tuple[str, int] | None = None


JOINT_TYPES: dict[str, JointType] = {
    # Grood & Suntay (1983) JCS: flexion about the femoral z, ab/adduction about the floating
    # axis, rotation about the tibial y. Euler a > 0 turns the foot forward (extension).
    "knee": JointType(
        name="knee",
        angle_names=("flexion", "adduction", "rotation"),
        sequence="ZXY",
        signs={"r": (-1.0, 1.0, 1.0), "l": (-1.0, -1.0, -1.0)},
        sided=True,
        planes=("sagittal", "frontal", "transverse"),
        positive=("flexion +", "varus +", "internal +"),
        titles=("flexion-extension", "varus-valgus (adduction)", "internal-external rotation"),
        hinge=True,
        flexion_axis="-z",
        flexes_one_way=True,
        clinical=True,
        sequence_rule="fixed",
        display="knee",
        opensim=(("knee_angle", 1.0), None, None),
        plugin_gait=("KneeAngles", 3),
    ),
    # ISB hip JCS (Wu et al. 2002, J Biomech 35:543): thigh relative to pelvis, flexion about the
    # pelvic z, ab/adduction about the floating axis, internal rotation about the femoral y.
    # Euler a > 0 turns the knee forward (flexion); b > 0 moves the knee to the left (adduction
    # of the right hip); c > 0 turns the thigh's front to the left (internal for the right hip).
    "hip": JointType(
        name="hip",
        angle_names=("flexion", "adduction", "rotation"),
        sequence="ZXY",
        signs={"r": (1.0, 1.0, 1.0), "l": (1.0, -1.0, -1.0)},
        sided=True,
        planes=("sagittal", "frontal", "transverse"),
        positive=("flexion +", "adduction +", "internal +"),
        titles=("flexion-extension", "ab-adduction", "internal-external rotation"),
        hinge=False,
        flexion_axis="z",
        clinical=True,
        sequence_rule="fixed",
        display="hip",
        opensim=(("hip_flexion", 1.0), ("hip_adduction", 1.0), ("hip_rotation", 1.0)),
        plugin_gait=("HipAngles", 3),
    ),
    # ISB (Wu et al. 2005) elbow: flexion, carrying angle, pronation-supination.
    "elbow": JointType(
        name="elbow",
        angle_names=("flexion", "carrying", "pronation"),
        sequence="ZXY",
        signs={"r": (1.0, -1.0, 1.0), "l": (1.0, 1.0, -1.0)},
        sided=True,
        planes=("sagittal", "frontal", "transverse"),
        positive=("flexion +", "valgus +", "pronation +"),
        titles=("flexion-extension", "carrying angle (valgus)", "pronation-supination"),
        hinge=True,
        flexion_axis="z",
        flexes_one_way=True,
        twist_axis="y",
        clinical=True,
        sequence_rule="fixed",
        display="elbow",
        opensim=(("elbow_flex", 1.0), None, ("pro_sup", 1.0)),
        plugin_gait=("ElbowAngles", 1),
    ),
    # Thorax relative to pelvis. Euler a > 0 turns the thorax's top backward (extension).
    "lumbar": JointType(
        name="lumbar",
        angle_names=("flexion", "lateral_bending", "axial_rotation"),
        sequence="ZXY",
        signs={"": (-1.0, 1.0, 1.0)},
        sided=False,
        planes=("sagittal", "frontal", "transverse"),
        positive=("flexion +", "to the right +", "to the left +"),
        titles=("flexion-extension", "lateral bending", "axial rotation"),
        hinge=False,
        flexion_axis="-z",
        clinical=True,
        sequence_rule="fixed",
        display="lumbar spine",
        opensim=(("lumbar_extension", -1.0), ("lumbar_bending", 1.0), ("lumbar_rotation", 1.0)),
    ),
    # The trunk's lean relative to a wheelchair (wheelchair-seating studies): the joint is
    # written chair relative to thorax (proximal thorax, distal chair), so that the thorax,
    # already the lumbar joint's distal segment, keeps one heading; R_chair/thorax = Ry(-c)
    # Rx(-b) Rz(-a) of the thorax's Rz(a) Rx(b) Ry(c) relative to the chair, hence the YXZ
    # sequence and the signs: forward lean (the thorax's flexion about the chair's z) +,
    # sideways lean to the right +, rotation to the left +, as the lumbar angles.
    "trunk_lean": JointType(
        name="trunk_lean",
        angle_names=("rotation", "sideways", "forward"),
        sequence="YXZ",
        signs={"": (-1.0, -1.0, 1.0)},
        sided=False,
        planes=("transverse", "frontal", "sagittal"),
        positive=("to the left +", "to the right +", "forward +"),
        titles=(
            "trunk rotation against the chair",
            "sideways trunk lean against the chair",
            "forward trunk lean against the chair",
        ),
        hinge=False,
        flexion_axis=None,
        clinical=True,
        sequence_rule="fixed",
        display="trunk against the chair",
    ),
    # ISB ankle joint complex (Wu et al. 2002, J Biomech 35:543): foot relative to shank,
    # dorsiflexion about the tibial z, inversion about the floating axis, internal rotation about
    # the foot's y. Euler a > 0 lifts the toes; b > 0 tilts the foot's top to the right
    # (inversion of the right foot); c > 0 turns the toes to the left (internal for the right).
    "ankle": JointType(
        name="ankle",
        angle_names=("dorsiflexion", "inversion", "rotation"),
        sequence="ZXY",
        signs={"r": (1.0, 1.0, 1.0), "l": (1.0, -1.0, -1.0)},
        sided=True,
        planes=("sagittal", "frontal", "transverse"),
        positive=("dorsiflexion +", "inversion +", "internal +"),
        titles=("dorsi-plantarflexion", "inversion-eversion", "internal-external rotation"),
        hinge=True,
        flexion_axis="z",
        clinical=True,
        sequence_rule="fixed",
        display="ankle",
        opensim=(("ankle_angle", 1.0), None, None),
        plugin_gait=("AnkleAngles", 1),
    ),
    "hinge": JointType(
        name="hinge",
        angle_names=("angle", "off_axis_1", "off_axis_2"),
        sequence="ZXY",  # for axis z; see HINGE_SEQUENCES
        signs={"": (1.0, 1.0, 1.0)},
        sided=False,
        planes=None,
        positive=("about the hinge axis +", "about the floating axis +", "about the distal axis +"),
        titles=("hinge angle", "off-axis angle 1", "off-axis angle 2"),
        hinge=True,
        flexion_axis=None,
        clinical=False,
        sequence_rule="axis",
        display="hinge",
    ),
    "ball": JointType(
        name="ball",
        angle_names=None,
        sequence="ZXY",
        signs={"": (1.0, 1.0, 1.0)},
        sided=False,
        planes=None,
        positive=("+", "+", "+"),
        titles=("first rotation", "second rotation", "third rotation"),
        hinge=False,
        flexion_axis=None,
        clinical=False,
        sequence_rule="any",
        display="ball joint",
        centre_heading=True,
    ),
}


def joint_type(name: str) -> JointType:
    """The :class:`JointType` called ``name``; :class:`InputError` for an unknown type."""
    if name not in JOINT_TYPES:
        raise InputError(
            f"unknown joint type {name!r}",
            where="joint type",
            remedy=f"use one of {', '.join(JOINT_TYPES)}",
        )
    return JOINT_TYPES[name]


def _axis(joint: Any) -> str | None:
    axis = getattr(joint, "axis", None)
    return axis.strip().lstrip("+") if axis else None


def sequence_problem(type_name: str, sequence: str | None, axis: str | None) -> str | None:
    """Why ``sequence`` (``None``/``""``: the default) and ``axis`` do not suit the type, or None.

    The one check the protocol loader and :func:`resolve_sequence` share.
    """
    jt = joint_type(type_name)
    letters = (axis or "").strip().lstrip("+-")
    if jt.sequence_rule == "axis":
        if letters not in HINGE_SEQUENCES:
            return f"a {jt.name} joint needs axis: x, y, z, -x, -y or -z, got {axis!r}"
    elif axis:
        return f"a {jt.name} joint takes no axis (only a hinge joint does)"
    if not sequence:
        return None
    if sequence not in TAIT_BRYAN:
        return (
            f"sequence {sequence!r} is not an intrinsic Tait-Bryan sequence "
            f"({', '.join(TAIT_BRYAN)})"
        )
    if jt.sequence_rule == "fixed" and sequence != jt.sequence:
        return f"a {jt.name} joint is decomposed {jt.sequence} only, got {sequence!r}"
    if jt.sequence_rule == "axis" and sequence[0] != letters.upper():
        return f"a hinge about {axis} needs a sequence starting with {letters.upper()}"
    return None


def resolve_sequence(type_name: str, sequence: str | None = None, axis: str | None = None) -> str:
    """The sequence a joint is decomposed with; :class:`InputError` when it does not suit."""
    problem = sequence_problem(type_name, sequence, axis)
    if problem:
        raise InputError(problem, where="joint sequence", remedy="fix the protocol's joint")
    jt = joint_type(type_name)
    if sequence:
        return sequence
    if jt.sequence_rule == "axis":
        return HINGE_SEQUENCES[(axis or "").strip().lstrip("+-")]
    return jt.sequence


def joint_sequence(joint: Any) -> str:
    """The sequence of a :class:`~motionlab.protocol.Joint` (its own, else the type's)."""
    return resolve_sequence(joint.type, getattr(joint, "sequence", "") or None, _axis(joint))


def names_for(type_name: str, sequence: str | None = None) -> tuple[str, str, str]:
    """Angle names of a type decomposed with ``sequence`` (ball: its letters, lower case)."""
    jt = joint_type(type_name)
    if jt.angle_names is not None:
        return jt.angle_names
    seq = sequence or jt.sequence
    return (seq[0].lower(), seq[1].lower(), seq[2].lower())


def angle_names(joint: Any) -> tuple[str, str, str]:
    """Angle names of a :class:`~motionlab.protocol.Joint`, in decomposition order."""
    return names_for(joint.type, joint_sequence(joint))


def normal_side(type_name: str, side: str) -> str:
    """``'r'``/``'l'`` for sided types, ``''`` otherwise; :class:`InputError` for a missing side."""
    jt = joint_type(type_name)
    if not jt.sided:
        return ""
    side = {"left": "l", "right": "r"}.get(side, side)
    if side not in ("l", "r"):
        raise InputError(
            f"a {jt.name} joint needs side 'l' or 'r', got {side!r}",
            where="joint side",
            remedy="set side: l or side: r in the protocol's joint",
        )
    return side


def signs_for(type_name: str, side: str = "", axis: str | None = None) -> np.ndarray:
    """(3,) clinical sign per Euler angle; a hinge about a negative axis flips its first angle."""
    signs = np.array(joint_type(type_name).signs[normal_side(type_name, side)], dtype=float)
    if axis and axis.strip().startswith("-"):
        signs[0] = -signs[0]
    return signs


def column_name(type_name: str, side: str, angle: str, joint_name: str = "") -> str:
    """CSV column of one angle.

    Clinical types: ``knee_r_flexion_deg``, ``lumbar_flexion_deg`` (no side for midline types);
    generic types: ``<joint_name>_<angle>_deg`` (``hinge3_angle_deg``).
    """
    jt = joint_type(type_name)
    if not jt.clinical:
        return f"{joint_name or type_name}_{angle}_deg"
    if not jt.sided or not side:
        return f"{type_name}_{angle}_deg"
    return f"{type_name}_{side}_{angle}_deg"


def angle_columns(joint: Any) -> list[tuple[str, str]]:
    """``[(angle name, column), ...]`` of a :class:`~motionlab.protocol.Joint`, in
    decomposition order. The one place angle columns are named."""
    return [(a, column_name(joint.type, joint.side, a, joint.name)) for a in angle_names(joint)]


def flexion_axis(joint: Any) -> str | None:
    """Segment axis (``'-z'``) about which the first angle turns the distal segment positively:
    the type's :attr:`JointType.flexion_axis`, or a hinge joint's own axis."""
    jt = joint_type(joint.type)
    if jt.sequence_rule == "axis":
        return _axis(joint)
    return jt.flexion_axis


def plane(joint: Any, angle: str) -> str:
    """Anatomical plane of one angle of a joint (from the table, else the sequence's axis)."""
    names = angle_names(joint)
    if angle not in names:
        return ""
    i = names.index(angle)
    jt = joint_type(joint.type)
    if jt.planes is not None:
        return jt.planes[i]
    return AXIS_PLANES[joint_sequence(joint)[i].lower()]


def positive(joint: Any, angle: str) -> str:
    """What a positive value of one angle means, for axis labels (``varus +``)."""
    names = angle_names(joint)
    if angle not in names:
        return ""
    jt = joint_type(joint.type)
    i = names.index(angle)
    if jt.sequence_rule == "axis" and i == 0:
        return f"about {flexion_axis(joint)} +"
    if jt.angle_names is None:
        return f"about +{angle} +"
    return jt.positive[i]


def title(type_name: str, angle: str) -> str:
    """Display name of one angle of a type (``varus-valgus (adduction)``); the name itself when
    the type does not know it."""
    jt = JOINT_TYPES.get(type_name)
    if jt is None:
        return angle
    if jt.angle_names is None:
        return f"rotation about {angle}"
    return jt.titles[jt.angle_names.index(angle)] if angle in jt.angle_names else angle


def opensim_coordinates() -> dict[str, tuple[str, float]]:
    """Angle column → (OpenSim coordinate of the Rajagopal 2015 model, sign), from
    :attr:`JointType.opensim`: ``knee_r_flexion_deg`` → ``("knee_angle_r", 1.0)``.

    Both use ISB-like frames (x anterior, y up, z right) and mirror the left side, so the signs
    agree except lumbar flexion (Rajagopal's ``lumbar_extension`` turns the torso backward about
    +z). Rajagopal's ``knee_angle`` is positive in flexion (gait2392's is negative), its
    ``ankle_angle`` in dorsiflexion; positive ``lumbar_bending`` bends to the right and
    ``lumbar_rotation`` turns to the left, as motionlab's; ``pro_sup`` is positive in pronation,
    ``elbow_flex`` in flexion. The knee's and ankle's other angles have no coordinate (one degree
    of freedom each in the model)."""
    out = {}
    for jt in JOINT_TYPES.values():
        for side in ("r", "l") if jt.sided else ("",):
            for angle, target in zip(jt.angle_names or (), jt.opensim, strict=False):
                if target is not None:
                    name = f"{target[0]}_{side}" if side else target[0]
                    out[column_name(jt.name, side, angle)] = (name, target[1])
    return out


def split_column(column: str) -> tuple[str, str]:
    """``knee_r_flexion_deg`` → ``("knee_r", "flexion")``, ``hinge3_off_axis_1_deg`` →
    ``("hinge3", "off_axis_1")``, ``shoulder_z_deg`` → ``("shoulder", "z")``; else
    ``(stem, "")``. Clinical names are tried first."""
    stem = column.removesuffix("_deg")
    for jt in JOINT_TYPES.values():
        if jt.clinical and jt.angle_names:
            for name in jt.angle_names:
                if stem.startswith(jt.name) and stem.endswith("_" + name):
                    return stem[: -len(name) - 1], name
    generic = [n for jt in JOINT_TYPES.values() if not jt.clinical for n in jt.angle_names or "xyz"]
    for name in generic:
        if stem.endswith("_" + name) and len(stem) > len(name) + 1:
            return stem[: -len(name) - 1], name
    return stem, ""
