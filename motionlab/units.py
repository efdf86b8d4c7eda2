"""Unit names and conversion factors to motionlab's internal SI units.

Readers call :func:`to_si` on the way in and record the original unit in
``SensorStream.source_units``.
"""

from __future__ import annotations

import math

import numpy as np

from motionlab.errors import InputError

STANDARD_GRAVITY = 9.80665  # m/s², the conventional value used by sensor vendors for "g"

#: factor that multiplies a value in the given unit to give the SI unit of its quantity
_FACTORS: dict[str, tuple[str, float]] = {
    # acceleration -> m/s^2
    "m/s^2": ("acc", 1.0),
    "m/s2": ("acc", 1.0),
    "m/s/s": ("acc", 1.0),
    "g": ("acc", STANDARD_GRAVITY),
    "mg": ("acc", STANDARD_GRAVITY / 1000.0),
    # angular velocity -> rad/s
    "rad/s": ("gyr", 1.0),
    "deg/s": ("gyr", math.pi / 180.0),
    "dps": ("gyr", math.pi / 180.0),
    "°/s": ("gyr", math.pi / 180.0),
    # magnetic field -> µT
    "ut": ("mag", 1.0),
    "µt": ("mag", 1.0),
    "microtesla": ("mag", 1.0),
    "nt": ("mag", 1e-3),
    "mt": ("mag", 1e3),
    "t": ("mag", 1e6),
    "gauss": ("mag", 100.0),
    "ga": ("mag", 100.0),
    "mgauss": ("mag", 0.1),
    "mga": ("mag", 0.1),
    # length -> m
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "cm": ("length", 1e-2),
    # time -> s
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "µs": ("time", 1e-6),
    # angle -> rad
    "rad": ("angle", 1.0),
    "deg": ("angle", math.pi / 180.0),
}

SI_UNITS = {"acc": "m/s^2", "gyr": "rad/s", "mag": "uT", "length": "m", "time": "s", "angle": "rad"}


def normalise_unit(unit: str) -> str:
    """Canonical lower-case spelling: ``'Deg/S'`` → ``'deg/s'``, ``'m/s²'`` → ``'m/s^2'``."""
    u = unit.strip().lower().replace(" ", "").replace("²", "^2").replace("sec", "s")
    return {"degrees/s": "deg/s", "degree/s": "deg/s", "uT".lower(): "ut"}.get(u, u)


def factor(unit: str, quantity: str | None = None) -> float:
    """Multiplier from ``unit`` to the SI unit of its quantity.

    Raises :class:`InputError` for an unknown unit or one of the wrong quantity
    (e.g. ``factor('deg/s', 'acc')``).
    """
    key = normalise_unit(unit)
    if key not in _FACTORS:
        raise InputError(f"unknown unit '{unit}'", remedy=f"use one of {sorted(_FACTORS)}")
    kind, f = _FACTORS[key]
    if quantity is not None and kind != quantity:
        raise InputError(
            f"unit '{unit}' is not a unit of {quantity}",
            remedy=f"use a unit of {quantity} such as {SI_UNITS[quantity]}",
        )
    return f


def to_si(values: np.ndarray, unit: str, quantity: str | None = None) -> np.ndarray:
    """``values`` (any shape) converted from ``unit`` to SI (float64); a value beyond float64
    in SI (1e308 g) becomes ±inf, which the ingest's QC counts as implausible."""
    with np.errstate(over="ignore"):
        return np.asarray(values, dtype=float) * factor(unit, quantity)
