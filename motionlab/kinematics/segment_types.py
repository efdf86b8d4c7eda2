"""The table of segment kinds: every fact about a body segment in one place (:data:`SEGMENT_TYPES`).

A protocol names its segments by kind and side: ``thigh_r``, ``upperarm_l``; midline kinds have
no side (``pelvis``, ``thorax``). A sensor map may write the kind and the side apart (segment
``thigh``, side ``r`` or ``right``). :func:`kind_side` splits a segment name, :func:`segment_type`
finds its kind through the aliases other tools use (``upper_arm``, ``trunk``).

Each kind knows its OpenSim body, the body of OpenSim's gait and upper-limb models (Rajagopal et
al. 2016, IEEE TBME 63:2068; gait2392) that OpenSense names an IMU after: ``<body>_<side>_imu``
for a sided kind (``tibia_r_imu``), ``<body>_imu`` for a midline one (``torso_imu``), so
that a segment without an OpenSim body (the lumbar sensor, a wheelchair) keeps its sensor label.
Plug-in Gait names its outputs by the joint (``RKneeAngles``), so its names are in the joint table
(:attr:`motionlab.kinematics.joint_types.JointType.plugin_gait`).

Adding a segment kind: one :class:`SegmentType` entry in :data:`SEGMENT_TYPES` plus its line in
``tests/test_segment_types.py``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SegmentType:
    """One segment kind (see the module docstring)."""

    name: str
    #: has a left and a right (``thigh_r``, ``thigh_l``); midline kinds have none
    sided: bool
    #: other names of the kind in other tools' files (``upper_arm``)
    aliases: tuple[str, ...] = ()
    #: OpenSim body without its side suffix (``femur`` for ``femur_r``); ``None``: none
    opensim: str | None = None


SEGMENT_TYPES: dict[str, SegmentType] = {
    t.name: t
    for t in (
        SegmentType("pelvis", sided=False, opensim="pelvis"),
        SegmentType("lumbar", sided=False),
        SegmentType("thorax", sided=False, aliases=("trunk",), opensim="torso"),
        SegmentType("head", sided=False),
        SegmentType("thigh", sided=True, opensim="femur"),
        SegmentType("shank", sided=True, opensim="tibia"),
        SegmentType("foot", sided=True, opensim="calcn"),
        SegmentType("upperarm", sided=True, aliases=("upper_arm",), opensim="humerus"),
        SegmentType("forearm", sided=True, opensim="radius"),
        SegmentType("hand", sided=True, opensim="hand"),
        SegmentType("chair", sided=False),
    )
}

_BY_NAME = {n: t for t in SEGMENT_TYPES.values() for n in (t.name, *t.aliases)}


def kind_side(segment: str) -> tuple[str, str]:
    """``'thigh_r'`` → ``('thigh', 'r')``; ``'pelvis'`` → ``('pelvis', '')``."""
    if segment[-2:] in ("_l", "_r"):
        return segment[:-2], segment[-1]
    return segment, ""


def segment_type(kind: str) -> SegmentType | None:
    """The :class:`SegmentType` of a kind or one of its aliases (``upper_arm``), else ``None``."""
    return _BY_NAME.get(kind)


def segment_of_opensim_imu(name: str) -> tuple[str, str] | None:
    """``(segment kind, side)`` of an OpenSense IMU name (``tibia_r_imu`` → ``('shank',
    'r')``, ``torso_imu`` → ``('thorax', '')``): the inverse of :func:`opensim_imu_name`;
    ``None`` for any other name."""
    stem = name.strip().lower().removesuffix("_imu")
    if stem == name.strip().lower():
        return None
    body, side = kind_side(stem)
    for st in _BY_NAME.values():
        if st.opensim == body and (side == "") != st.sided:
            return st.name, side
    return None


def opensim_imu_name(segment: str, side: str = "") -> str | None:
    """OpenSense's name of the IMU on ``segment`` (``upperarm_r``, or ``upperarm`` with ``side``
    ``r``/``right``): ``humerus_r_imu``, ``torso_imu``; ``None`` when the kind has no OpenSim
    body."""
    kind, own_side = kind_side(segment)
    side = own_side or {"right": "r", "left": "l"}.get(side, side)
    st = segment_type(kind)
    if st is None or st.opensim is None:
        return None
    if st.sided and side in ("r", "l"):
        return f"{st.opensim}_{side}_imu"
    return f"{st.opensim}_imu"
