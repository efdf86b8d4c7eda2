"""Orientation estimation: one interface for every estimator.

>>> from motionlab.fusion import estimate
>>> res = estimate("madgwick", gyr, acc, mag, rate=100.0, beta=0.05)   # doctest: +SKIP
>>> res.quat          # (N, 4), scalar first, sensor -> ENU earth

``mag=None`` gives a 6-D estimate (arbitrary but fixed heading). ``name="default"`` is the
offline smoother. Every estimator's tunables live in one parameter dataclass (see
:mod:`motionlab.fusion.registry`); ``motionlab fuse --list`` prints them with defaults and units.
"""

from motionlab.fusion.registry import (
    DEFAULT_ESTIMATOR,
    FusionResult,
    available,
    estimate,
    get,
    register,
)

__all__ = ["DEFAULT_ESTIMATOR", "FusionResult", "available", "estimate", "get", "register"]
