"""Gyroscope bias from the rest windows of a recording.

At rest the gyroscope measures its bias plus noise (Ricci 2015, thesis eqs. 2.6–2.7), so the
bias is the mean angular rate over the rest samples (long-term averaging while stationary,
thesis §2.2; the Allan curve says how long: about 20 s for the APDM Opal, §2.1). Rest windows
are found automatically (:func:`motionlab.fusion.rest.find_rest`), so any recording with a few
seconds of stillness — before, between or after movements — gives a bias.

Units: gyr rad/s, acc m/s², time s. The correction is ``ω = y − bias``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion.rest import find_rest
from motionlab.sensorcal._validate import positive_rate, samples3
from motionlab.timebase import runs


@dataclass
class GyroBias:
    """A gyroscope bias estimate (rad/s) and the evidence behind it.

    Attributes
    ----------
    bias
        (3,) mean rate over the rest samples, rad/s.
    std_error
        (3,) standard error of ``bias`` for white noise, ``noise / √n``, rad/s.
    noise
        (3,) standard deviation of the rate at rest, rad/s.
    windows
        (W, 2) start and end time of each rest window, s.
    window_bias
        (W, 3) mean rate of each rest window, rad/s.
    rest_s
        Total rest time used, s.
    mask
        (N,) bool, the rest samples.
    """

    bias: np.ndarray
    std_error: np.ndarray
    noise: np.ndarray
    windows: np.ndarray
    window_bias: np.ndarray
    rest_s: float
    mask: np.ndarray

    @property
    def spread(self) -> np.ndarray:
        """(3,) largest minus smallest window mean, rad/s: the in-run bias stability seen."""
        return np.ptp(self.window_bias, axis=0)

    def quality(self) -> dict[str, Any]:
        """JSON-able quality figures (rad/s and s)."""
        return {
            "rest_s": round(self.rest_s, 3),
            "n_windows": len(self.windows),
            "std_error_rad_s": self.std_error.tolist(),
            "noise_rad_s": self.noise.tolist(),
            "window_spread_rad_s": self.spread.tolist(),
        }


def gyro_bias(
    gyr: np.ndarray,
    acc: np.ndarray | None,
    rate: float,
    time: np.ndarray | None = None,
    min_rest: float = 2.0,
    gyr_threshold: float = np.deg2rad(2.0),
    acc_threshold: float = 0.5,
    min_duration: float = 1.5,
) -> GyroBias:
    """Estimate the gyroscope bias from the rest windows found in a recording.

    Parameters
    ----------
    gyr, acc
        (N, 3) angular rate (rad/s) and specific force (m/s²); ``acc`` may be None (then only
        the gyroscope judges rest).
    rate
        Sampling rate, Hz.
    time
        (N,) sample times, s, for the window report; default ``arange(N) / rate``.
    min_rest
        Least total rest time, s; less raises :class:`InputError`. Ricci (2015, §2.1) found
        about 20 s optimal for the Opal.
    gyr_threshold, acc_threshold, min_duration
        Rest detector settings (rad/s, m/s², s), see :func:`~motionlab.fusion.rest.find_rest`.

    Returns
    -------
    GyroBias
    """
    rate = positive_rate(rate)
    gyr = samples3(gyr, "gyr", 2)
    if acc is not None:
        acc = samples3(acc, "acc", 2)
        if len(acc) != len(gyr):
            raise InputError(f"{len(acc)} acc samples but {len(gyr)} gyr samples", where="acc")
    t = np.arange(len(gyr)) / rate if time is None else np.asarray(time, dtype=float)
    mask = find_rest(gyr, acc, rate, gyr_threshold, acc_threshold, min_duration)
    rest_s = float(mask.sum() / rate)
    if rest_s < min_rest:
        raise InputError(
            f"only {rest_s:.1f} s at rest, need {min_rest:g} s for a gyroscope bias",
            where="gyr",
            remedy="record the sensor lying still (about 20 s) before or after the movements",
        )
    idx = runs(mask)
    rest = gyr[mask]
    noise = rest.std(axis=0, ddof=1)
    window_bias = np.array([gyr[a:b].mean(axis=0) for a, b in idx])
    return GyroBias(
        bias=rest.mean(axis=0),
        std_error=noise / np.sqrt(len(rest)),
        noise=noise,
        windows=np.column_stack((t[idx[:, 0]], t[idx[:, 1] - 1])),
        window_bias=window_bias,
        rest_s=rest_s,
        mask=mask,
    )
