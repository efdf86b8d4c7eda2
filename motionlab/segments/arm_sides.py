"""Arms swapped left for right in the sensor map: an elbow's carrying angle in the stand.

An elbow's frames are mirrored by its side (ISB: z to the subject's right on both arms, so the
carrying angle is valgus-positive on either side), and the stand and the free movement that
calibrate the ``arm`` protocol are the same for a left arm as for a right one: a left arm's
sensors mapped as the right arm's run through, their flexion right, and every finding put on
the other side. The one angle that tells the two arms apart is the carrying angle: with the
elbow straight an adult's forearm points 5-15° away from the body (valgus; MedlinePlus Medical
Encyclopedia, "Carrying angle of the elbow - excessive"; under that, cubitus varus, a
deformity after a fracture). Mirrored, it reads as varus, its sign turned.

Measured (simulated ``arm`` sessions, ``skin`` preset, random mountings, seeds 0-9; each
elbow's median carrying angle over the stand): +7.0 to +14.5° as mapped, −7.0 to −14.5° with
both arms' sensors swapped, every other angle the same; the median over the free movement
+2.6 to +10.6° and its negative. The real 16-IMU recording's elbows are ``not determined``
(docs/kinematics.md), so no real elbow has tested this; the threshold leaves 12° between the
simulated elbows' lowest stand value and it. The clinical ``elbow`` protocol refuses swapped
arms already (its steps move the arm the sensors are not on).

An elbow whose carrying angle reads more than :data:`CARRYING_VARUS_DEG` varus in its reference
pose, its flexion axis found (not ``not determined``), has every angle ``weak`` at best, saying
why; a warning names its sensors, or, both elbows so, the arms.
"""

from __future__ import annotations

import numpy as np

from motionlab.binding import sensor_for_segment
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.kinematics.joint_types import angle_columns, joint_type
from motionlab.protocol import Protocol
from motionlab.results import JointGrades, SegmentCalibration
from motionlab.rotations import resample
from motionlab.segments import grades as grading
from motionlab.segments.sensors import SegmentQuats
from motionlab.segments.steps import reference_step
from motionlab.session import Session

#: an elbow whose carrying angle in its reference pose reads more varus than this (deg) looks
#: mirrored: its sensors on the other arm (module notes)
CARRYING_VARUS_DEG = 5.0


def pose_carrying(
    protocol: Protocol, calibration: SegmentCalibration, seg_q: SegmentQuats
) -> dict[str, tuple[str, float]]:
    """Per elbow joint with a reference pose in ``calibration.steps`` (the stand, its upper arm
    vertical): the pose's name and the median carrying angle (deg, valgus positive) over it,
    from the segment orientations ``seg_q`` (:func:`motionlab.segments.segment_orientations`)."""
    out = {}
    for name, joint in protocol.joints.items():
        if joint_type(joint.type).name != "elbow" or not {joint.proximal, joint.distal} <= set(
            seg_q
        ):
            continue
        step = reference_step(protocol, joint.proximal, joint.distal)
        span = calibration.steps.get(step) if step else None
        if not span:
            continue
        t = seg_q[joint.proximal][0]
        t = t[(t >= span[0]) & (t <= span[1])]
        if len(t) < 2:
            continue
        qp, qd = (resample(*seg_q[seg], t) for seg in (joint.proximal, joint.distal))
        carrying = joint_angles(qp, qd, joint)[angle_columns(joint)[1][1]]  # the second angle
        if np.isfinite(carrying).any():
            out[name] = (step, float(np.nanmedian(carrying)))
    return out


def _varus(graded: dict[str, JointGrades], carrying: dict[str, tuple[str, float]]) -> dict:
    """The elbows of ``carrying`` reading varus beyond the threshold whose flexion axis was
    found: ``{joint: (pose, deg)}``."""
    return {
        name: (step, deg)
        for name, (step, deg) in carrying.items()
        if deg < -CARRYING_VARUS_DEG
        and name in graded
        and graded[name].grades[:1] != ["not determined"]
    }


def _why(step: str, deg: float) -> str:
    """Why an elbow reading ``deg`` (deg, valgus positive) in pose ``step`` is in doubt."""
    return (
        f"the carrying angle reads {-deg:.0f}° varus in the {step} pose, where an elbow is "
        "5-15° valgus: the arm's sensors look swapped left for right (or the elbow is in varus)"
    )


def side_graded(
    graded: dict[str, JointGrades], carrying: dict[str, tuple[str, float]]
) -> dict[str, JointGrades]:
    """``graded`` with every angle of an elbow whose carrying angle reads varus in its
    reference pose (``carrying``, :func:`pose_carrying`) ``weak`` at best (module notes)."""
    out = dict(graded)
    for name, (step, deg) in _varus(graded, carrying).items():
        out[name] = grading.lowered(out[name], ["weak"] * len(out[name].grades), _why(step, deg))
    return out


def side_warnings(
    session: Session,
    protocol: Protocol,
    graded: dict[str, JointGrades],
    carrying: dict[str, tuple[str, float]],
) -> list[str]:
    """The lines that tell the user the arms' sensors look swapped (module notes): one for
    both elbows, else one per elbow naming its sensors."""
    varus = _varus(graded, carrying)
    if not varus:
        return []
    elbows = [n for n, j in protocol.joints.items() if joint_type(j.type).name == "elbow"]
    if len(varus) >= 2 and len(varus) == len(elbows):
        read = ", ".join(f"{name} {-deg:.0f}°" for name, (_, deg) in varus.items())
        step = next(iter(varus.values()))[0]
        return [
            f"both elbows read varus in the {step} pose ({read}), where elbows are 5-15° "
            "valgus: the arms' sensors look swapped left for right: swap the sides of the arm "
            "sensors in the sensor map (right <-> left) and start again from ingest"
        ]
    lines = []
    for name, (step, deg) in varus.items():
        joint = protocol.joints[name]
        labels = [sensor_for_segment(session, s) for s in (joint.proximal, joint.distal)]
        lines.append(
            f"{name}: {_why(step, deg)}: are {labels[0]} and {labels[1]} on the "
            f"{'right' if joint.side == 'r' else 'left'} arm?"
        )
    return lines
