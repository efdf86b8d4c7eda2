"""IMU-to-IMU clock synchronisation from the joint centres the segments share and the heel strikes.

Sensors that record on their own clocks (no radio synchronisation: consumer IMUs, loggers started
one by one, Xsens DOT without its sync) disagree by tens of milliseconds in offset and 10–50 ppm in
rate. 10 ms at a knee's 300 °/s in gait is 3° of flexion, so the clocks must agree to about a
millisecond before two sensors make a joint angle.

Two independent timing signals per pair of sensors, one module each:

- :mod:`.joint_centre`: two segments joined at a joint share the joint centre, whose
  acceleration seen from either sensor has the same magnitude at every instant (Seel, Schauer &
  Raisch 2012); the clock shift that makes them agree, fitted with the lever arms
  (:func:`estimate_clock`, neighbouring segments only);
- :mod:`.impacts`: the heel strikes shake every leg and pelvis sensor at one instant; the lag
  that maximises the correlation of two sensors' transient envelopes (:func:`impact_clock`,
  any two sensors).

:mod:`.pairs` chooses which sensors are timed against which (the sync tree), :mod:`.stage` puts
a session on one clock (:func:`synchronise`: sensor by sensor down the tree by the joint centre
without heel strikes, every clock at once by :mod:`motionlab.clocknet` with them), and
:mod:`.common` holds what the methods share.

A correction is applied only when it is reliable (joint centre: standard error ≤
``joint_centre.MAX_SE_S`` over the recording, and the joint-centre model fits: RMS residual ≤
``joint_centre.MAX_RESIDUAL_M_S2``; impacts: standard error ≤ ``impacts.IMPACT_MAX_SE_S``) and
differs from zero (by more than twice that and ``MIN_CORRECTION_S``); otherwise the sensor
keeps its clock and the reason is recorded. Segments that never move together carry no timing
information (a still pelvis under a bending trunk), and there the timing does not matter
either. The bench (``bench/joint_angles.py``) reports the accuracy reached per pair.
"""

from motionlab.clocksync.common import MAX_OFFSET_S
from motionlab.clocksync.impacts import impact_clock
from motionlab.clocksync.joint_centre import estimate_clock
from motionlab.clocksync.pairs import sync_forest, sync_tree
from motionlab.clocksync.stage import choose, describe, synchronise, unsynchronise
from motionlab.results import ClockFit, ClockSync

__all__ = [
    "MAX_OFFSET_S",
    "ClockFit",
    "ClockSync",
    "choose",
    "describe",
    "estimate_clock",
    "impact_clock",
    "sync_forest",
    "sync_tree",
    "synchronise",
    "unsynchronise",
]
