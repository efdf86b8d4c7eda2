"""What the arm's stand must show: arms on their own side and forearms hanging.

**Arms swapped left for right in the sensor map**: an elbow's carrying angle in the stand.

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

**A forearm that does not hang in the stand.** The ``arm`` protocol's stand is the first rest
long enough whatever its pose (the sensors' placement is a hint), and it is every elbow angle's
zero: a recording that starts seated with the hands in the lap had that rest taken for the
stand, and its elbow flexion read 70-111° off the truth (RMSE, simulated seed 1, elbows at 90°
in the lap), graded ``weak``, with a warning that the arms looked swapped. The free movement
measures each forearm's long axis in its sensor (the two-axis fit's pronation axis,
:func:`motionlab.segments.movement.fit_two_dof`); carried by the forearm sensor's orientation
over the stand it hangs within the carrying angle of the vertical: 7.7-14.1° on the simulated
``arm`` sessions (seeds 0-9, ``skin`` preset; the simulator's carrying angle is 10°), an
adult's carrying angle 5-15° (above) plus a relaxed elbow's few degrees of flexion; in the lap
80-81°, elbows at 60° 50°, at 30° 22-23°. Beyond :data:`HANGING_MAX_DEG` the elbow's angles are
``not determined`` (their zero is not the anatomical pose), the carrying-angle check above is
not made for it, and a warning says what to record.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.kinematics.joint_types import angle_columns, joint_type
from motionlab.protocol import Protocol
from motionlab.results import JointGrades, SegmentCalibration, TwoAxisFit
from motionlab.rotations import resample
from motionlab.segments import grades as grading
from motionlab.segments.sensors import SegmentQuats, sensor_orientation
from motionlab.segments.steps import reference_step
from motionlab.session import Session

#: an elbow whose carrying angle in its reference pose reads more varus than this (deg) looks
#: mirrored: its sensors on the other arm (module notes)
CARRYING_VARUS_DEG = 5.0
#: a forearm whose long axis lies further than this (deg) from the vertical in the reference
#: pose does not hang: the pose is no stand with the arms by the sides (module notes)
HANGING_MAX_DEG = 40.0


def _elbow_spans(protocol: Protocol, calibration: SegmentCalibration):
    """``(joint name, joint, reference step, its span s)`` of every elbow whose reference pose
    ``calibration.steps`` found."""
    for name, joint in protocol.joints.items():
        if joint_type(joint.type).name != "elbow":
            continue
        step = reference_step(protocol, joint.proximal, joint.distal)
        span = calibration.steps.get(step) if step else None
        if span:
            yield name, joint, step, span


def pose_hanging(
    session: Session, protocol: Protocol, calibration: SegmentCalibration
) -> dict[str, tuple[str, float]]:
    """Per elbow with a two-axis fit from the movement and a reference pose: the pose's name
    and the angle (deg) between the vertical and the forearm's long axis (the fit's pronation
    axis in the forearm sensor, carried by that sensor's orientation, averaged over the pose):
    how far the forearm lies from hanging (module notes)."""
    out = {}
    for name, joint, step, span in _elbow_spans(protocol, calibration):
        fit = calibration.hinges.get(name)
        label = sensor_for_segment(session, joint.distal)
        if not isinstance(fit, TwoAxisFit) or fit.verdict == "not determined" or label is None:
            continue
        t, q = session.sensors[label].time, sensor_orientation(session, label)
        if len(q) != len(t):  # orientations on another time base: nothing to read the pose on
            continue
        pose = (t >= span[0]) & (t <= span[1]) & np.isfinite(q).all(axis=1)
        if pose.sum() < 2:
            continue
        axis = rot.rotate(q[pose], np.broadcast_to(fit.axis_distal, (int(pose.sum()), 3)))
        mean = axis.mean(axis=0)
        up = abs(float(mean[2])) / float(np.linalg.norm(mean))
        out[name] = (step, float(np.degrees(np.arccos(min(up, 1.0)))))
    return out


def _not_hanging(hanging: dict[str, tuple[str, float]]) -> dict[str, tuple[str, float]]:
    """The elbows of ``hanging`` whose forearm lies beyond :data:`HANGING_MAX_DEG`."""
    return {name: v for name, v in hanging.items() if v[1] > HANGING_MAX_DEG}


def hanging_only(
    carrying: dict[str, tuple[str, float]], hanging: dict[str, tuple[str, float]]
) -> dict[str, tuple[str, float]]:
    """``carrying`` without the elbows whose forearm does not hang: their pose says nothing of
    the arm's side."""
    return {k: v for k, v in carrying.items() if k not in _not_hanging(hanging)}


def _hang_why(step: str, deg: float) -> str:
    return (
        f"the forearm lies {deg:.0f}° from hanging in the {step} pose (a straight arm hanging "
        f"by the side: under {HANGING_MAX_DEG:.0f}°): the angles' zero is not the anatomical "
        "pose"
    )


def hang_graded(
    graded: dict[str, JointGrades], hanging: dict[str, tuple[str, float]]
) -> dict[str, JointGrades]:
    """``graded`` with every angle of an elbow whose forearm does not hang in its reference
    pose (``hanging``, :func:`pose_hanging`) ``not determined`` (module notes)."""
    whys = {name: _hang_why(step, deg) for name, (step, deg) in _not_hanging(hanging).items()}
    return _lowered_all(graded, whys, "not determined")


def hang_warnings(
    protocol: Protocol, calibration: SegmentCalibration, hanging: dict[str, tuple[str, float]]
) -> list[str]:
    """One line per elbow whose forearm does not hang in its reference pose, saying what to
    record."""
    spans = {name: span for name, _, _, span in _elbow_spans(protocol, calibration)}
    lines = []
    for name, (step, deg) in _not_hanging(hanging).items():
        span = spans[name]
        lines.append(
            f"{name}: {_hang_why(step, deg)}; the rest at {span[0]:.1f}-{span[1]:.1f} s was taken "
            f"for it (seated, the hands in the lap?): record the {step} pose for 5 s, arms "
            "hanging by the sides, elbows straight, palms forward"
        )
    return lines


def pose_carrying(
    protocol: Protocol, calibration: SegmentCalibration, seg_q: SegmentQuats
) -> dict[str, tuple[str, float]]:
    """Per elbow joint with a reference pose in ``calibration.steps`` (the stand, its upper arm
    vertical): the pose's name and the median carrying angle (deg, valgus positive) over it,
    from the segment orientations ``seg_q`` (:func:`motionlab.segments.segment_orientations`)."""
    out = {}
    for name, joint, step, span in _elbow_spans(protocol, calibration):
        if not {joint.proximal, joint.distal} <= set(seg_q):
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
    whys = {name: _why(step, deg) for name, (step, deg) in _varus(graded, carrying).items()}
    return _lowered_all(graded, whys, "weak")


def _lowered_all(
    graded: dict[str, JointGrades], whys: dict[str, str], grade: str
) -> dict[str, JointGrades]:
    """``graded`` with every angle of each joint of ``whys`` ``grade`` at best, its reason
    added (:func:`motionlab.segments.grades.lowered`)."""
    out = dict(graded)
    for name, why in whys.items():
        if name in out:
            out[name] = grading.lowered(out[name], [grade] * len(out[name].grades), why)
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
