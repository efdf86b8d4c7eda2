"""Input checks shared by the sensor-calibration functions: one clear :class:`InputError` each."""

from __future__ import annotations

import numpy as np

from motionlab.errors import InputError


def samples3(
    x: object, name: str, min_samples: int = 1, remedy: str | None = None, what: str = "samples"
) -> np.ndarray:
    """``x`` as a float64 (N, 3) array of finite values with at least ``min_samples`` rows.

    ``name`` says where the data come from (``"gyr"``, ``"sensor shank_r acc"``) and is used as
    the error's place.
    """
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise InputError("not numeric", where=name, remedy="give an N×3 array") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"shape {arr.shape}, expected N×3", where=name, remedy="give an N×3 array")
    if len(arr) < min_samples:
        raise InputError(
            f"only {len(arr)} {what}, need at least {min_samples}",
            where=name,
            remedy=remedy or "record longer",
        )
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise InputError(
            f"{int(bad.sum())} {what} are NaN or infinite (first: row {first})",
            where=name,
            remedy="fill or trim the gaps first (motionlab ingest fills short gaps)",
        )
    return np.ascontiguousarray(arr)


def positive_rate(rate: float) -> float:
    """The sampling rate (Hz) as a positive finite float."""
    rate = float(rate)
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"sampling rate {rate} Hz is not positive", where="rate")
    return rate
