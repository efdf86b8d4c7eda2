"""What a stand-and-walk recording (the ``walk`` protocol: poses, then walking only) must show
before its calibration is trusted: a stand that is a stand, and thigh and shank sensors the
right way round.

- **The stand.** The sensor-to-segment placement is a hint, so the static step is the first rest
  long enough (:mod:`.steps`), and a recording without a stand before its walk used to hand that
  step its seated rest: the thighs horizontal, taken as upright. Walking, each leg segment and
  the pelvis swing about the direction they have in a stand (the thigh's mean flexion over a
  stride is 10-15°), so the mean of each segment's up direction over the movement after the
  pose (its sensor frame, from the fused orientation) lies close to the pose's: 2-19° on the
  real 16-IMU walk (pelvis 2°, thighs 14-16°, shanks 16-19°), where its seated rest taken as the
  stand gives the thighs 66-69°. A rest beyond ``STAND_WALK_DEG`` is passed over for a later
  one (a recording that starts seated, stands up, stands and walks), and with none the step is
  missing: one line naming the rest and why.
- **Thigh and shank swapped** (:class:`.gait_axes.SwappedSensors`): the refusal names both
  sensors and their map keys.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.protocol import CalibrationStep, Protocol, axis_vector
from motionlab.segments import gait_axes
from motionlab.segments.sensors import Streams, sensor_orientation
from motionlab.segments.steps import PoseCheck
from motionlab.session import Session

#: largest angle (deg) between a segment's up in the stand and its mean up while moving after it
STAND_WALK_DEG = 40.0
#: a sample moves when its sensor turns faster than this (rad/s, about 30 °/s)
MOVING_RAD_S = 0.5
#: fewest moving samples after the stand for the check
MIN_MOVING = 200


def stand_and_walk(protocol: Protocol) -> bool:
    """Whether the protocol's recording is poses and walking only (the ``walk`` protocol): then
    the movement a knee's axes come from is the walk's swings, where a thigh turns slower than
    its shank. Not where other tasks or functional steps move the leg too (the ``knee``
    protocol's hip flexions turn the thigh twice as fast as the shank)."""
    return (
        bool(protocol.tasks)
        and all(task.is_gait for task in protocol.tasks)
        and all(step.kind == "static" for step in protocol.calibration)
    )


def stand_tilts(
    session: Session, protocol: Protocol, streams: Streams, step: str, span: tuple[float, float]
) -> dict[str, float]:
    """Per segment with a vertical axis in static ``step`` (a rest at ``span``, s): the angle
    (deg) between its sensor's up in the rest and its mean up over the moving samples after it;
    NaN where fewer than ``MIN_MOVING`` samples move after it. Sensors with orientations only
    (no rates of their own) are left out."""
    spec = next(s for s in protocol.calibration if s.name == step)
    out = {}
    for seg in spec.vertical_axis:
        label = sensor_for_segment(session, seg)
        if seg not in streams or label is None or session.sensors[label].gyr is None:
            continue
        t, _, gyr = streams[seg]
        q = sensor_orientation(session, label)
        if len(q) != len(t):  # an orientation-only sensor: no rates of its own to judge by
            continue
        up = rot.rotate(rot.conj(q), axis_vector("z"))
        pose = (t >= span[0]) & (t <= span[1])
        moving = (t > span[1]) & (np.linalg.norm(gyr, axis=1) > MOVING_RAD_S)
        moving &= np.isfinite(up).all(axis=1)
        if pose.sum() < 2:
            continue
        if moving.sum() < MIN_MOVING:  # no walk after the rest
            out[seg] = float("nan")
            continue
        a, b = (rot.normalize(np.nanmean(up[sel], axis=0)) for sel in (pose, moving))
        out[seg] = float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))
    return out


def pose_check(session: Session, protocol: Protocol, streams: Streams) -> PoseCheck | None:
    """For a stand-and-walk recording, the check :func:`.steps.find_steps` asks of a rest
    before taking it for a static step (module notes): why it is no stand, or None. None for
    other protocols."""
    if not stand_and_walk(protocol):
        return None

    def check(step: CalibrationStep, span: tuple[float, float]) -> str | None:
        tilts = stand_tilts(session, protocol, streams, step.name, span)
        if tilts and all(np.isnan(d) for d in tilts.values()):
            return f"the rest at {span[0]:.1f}-{span[1]:.1f} s has no walk after it"
        off = {seg: deg for seg, deg in tilts.items() if deg > STAND_WALK_DEG}
        if not off:
            return None
        segs = ", ".join(f"{seg} {deg:.0f}°" for seg, deg in off.items())
        return (
            f"the rest at {span[0]:.1f}-{span[1]:.1f} s is no {step.pose} pose: the segments "
            f"lie far from where they point while moving after it ({segs}; after a stand under "
            f"{STAND_WALK_DEG:.0f}°), as after a seated rest"
        )

    return check


def swapped(session: Session, proximal: str, distal: str, ratio: float) -> InputError:
    """The refusal of a thigh (``proximal``) and a shank (``distal``) whose sensors turn the wrong
    way round over the walk (:class:`.gait_axes.SwappedSensors`), naming their map keys."""
    lo, hi = gait_axes.REAL_WALK_SPEED_RATIO
    names = []
    for seg in (proximal, distal):
        label = sensor_for_segment(session, seg)
        key = session.sensors[label].attrs.get("map_key", label) if label else seg
        names.append(f"{seg}'s sensor {label}" + (f" (map key {key})" if key != label else ""))
    return InputError(
        f"{names[0]} turns {ratio:.1f} times as fast over the walk as {names[1]}, where a shank "
        f"turns faster than its thigh (real walks: {lo:.2f}-{hi:.2f} times): the two look swapped",
        where="the sensor map",
        remedy="swap the two sensors' segments in the sensor map (or the sensors on the leg) "
        "and start again from ingest",
    )
