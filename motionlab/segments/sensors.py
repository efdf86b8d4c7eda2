"""A segment's sensor signals as the calibration and the angles read them.

The sensor on a segment is :func:`motionlab.binding.sensor_for_segment`'s. Its orientation
(:func:`sensor_orientation`) is the fusion stage's result (``session.results.fusion[label].quat``,
as ``motionlab fuse`` stores them) or, for a sensor without raw accelerometer and gyroscope,
the vendor's ``quat``. A sensor with raw signals but no fusion result is refused: nothing is
fused here behind the user's back (the fusion stage also prepares the signals and estimates
the accelerometer bias the calibration subtracts). Its accelerometer is read less the bias the
fusion estimated (:func:`corrected_acc`).

The lowest module of the calibration: it imports nothing of :mod:`motionlab.segments` or
:mod:`motionlab.kinematics` beyond the tables, so both read a sensor's signals from here.
"""

from __future__ import annotations

import numpy as np

from motionlab.binding import sensor_for_segment, signals_from_orientation
from motionlab.errors import InputError
from motionlab.protocol import Protocol
from motionlab.segments.skin_lag import TRUNK
from motionlab.session import Session

#: ``{segment: (time s, acc m/s², gyr rad/s)}``
Streams = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
#: ``{segment: (time s, quaternion (N, 4))}``
SegmentQuats = dict[str, tuple[np.ndarray, np.ndarray]]


def _no_sensor(protocol: Protocol, segment: str) -> InputError:
    """The error of a protocol segment that no sensor is on."""
    return InputError(
        f"no sensor on segment '{segment}'",
        where=f"protocol {protocol.name}",
        remedy="name the sensor after the segment or set its segment at ingest",
    )


def corrected_acc(session: Session, label: str) -> np.ndarray:
    """Sensor ``label``'s accelerometer (N, 3) m/s² less the bias its fusion estimated
    (``results.fusion[label].acc_bias``, the default estimator's accelerometer-bias states at
    the calibration's prior, :func:`motionlab.fusion.stage.calibration_acc_bias`, zero where
    the movement next to a rest cannot level it; the recording as it is when there is none):
    a stand's gravity direction is then not tilted by the bias that the fused orientation of
    the movement next to it does not have."""
    return _less_bias(session, label, "acc", "acc_bias")


def corrected_gyr(session: Session, label: str) -> np.ndarray:
    """Sensor ``label``'s gyroscope (N, 3) rad/s less the bias its fusion estimated
    (``results.fusion[label].gyro_bias``; the recording as it is when there is none): a
    functional axis, a hinge fit or a heading tie then reads the segment's rotation, not the
    constant rate an uncalibrated gyroscope adds (3-6 °/s on the ``harsh`` simulated preset tilted
    a pelvis's flexion axis and set a lumbar lateral bending 6.6° off throughout)."""
    return _less_bias(session, label, "gyr", "gyro_bias")


def _less_bias(session: Session, label: str, channel: str, bias_field: str) -> np.ndarray:
    """Sensor ``label``'s ``channel`` less its fusion entry's ``bias_field`` (per sample, same
    shape), or as recorded when the fusion gave none."""
    x = np.asarray(getattr(session.sensors[label], channel), dtype=float)
    fused = session.results.fusion.get(label)
    bias = None if fused is None else getattr(fused, bias_field)
    if bias is None:
        return x
    bias = np.asarray(bias, dtype=float)
    return x - bias if bias.shape == x.shape else x


def streams_of(session: Session, protocol: Protocol) -> Streams:
    """``{segment: (time, acc, gyr)}`` for every protocol segment that has a sensor (``acc``
    and ``gyr`` less the fusion's biases, :func:`corrected_acc`, :func:`corrected_gyr`)."""
    out: Streams = {}
    for seg, spec in protocol.segments.items():
        label = sensor_for_segment(session, seg)
        if label is None:
            if spec.required:
                raise _no_sensor(protocol, seg)
            continue
        s = session.sensors[label]
        if s.acc is not None and s.gyr is not None:
            out[seg] = (s.time, corrected_acc(session, label), corrected_gyr(session, label))
        elif s.quat is not None:  # rows without a finite orientation are missing samples
            q = np.asarray(s.quat, float)
            ok = np.isfinite(q).all(axis=1)
            out[seg] = signals_from_orientation(s.time[ok], q[ok])
        else:
            raise InputError(
                f"sensor '{label}' has neither accelerometer and gyroscope nor an orientation",
                where=f"sensor {label}",
                remedy="calibration needs raw acc and gyr, or the vendor's orientation",
            )
    _check_overlap(session, out)
    return out


#: the protocol's sensors must share at least this much recording (s)
MIN_SHARED_S = 1.0


def _check_overlap(session: Session, streams: Streams) -> None:
    """An :class:`InputError` naming each segment's sensor and span when the streams share less
    than ``MIN_SHARED_S`` and less than half the shortest of them: a device whose clock was not
    set before recording (an x-IMU3 an hour off), or files of different recordings. The clock
    sync corrects fractions of a second."""
    if len(streams) < 2:
        return
    start = max(float(t[0]) for t, _, _ in streams.values())
    end = min(float(t[-1]) for t, _, _ in streams.values())
    shortest = min(float(t[-1] - t[0]) for t, _, _ in streams.values())
    # a short recording (a single pose) is too short, which the steps say; not a clock's fault
    if end - start >= min(MIN_SHARED_S, 0.5 * shortest):
        return
    spans = ", ".join(
        f"{seg}'s {sensor_for_segment(session, seg)} {t[0]:.1f}–{t[-1]:.1f} s"
        for seg, (t, _, _) in streams.items()
    )
    raise InputError(
        f"the sensors share {max(end - start, 0.0):.1f} s of recording ({spans}, session time)",
        where="sensor clocks",
        remedy="synchronise the devices' clocks before recording, or give the files of one "
        "recording",
    )


def sensor_orientation(session: Session, label: str) -> np.ndarray:
    """(N, 4) sensor → earth orientation of one sensor (see the module docstring); an
    :class:`InputError` for a sensor with raw acc and gyr that has not been fused."""
    fused = session.results.fusion.get(label)
    if fused is not None:
        q = np.asarray(fused.quat, dtype=float)
        if q.shape != (session.sensors[label].n_samples, 4):
            raise InputError(
                f"fusion result has shape {q.shape}, the sensor {session.sensors[label].n_samples}"
                " samples",
                where=f"results/fusion/{label}/quat",
                remedy="fuse again with force=True after ingest",
                argument="force",
            )
        return q
    s = session.sensors[label]
    if s.acc is not None and s.gyr is not None:
        raise InputError(
            f"sensor '{label}' has no fusion result",
            where=f"results/fusion/{label}",
            remedy="run 'motionlab fuse' (or motionlab.fuse(session)) first",
        )
    if s.quat is not None:
        return np.asarray(s.quat, dtype=float)
    raise InputError(
        f"sensor '{label}' has neither an orientation nor acc and gyr",
        where=f"sensor {label}",
        remedy="run motionlab fuse or ingest a file with orientation",
    )


def joint_segments(protocol: Protocol) -> list[str]:
    """The segments the protocol's joints use, in order of first use."""
    return list(dict.fromkeys(s for j in protocol.joints.values() for s in (j.proximal, j.distal)))


def angle_segments(session: Session, protocol: Protocol) -> list[str]:
    """The segments the joint angles need: the joints' (:func:`joint_segments`), and the trunk
    when it has a sensor, against which an upper arm's skin lag is undone (:mod:`.skin_lag`)."""
    segs = joint_segments(protocol)
    if TRUNK in protocol.segments and TRUNK not in segs and sensor_for_segment(session, TRUNK):
        segs.append(TRUNK)
    return segs


def sensor_quats(
    session: Session,
    protocol: Protocol,
    segments: list[str] | None = None,
) -> SegmentQuats:
    """``{segment: (time, q_sensor)}`` of the segments the angles need (:func:`angle_segments`),
    or of ``segments``.

    Rows without a finite orientation (a vendor file's gaps, e.g. ``NaN`` rows of a ``.sto``)
    are left out, as missing samples are: the angles SLERP across them."""
    quats = {}
    for seg in segments or angle_segments(session, protocol):
        label = sensor_for_segment(session, seg)
        if label is None:
            raise _no_sensor(protocol, seg)
        q = sensor_orientation(session, label)
        ok = np.isfinite(q).all(axis=1)
        quats[seg] = (
            (session.sensors[label].time[ok], q[ok])
            if not ok.all()
            else (session.sensors[label].time, q)
        )
    return quats
