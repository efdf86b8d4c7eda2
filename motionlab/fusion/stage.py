"""The fusion stage: every chosen sensor's orientation by one estimator, stored in the session.

``motionlab fuse`` and ``motionlab run`` (:mod:`motionlab.pipeline`) both call
:func:`fuse_session`. Each sensor's :class:`~motionlab.results.FusionEntry` in
``session.results.fusion`` holds the estimator's ``name``, ``quat`` ((N, 4), sensor → ENU earth,
on the sensor's own time stamps, which are passed to the estimator so that packet-loss gaps are
bridged), its ``params``, whether the ``magnetometer`` was used, and what the estimator reports
besides: ``gyro_bias``, ``rest``, ``mag_disturbed``, the marker ``scenario``, and
``gaps_bridged_s`` (the gaps it ran across).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion import registry
from motionlab.results import FusionEntry
from motionlab.session import Session

Progress = Callable[[list[str], str], Iterable[str]]


def fusable(session: Session, labels: list[str] | None = None) -> list[str]:
    """The sensors (of ``labels``, default all) that have a gyroscope and an accelerometer."""
    chosen = list(session.sensors) if labels is None else list(labels)
    return [
        k
        for k in chosen
        if session.sensors[k].gyr is not None and session.sensors[k].acc is not None
    ]


def fuse_session(
    session: Session,
    name: str = "default",
    params: dict[str, str] | None = None,
    sensors: list[str] | None = None,
    *,
    force: bool = False,
    path: str | Path | None = None,
    references: dict[str, Any] | None = None,
    magnetometer: bool = True,
    progress: Progress | None = None,
) -> list[str]:
    """Run estimator ``name`` on ``sensors`` and store the results in ``session.results.fusion``.

    Parameters
    ----------
    session
        The session; its ``results.fusion`` gets one entry per sensor (module docstring).
    name, params
        Registered estimator and its parameters as text (``{"beta": "0.1"}``), checked before
        any work.
    sensors
        Sensor labels (default: every sensor with gyroscope and accelerometer).
    force
        Replace existing entries; without it an existing entry is an :class:`InputError`
        naming ``path`` (the session file).
    references
        Marker reference vectors per sensor label (IMU + marker fusion).
    magnetometer
        Use the magnetometer where the sensor has one (``False``: 6-D, arbitrary heading).
    progress
        ``progress(labels, text)`` wraps the iteration over the sensors (a progress bar).

    Returns
    -------
    list of str
        The sensors fused, in order.
    """
    est = registry.get(name)
    params = dict(params or {})
    registry.make_params(est, params)  # fail on a bad parameter before any work
    sensors = fusable(session) if sensors is None else list(sensors)
    store = session.results.fusion
    for label in sensors:
        if label in store and not force:
            raise InputError(
                "already holds a fusion result",
                path,
                f"results/fusion/{label}",
                "add force=True to replace it",
                argument="force",
            )
    text = f"fusing ({est.name}{'' if magnetometer else ', 6-D'})"
    done = []
    for label in progress(sensors, text) if progress else sensors:
        s = session.sensors[label]
        mag = s.mag if magnetometer else None
        ref = (references or {}).get(label)
        res = registry.estimate(
            est.name, s.gyr, s.acc, mag, s.rate_hz, references=ref, time=s.time, **params
        )
        if not np.isfinite(res.quat).all(axis=1).any():
            raise InputError(
                f"fusion ({est.name}) gives no finite orientation for this sensor",
                path,
                f"sensor {label}",
                "its data hold non-finite or implausible values: see 'motionlab info' (QC)",
            )
        resampled = res.extra.get("resampled")  # packet-loss gaps the estimator ran across
        store[label] = FusionEntry(
            res.name,
            res.quat,
            res.params,
            magnetometer=mag is not None,
            scenario=res.extra.get("scenario"),
            gaps_bridged_s=None if resampled is None else resampled["spans_s"],
            gyro_bias=res.gyro_bias,
            rest=res.rest,
            mag_disturbed=res.mag_disturbed,
        )
        done.append(label)
    return done
