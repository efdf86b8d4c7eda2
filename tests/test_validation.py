"""End to end: a simulated session with markers against its exact truth, the CLI, and BROAD.

The acceptance case: knee protocol, markers at 120 Hz on a camera clock 0.137 s ahead and
100 ppm fast, random sensor mountings (so random sensor-to-cluster rotations), 1 mm marker
noise and occlusions of 0.3 s six times a minute per marker. The IMU orientations are the true
ones with a smooth, seeded error of about 1° (a stand-in for a fusion filter, so that the test
checks validation and not fusion).
"""

import copy
import importlib.util
import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import ROOT, SHARED, needs_shared
from typed_results import untyped

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.protocol import load_protocol
from motionlab.results import FusionEntry, Results
from motionlab.segments import calibrate_segments
from motionlab.session import Session, load_session, save_session
from motionlab.simulate import simulate
from motionlab.simulate.errors import Preset
from motionlab.simulate.markers import write_c3d
from motionlab.validation import movement_mask, validate
from motionlab.validation.optical import resample_quat, rigid_fit

OFFSET_S, DRIFT = 0.137, 100e-6


#: occluded, slightly noisy markers
VALIDATION_PRESET = Preset(
    "validation", marker_noise_m=0.001, occlusions_per_min=6.0, occlusion_mean_s=0.3
)


def _fusion_stand_in(truth, label: str, t: np.ndarray, seed: int, knots: int) -> np.ndarray:
    """True sensor orientation at its sample times times a slowly wandering ~1° error."""
    q = resample_quat(truth.time, truth.sensors[label]["orientation"], t)
    rng = np.random.default_rng(seed)
    at = np.linspace(t[0], t[-1], knots)
    wander = np.column_stack([np.interp(t, at, rng.normal(0, 0.6, knots)) for _ in range(3)])
    return rot.make_continuous(rot.mul(rot.from_rotvec(np.radians(wander)), q))


def calibrate_with_truth(session, truth, protocol, knots: int = 30) -> None:
    """Give ``session`` fusion stand-ins (:func:`_fusion_stand_in`, ``knots`` wander knots) and
    calibrate it from them at the true step times (the calibration is not what is tested): the
    orientations calibrated are the ones validated, as after ``motionlab fuse``."""
    session.results.fusion = {
        k: FusionEntry("truth", _fusion_stand_in(truth, k, s.time, i, knots))
        for i, (k, s) in enumerate(session.sensors.items())
    }
    for step in protocol.calibration:
        s = truth.step(step.name)
        step.time_range = (s["start_s"], s["end_s"])
    session.results.calibration = calibrate_segments(session, protocol)


@pytest.fixture(scope="module")
def knee():
    protocol = load_protocol("knee")
    session, truth = simulate(protocol, 150.0, 3, VALIDATION_PRESET, markers=True)
    calibrate_with_truth(session, truth, protocol)
    result = validate(session, protocol=protocol)
    return session, truth, protocol, result


def test_clock_offset_and_drift_are_recovered(knee):
    _, _, _, result = knee
    sync = result.sync
    assert abs(sync.time_offset_s - OFFSET_S) < 0.5 / 100.0  # half an IMU sample
    assert abs(sync.drift_ppm - DRIFT * 1e6) < 20.0
    assert sync.inlier_ratio > 0.9


def test_alignment_rotations_are_recovered(knee):
    session, truth, _, result = knee
    al = result.alignment
    y_err = rot.angle_between(al.lab_to_earth.quat, truth.markers["lab_rotation"])
    assert np.degrees(y_err) < 0.5
    for label in session.sensors:
        # true sensor → cluster: the cluster's estimated shape fitted onto its true layout
        pairs = zip(truth.markers["labels"], truth.markers["segments"], strict=True)
        idx = [i for i, (lab, seg) in enumerate(pairs) if seg == label and "_C" in lab]
        shape = result.optical[label].shape_m
        segment_to_cluster = rigid_fit(truth.markers["local"][idx], shape[None])[0][0]
        x_true = rot.mul(segment_to_cluster, truth.sensors[label]["mounting"])
        x_err = rot.angle_between(al.sensor_to_cluster[label].quat, x_true)
        assert np.degrees(x_err) < 0.5, label
        assert rot.angle(x_true) > np.radians(10)  # a real rotation to recover


def test_joint_angle_rmse_equals_rmse_against_truth(knee):
    _, truth, _, result = knee
    angles = result.angles
    t = angles.time_s
    for col, true_deg in truth.joint_angles.items():
        entry = angles.columns[col]
        err = entry.imu_deg - np.interp(t, truth.time, true_deg)
        direct = float(np.sqrt(np.nanmean(err**2)))
        assert abs(entry.rmse_deg - direct) < 0.2, (col, entry.rmse_deg, direct)
        assert entry.loa_deg[0] < entry.bias_deg < entry.loa_deg[1]
    flex = angles.columns["knee_r_flexion_deg"]
    assert flex.cmc > 0.99 and flex.r > 0.99
    reps = flex.repetitions
    assert reps.n >= 5 and np.all(reps.rmse_deg < 5.0)


def test_optical_side_reports_gaps_and_frames(knee):
    _, _, _, result = knee
    for seg, info in result.optical.items():
        assert info.frame == "landmarks", seg
        assert 0.95 < info.fitted_fraction <= 1.0
        assert 0.8 < info.residual_rms_mm < 1.6  # 1 mm noise per coordinate, 4 markers
    assert sum(info.n_long_gaps for info in result.optical.values()) > 0


def test_movement_mask_follows_the_steps(knee):
    session, truth, _, _ = knee
    t = session.sensors["pelvis"].time
    moving = movement_mask(session, list(session.sensors), t)
    for name, expect in (("standing", False), ("sitting", False), ("gait", True)):
        step = truth.step(name)
        inner = (t > step["start_s"] + 0.5) & (t < step["end_s"] - 0.5)
        assert moving[inner].mean() == pytest.approx(float(expect), abs=0.05), name


def test_cli_json_csv_and_force(knee, tmp_path):
    session, _, _, _ = knee
    ses = Session(sensors=session.sensors, metadata=session.metadata,
                  results=Results(fusion=session.results.fusion,
                                  calibration=copy.copy(session.results.calibration)))  # fmt: skip
    ses.results.calibration.protocol_path = "knee"
    path, c3d = tmp_path / "s.h5", tmp_path / "markers.c3d"
    save_session(ses, path)
    write_c3d(session.markers["optical"], c3d)
    runner = CliRunner()
    csv = tmp_path / "csv"
    args = ["validate", str(path), "--reference", str(c3d), "--json", "--csv", str(csv)]
    out = runner.invoke(main, args)
    assert out.exit_code == 0, out.output
    digest = json.loads(out.output)
    assert abs(digest["time_offset_s"] - OFFSET_S) < 0.005
    assert set(digest["alignment"]["sensor_to_cluster"]) == set(ses.sensors)
    assert len(digest["alignment"]["lab_to_earth"]["quat"]) == 4
    flex = digest["angles"]["knee_l_flexion_deg"]
    assert {"rmse_deg", "bias_deg", "loa_deg", "r", "cmc"} <= set(flex)
    assert (tmp_path / "csv" / "validation_metrics.csv").is_file()
    stored = load_session(path).results.validation
    assert stored.angles.columns["knee_l_flexion_deg"].rmse_deg == pytest.approx(flex["rmse_deg"])
    assert untyped(stored, "validation") == []  # records to the leaves, as stored and read back
    again = runner.invoke(main, ["validate", str(path), "--reference", str(c3d)])
    assert again.exit_code == 2 and "--force" in again.output


def _bench_broad():
    spec = importlib.util.spec_from_file_location("bench_broad", ROOT / "bench" / "broad.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@needs_shared
def test_broad_mode_none_reproduces_the_benchmark():
    from motionlab.fusion import estimate
    from motionlab.io.broad import read

    path = SHARED / "datasets" / "broad" / "33_disturbed_attached_magnet_2cm.hdf5"
    bench = _bench_broad()
    trial = next(t for t in bench.load_trials(path.parent) if t["name"] == path.stem)
    expected = bench.run([trial], ["madgwick"], {})["madgwick"][0]
    rec = read(path)
    ses = Session(sensors={"imu": rec.sensors[0]}, markers={"optical": rec.markers[0]})
    s = ses.sensors["imu"]
    fused = estimate("madgwick", s.gyr, s.acc, s.mag, s.attrs["nominal_rate_hz"])
    ses.results.fusion = {"imu": FusionEntry("madgwick", fused.quat)}
    exact = validate(ses, mode="none", sync=False, movement_only=True).orientation.sensors["imu"]
    synced = validate(ses, mode="none", movement_only=True)
    again = synced.orientation.sensors["imu"]
    for key, ours, synced_deg in (
        ("total_rmse_deg", exact.total_rmse_deg, again.total_rmse_deg),
        ("heading_rmse_deg", exact.heading_rmse_deg, again.heading_rmse_deg),
        ("inclination_rmse_deg", exact.inclination_rmse_deg, again.inclination_rmse_deg),
    ):
        assert ours == pytest.approx(expected[key], abs=1e-9)
        assert synced_deg == pytest.approx(expected[key], abs=0.05)
    # BROAD shares one clock; its optical stream sits about 4 ms (1.2 samples) before the IMU
    # in every trial here, which the synchronisation finds (see bench/validation.py)
    assert abs(synced.sync.time_offset_s) < 0.01
    assert abs(synced.sync.drift_ppm) < 10.0


def test_figures_draw_the_stored_result(knee):
    import io

    from motionlab.validation import figures

    _, _, _, result = knee
    cols = ["knee_r_flexion_deg", "knee_r_adduction_deg"]
    drawn = {
        "overlay": (figures.angle_overlay(result, cols), 2),
        "error": (figures.angle_error(result, cols), 2),
        "bland_altman": (figures.bland_altman(result, cols[0]), 1),
        "sync": (figures.sync_figure(result), 1),
        "alignment": (figures.alignment_figure(result), 5),
    }
    for name, (fig, n_axes) in drawn.items():
        assert len(fig.axes) == n_axes, name
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=40)
        assert buf.getvalue()[:4] == b"\x89PNG", name


def test_cli_bad_inputs_give_one_line_and_exit_2(tmp_path):
    from motionlab.session import SensorStream

    t = np.arange(10) / 100.0
    path = tmp_path / "s.h5"
    save_session(Session(sensors={"imu": SensorStream("imu", t, gyr=np.zeros((10, 3)))}), path)
    bad_map = tmp_path / "map.yaml"
    bad_map.write_text("segments:\n  imu:\n    cluster: [A, B]\n")
    runner = CliRunner()
    for args, message in (
        ([str(path)], "has no optical data"),
        ([str(path), "--reference", str(tmp_path / "none.c3d")], "no such reference file"),
        ([str(path), "--markers", str(bad_map)], "map.yaml line 3, key segments.imu.cluster"),
        ([str(path), "--mode", "sideways"], "Invalid value for '--mode'"),
    ):
        out = runner.invoke(main, ["validate", *args])
        assert out.exit_code == 2, (args, out.output)
        assert message in out.output, out.output


def test_a_sensor_that_hardly_turned_does_not_refuse_the_alignment_of_the_others():
    """A simulated standing lumbar session with its optical reference refused the whole run
    ('too little rotation to align the IMU with the optical data'): its pelvis hardly turned.
    That sensor's alignment is not determined (conditioning 0, its agreements withheld); the
    moving one's is still found; with no sensor turning the refusal stands."""
    from motionlab.errors import InputError
    from motionlab.validation.align import align

    t = np.arange(0, 20, 0.01)
    moving = rot.from_rotvec(np.column_stack([0.6 * np.sin(1.1 * t), 0.4 * np.sin(0.7 * t + 1),
                                              0.5 * np.sin(0.9 * t + 2)]))  # fmt: skip
    still = np.tile(rot.from_rotvec(np.array([0.1, 0.2, 0.3])), (len(t), 1))
    y = rot.from_rotvec(np.array([0.2, -0.1, 0.7]))
    x = rot.from_rotvec(np.array([-0.3, 0.1, 0.2]))

    def optical(a):  # a = Y b X
        return rot.mul(rot.mul(rot.conj(np.broadcast_to(y, a.shape)), a),
                       rot.conj(np.broadcast_to(x, a.shape)))  # fmt: skip

    al = align({"pelvis": (still, optical(still)), "thorax": (moving, optical(moving))})
    assert al.conditioning["pelvis"] == 0 and al.conditioning["thorax"] > 0.1
    assert np.degrees(rot.angle(rot.mul(rot.conj(al.sensor_to_cluster["thorax"]), x))) < 0.5
    with pytest.raises(InputError, match="too little rotation"):
        align({"pelvis": (still, optical(still))})
