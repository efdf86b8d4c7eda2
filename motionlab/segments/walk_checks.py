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
  missing: one line naming the rest and why. A rest with no walk after it is judged against
  the walk before it: a walk that ends with its stand (:func:`.steps.task_window` then puts
  the walk before the stand).
- **Thigh and shank swapped** (:class:`.gait_axes.SwappedSensors`): the refusal names both
  sensors and their map keys.
- **Legs swapped left for right** (:func:`sides_check`): each knee's fit holds, its flexion is
  right, and the report would put every finding on the other side. Walking, the body's centre
  passes over the stance foot, and through single support the ground pushes it back towards the
  other foot (Winter 2009, Biomechanics and Motor Control of Human Movement: the mediolateral
  ground reaction force is medial through most of stance), so the pelvis accelerates towards the
  swinging leg while that leg's shank turns fastest. The correlation of the pelvis sensor's
  sideways acceleration (towards the pelvis's right, from its calibrated frame) with the right
  shank's angular speed less the left's, both low-passed at ``SIDES_LOWPASS_HZ`` and taken
  less their ``SIDES_DETREND_S`` means (turns, biases), over the walk: +0.37 to +0.69 in 6-s
  windows of the real 16-IMU walk (+0.50 over all of it), +0.54 to +0.91 on simulated walks
  (seeds 0-5, ``bench/gait_pelvis.py``), the negative of these with the legs swapped in the map.
  Below ``SIDES_CORR`` the recording is refused, naming the shanks' sensors; the thighs say
  nothing reliable (their speed peaks in a different part of the stride on real and simulated
  walks: -0.50 and -0.06 to +0.43). The walker's right comes from the pelvis frame, so the
  check runs only where its forward direction is sure (:func:`sides_check`): a forward
  direction 180° off reads as legs swapped.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.protocol import CalibrationStep, Protocol, axis_vector
from motionlab.results import SegmentRecord
from motionlab.segments import gait_axes
from motionlab.segments.sensors import Streams, sensor_orientation
from motionlab.segments.steps import PoseCheck, stand_and_walk
from motionlab.session import Session, estimate_rate
from motionlab.timebase import interp_columns

#: largest angle (deg) between a segment's up in the stand and its mean up while moving after it
STAND_WALK_DEG = 40.0
#: a sample moves when its sensor turns faster than this (rad/s, about 30 °/s)
MOVING_RAD_S = 0.5
#: fewest moving samples after the stand for the check
MIN_MOVING = 200
#: the legs are refused as swapped below this correlation of the pelvis's sideways acceleration
#: with the shanks' swing (module notes; real walks +0.37 to +0.69, swapped the negative) …
SIDES_CORR = -0.2
#: … over at least this much walking (s; the real walk's 6-s windows all gave +0.37 or more)
SIDES_MIN_S = 6.0
SIDES_LOWPASS_HZ = 3.0  # the stride's first harmonics; impacts and soft tissue above
SIDES_DETREND_S = 2.0  # about two strides: turns and accelerometer biases are slower
#: walking: both shanks' angular speeds summed above this (rad/s; a walking shank swings at
#: 4-7 rad/s)
SIDES_WALKING_RAD_S = 2.0


def stand_tilts(
    session: Session, protocol: Protocol, streams: Streams, step: str, span: tuple[float, float]
) -> dict[str, float]:
    """Per segment with a vertical axis in static ``step`` (a rest at ``span``, s): the angle
    (deg) between its sensor's up in the rest and its mean up over the moving samples after it,
    or before it where fewer than ``MIN_MOVING`` move after it (a stand that ends the walk);
    NaN where neither has that many. Sensors with orientations only (no rates of their own)
    are left out."""
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
        fast = (np.linalg.norm(gyr, axis=1) > MOVING_RAD_S) & np.isfinite(up).all(axis=1)
        moving = fast & (t > span[1])
        if moving.sum() < MIN_MOVING:  # no walk after the rest: the walk before a stand
            moving = fast & (t < span[0])
        if pose.sum() < 2:
            continue
        if moving.sum() < MIN_MOVING:  # no walk after the rest, nor before it
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
            return f"the rest at {span[0]:.1f}-{span[1]:.1f} s has no walk after or before it"
        off = {seg: deg for seg, deg in tilts.items() if deg > STAND_WALK_DEG}
        if not off:
            return None
        segs = ", ".join(f"{seg} {deg:.0f}°" for seg, deg in off.items())
        return (
            f"the rest at {span[0]:.1f}-{span[1]:.1f} s is no {step.pose} pose: the segments "
            f"lie far from where they point while walking ({segs}; beside a stand under "
            f"{STAND_WALK_DEG:.0f}°), as beside a seated rest"
        )

    return check


def _map_place(session: Session) -> str:
    """``"the sensor map <file>"``: the map the session was read with (its provenance), or
    ``"the sensor map"`` when the session does not say."""
    for run in reversed(session.provenance or []):
        path = (run.get("parameters") or {}).get("map")
        if path:
            return f"the sensor map {Path(str(path)).name}"
    return "the sensor map"


def _named(session: Session, seg: str) -> str:
    """``"<segment>'s sensor <label> (map key <key>)"`` (the key when it differs)."""
    label = sensor_for_segment(session, seg)
    key = session.sensors[label].attrs.get("map_key", label) if label else seg
    return f"{seg}'s sensor {label}" + (f" (map key {key})" if key != label else "")


def swapped(session: Session, proximal: str, distal: str, ratio: float) -> InputError:
    """The refusal of a thigh (``proximal``) and a shank (``distal``) whose sensors turn the wrong
    way round over the walk (:class:`.gait_axes.SwappedSensors`), naming their map keys."""
    lo, hi = gait_axes.REAL_WALK_SPEED_RATIO
    names = [_named(session, seg) for seg in (proximal, distal)]
    return InputError(
        f"{names[0]} turns {ratio:.1f} times as fast over the walk as {names[1]}, where a shank "
        f"turns faster than its thigh (real walks: {lo:.2f}-{hi:.2f} times): the two look swapped",
        where=_map_place(session),
        remedy="swap the two sensors' segments in the sensor map (or the sensors on the leg) "
        "and start again from ingest",
    )


def _speed_on(t: np.ndarray, stream: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """A stream's angular speed (rad/s) at ``t`` (s), through its finite samples; NaN outside
    its span."""
    ts, _, gyr = stream
    out = interp_columns(t, ts, np.linalg.norm(gyr, axis=1)[:, None])[:, 0]
    out[(t < ts[0]) | (t > ts[-1])] = np.nan
    return out


def _smooth(x: np.ndarray, fs: float) -> np.ndarray:
    """``x`` low-passed at ``SIDES_LOWPASS_HZ`` less its ``SIDES_DETREND_S`` moving mean."""
    y = sosfiltfilt(butter(2, SIDES_LOWPASS_HZ, fs=fs), x)
    return y - uniform_filter1d(y, max(1, int(round(SIDES_DETREND_S * fs))), mode="nearest")


def sway_swing_correlation(
    session: Session,
    streams: Streams,
    pelvis_mounting: np.ndarray,
    after_s: float,
    before_s: float = np.inf,
) -> tuple[float, float]:
    """The correlation of the pelvis sensor's sideways acceleration (towards the pelvis's right:
    the segment's z through ``pelvis_mounting``, segment → sensor) with the right shank's
    angular speed less the left's over the walking after ``after_s`` and before ``before_s``
    (s), and the walking's
    length (s); see the module notes. NaN when the walk is shorter than ``SIDES_MIN_S``."""
    t, acc, _ = streams["pelvis"]
    q = sensor_orientation(session, sensor_for_segment(session, "pelvis"))
    if len(q) != len(t):  # an orientation-only sensor: no accelerations of its own
        return float("nan"), 0.0
    fs = estimate_rate(t)
    right = rot.rotate(q, np.broadcast_to(rot.rotate(pelvis_mounting, axis_vector("z")), acc.shape))
    right[:, 2] = 0.0
    right /= np.maximum(np.linalg.norm(right, axis=1), 1e-9)[:, None]
    side = np.einsum("ij,ij->i", rot.rotate(q, acc), right)
    speed = {leg: _speed_on(t, streams[f"shank_{leg}"]) for leg in "rl"}
    ok = np.isfinite(side) & np.isfinite(speed["r"]) & np.isfinite(speed["l"])
    if ok.sum() < SIDES_MIN_S * fs:
        return float("nan"), 0.0
    fill = {k: np.interp(t, t[ok], v[ok]) for k, v in (("side", side), *speed.items())}
    a, r, l = (_smooth(fill[k], fs) for k in ("side", "r", "l"))
    walking = ok & (t > after_s) & (t < before_s) & (fill["r"] + fill["l"] > SIDES_WALKING_RAD_S)
    seconds = float(walking.sum() / fs)
    if seconds < SIDES_MIN_S or np.std(a[walking]) == 0 or np.std((r - l)[walking]) == 0:
        return float("nan"), seconds
    return float(np.corrcoef(a[walking], (r - l)[walking])[0, 1]), seconds


def sides_check(
    session: Session,
    protocol: Protocol,
    streams: Streams,
    pelvis: SegmentRecord,
    after_s: float,
    before_s: float = np.inf,
) -> None:
    """For a stand-and-walk recording with a pelvis and both shanks, an :class:`InputError`
    naming the shanks' sensors when they swing as the other side's (module notes): the legs'
    sensors swapped left for right in the sensor map. Nothing where it cannot tell. The
    walker's right comes from the ``pelvis`` frame (the 6-D sensors share no heading): call it
    only where the walk's first (or last) steps gave or confirmed its forward direction
    (0-2.3° on simulated walks, :mod:`.walk_forward`); the walk lies after ``after_s`` and
    before ``before_s`` (s); a hint the stand cannot refute (it sees only the
    vertical) or the turns (up to 98° off) may be half a turn off."""
    if not stand_and_walk(protocol) or not {"pelvis", "shank_r", "shank_l"} <= set(streams):
        return
    mounting = np.asarray(pelvis.mounting, float)
    corr, seconds = sway_swing_correlation(session, streams, mounting, after_s, before_s)
    if not corr < SIDES_CORR:
        return
    raise InputError(
        f"over {seconds:.0f} s of walking the pelvis is pushed towards the left while "
        f"{_named(session, 'shank_r')} swings, and towards the right while "
        f"{_named(session, 'shank_l')} does (correlation {corr:+.2f}; a walk pushes it towards "
        "the swinging leg, real walks +0.4 to +0.7): the legs' sensors look swapped left for "
        "right",
        where=_map_place(session),
        remedy="swap the sides of the leg sensors in the sensor map (right <-> left; the thighs "
        "too if they were swapped with the shanks) and start again from ingest",
    )
