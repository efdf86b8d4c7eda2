"""Sensor calibration: gyroscope bias, accelerometer and magnetometer corrections, noise figures.

Every function takes SI arrays of shape (N, 3) (gyr rad/s, acc m/s², mag µT; first dimension
time) and raises :class:`~motionlab.errors.InputError` for data it cannot use (too few samples,
NaN, poor coverage of orientations). Corrections have one form, ``v = C (y − o)``, and are kept
per device serial in a calibration file (:mod:`.calfile`) that ``fuse`` (and ``ingest``) apply.

- :func:`gyro_bias`: bias from the rest windows found in a recording (:mod:`.gyro`).
- :func:`fit_ellipsoid`: offset and 3×3 correction of an accelerometer or magnetometer, with
  residual, coverage and field-norm figures (:mod:`.ellipsoid`).
- :func:`multiposition`, :func:`find_poses`: accelerometer bias, scale and misalignment from
  static poses (:mod:`.multiposition`).
- :func:`allan_analysis`: overlapping Allan deviation and its white-noise, bias-instability and
  rate-random-walk terms (:mod:`.allan`).
- :func:`load_calibration`, :func:`find_calibration`, :func:`save_calibration`,
  :func:`apply_calibration`, :func:`apply_calibration_dir` (:mod:`.calfile`).

References: Ricci, PhD thesis, Campus Bio-Medico 2015, §2.1–2.2 (eqs. 2.2–2.17); IEEE Std
952-1997 Annex C; Li & Griffiths, GMP 2004; Tedaldi, Pretto & Menegatti, ICRA 2014.
"""

from motionlab.fusion.rest import find_rest
from motionlab.sensorcal.allan import AllanResult, allan_analysis, allan_deviation
from motionlab.sensorcal.calfile import (
    ChannelCalibration,
    SensorCalibration,
    apply_calibration,
    apply_calibration_dir,
    calibration_key,
    calibration_path,
    find_calibration,
    load_calibration,
    save_calibration,
)
from motionlab.sensorcal.ellipsoid import EllipsoidFit, coverage, fibonacci_sphere, fit_ellipsoid
from motionlab.sensorcal.gyro import GyroBias, gyro_bias
from motionlab.sensorcal.multiposition import MultiPositionFit, find_poses, multiposition

__all__ = [
    "AllanResult",
    "ChannelCalibration",
    "EllipsoidFit",
    "GyroBias",
    "MultiPositionFit",
    "SensorCalibration",
    "allan_analysis",
    "allan_deviation",
    "apply_calibration",
    "apply_calibration_dir",
    "calibration_key",
    "calibration_path",
    "coverage",
    "fibonacci_sphere",
    "find_calibration",
    "find_poses",
    "find_rest",
    "fit_ellipsoid",
    "gyro_bias",
    "load_calibration",
    "multiposition",
    "save_calibration",
]
