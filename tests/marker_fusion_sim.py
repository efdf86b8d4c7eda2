"""Simulated session and error figures for the IMU + marker fusion acceptance (not a test module).

Shared by ``tests/test_fusion_markers.py`` and ``bench/marker_fusion.py``. The session is the
knee protocol of :func:`motionlab.simulate.simulate` with markers (120 Hz camera clock, 0.137 s
offset, 100 ppm drift, 1 mm noise, its own short random occlusions) and the ``typical`` IMU
errors except the ones sensor calibration removes (scale factors, axis misalignment, soft and
hard iron): gyroscope bias 0.5°/s, accelerometer bias 0.1 m/s², noise, bias walk, quantisation,
clock offsets and drift, jitter, lost packets and soft-tissue wobble stay. On top, whole marker
frames are hidden in blocks of 1–5 s until ``occluded`` of the frames are gone. The IMU streams
get the ingest's short-gap filling (:func:`motionlab.timebase.fill_short_gaps`), the filled spans
listed in ``qc["filled_spans_s"]`` as ingest lists them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.fusion.stage import filled_spans
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset
from motionlab.timebase import fill_short_gaps
from motionlab.validation.markermap import default_marker_map
from motionlab.validation.optical import resample_quat, track_cluster

_TYPICAL = get_preset("typical")
CALIBRATED = dataclasses.replace(
    _TYPICAL,
    name="typical-calibrated",
    gyr=dataclasses.replace(_TYPICAL.gyr, scale_sigma=0.0, misalignment_sigma=0.0),
    acc=dataclasses.replace(_TYPICAL.acc, scale_sigma=0.0, misalignment_sigma=0.0),
    mag=dataclasses.replace(_TYPICAL.mag, scale_sigma=0.0, misalignment_sigma=0.0),
    hard_iron_sigma=0.0,
    soft_iron_sigma=0.0,
)
GAP_FILL_S = 0.1


def hidden_blocks(t: np.ndarray, fraction: float, rng, shortest: float = 1.0, longest: float = 5.0):
    """Blocks of ``shortest``–``longest`` s (1 s apart at least) covering ``fraction`` of the
    samples at times ``t``: bool mask."""
    hidden = np.zeros(len(t), bool)
    while hidden.mean() < fraction:
        length = rng.uniform(shortest, longest)
        start = rng.uniform(t[0], t[-1] - length)
        if hidden[(t >= start - 1.0) & (t <= start + length + 1.0)].any():
            continue
        hidden |= (t >= start) & (t <= start + length)
    return hidden


def acceptance_session(
    duration: float = 60.0, seed: int = 1, occluded: float = 0.3, preset=None, gait=None
):
    """``(session, truth, hidden)``: the simulated session with occlusion blocks (module doc);
    ``gait``: the walk's options (:func:`motionlab.simulate.simulate`)."""
    session, truth = simulate(
        "knee", duration, seed, preset or CALIBRATED, markers=True, calibration=False, gait=gait
    )
    for label, stream in session.sensors.items():  # as ingest fills them, and lists them
        filled, report = fill_short_gaps(stream, GAP_FILL_S)
        qc = {**filled.qc, "filled_spans_s": report["filled_spans_s"]}
        session.sensors[label] = dataclasses.replace(filled, qc=qc)
    markers = session.markers["optical"]
    hidden = hidden_blocks(markers.time, occluded, np.random.default_rng(seed))
    markers.positions[hidden] = np.nan
    return session, truth, hidden


def truth_at_samples(session, truth, label: str) -> tuple[np.ndarray, np.ndarray]:
    """True sensor orientation (N, 4) at the sensor's samples and their optical-clock times."""
    sensor = truth.sensors[label]
    t_true = (session.sensors[label].time - sensor["clock_offset_s"]) / (1 + sensor["clock_drift"])
    q = rot.resample(truth.time, sensor["orientation"], t_true)
    return q, truth.markers["clock_offset_s"] + (1 + truth.markers["clock_drift"]) * t_true


def cluster_error(session, truth, label: str, sensor_to_cluster: np.ndarray) -> float:
    """Angle (deg) between a sensor → cluster rotation and the true one (the mean over the
    record of the true sensor orientation seen from the cluster's, soft tissue averaged)."""
    markers = session.markers["optical"]
    mmap = default_marker_map(markers, None, list(session.sensors))
    q_true, t_opt = truth_at_samples(session, truth, label)
    cols = [markers.labels.index(m) for m in mmap.segments[label].cluster]
    track = track_cluster(markers.time, markers.positions[:, cols])
    b = resample_quat(track.time, track.quat, t_opt)
    ok = np.isfinite(b).all(axis=1)
    y = rot.conj(truth.markers["lab_rotation"])
    x_true = rot.mean(rot.mul(rot.conj(b[ok]), rot.mul(y, q_true[ok])))
    return float(np.degrees(rot.angle_between(x_true, sensor_to_cluster)))


def rms(err: np.ndarray, mask: np.ndarray) -> float:
    return float(np.sqrt(np.mean(err[mask] ** 2)))


def evaluate(session, truth, hidden, refs, name: str, **params) -> dict[str, dict[str, float]]:
    """Per sensor with references: RMS error (deg) of the fused estimate on the samples with
    marker vectors (``visible``) and in the hidden blocks (``gaps``), and of the IMU-only
    estimate in the blocks and overall."""
    markers = session.markers["optical"]
    out = {}
    for label, ref in refs.items():
        s = session.sensors[label]
        q_true, t_opt = truth_at_samples(session, truth, label)
        in_block = np.interp(t_opt, markers.time, hidden.astype(float)) > 0.5
        # as the fusion stage runs it: ingest's filled gaps judged as the gaps they are
        kw = {"time": s.time, "filled_spans": filled_spans(s), **params}
        fused = estimate(name, s.gyr, s.acc, s.mag, s.rate_hz, references=ref, **kw)
        alone = estimate(name, s.gyr, s.acc, s.mag, s.rate_hz, **kw)
        e_fused = np.degrees(rot.angle_between(fused.quat, q_true))
        e_alone = np.degrees(rot.angle_between(alone.quat, q_true))
        out[label] = {
            "visible": rms(e_fused, ref.visible),
            "gaps": rms(e_fused, in_block),
            "imu_only_gaps": rms(e_alone, in_block),
            "imu_only": rms(e_alone, np.ones(len(e_alone), bool)),
        }
    return out
