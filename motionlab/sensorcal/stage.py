"""The sensor-calibration stage: run the chosen kinds on one sensor and merge into its file.

Kinds and what they write into the sensor's :class:`~motionlab.sensorcal.calfile.SensorCalibration`:

=========  ========================================================  =================
kind       data used                                                 writes
=========  ========================================================  =================
gyro       rest windows anywhere in the recording                    ``channels.gyr``
acc        quasi-static samples (rest, or turning < 10 °/s)          ``channels.acc``
mag        every sample, slow rotations covering the sphere          ``channels.mag``
multipos   mean of each static pose (≥ 2 s)                          ``channels.acc``
allan      the whole recording, which must be static                 ``noise.gyr/acc``
=========  ========================================================  =================

The ellipsoid fits use at most 20 000 samples, evenly spaced. Without a list of kinds
(``auto``) every kind but ``allan`` is tried and the ones the data do not support are skipped
with the reason; ``multipos`` is preferred to ``acc``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion.rest import find_rest
from motionlab.sensorcal.allan import AllanResult, allan_analysis
from motionlab.sensorcal.calfile import ChannelCalibration, SensorCalibration, calibration_key
from motionlab.sensorcal.ellipsoid import fit_ellipsoid
from motionlab.sensorcal.gyro import gyro_bias
from motionlab.sensorcal.multiposition import find_poses, multiposition
from motionlab.session import SensorStream
from motionlab.units import STANDARD_GRAVITY

KINDS = ("gyro", "acc", "mag", "multipos", "allan")
AUTO_KINDS = ("gyro", "multipos", "acc", "mag")
NEEDS = {"gyro": "gyr", "acc": "acc", "mag": "mag", "multipos": "acc", "allan": "gyr"}
TARGET = {"gyro": "gyr", "acc": "acc", "mag": "mag", "multipos": "acc", "allan": "noise"}
MAX_SAMPLES = 20_000  # enough for an ellipsoid fit; keeps it under a second
ALLAN_MIN_S = 60.0
ALLAN_MIN_REST = 0.9


@dataclass
class KindResult:
    """One kind's outcome: the channel correction or noise figures, and the fit behind it."""

    kind: str
    channel: ChannelCalibration | None
    noise: dict[str, AllanResult] | None
    fit: Any


def _gyro(s: SensorStream) -> KindResult:
    fit = gyro_bias(s.gyr, s.acc, s.rate_hz, s.time)
    cal = ChannelCalibration(fit.bias, np.eye(3), "rest-windows", quality=fit.quality())
    return KindResult("gyro", cal, None, fit)


def _decimate(y: np.ndarray) -> np.ndarray:
    return y[:: max(1, int(np.ceil(len(y) / MAX_SAMPLES)))]


def _acc(s: SensorStream, gravity: float) -> KindResult:
    gyr = np.zeros_like(s.acc) if s.gyr is None else s.gyr
    still = find_rest(gyr, s.acc, s.rate_hz, gyr_threshold=np.deg2rad(10.0), min_duration=0.5)
    fit = fit_ellipsoid(_decimate(s.acc[still]), gravity, min_coverage=0.08, name="quasi-static")
    cal = ChannelCalibration(fit.offset, fit.matrix, "ellipsoid", quality=fit.quality())
    return KindResult("acc", cal, None, fit)


def _mag(s: SensorStream, field_norm: float | None) -> KindResult:
    fit = fit_ellipsoid(_decimate(s.mag), norm=field_norm, name="samples")
    cal = ChannelCalibration(fit.offset, fit.matrix, "ellipsoid", quality=fit.quality())
    return KindResult("mag", cal, None, fit)


def _multipos(s: SensorStream, gravity: float) -> KindResult:
    poses, counts = find_poses(s.acc, s.gyr, s.rate_hz)
    fit = multiposition(poses, gravity, weights=counts)
    cal = ChannelCalibration(fit.bias, fit.matrix, f"multiposition-{fit.method}")
    cal.quality = fit.quality()
    return KindResult("multipos", cal, None, fit)


def _allan(s: SensorStream) -> KindResult:
    if s.duration_s < ALLAN_MIN_S:
        raise InputError(
            f"{s.duration_s:.0f} s recorded, need at least {ALLAN_MIN_S:.0f} s",
            where="gyr",
            remedy="record the sensor at rest for a long time (an hour shows the random walk)",
        )
    rest = find_rest(s.gyr, s.acc, s.rate_hz).mean()
    if rest < ALLAN_MIN_REST:
        raise InputError(
            f"only {rest:.0%} of the recording is at rest, need {ALLAN_MIN_REST:.0%}",
            where="gyr",
            remedy="record the sensor lying still, untouched",
        )
    noise = {ch: allan_analysis(getattr(s, ch), s.rate_hz) for ch in ("gyr", "acc")
             if getattr(s, ch) is not None}  # fmt: skip
    return KindResult("allan", None, noise, noise)


def run_kind(
    s: SensorStream, kind: str, gravity: float = STANDARD_GRAVITY, field_norm: float | None = None
) -> KindResult:
    """Run one calibration ``kind`` on sensor ``s``; errors name the sensor."""
    if getattr(s, NEEDS[kind]) is None:
        raise InputError(f"has no {NEEDS[kind]} data", where=f"sensor {s.label}")
    try:
        if kind == "gyro":
            return _gyro(s)
        if kind == "acc":
            return _acc(s, gravity)
        if kind == "mag":
            return _mag(s, field_norm)
        if kind == "multipos":
            return _multipos(s, gravity)
        return _allan(s)
    except InputError as exc:
        inner = exc.where not in (None, kind, NEEDS[kind])
        where = f"sensor {s.label} {kind}" + (f" ({exc.where})" if inner else "")
        raise InputError(exc.message, exc.path, where, exc.remedy, exc.arguments) from None


def calibrate_sensor(
    s: SensorStream,
    kinds: Sequence[str] = (),
    gravity: float = STANDARD_GRAVITY,
    field_norm: float | None = None,
) -> tuple[list[KindResult], dict[str, str]]:
    """Run ``kinds`` on ``s`` (every supported kind when empty); returns results and skips.

    With explicit kinds any failure raises :class:`InputError`; in automatic mode a kind the
    data do not support is skipped with its reason, and ``acc`` is skipped once ``multipos``
    has calibrated the accelerometer.
    """
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise InputError(
            f"unknown kind {unknown[0]!r}", where="argument kinds", remedy=", ".join(KINDS),
            argument="kinds",
        )  # fmt: skip
    if "acc" in kinds and "multipos" in kinds:
        raise InputError(
            "acc and multipos both calibrate the accelerometer", where="argument kinds",
            remedy="choose one", argument="kinds",
        )  # fmt: skip
    if kinds:
        return [run_kind(s, k, gravity, field_norm) for k in kinds], {}
    results, skipped = [], {}
    for kind in AUTO_KINDS:
        if kind == "acc" and any(r.kind == "multipos" for r in results):
            continue
        try:
            results.append(run_kind(s, kind, gravity, field_norm))
        except InputError as exc:
            skipped[kind] = exc.line()
    if not results:
        raise InputError(
            "no calibration is possible from this recording",
            where=f"sensor {s.label}",
            remedy="; ".join(skipped.values()),
        )
    return results, skipped


def merge(
    existing: SensorCalibration | None,
    s: SensorStream,
    results: Sequence[KindResult],
    source: str | Path,
    force: bool,
    path: str | Path | None = None,
) -> SensorCalibration:
    """``existing`` (or a new calibration for ``s``) updated with ``results``.

    A channel or noise entry already present is replaced only with ``force``.
    """
    key = calibration_key(s)
    if existing is not None and existing.serial != key:  # filed under this sensor's name
        raise InputError(
            f"holds serial {existing.serial}, the sensor is {key}",
            path,
            "key serial",
            "move the file away or correct its serial: a calibration is filed by its serial",
        )
    cal = existing or SensorCalibration(serial=key, vendor=s.vendor)
    cal.source = f"{Path(source).name}#{s.label}"
    for r in results:
        if r.channel is not None:
            taken = [TARGET[r.kind]] if TARGET[r.kind] in cal.channels else []
        else:
            taken = [f"noise.{ch}" for ch in r.noise if ch in cal.noise]
        if taken and not force:
            raise InputError(
                f"already holds a {taken[0]} calibration for {key}",
                path,
                remedy="add force=True to replace it",
                argument="force",
            )
        if r.channel is not None:
            cal.channels[TARGET[r.kind]] = r.channel
        else:
            cal.noise.update({ch: res.quality() for ch, res in r.noise.items()})
    return cal
