"""The upper arm's skin lag undone in the angles.

A sensor strapped on the upper arm sits on skin that follows only part of the humerus' rotation
about its long axis (docs/simulator.md, "The upper arm under the skin"). The two-axis fit of the
elbow (:func:`.movement.fit_two_dof`) finds that part, ``axial_follow`` = ``1 / (1 + k)``; here
the segment's orientation is turned about its long axis (segment y) by ``k τ(t)``, where
``τ`` is the sensor's twist about that axis away from the reference pose (the stand, arms
hanging), taken relative to the trunk: the skin is anchored there, so the skin is stretched by
the arm's twist against the trunk, not by the body turning in the room. Elastic skin lags by
its configuration, not its path, so ``τ`` is the swing-twist decomposition's twist (of the
orientation relative to the trunk against the same in the reference pose), not an integrated
rate. Without a trunk sensor nothing is undone: a turn of the whole body would be read as twist.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.results import TwoAxisFit

#: the segment the upper arm's skin is anchored on, whose sensor (when there is one) the twist
#: is taken against
TRUNK = "thorax"


def undo_lag(
    t: np.ndarray,
    q_segment: np.ndarray,
    reference: tuple[float, float],
    follow: float,
    trunk: tuple[np.ndarray, np.ndarray],
) -> np.ndarray:
    """Segment orientations (N, 4) turned about their long axis (segment y) by the part of the
    segment's twist against the ``trunk`` (``(time s, q)``, any frame) that the sensor did not
    follow: ``(1/follow − 1) τ``, ``τ`` the twist away from the ``reference`` pose (s)."""
    t_trunk, q_trunk = trunk
    ref = (t >= reference[0]) & (t <= reference[1])
    if not ref.any() or not covers(trunk, reference):
        return q_segment  # no pose to take the twist from (calibration checked it: defensive)
    relative = rot.mul(rot.conj(rot.resample(t_trunk, q_trunk, t)), q_segment)
    away = rot.mul(rot.conj(rot.mean(relative[ref])), relative)
    long_axis = np.array([0.0, 1.0, 0.0])
    angle = (1.0 / follow - 1.0) * rot.twist_angle(away, long_axis)
    return rot.mul(q_segment, rot.from_axis_angle(long_axis, angle))


def covers(stream: tuple | None, reference: tuple[float, float] | None) -> bool:
    """Whether a trunk sensor's ``stream`` (``(time s, ...)``) spans the ``reference`` pose (s),
    so that the twist can be taken against it."""
    if stream is None or reference is None or len(stream[0]) < 2:
        return False
    return bool(stream[0][0] <= reference[0] and stream[0][-1] >= reference[1])


def lag_undone(fit: object) -> bool:
    """Whether the angles undo a joint's skin lag: a two-axis fit that found its proximal sensor
    following less than all of the segment's twist, with a trunk sensor to take it against."""
    return (
        isinstance(fit, TwoAxisFit)
        and bool(fit.lag_anchor)
        and np.isfinite(fit.axial_follow)
        and 0.0 < fit.axial_follow < 1.0
    )
