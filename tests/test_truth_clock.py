"""An analysis of a simulated recording is compared with the truth on the true time: the
analysis's ``time_s`` is its reference sensor's own clock (``Truth.true_time`` maps it)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_simulate import knee_protocol

from motionlab.errors import InputError
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.simulate import simulate
from motionlab.simulate.errors import PRESETS, get_preset


def test_true_time_maps_a_sensor_clock_to_the_true_instants():
    """The recorded stamps map to their true instants exactly, instants between them to the
    clock model's (offset, drift) within its jitter; stamps of another recording are refused."""
    session, truth = simulate(knee_protocol(), 20.0, 7, "typical", calibration=False)
    label = next(iter(session.sensors))
    stamps, info = session.sensors[label].time, truth.sensors[label]
    assert np.array_equal(truth.true_time(label, stamps, stamps), info["sample_time"])
    mid = 0.5 * (stamps[100:200] + stamps[101:201])
    model = (mid - info["clock_offset_s"]) / (1.0 + info["clock_drift"])
    jitter = PRESETS["typical"].timing.jitter_s
    assert np.abs(truth.true_time(label, stamps, mid) - model).max() < 6 * jitter
    with pytest.raises(InputError, match="stamps"):
        truth.true_time(label, stamps[:-1], stamps)


def _skin_late_clock(late_s: float):
    """The ``skin`` preset on one radio clock (no sync to make) that reads ``late_s`` (s) behind
    the true time."""
    preset = get_preset("skin")
    timing = dataclasses.replace(preset.timing, clock_offset_sigma_s=0.0, clock_drift_sigma=0.0)
    return dataclasses.replace(preset, timing=timing), late_s


def test_a_walks_knee_flexion_read_on_the_true_time():
    """A 25-s ``skin`` walk through ``motionlab run``'s stages on one clock 25 ms behind the
    true time: its angles' ``time_s`` is that clock. Read against the truth at ``time_s`` taken
    as the true time, the knee flexion is out of step by the clock's offset (a 240-s walk,
    seed 4, its pelvis clock 23 ms off: 5.4° / 5.7° RMSE, mistaken for the product's error);
    read at ``Truth.true_time`` it is the product's own (2.0° / 2.5° there)."""
    protocol = load_protocol("walk")
    preset, late = _skin_late_clock(0.025)
    session, truth = simulate(protocol, 25.0, 4, preset, mounting="random", rest_s=2.0)
    for label, s in session.sensors.items():
        session.sensors[label] = dataclasses.replace(s, time=s.time - late)
    stamps = session.sensors["pelvis"].time.copy()
    prepare_sensors(session)
    analyse(session, PipelineOptions(protocol, progress=False, clock_sync=False))
    ang = session.results.angles.columns()
    true_t = truth.true_time("pelvis", stamps, ang["time_s"])
    assert np.mean(true_t - ang["time_s"]) == pytest.approx(late, abs=0.002)
    walk = truth.step("walk")
    inside = (true_t > walk["start_s"] + 1) & (true_t < walk["end_s"] - 1)
    for side in "rl":
        col = f"knee_{side}_flexion_deg"
        ok = inside & np.isfinite(ang[col])
        on_true = ang[col] - np.interp(true_t, truth.time, truth.joint_angles[col])
        naive = ang[col] - np.interp(ang["time_s"], truth.time, truth.joint_angles[col])
        rms, rms_naive = (float(np.sqrt(np.mean(e[ok] ** 2))) for e in (on_true, naive))
        assert rms < 2.5 and rms_naive > rms + 2.0, (col, rms, rms_naive)
