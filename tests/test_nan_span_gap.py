"""A sensor's samples that are not numbers for longer than the fusion bridges (0.1 s) are the
packet loss they stand for (vendors write NaN rows for lost packets): the rows are dropped at
ingest, and the gap they leave is kept, fused across and left without angles exactly as the same
samples dropped from the time stamps would be. A run of 0.1 s or less stays for the fusion to
bridge; a magnetometer's NaN run makes no gap of the accelerometer and gyroscope."""

from __future__ import annotations

import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from conftest import generic_reader

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_input_boundaries import cli, refused  # noqa: E402

from motionlab.errors import InputError  # noqa: E402
from motionlab.fusion.stage import fuse_session  # noqa: E402
from motionlab.ingest import ingest  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.session import SensorStream, Session, load_session, save_session  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402
from motionlab.timebase import take  # noqa: E402

SPAN = (18.0, 19.0)  # s: the left thigh's lost second, mid-walk


def _inside(t: np.ndarray) -> np.ndarray:
    return (t > SPAN[0]) & (t < SPAN[1])


@pytest.fixture(scope="module")
def walks():
    """A stand and a 20-s walk, twice: the left thigh's acc and gyr NaN over ``SPAN``, and the
    same samples dropped (lost packets), each analysed."""
    proto = load_protocol("walk")
    session, truth = simulate(proto, 28.0, 2, "typical", soft_tissue="motion")
    for label, s in list(session.sensors.items()):
        session.sensors[label] = dataclasses.replace(
            s, time=truth.sensors[label]["sample_time"], mag=None
        )
    nan, dropped = copy.deepcopy(session), session
    s = nan.sensors["thigh_l"]
    nan.metadata["lost"] = int(_inside(s.time).sum())
    acc, gyr = s.acc.copy(), s.gyr.copy()
    acc[_inside(s.time)] = np.nan
    gyr[_inside(s.time), 1] = np.nan  # one axis is enough
    nan.sensors["thigh_l"] = dataclasses.replace(s, acc=acc, gyr=gyr)
    s = dropped.sensors["thigh_l"]
    dropped.sensors["thigh_l"] = take(s, np.flatnonzero(~_inside(s.time)))
    for ses in (nan, dropped):
        prepare_sensors(ses)
        analyse(ses, PipelineOptions(proto, progress=False, clock_sync=False))
    return nan, dropped


def test_the_nan_rows_become_the_gap_of_the_samples_dropped(walks):
    nan, dropped = walks
    a, b = nan.sensors["thigh_l"], dropped.sensors["thigh_l"]
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.gyr, b.gyr)
    assert a.qc["gaps"] == b.qc["gaps"] and any(g[1] - g[0] > 0.9 for g in a.qc["gaps"])
    assert a.qc["dropped_samples"] == b.qc["dropped_samples"]
    assert a.qc["nan_rows_dropped"] == nan.metadata["lost"] > 90
    assert a.qc["nan_spans"]["acc"] and a.qc["flags"]["nan_spans"]  # as recorded


def test_no_angles_in_the_nan_span_and_the_same_angles_elsewhere(walks):
    nan, dropped = walks
    a, b = nan.results.angles.columns(), dropped.results.angles.columns()
    t = a["time_s"]
    np.testing.assert_array_equal(t, b["time_s"])
    inside = _inside(t)
    assert inside.sum() > 50
    for column in ("knee_l_flexion_deg", "hip_l_flexion_deg"):
        assert np.isnan(a[column][inside]).all()
    assert np.isfinite(a["knee_r_flexion_deg"][inside]).all()
    for column in a:
        np.testing.assert_allclose(a[column], b[column], atol=1e-6, equal_nan=True)
    gaps = nan.results.fusion["thigh_l"].gaps_bridged_s
    assert any(g[0] <= SPAN[0] + 0.02 and g[1] >= SPAN[1] - 0.02 for g in np.asarray(gaps))


def _stream(n: int = 1000, mag: bool = False) -> SensorStream:
    rng = np.random.default_rng(5)
    t = np.arange(n) / 100.0
    acc = rng.normal(0, 0.05, (n, 3)) + [0.0, 0.0, 9.81]
    extra = {"mag": rng.normal(0, 0.3, (n, 3)) + [0.0, 20.0, -40.0]} if mag else {}
    return SensorStream("shank_r", t, acc=acc, gyr=rng.normal(0, 0.01, (n, 3)),
                        segment="shank", side="r", **extra)  # fmt: skip


def _prepared(s: SensorStream) -> SensorStream:
    ses = Session(metadata={})
    ses.sensors[s.label] = s
    prepare_sensors(ses)
    return ses.sensors[s.label]


def test_a_run_the_fusion_bridges_is_left_to_it():
    s = _stream()
    s.gyr[400:409] = np.nan  # 0.1 s from the finite sample before to the one after
    out = _prepared(s)
    assert out.n_samples == 1000 and not out.qc["gaps"] and "nan_rows_dropped" not in out.qc
    entry = fuse_session(Session(sensors={"shank_r": out}), "madgwick", magnetometer=False)
    assert entry["shank_r"].nan_bridged_s == [[4.0, 4.08]]


def test_a_magnetometer_nan_run_makes_no_gap():
    s = _stream(mag=True)
    s.mag[200:500] = np.nan
    out = _prepared(s)
    assert out.n_samples == 1000 and not out.qc["gaps"] and out.qc["nan_spans"]["mag"]
    ses = Session(sensors={"shank_r": out})
    assert np.isfinite(fuse_session(ses, "madgwick", magnetometer=False)["shank_r"].quat).all()
    with pytest.raises(InputError) as exc:  # 9-D: no magnetometer to hold for 3 s
        fuse_session(ses, "madgwick", magnetometer=True)
    assert "mag not a number from 2.00 s" in exc.value.line()
    assert "fuse without the magnetometer" in exc.value.line()


def test_gaps_are_measured_at_the_rate_recorded_before_the_nan_rows_go():
    """A sensor whose rows are NaN but for three samples: measured on what was left, its
    rate read 1/3 Hz and it had no gap at all; at the 100 Hz recorded its two losses are
    the gaps kept."""
    s = _stream()
    keep = np.zeros(1000, bool)
    keep[[0, 400, 999]] = True
    s.acc[~keep] = np.nan
    out = _prepared(s)
    assert out.n_samples == 3 and out.qc["nan_rows_dropped"] == 997
    assert np.allclose(out.qc["gaps"], [[0.0, 4.0], [4.0, 9.99]])
    assert out.qc["dropped_samples"] == 997


def test_a_sensor_with_no_finite_sample_left_is_refused_in_one_line(tmp_path):
    s = _stream()
    s.acc[1:] = np.nan
    ses = Session(metadata={})
    ses.sensors[s.label] = s
    save_session(ses, tmp_path / "s.h5")
    refused(cli(tmp_path, "fuse", "s.h5", "-o", "o.h5"),
            "sensor shank_r: acc/gyr not a number in 999 of its 1000 samples")  # fmt: skip


def test_nan_rows_in_a_csv_are_kept_as_a_gap(tmp_path):
    """A CSV export with empty fields for 0.5 s of lost packets: ingest keeps the gap, and
    ``info`` says the rows were dropped."""
    s = _stream(600)
    table = pd.DataFrame(np.column_stack([s.time, s.acc, s.gyr]),
                         columns=["t", "ax", "ay", "az", "gx", "gy", "gz"])  # fmt: skip
    table.loc[200:249, ["ax", "ay", "az", "gx", "gy", "gz"]] = np.nan
    table.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "map.yaml").write_text(yaml.safe_dump({"reader": generic_reader()}))
    (out,) = ingest([tmp_path / "a.csv"], tmp_path / "map.yaml").sensors.values()
    assert out.n_samples == 550 and out.qc["nan_rows_dropped"] == 50
    assert out.qc["gaps"] == [[1.99, 2.5]] and out.qc["flags"]["gaps"]
    r = cli(tmp_path, "ingest", "a.csv", "--map", "map.yaml", "-o", "s.h5")
    assert r.exit_code == 0, r.output
    info = cli(tmp_path, "info", "s.h5").output
    assert "gaps kept as missing: 1.99–2.50 s" in info and "50 nan rows dropped" in info


def test_a_session_ingested_with_its_nan_runs_loses_them_when_prepared():
    """A stream whose ingest kept a long NaN run (an ingest before they were dropped) gets the
    gap now: dropped, kept, listed in ``qc["gaps"]``; ``--rate``'s NaN inside a kept gap too."""
    s = _stream()
    s.gyr[300:400] = np.nan
    s.qc = {"gap_max_s": 0.1, "gaps": [], "flags": {"gaps": False}, "gaps_filled": 0}
    out = _prepared(s)
    assert out.n_samples == 900 and out.qc["gaps"] == [[2.99, 4.0]] and out.qc["flags"]["gaps"]
    assert _prepared(out).qc == out.qc  # once is enough


def test_a_resampled_session_with_a_kept_gap_is_fused(tmp_path):
    """``ingest --rate`` fills a kept gap's instants with NaN; ``fuse`` refused it ("gyr/acc
    not a number … export the recording again") for a gap like any other."""
    s = _stream()
    keep = np.r_[0:300, 400:1000]
    table = pd.DataFrame(np.column_stack([s.time, s.acc, s.gyr])[keep],
                         columns=["t", "ax", "ay", "az", "gx", "gy", "gz"])  # fmt: skip
    table.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "map.yaml").write_text(yaml.safe_dump({"reader": generic_reader()}))
    r = cli(tmp_path, "ingest", "a.csv", "--map", "map.yaml", "--rate", "50", "-o", "s.h5")
    assert r.exit_code == 0, r.output
    r = cli(tmp_path, "fuse", "s.h5", "-o", "f.h5")
    assert r.exit_code == 0, r.output
    out = load_session(tmp_path / "f.h5")
    (stream,) = out.sensors.values()
    assert stream.qc["gaps"] == [[2.98, 4.0]]
    assert np.isfinite(out.results.fusion[stream.label].quat).all()


def test_a_stand_lost_by_one_sensor_is_said_with_the_sensor(walks):
    """The left thigh NaN (or lost) over the whole stand: the stand is looked for where every
    sensor has data, and its refusal now says which sensor has none there (the final rest,
    with no walk after it, is not the stand: ``walk_checks`` as the calibration asks)."""
    from motionlab.segments.steps import find_steps

    _, dropped = walks
    streams = {s.label: (s.time, s.acc, s.gyr) for s in dropped.sensors.values()}
    t, acc, gyr = streams["thigh_l"]
    later = t > 12.0
    streams["thigh_l"] = (t[later], acc[later], gyr[later])
    with pytest.raises(InputError) as exc:
        find_steps(
            streams,
            load_protocol("walk"),
            suggest=False,
            pose_check=lambda step, span: "no walk after it" if span[0] > 20 else None,
        )
    assert "'standing'" in exc.value.line()
    assert "thigh_l has data only from 12.0 s (the others from 0.0 s)" in exc.value.line()
