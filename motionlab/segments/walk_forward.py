"""The pelvis's forward direction from the walk's first steps (or, where they do not give it,
from its turns), for a pelvis sensor whose placement hint the stand or the walk contradicts.

The first steps come first: on ``bench/real_world.py``'s walk (random mountings, the ``skin``
preset, 74 s, seeds 0-19; ``bench/pelvis_forward.py``) they lay 0.0-2.3° from the true pelvis x
on every seed (median 0.6°; 0.3-3.2°, median 1.5°, before the velocity was taken in the earth
frame and averaged over the last second, :func:`forward_from_start`), the turns 4.2-26°
(over 5° on 17 of 18 seeds; one ``typical`` seed, 18, 98.6°),
and the hips' mean RMSE fell from 1.39 / 1.48° (flexion, right / left) to 1.26 / 1.27° when the
first steps replaced the turns.
The turns remain for a walk that does not start right after the stand.

With only gravity in the stand, the pelvis sensor's heading on the pelvis is the protocol's
placement hint. When the stand shows the hint is wrong (the sensor's measured vertical more than
60° from where the hint puts it: :func:`motionlab.segments.placement.contradicted`), the hint's
forward direction means nothing: with random mountings it was 97–142° off the true pelvis x on
simulated walks (``bench/real_world.py`` seeds 0, 1, 2, 4), which turned the pelvis angles
(tilt and obliquity swap and change sign) and put up to 8° into the hips.

Walking round a turn, the body's centre accelerates towards the inside of the turn: in the
horizontal plane ``a = v ω (ẑ × f) + v̇ f`` for a forward direction ``f``, a speed ``v`` and a
turning rate ``ω`` about the vertical ``ẑ``. So the part of the horizontal acceleration that
follows the turning rate points to the left of ``f`` in a left turn and gives ``f``, with its
sign: ``f ∝ Σ ω′ (a′ × ẑ)`` (primes: deviations from the walk's means, which removes a constant
accelerometer bias and the ellipse's mean turning), expressed in the sensor frame sample by
sample with the fused orientation. Signals are low-passed at ``LOWPASS_HZ`` (below the stride
frequency). The sensor's lever arm from the body's path turns the estimate: a sensor 0.11 m
behind the pelvis centre sees ``ω² r`` forward in a turn, which turned ``f`` by −4 to −22° on
the nominal simulated walks and −14 to +5° with random mountings and soft-tissue motion (60 s
walks). So it replaces only a contradicted hint, and the frame is graded ``weak``.

The turns are used when the walk has at least ``MIN_TURNS`` turns (runs of ``|ω| ≥
TURN_RAD_S`` of at least ``TURN_MIN_S``) whose own estimates lie within ``MAX_SPREAD_DEG`` of the
whole walk's, or within
``MAX_SPREAD_CONTRADICTED_DEG`` when the stand has already refuted the hint: on
``bench/real_world.py`` (random mountings, soft-tissue motion, 74 s) the turns of four such
pelvises spread by 36-56°, their whole-walk direction was still 4.5-17° off where the hint was
arbitrary, and the hip means fell from 3.35 / 3.50° (flexion / adduction, right) to 1.62 / 1.62°.

The stand sees only the vertical: a hint it does not refute may still be turned about the
vertical. The walk refutes it when its forward direction lies further from the hint's than the
method's own bound (``grades.HEADING_BOUND_DEG``) plus ``HINT_HEADING_DEG``: then the hint is off
by more than that bound, and the walk's direction is the better one (seed 5 there: a hint 59.5°
off, the first steps 0.7° off; hip flexion 3.3 / 4.4° → 1.3 / 1.3°).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import cumulative_trapezoid

from motionlab import rotations as rot
from motionlab.dsp import butter, sosfiltfilt
from motionlab.session import estimate_rate
from motionlab.timebase import runs
from motionlab.units import STANDARD_GRAVITY

LOWPASS_HZ = 0.5
TURN_RAD_S = 0.3  # |ω| low-passed (simulated ellipse: 0.15-0.2 on its sides, 0.4-0.55 in turns)
TURN_MIN_S = 1.0
MIN_TURNS = 2
MAX_SPREAD_DEG = 30.0
# where the stand has shown the hint wrong, its forward is anyone's guess (90° off on average):
# turns that agree less well still beat it
MAX_SPREAD_CONTRADICTED_DEG = 60.0
RHO = 0.6  # weight of the axis in the frame fit (secondary to gravity)
# how far (deg) a pelvis sensor strapped over the sacrum as the protocol says may sit from its
# hint's heading; a walk whose forward direction lies further from the hint's than this plus
# the walk's own bound (grades.HEADING_BOUND_DEG) shows the hint wrong even where the stand,
# which sees only the vertical, did not
HINT_HEADING_DEG = 20.0
START_S = 2.0  # the first steps after the stand whose velocity gives the walking direction …
# … averaged over their last second, about a stride: the pelvis sways over each stance foot by
# about 2 cm to each side (Perry & Burnfield 2010), ±0.1 m/s sideways at stride frequency, which
# the velocity at one instant carries
START_AVERAGE_S = 1.0
MIN_START_SPEED_M_S = 0.3
# a walker who has set off keeps going: over the last second the velocity gained stays above this
# share of its mean (simulated walks, seeds 0-5: 0.80-0.93; the real 16-IMU walk 0.76), where a
# walk that was going before the "stand" (the real walk cut in mid-stride after a stand) swings
# through 0.19 of it, its direction the integration's start and not the walk's
START_STEADY = 0.5
# a walker who turns further than this (deg, about the vertical) in the first steps (setting off
# towards a walkway beside them) gains velocity along no one pelvis direction: the direction
# gained lies between the start's and the end's, up to half the turn from each, which is the
# method's bound (grades.HEADING_BOUND_DEG, 10°) at 20°; straight starts turn 2.2° (the real
# 16-IMU walk) and 2.7-4.0° (bench/real_world.py, seeds 0-19)
MAX_START_TURN_DEG = 20.0


@dataclass(frozen=True)
class ForwardDirection:
    """The pelvis's forward direction as one of the walk's methods found it (or why not).

    ``used``: found; ``axis`` (3,): the unit forward direction, horizontal in the stand, in
    sensor coordinates (``None`` when not found); ``reason``: why not, in words (empty when
    found); ``turns``: the turns the direction came from (0 for the walk's start);
    ``spread_deg``: how far (deg) the turns' directions lay from the whole walk's (``None``
    without two turns); ``speed_m_s``: the horizontal speed gained over the walk's first
    seconds (``forward_from_start``; ``None`` otherwise).
    """

    used: bool
    axis: np.ndarray | None = None
    reason: str = ""
    turns: int = 0
    spread_deg: float | None = None
    speed_m_s: float | None = None


def forward_from_turns(
    t: np.ndarray,
    acc: np.ndarray,
    q: np.ndarray,
    gyr: np.ndarray,
    up: np.ndarray,
    after_s: float,
    max_spread_deg: float = MAX_SPREAD_DEG,
    before_s: float = np.inf,
) -> ForwardDirection:
    """The forward direction (unit, horizontal in the stand, sensor frame) from the turns.

    ``t`` (s), ``acc`` (m/s², specific force) and ``gyr`` (rad/s) of one sensor with its fused
    orientation ``q`` (sensor → earth, (N, 4)); ``up`` its vertical in the stand (sensor frame);
    only samples after ``after_s`` (the stand's end) and before ``before_s`` count (a walk
    that ends with its stand: ``after_s`` −inf, ``before_s`` the stand's start).
    """
    walk = (t > after_s) & (t < before_s)
    if walk.sum() < 100:
        return ForwardDirection(False, reason="no walk beside the stand")
    rate = estimate_rate(t)
    if not rate > 2.5 * LOWPASS_HZ:
        return ForwardDirection(False, reason="sampling too slow")
    sos = butter(2, LOWPASS_HZ, fs=rate)
    a = sosfiltfilt(sos, rot.rotate(q, acc) - np.array([0.0, 0.0, STANDARD_GRAVITY]), axis=0)
    yaw = sosfiltfilt(sos, rot.rotate(q, gyr)[:, 2])
    a = a - a[walk].mean(axis=0)
    w = yaw - yaw[walk].mean()
    left = np.column_stack([a[:, 1], -a[:, 0], np.zeros(len(t))])  # a × ẑ
    contrib = rot.rotate(rot.conj(q), w[:, None] * left)  # in the sensor frame
    up = np.asarray(up, float) / np.linalg.norm(up)

    def horizontal(v: np.ndarray) -> np.ndarray | None:
        h = v - (v @ up) * up
        n = float(np.linalg.norm(h))
        return h / n if n > 0 else None

    whole = horizontal(contrib[walk].sum(axis=0))
    if whole is None:
        return ForwardDirection(False, reason="no turns in the walk")
    parts = []
    for i, j in runs(walk & (np.abs(yaw) >= TURN_RAD_S)):
        if (j - i) / rate >= TURN_MIN_S:
            h = horizontal(contrib[i:j].sum(axis=0))
            if h is not None:
                parts.append(h)
    if len(parts) < MIN_TURNS:
        why = f"{len(parts)} turn(s) in the walk, {MIN_TURNS} needed"
        return ForwardDirection(False, reason=why, turns=len(parts))
    spread = max(float(np.degrees(np.arccos(np.clip(p @ whole, -1.0, 1.0)))) for p in parts)
    if spread > max_spread_deg:
        why = f"the turns disagree by up to {spread:.0f} deg"
        return ForwardDirection(False, reason=why, turns=len(parts), spread_deg=spread)
    return ForwardDirection(True, axis=whole, turns=len(parts), spread_deg=spread)


def forward_from_end(
    t: np.ndarray, acc: np.ndarray, q: np.ndarray, up: np.ndarray, before_s: float
) -> ForwardDirection:
    """The forward direction from the last steps before a stand that starts at ``before_s``
    (s): a walk that ends at rest loses its velocity over its last ``START_S`` seconds as one
    that starts from rest gains it, so this is :func:`forward_from_start` on the recording
    reversed in time, whose velocity points backwards. Arguments as there."""
    found = _from_rest(-t[::-1], acc[::-1], q[::-1], up, -before_s, _END)
    return replace(found, axis=-found.axis) if found.used else found


@dataclass(frozen=True)
class _Words:
    """How a reason names the walk's edge beside the stand (its start, or its end)."""

    beside: str  # where the steps are, against the stand
    steps: str
    starts: str  # the walk ... the stand
    change: str  # the velocity ...
    rest: str  # from rest / to rest
    second: str  # the second of the steps the velocity is averaged over


_START = _Words("right after the stand", "first steps", "does not start", "gained", "from rest",
                "last second")  # fmt: skip
_END = _Words("right before the stand", "last steps", "does not end", "lost", "to rest",
              "first second")  # fmt: skip


def forward_from_start(
    t: np.ndarray, acc: np.ndarray, q: np.ndarray, up: np.ndarray, after_s: float
) -> ForwardDirection:
    """The forward direction (unit, horizontal in the stand, sensor frame) from the first steps
    after the stand: the walk starts from rest, so the horizontal velocity gained over its first
    ``START_S`` seconds points the way the walker goes. The horizontal specific force, less its
    mean over the end of the stand, is integrated in the earth frame (a walker may curve as they
    set off), and the velocity, seen from the sensor at each instant, is averaged over the last
    ``START_AVERAGE_S`` (about a stride: the pelvis's sideways sway cancels). Needs no turn.
    Not where the walker turns more than ``MAX_START_TURN_DEG`` in those seconds. Arguments as
    :func:`forward_from_turns`."""
    return _from_rest(t, acc, q, up, after_s, _START)


def _from_rest(
    t: np.ndarray, acc: np.ndarray, q: np.ndarray, up: np.ndarray, after_s: float, words: _Words
) -> ForwardDirection:
    """:func:`forward_from_start`, its reasons in ``words``."""
    start = (t > after_s) & (t <= after_s + START_S)
    still = (t > after_s - 2.0) & (t <= after_s)
    if start.sum() < 10 or still.sum() < 5:
        return ForwardDirection(False, reason=f"no walk {words.beside}")
    vertical = rot.rotate(rot.conj(q), np.broadcast_to([0.0, 0.0, 1.0], (len(q), 3)))
    horizontal = acc - np.einsum("ij,ij->i", acc, vertical)[:, None] * vertical
    ts = t[start]
    # velocity in the earth frame (the walker may curve), then seen from the sensor at each
    # instant of the last second: the pelvis faces the way it goes, up to its swing
    dv = rot.rotate(q[start], horizontal[start] - horizontal[still].mean(axis=0))
    dv[:, 2] = 0.0
    velocity = cumulative_trapezoid(dv, ts, axis=0, initial=0.0)
    last = ts > ts[-1] - START_AVERAGE_S
    up = np.asarray(up, float) / np.linalg.norm(up)
    seen = rot.rotate(rot.conj(q[start][last]), velocity[last])
    seen -= np.outer(seen @ up, up)
    gained = seen.mean(axis=0)
    speed = float(np.linalg.norm(gained))
    if not speed >= MIN_START_SPEED_M_S:
        why = f"the walk {words.starts} {words.beside}"
        return ForwardDirection(False, reason=why, speed_m_s=speed)
    slowest = float(np.min(np.linalg.norm(seen, axis=1)))
    if slowest < START_STEADY * speed:
        why = (
            f"the velocity {words.change} falls to {slowest:.2f} m/s in the {words.second} of the "
            f"{words.steps}: no walk {words.rest} (a recording cut in mid-walk?)"
        )
        return ForwardDirection(False, reason=why, speed_m_s=speed)
    ends = q[np.flatnonzero(start)[[0, -1]]]
    turn = rot.mul(ends[1], rot.conj(ends[0]))  # earth frame: its part about up is the turn
    turned = abs((float(np.degrees(2.0 * np.arctan2(turn[3], turn[0]))) + 180.0) % 360.0 - 180.0)
    if turned > MAX_START_TURN_DEG:
        why = f"the walker turned {turned:.0f}° in the {words.steps}"
        return ForwardDirection(False, reason=why, speed_m_s=speed)
    return ForwardDirection(True, axis=gained / speed, speed_m_s=speed)
