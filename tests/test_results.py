"""Typed stage results: every attribute documented (and the report's rows'), the session file's
old schema and the layout before the typed records still load."""

import dataclasses
import inspect
import json
import typing

import h5py
import numpy as np
import pandas as pd
import pytest

import motionlab.results as results_module
from motionlab.report.model import CalibrationRow, GradeRow, QualityRow, RomRow, SymmetryRow
from motionlab.results import (
    STAGES,
    AlignmentRotation,
    AngleAgreement,
    AngleMetrics,
    AngleTable,
    AxisMeasurement,
    CentreHeading,
    ClockFit,
    ClockSync,
    CrossTalk,
    FusionEntry,
    Gait,
    GaitEvents,
    GaitPelvis,
    GaitSummary,
    HeadingCorrection,
    HeadingTie,
    HeadingTies,
    HingeFit,
    HipAxis,
    JointGrades,
    Metrics,
    MovementProfile,
    OpticalSegmentInfo,
    OpticalSync,
    OrientationErrors,
    OutOfPlaneOffset,
    RepetitionAgreement,
    Results,
    SegmentCalibration,
    SegmentQuality,
    SegmentRecord,
    SensorOrientationError,
    SpatialAlignment,
    StanceMetrics,
    StrideStats,
    StrideTable,
    TaskBlock,
    TrunkCompensation,
    TrunkMovement,
    TwoAxisFit,
    Validation,
    ValidationReference,
)
from motionlab.session import SCHEMA_VERSION, SensorStream, Session, load_session, save_session

#: every record class of the results module, and the report's rows
RECORDS = tuple(
    cls
    for _, cls in inspect.getmembers(results_module, inspect.isclass)
    if dataclasses.is_dataclass(cls)
    and cls.__module__ == results_module.__name__
    and cls is not Results  # its fields are the stages, documented in the module's table
) + (GradeRow, RomRow, SymmetryRow, QualityRow, CalibrationRow)


@pytest.mark.parametrize("cls", RECORDS, ids=lambda c: c.__name__)
def test_every_attribute_of_a_result_is_documented(cls):
    """As gaitmap tests its ``results_``: each field is named in its class's docstring (or, for
    an inherited field, in its base class's)."""
    doc = "".join(inspect.getdoc(c) or "" for c in cls.__mro__ if dataclasses.is_dataclass(c))
    missing = [
        f.name for f in dataclasses.fields(cls) if f.name != "more" and f"``{f.name}``" not in doc
    ]
    assert not missing, f"{cls.__name__} does not document {missing}"


def test_the_records_reach_the_leaves():
    """Every record class is listed above (the ones a session stores) and no field of one is
    declared ``Any`` (``more`` aside, where the keys a newer version wrote are kept): a result's
    dictionaries are maps keyed by the data's own names holding records, arrays or numbers."""
    assert {FusionEntry, SegmentRecord, AxisMeasurement, Validation, StrideTable} <= set(RECORDS)
    untyped = [
        f"{cls.__name__}.{name}"
        for cls in RECORDS
        for name, hint in typing.get_type_hints(cls).items()
        if name in {f.name for f in dataclasses.fields(cls)} - {"more"} and "Any" in str(hint)
    ]
    assert untyped == []


def test_every_stage_is_documented_in_the_module_table():
    doc = results_module.__doc__
    fields = [f.name for f in dataclasses.fields(Results) if f.name != "more"]
    assert fields == list(STAGES)
    assert all(f"``{name}``" in doc for name in STAGES)


def test_the_angle_table_holds_only_numbers_in_its_columns():
    t = np.arange(5) / 100.0
    table = AngleTable.from_columns(
        {"time_s": t, "knee_r_flexion_deg": np.ones(5)}, "accel-only", {"walk": (0.0, 0.04)}
    )
    df = pd.DataFrame(table.columns())
    assert list(df.columns) == ["time_s", "knee_r_flexion_deg"]
    assert all(k.kind == "f" for k in df.dtypes)
    assert table.units == {"knee_r_flexion_deg": "deg"} and table.method == "accel-only"
    back = AngleTable.from_tree(table.to_tree())
    assert back.events == {"walk": (0.0, 0.04)} and back.method == "accel-only"
    np.testing.assert_array_equal(back.time, t)


def _analysed_session() -> Session:
    rng = np.random.default_rng(3)
    t = np.arange(200) / 100.0
    q = np.tile([1.0, 0.0, 0.0, 0.0], (200, 1))
    sensor = SensorStream("shank_r", t, acc=rng.normal(size=(200, 3)), gyr=np.zeros((200, 3)))
    fit = ClockFit("thigh_r", "shank_r", 0.012, 2e-5, 1.0, 4e-4, 1e-6, 0.02, 30.0, "applied")
    res = Results(
        clock_sync=ClockSync({"shank_r": fit}),
        fusion={"shank_r": FusionEntry("default", q, {"gain": 0.5}, magnetometer=False)},
        calibration=SegmentCalibration(
            "knee", steps={"stand": [0.1, 0.6], "squat": None}, protocol_path="knee.yaml"
        ),
        angles=AngleTable(t, {"knee_r_flexion_deg": rng.normal(size=200)}),
        heading={"knee_r": HeadingCorrection("hinge", 3, 1.0, 0.5, 0.1)},
        metrics=Metrics("knee", blocks={"walk": TaskBlock(0.8, 1.9)}),
        gait=Gait("no gait: no shank sensor under a knee joint"),
    )
    return Session(sensors={"shank_r": sensor}, results=res)


def test_a_schema_1_file_loads(tmp_path):
    """Schema 1 (before the typed results) had the same layout without the angle table's
    ``units`` and ``events``: such a file loads, with the units from the column names and the
    events from the calibration steps and the metric blocks, and is written back as schema 2."""
    ses = _analysed_session()
    path = tmp_path / "old.h5"
    save_session(ses, path)
    with h5py.File(path, "r+") as f:  # the file as schema 1 wrote it
        f.attrs["schema_version"] = 1
        del f["results/angles/units"], f["results/angles/events"]
        assert json.loads(f["results/angles"].attrs["method"]) == "imu"
        assert f["results/clock_sync/shank_r"].attrs["status"] == '"applied"'
    old = load_session(path)
    assert old.schema_version == 1
    res = old.results
    assert res.stages() == ["clock_sync", "fusion", "calibration", "angles", "heading",
                            "metrics", "gait"]  # fmt: skip
    assert res.clock_sync.fits["shank_r"] == ses.results.clock_sync.fits["shank_r"]
    assert res.fusion["shank_r"].magnetometer is False
    np.testing.assert_array_equal(res.fusion["shank_r"].quat, ses.results.fusion["shank_r"].quat)
    assert res.calibration.protocol_source == "knee.yaml"
    assert res.angles.units == {"knee_r_flexion_deg": "deg"}
    assert res.angles.events == {"stand": (0.1, 0.6), "walk": (0.8, 1.9)}
    np.testing.assert_array_equal(res.angles.data["knee_r_flexion_deg"],
                                  ses.results.angles.data["knee_r_flexion_deg"])  # fmt: skip
    assert res.heading["knee_r"] == ses.results.heading["knee_r"]
    assert res.metrics.spans() == {"walk": (0.8, 1.9)}
    assert not res.gait.ok
    save_session(old, tmp_path / "new.h5")
    with h5py.File(tmp_path / "new.h5") as f:
        assert int(f.attrs["schema_version"]) == SCHEMA_VERSION == 3
        assert "events" in f["results/angles"]


def test_results_round_trip_through_the_file(tmp_path):
    ses = _analysed_session()
    save_session(ses, tmp_path / "s.h5")
    back = load_session(tmp_path / "s.h5").results
    assert back.angles.events == {}
    assert back.heading == ses.results.heading
    assert back.clock_sync == ses.results.clock_sync
    assert back.gait == ses.results.gait


def _old_calibration_tree() -> dict:
    """A calibration as the session file held it before the typed records (segment records,
    their quality and the hinge fits were dicts), with a key a newer motionlab wrote in each."""
    quality = {"ok": False, "messages": ["shank_r: repeat the squat"], "min_rho": 0.91,
               "separation_deg": None, "lm_difference_deg": None,
               "hinge_check_deg": {"squat": 2.5}, "future_q": 1}  # fmt: skip
    segment = {"mounting": np.array([1.0, 0.0, 0.0, 0.0]), "method": "single_axis",
               "axes": {"stand": {"step": "stand", "kind": "static", "method": "gravity",
                                  "sensor_axis": np.array([0.0, 0.0, 1.0]),
                                  "segment_axis": np.array([0.0, 1.0, 0.0]), "rho": 0.99,
                                  "reference_rho": None, "joint_movement": False,
                                  "secondary": False, "used": True, "residual_deg": 0.4,
                                  "future_a": 3}},
               "quality": quality, "sensor": "shank_r", "hint_contradicted": True,
               "future_s": "kept"}  # fmt: skip
    hinge = {"used_for": "axes", "method": "seel", "witness_deg": np.nan, "dominance": np.nan,
             "proximal_tilt_deg": np.nan, "speed_ratio": np.nan, "joint": "elbow_r",
             "axis_proximal": np.array([0.0, 0.0, 1.0]), "axis_distal": np.array([0.0, 1.0, 0.0]),
             "residual_rad_s": 0.1, "relative_residual": 0.2, "consistency_deg": 3.0,
             "relative_sign": "measured", "sign": "anatomy", "excursion_deg": [120.0, -5.0],
             "window_s": [1.0, 9.0], "n_samples": 800, "verdict": "weak", "reasons": ["short"],
             "kind": "two_axes", "flexion_distal": np.array([0.0, 0.0, 1.0]),
             "heading_times": np.array([2.0, 4.0]), "heading_deltas": np.array([0.1, 0.2]),
             "future_h": [1, 2]}  # fmt: skip
    hip = {"used": False, "turn_deg": 0.0, "rho": 0.62, "n_samples": 900, "tilt_deg": 4.0,
           "reason": "no dominant hip axis (rho 0.62)"}  # fmt: skip
    trunk = {"rest_s": [0.5, 2.0], "rest_speed_deg_s": 0.8, "axis_ratio": 2.1,
             "energy_ratio": 1.4, "axis_rank": 1, "one_sided": [3.0, 1.2],
             "excursion_deg": [40.0, -8.0], "sign_ratio": 3.0, "heading_deg": 12.0,
             "heading_rho": 0.9, "heading_drift_deg": None, "future_t": 2}  # fmt: skip
    grades = {"lumbar": {"grades": ["determined", "determined", "weak"],
                         "reasons": ["", "", "few turns"], "trunk": trunk},
              "elbow_r": {"grades": ["weak"] * 3, "reasons": ["short"] * 3}}  # fmt: skip
    centres = {"hip_r": {"heading_times": np.array([1.0, 3.0]),
                         "heading_deltas": np.array([0.2, 0.3]), "anchors": 2},
               "lumbar": {"heading_times": [1.25], "heading_deltas": [0.05],
                          "method": "trunk rest"}}  # fmt: skip
    headings = {"sha256": {"thigh_r": "ab" * 32, "shank_r": "cd" * 32},
                "joints": {"knee_r": {"source": "hinge", "times": np.array([0.5, 9.5]),
                                      "deltas": np.array([0.01, 0.02])}}}  # fmt: skip
    return {"protocol": "elbow", "ok": False, "segments": {"forearm_r": segment},
            "hinges": {"elbow_r": hinge}, "hip_axes": {"hip_r": hip},
            "grades": grades, "centres": centres, "headings": headings}  # fmt: skip


def test_a_calibration_stored_before_the_typed_records_loads_and_is_stored_the_same(tmp_path):
    """The segment records, their quality, the hinge fits, the hip axes, the grades (with a
    trunk calibration's movement), the centres' and the joints' heading ties are typed in
    memory, the file's layout is the dicts' (``None`` fields as JSON null), and keys a newer
    motionlab wrote are kept in ``more`` and written back."""
    from motionlab.session import _read_tree, _write_tree

    old = _old_calibration_tree()
    path = tmp_path / "old.h5"
    save_session(Session(), path)
    with h5py.File(path, "r+") as f:  # the calibration as an older motionlab wrote it
        _write_tree(f.require_group("results").create_group("calibration"), old)
    cal = load_session(path).results.calibration
    seg, fit = cal.segments["forearm_r"], cal.hinges["elbow_r"]
    assert isinstance(seg, SegmentRecord) and isinstance(seg.quality, SegmentQuality)
    assert seg.method == "single_axis" and seg.sensor == "shank_r" and seg.hint_contradicted
    assert seg.quality.messages == ["shank_r: repeat the squat"] and not seg.quality.ok
    assert seg.quality.separation_deg is None and seg.quality.hinge_check_deg == {"squat": 2.5}
    stand = seg.axes["stand"]
    assert isinstance(stand, AxisMeasurement) and stand.rho == 0.99 and stand.in_fit
    assert stand.reference_rho is None and stand.hinge_check_deg is None
    assert stand.more == {"future_a": 3} and seg.more == {"future_s": "kept"}
    assert seg.quality.more == {"future_q": 1}
    assert isinstance(fit, TwoAxisFit) and fit.verdict == "weak" and fit.reasons == ["short"]
    assert list(fit.excursion_deg) == [120.0, -5.0] and fit.more == {"future_h": [1, 2]}
    np.testing.assert_array_equal(fit.heading_deltas, [0.1, 0.2])
    hip = cal.hip_axes["hip_r"]
    assert isinstance(hip, HipAxis) and not hip.used and hip.rho == 0.62 and hip.tilt_deg == 4.0
    lumbar, elbow = cal.grades["lumbar"], cal.grades["elbow_r"]
    assert isinstance(lumbar, JointGrades) and lumbar.reasons[2] == "few turns"
    assert isinstance(lumbar.trunk, TrunkMovement) and lumbar.trunk.excursion_deg == [40.0, -8.0]
    assert lumbar.trunk.heading_drift_deg is None
    assert lumbar.trunk.more == {"axis_rank": 1, "future_t": 2}  # axis_rank: a field no more
    assert elbow.grades == ["weak"] * 3 and elbow.trunk is None
    assert JointGrades.from_tree({"grades": ["weak"] * 3}).reasons == []
    hip_c, lumbar_c = cal.centres["hip_r"], cal.centres["lumbar"]
    assert isinstance(hip_c, CentreHeading) and hip_c.anchors == 2 and hip_c.method is None
    assert lumbar_c.method == "trunk rest" and lumbar_c.heading_deltas == [0.05]
    np.testing.assert_array_equal(hip_c.heading_times, [1.0, 3.0])
    assert isinstance(cal.headings, HeadingTies) and cal.headings.sha256["shank_r"] == "cd" * 32
    knee = cal.headings.joints["knee_r"]
    assert isinstance(knee, HeadingTie) and knee.source == "hinge"
    np.testing.assert_array_equal(knee.deltas, [0.01, 0.02])
    assert SegmentCalibration.from_tree({"protocol": "knee", "headings": {}}).headings is None
    save_session(load_session(path), tmp_path / "again.h5")
    with h5py.File(tmp_path / "again.h5") as f:
        again = _read_tree(f["results/calibration"])
    with h5py.File(path) as f:
        stored = _read_tree(f["results/calibration"])
    for name in ("segments", "hinges", "hip_axes", "grades", "centres", "headings"):
        assert json.dumps(again[name], sort_keys=True, default=repr) == json.dumps(
            stored[name], sort_keys=True, default=repr
        )


def test_a_hinge_fit_round_trips_and_a_plain_one_has_no_kind():
    z = np.array([0.0, 0.0, 1.0])
    fit = HingeFit("knee_r", z, -z, 0.1, 0.2, 3.0, "measured", "anatomy", (60.0, 1.0), (0.5, 9.5),
                   900, "determined")  # fmt: skip
    tree = fit.to_tree()
    assert "kind" not in tree and tree["excursion_deg"] == [60.0, 1.0]
    back = HingeFit.from_tree(tree)
    assert type(back) is HingeFit and back.to_tree().keys() == tree.keys()
    assert back.verdict == "determined" and back.n_samples == 900


def test_the_validation_sync_is_typed_and_stored_as_before(tmp_path):
    """``validation.sync`` is an :class:`OpticalSync`; its tree is the dict the file held
    before (one attribute per scalar, one dataset per window array), a newer key kept."""
    tree = {"method": "cross-correlation", "time_offset_s": 0.25, "drift_ppm": 12.0,
            "inlier_ratio": 0.9, "residual_rms_s": 0.002, "coarse_lag_s": 0.2, "n_windows": 2,
            "window_time_s": np.array([5.0, 10.0]), "window_lag_s": np.array([0.25, 0.25]),
            "window_sd_s": np.array([1e-3, 1e-3]), "window_corr": np.array([0.9, 0.8]),
            "window_pair": np.array([0, 0]), "inliers": np.array([True, False]),
            "standard_error_s": 4e-4, "grade": "good", "fallback": "", "signal": "gyroscope",
            "sensor_residual_s": {"shank_r": 0.0}, "future": 3}  # fmt: skip
    val = Validation.from_tree({"mode": "full", "sync": tree})
    sync = val.sync
    assert isinstance(sync, OpticalSync) and sync.time_offset_s == 0.25 and sync.grade == "good"
    assert sync.more == {"future": 3} and sync.sensor_residual_s == {"shank_r": 0.0}
    back = val.to_tree()["sync"]
    assert back.keys() == tree.keys()
    for k, v in tree.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(back[k], v)
        else:
            assert back[k] == v, k
    ses = Session(results=Results(validation=val))
    save_session(ses, tmp_path / "v.h5")
    again = load_session(tmp_path / "v.h5").results.validation.sync
    np.testing.assert_array_equal(again.inliers, [True, False])
    assert again.n_windows == 2 and again.more == {"future": 3}
    assert Validation.from_tree({"mode": "full"}).sync.method == "none"  # no sync stored


def test_the_validation_alignment_is_typed_and_stored_as_before():
    """``validation.alignment`` is a :class:`SpatialAlignment` of :class:`AlignmentRotation`;
    the dict the file held loads (a newer key kept) and its tree is that dict; an empty one
    (as a validation without it held) reads as ``None``."""
    tree = {"mode": "heading",
            "lab_to_earth": {"quat": np.array([1.0, 0.0, 0.0, 0.0]), "angle_deg": 0.0},
            "sensor_to_cluster": {"shank_r": {"quat": np.array([0.0, 1.0, 0.0, 0.0]),
                                              "angle_deg": 180.0}},
            "heading_deg": {"shank_r": 12.0}, "residual_rms_deg": {"shank_r": 1.5},
            "conditioning": {"shank_r": 0.4}, "future_a": True}  # fmt: skip
    al = Validation.from_tree({"mode": "heading", "alignment": tree}).alignment
    assert isinstance(al, SpatialAlignment) and al.more == {"future_a": True}
    x = al.sensor_to_cluster["shank_r"]
    assert isinstance(x, AlignmentRotation) and x.angle_deg == 180.0
    assert json.dumps(al.to_tree(), default=repr) == json.dumps(tree, default=repr)
    assert Validation.from_tree({"mode": "full", "alignment": {}}).alignment is None


def test_metrics_stored_before_the_typed_records_load_and_are_stored_the_same(tmp_path):
    """``metrics.joints[task][column]`` is an :class:`AngleMetrics` and a block a
    :class:`TaskBlock`; a file holding them as dicts loads, a newer key is kept, and they are
    written back as they were."""
    from motionlab.session import _read_tree, _write_tree

    flex = {"rom_deg": 60.0, "min_deg": 2.0, "max_deg": 62.0, "repetitions": 2,
            "cycle_max_deg": np.array([61.0, 62.0]), "cycle_min_deg": np.array([2.0, 3.0]),
            "cycle_max_mean_deg": 61.5, "cycle_min_mean_deg": 2.5,
            "curve_mean_deg": np.linspace(2.0, 62.0, 101), "curve_sd_deg": np.ones(101),
            "cycle_start_s": np.array([1.0, 2.1]), "future_m": "kept"}  # fmt: skip
    tree = {"protocol": "knee", "joints": {"squat": {"knee_r_flexion_deg": flex}},
            "blocks": {"squat": {"start_s": 0.5, "end_s": 3.5, "source": "given"}}}  # fmt: skip
    path = tmp_path / "old.h5"
    save_session(Session(), path)
    with h5py.File(path, "r+") as f:
        _write_tree(f.require_group("results").create_group("metrics"), tree)
    m = load_session(path).results.metrics.joints["squat"]["knee_r_flexion_deg"]
    assert isinstance(m, AngleMetrics) and m.repetitions == 2 and m.cycle_min_mean_deg == 2.5
    assert m.more == {"future_m": "kept"}
    block = load_session(path).results.metrics.blocks["squat"]
    assert isinstance(block, TaskBlock) and block.source == "given" and block.end_s == 3.5
    np.testing.assert_array_equal(m.cycle_start_s, [1.0, 2.1])
    save_session(load_session(path), tmp_path / "again.h5")
    with h5py.File(tmp_path / "again.h5") as f:
        again = _read_tree(f["results/metrics"])
    with h5py.File(path) as f:
        stored = _read_tree(f["results/metrics"])
    assert json.dumps(again, sort_keys=True, default=repr) == json.dumps(
        stored, sort_keys=True, default=repr
    )
    bare = AngleMetrics(1.0, 0.0, 1.0)  # no cycles: NaN curves, no starts stored
    assert bare.repetitions == 0 and np.isnan(bare.curve_mean_deg).all()
    assert "cycle_start_s" not in bare.to_tree()


def test_a_gait_summary_and_profile_stored_as_dicts_load_and_are_stored_the_same():
    """``gait.summary`` is a :class:`GaitSummary` and ``gait.map`` a :class:`MovementProfile`;
    the dicts the file held load (a newer key kept) and their trees are those dicts."""
    stats = {"mean": 1.1, "sd": 0.05, "cv_pct": 4.5, "se": 0.02, "median": 1.1, "q1": 1.05,
             "q3": 1.15, "strides_n": 8}  # fmt: skip
    summ = {"sides": {"r": {"stride_time_s": stats}, "l": {"stride_time_s": stats}},
            "min_strides": 3, "cadence_steps_per_min": 109.0, "step_pairs": 7,
            "step_time_asymmetry_pct": 2.0, "step_time_asymmetry_se_pct": 0.5,
            "stride_time_cv_pct": 3.0, "stride_time_cv_se_pct": 0.8, "walking_speed_m_s": 1.2,
            "strides_kept": 16, "strides_rejected": {"turn": 2}, "withheld": {},
            "future_g": 1}  # fmt: skip
    mp = {"gvs": {"r": {"knee_flexion": 5.0}}, "gps": {"r": 5.0, "overall": np.nan},
          "population_gps_deg": 5.5, "variables": ["knee_flexion"],
          "withheld": {"l": {"knee_flexion": "weak"}},
          "not_computed": "GPS not computed: left knee flexion weak"}  # fmt: skip
    gait = Gait.from_tree({"status": "ok", "summary": summ, "map": mp})
    s = gait.summary
    assert isinstance(s, GaitSummary) and s.step_pairs == 7 and s.strides_rejected == {"turn": 2}
    assert s.sides["r"]["stride_time_s"].strides_n == 8 and s.more == {"future_g": 1}
    assert gait.to_tree()["summary"] == summ
    assert isinstance(gait.map, MovementProfile) and gait.map.withheld == mp["withheld"]
    assert json.dumps(gait.to_tree()["map"]) == json.dumps(mp)  # NaN as NaN
    ungated = {k: mp[k] for k in ("gvs", "gps", "variables")}  # before the gating and its norm
    old = MovementProfile.from_tree(ungated)
    assert old.withheld is None and old.population_gps_deg is None and old.to_tree() == ungated
    assert Gait.from_tree({"status": "no gait: no shank"}).summary is None


def _old_validation_tree() -> dict:
    """A validation as the session file held it before its optical, orientation, angle and
    reference records (the dicts :func:`motionlab.validation.validate` built), with a key a
    newer motionlab might add at each level."""
    n = 6
    t = np.arange(n) / 60.0
    cluster = {"source": "cluster", "landmarks": ["LFE", "MFE"], "fitted_fraction": 0.99,
               "interpolated_fraction": 0.01, "flagged_fraction": 0.0, "n_long_gaps": 1,
               "residual_rms_mm": 1.1, "shape_m": np.eye(4, 3), "static_source": "still window",
               "static_s": [1.0, 4.0], "landmark_spread_mm": {"LFE": 0.5, "MFE": 0.7},
               "landmark_rms_mm": {}, "frame": "landmarks", "future_o": 1}  # fmt: skip
    body = {"source": "rigid_body", "landmarks": [], "fitted_fraction": 1.0,
            "rigid_body": "Shank", "segment_frame": True, "frame": "segment_frame"}  # fmt: skip
    errors = {"total_deg": np.full(n, 2.0), "heading_deg": np.full(n, 1.0),
              "inclination_deg": np.full(n, 1.5), "total_rmse_deg": 2.0,
              "heading_rmse_deg": 1.0, "inclination_rmse_deg": 1.5, "median_deg": 2.0,
              "iqr_deg": 0.1, "p95_deg": 2.2, "n_samples": n, "future_e": "x"}  # fmt: skip
    unseen = {"total_deg": np.full(n, np.nan), "heading_deg": np.full(n, np.nan),
              "inclination_deg": np.full(n, np.nan), "n_samples": 0}  # fmt: skip
    reps = {"n": 2, "start_s": np.array([0.0, 0.05]), "end_s": np.array([0.04, 0.08]),
            "rmse_deg": np.array([1.0, 1.2]), "bias_deg": np.array([0.1, -0.1]),
            "rom_error_deg": np.array([0.5, 0.4]), "peak_error_deg": np.array([0.2, 0.3]),
            "cmc": 0.99}  # fmt: skip
    flex = {"rmse_deg": 1.0, "bias_deg": 0.2, "sd_deg": 0.9, "max_abs_deg": 2.5,
            "rmse_centred_deg": 0.95, "r": 0.999, "cmc": 0.998, "loa_deg": [-1.6, 2.0],
            "n_samples": n, "imu_deg": np.linspace(0, 60, n), "ref_deg": np.linspace(1, 61, n),
            "repetitions": reps, "future_a": [1, 2]}  # fmt: skip
    nan = float("nan")
    rotation = {"rmse_deg": nan, "bias_deg": nan, "sd_deg": nan, "max_abs_deg": nan,
                "rmse_centred_deg": nan, "r": nan, "cmc": nan, "loa_deg": [nan, nan],
                "n_samples": 1, "imu_deg": np.zeros(n), "ref_deg": np.full(n, np.nan)}  # fmt: skip
    return {
        "mode": "angles", "marker_set": "optical", "movement_only": False,
        "pairs": {"shank_r": "shank_r"}, "sync": OpticalSync().to_tree(),
        "optical": {"thigh_r": cluster, "shank_r": body},
        "orientation": {"time_s": t, "shank_r": errors, "thigh_r": unseen, "future_t": 2},
        "angles": {"time_s": t, "knee_r_flexion_deg": flex, "knee_r_rotation_deg": rotation},
        "notes": ["a note"],
        "reference": {"kind": "model_angles", "file": "pig.c3d",
                      "mapping": {"knee_r_flexion_deg": "RKneeAngles.X"}, "future_r": 0},
    }  # fmt: skip


def test_a_validation_stored_as_dicts_loads_typed_and_is_stored_the_same(tmp_path):
    """``validation.optical``, ``orientation``, ``angles`` and ``reference`` are records; a
    file holding them as dicts loads (newer keys kept) and is written back byte for byte:
    the same groups, datasets and attributes in the same order."""
    from motionlab.session import _read_tree, _write_tree

    path = tmp_path / "old.h5"
    save_session(Session(), path)
    with h5py.File(path, "r+") as f:
        group = f.require_group("results").create_group("validation", track_order=True)
        _write_tree(group, _old_validation_tree())
    val = load_session(path).results.validation
    thigh, shank = val.optical["thigh_r"], val.optical["shank_r"]
    assert isinstance(thigh, OpticalSegmentInfo) and thigh.frame == "landmarks"
    assert thigh.static_s == [1.0, 4.0] and thigh.n_long_gaps == 1 and thigh.rigid_body is None
    assert thigh.landmark_spread_mm["MFE"] == 0.7 and thigh.more == {"future_o": 1}
    assert shank.segment_frame is True and shank.shape_m is None and shank.landmarks == []
    assert isinstance(val.orientation, OrientationErrors) and val.orientation.more == {
        "future_t": 2
    }
    errors = val.orientation.sensors["shank_r"]
    assert isinstance(errors, SensorOrientationError) and errors.p95_deg == 2.2
    assert errors.more == {"future_e": "x"} and len(val.orientation.time_s) == 6
    unseen = val.orientation.sensors["thigh_r"]
    assert unseen.total_rmse_deg is None and unseen.n_samples == 0
    flex = val.angles.columns["knee_r_flexion_deg"]
    assert isinstance(flex, AngleAgreement) and flex.loa_deg == [-1.6, 2.0] and flex.r == 0.999
    assert isinstance(flex.repetitions, RepetitionAgreement) and flex.repetitions.n == 2
    np.testing.assert_array_equal(flex.repetitions.rom_error_deg, [0.5, 0.4])
    assert flex.more == {"future_a": [1, 2]}
    assert val.angles.columns["knee_r_rotation_deg"].repetitions is None
    assert np.isnan(val.angles.columns["knee_r_rotation_deg"].rmse_deg)
    ref = val.reference
    assert isinstance(ref, ValidationReference) and ref.kind == "model_angles"
    assert ref.frames is None and ref.mapping == {"knee_r_flexion_deg": "RKneeAngles.X"}
    assert ref.more == {"future_r": 0}
    save_session(load_session(path), tmp_path / "again.h5")

    def groups(name):  # every group's attributes and members, in the order the file keeps
        out = []
        with h5py.File(name) as f:
            f["results/validation"].visititems(
                lambda k, item: out.append((k, list(item.attrs.items())))
            )
            out.append(("", list(f["results/validation"].attrs.items())))
            tree = _read_tree(f["results/validation"])
        return json.dumps(out, default=repr), json.dumps(tree, default=repr)

    assert groups(tmp_path / "again.h5") == groups(path)
    # an empty validation (a file without these keys) is stored as before: empty groups
    bare = Validation.from_tree({"mode": "full"})
    assert bare.to_tree()["orientation"] == {} and bare.to_tree()["reference"] == {}
    assert bare.angles is None and "angles" not in bare.to_tree()


def _stored_again(tmp_path, stage: str, tree: dict) -> tuple[dict, dict, object]:
    """``(tree read from a file holding ``tree`` as ``/results/<stage>``, the tree read after
    loading and saving that file, the loaded result)``."""
    from motionlab.session import _read_tree, _write_tree

    path = tmp_path / f"old_{stage}.h5"
    save_session(Session(), path)
    with h5py.File(path, "r+") as f:
        _write_tree(f.require_group("results").create_group(stage, track_order=True), tree)
    loaded = load_session(path)
    save_session(loaded, tmp_path / f"again_{stage}.h5")
    with h5py.File(path) as f:
        stored = _read_tree(f[f"results/{stage}"])
    with h5py.File(tmp_path / f"again_{stage}.h5") as f:
        again = _read_tree(f[f"results/{stage}"])
    return stored, again, getattr(loaded.results, stage)


def _same(a: dict, b: dict) -> bool:
    """The same keys in the same order with the same values (NaN equal to NaN)."""
    return json.dumps(a, default=repr) == json.dumps(b, default=repr)


def test_out_of_plane_metrics_stored_as_dicts_load_typed_and_are_stored_the_same(tmp_path):
    """``metrics.gait``, ``out_of_plane_offset``, ``trunk_compensation`` and ``cross_talk``
    entries are :class:`StanceMetrics`, :class:`OutOfPlaneOffset`, :class:`TrunkCompensation`
    (its angles :class:`TrunkAngleStats`) and :class:`CrossTalk` (its off-axis angles
    :class:`OffAxisRange`); the dicts the file held before load, a newer key is kept, and the
    file written back holds the same keys in the same order."""
    stance = {"strides": 2, "varus_thrust_deg": np.array([2.5, 3.5]),
              "varus_thrust_mean_deg": 3.0, "varus_thrust_sd_deg": 0.7071,
              "varus_thrust_above_pct": 50.0, "threshold_deg": 3.0,
              "stance_rotation_range_deg": np.array([8.0, 9.0]),
              "stance_rotation_range_mean_deg": 8.5, "stance_rotation_range_sd_deg": 0.7071,
              "heel_strike_s": np.array([1.0, 2.1]), "toe_off_s": np.array([1.6, 2.7]),
              "future_s": 1}  # fmt: skip
    offset = {"axes": ["y", "z"], "peak_deg": 4.0, "mean_deg": 1.5, "above_pct": 0.0,
              "threshold_deg": 5.0, "repetition_peak_deg": np.array([3.0, 4.0]),
              "offset_deg": np.linspace(0.0, 4.0, 50)}  # fmt: skip
    angle = {"max_deg": 15.0, "min_deg": -1.0, "peak_abs_deg": 15.0, "above_pct": 20.0,
             "threshold_deg": 10.0}  # fmt: skip
    trunk = {"flexion": angle, "lateral_bending": angle | {"threshold_deg": np.inf},
             "axial_rotation": angle | {"future_a": "kept"}, "compensated": True,
             "angles_deg": np.zeros((40, 3)), "future_t": [1, 2]}  # fmt: skip
    cross = {"on_axis": "flexion", "on_axis_rom_deg": 80.0,
             "adduction": {"rom_deg": 4.0, "ratio_pct": 5.0, "nominal_rom_deg": 16.0,
                           "change_pct": -75.0},
             "rotation": {"rom_deg": 8.0, "ratio_pct": 10.0}}  # fmt: skip
    tree = {"protocol": "knee", "joints": {}, "blocks": {},
            "gait": {"gait": {"knee_r": stance}},
            "out_of_plane_offset": {"bend": {"lumbar": offset}},
            "trunk_compensation": {"bend": trunk},
            "cross_talk": {"knee_flexion_r": {"knee_r": cross}}}  # fmt: skip
    stored, again, m = _stored_again(tmp_path, "metrics", tree)
    g = m.gait["gait"]["knee_r"]
    assert isinstance(g, StanceMetrics) and g.strides == 2 and g.more == {"future_s": 1}
    np.testing.assert_array_equal(g.toe_off_s, [1.6, 2.7])
    o = m.out_of_plane_offset["bend"]["lumbar"]
    assert isinstance(o, OutOfPlaneOffset) and o.axes == ["y", "z"] and o.peak_deg == 4.0
    t = m.trunk_compensation["bend"]
    assert isinstance(t, TrunkCompensation) and t.compensated and t.more == {"future_t": [1, 2]}
    assert list(t.per_angle) == ["flexion", "lateral_bending", "axial_rotation"]
    assert t.per_angle["lateral_bending"].threshold_deg == np.inf
    assert t.per_angle["axial_rotation"].more == {"future_a": "kept"}
    c = m.cross_talk["knee_flexion_r"]["knee_r"]
    assert (
        isinstance(c, CrossTalk)
        and c.on_axis == "flexion"
        and list(c.off_axis)
        == [
            "adduction",
            "rotation",
        ]
    )
    assert c.off_axis["adduction"].change_pct == -75.0
    assert c.off_axis["rotation"].nominal_rom_deg is None
    assert _same(again, stored)


def test_gait_events_strides_pelvis_and_side_statistics_load_typed_and_are_stored_the_same(
    tmp_path,
):
    """``gait.tasks`` are :class:`TaskBlock`, ``events`` :class:`GaitEvents`, ``strides`` a
    :class:`StrideTable`, ``pelvis`` a :class:`GaitPelvis` and a side's column statistics
    :class:`StrideStats`; the dicts the file held before load (a file from before the median,
    the standard error and ``strides_n`` too) and are written back as they were."""
    n = 4
    stats = {"mean": 1.1, "sd": 0.05, "cv_pct": 4.5, "se": 0.02, "median": 1.1, "q1": 1.05,
             "q3": 1.15, "strides_n": n}  # fmt: skip
    oldest = {"mean": 1.1, "sd": 0.05, "cv_pct": 4.5, "n": n}  # the first gait summaries
    strides = {"start_s": np.arange(n, dtype=float), "kept": np.array([True, True, False, True]),
               "stride_time_s": np.full(n, 1.1), "cadence_steps_per_min": np.full(n, 109.0),
               "side": np.array(["r", "l", "r", "l"]),
               "reason": np.array(["", "", "turn", ""])}  # fmt: skip
    events = {"ic": np.array([0.0, 1.1]), "ic_confidence": np.ones(2),
              "fc": np.array([0.7, 1.8]), "fc_confidence": np.ones(2)}  # fmt: skip
    summary = {
        "sides": {"r": {"stride_time_s": stats}, "l": {"stride_time_s": oldest}},
        "min_strides": 3,
        "cadence_steps_per_min": 109.0,
        "step_pairs": 1,
        "step_time_asymmetry_pct": np.nan,
        "step_time_asymmetry_se_pct": np.nan,
        "stride_time_cv_pct": 3.0,
        "stride_time_cv_se_pct": 0.8,
        "walking_speed_m_s": np.nan,
        "strides_kept": 3,
        "strides_rejected": {"turn": 1},
        "withheld": {"step_time_asymmetry_pct": "not enough paired steady steps"},
    }
    pelvis = {"time_s": np.arange(5) / 100, "pelvis_tilt_deg": np.ones(5),
              "pelvis_obliquity_deg": np.zeros(5), "pelvis_rotation_deg": -np.ones(5),
              "method": "pelvis frame from the calibration"}  # fmt: skip
    tree = {"status": "ok", "tasks": {"walk": {"start_s": 0.5, "end_s": 30.0}},
            "events": {"r": events, "l": events},
            "strides": strides, "summary": summary,
            "walking_speed": "not measured", "pelvis": pelvis}  # fmt: skip
    stored, again, g = _stored_again(tmp_path, "gait", tree)
    assert isinstance(g.tasks["walk"], TaskBlock) and g.tasks["walk"].end_s == 30.0
    assert isinstance(g.events["r"], GaitEvents)
    np.testing.assert_array_equal(g.events["l"].fc, [0.7, 1.8])
    assert isinstance(g.strides, StrideTable) and g.strides.step_length_m is None
    assert list(g.strides.side) == ["r", "l", "r", "l"] and g.strides.kept.sum() == 3
    assert list(g.strides.frame().columns) == list(strides)
    assert isinstance(g.pelvis, GaitPelvis) and g.pelvis.angles_deg().shape == (5, 3)
    r, left = g.summary.sides["r"]["stride_time_s"], g.summary.sides["l"]["stride_time_s"]
    assert isinstance(r, StrideStats) and r.strides_n == n and r.q3 == 1.15
    assert left.strides_n is None and left.se is None and left.more == {"n": n}
    assert _same(again, stored)


@pytest.mark.parametrize(
    ("stage", "tree"),
    [
        ("metrics", {"protocol": "knee", "gait": 5}),
        ("metrics", {"protocol": "knee", "cross_talk": {"squat": {"knee_r": [1.0]}}}),
        ("gait", {"status": "ok", "strides": 3}),
        ("gait", {"status": "ok", "events": {"r": "ic"}}),
    ],
)
def test_a_damaged_leaf_record_is_refused_with_an_input_error(tmp_path, stage, tree):
    """A group the records expect stored as a value (a damaged file) is a one-line error."""
    from motionlab.errors import InputError
    from motionlab.session import _write_tree

    path = tmp_path / "bad.h5"
    save_session(Session(), path)
    with h5py.File(path, "r+") as f:
        _write_tree(f.require_group("results").create_group(stage), tree)
    with pytest.raises(InputError, match="does not hold stage results"):
        load_session(path)
