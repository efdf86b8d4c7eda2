"""Validation against optical motion capture: the acceptance numbers, as Markdown tables.

1. Simulated knee sessions (packaged protocol, 150 s) with markers at 120 Hz on a camera clock
   0.137 s ahead and 100 ppm fast, random sensor mountings, 1 mm marker noise and occlusions
   (0.3 s, 6 per minute per marker). Three IMU sides: ``stand-in`` (true orientations times a
   smooth ~1° error: checks the validation itself, mode ``full``), ``fused 9-D`` (the
   ``typical`` sensor error preset with ideal IMU clocks, fused with the magnetometer by
   ``--fused-estimator``, mode ``full``: the preset's uncalibrated hard and soft iron make the
   fused headings wrong by several degrees, which the alignment absorbs) and ``fused 6-D``
   (the same without the magnetometer, mode ``heading``). Reported: clock offset and drift
   errors, the largest error of the lab → earth (in heading mode: its tilt) and sensor → cluster
   rotations, and the largest difference between the joint-angle RMSE that ``validate`` reports
   and the RMSE against the simulator's truth.
2. BROAD trials: ``validate`` with mode ``none`` against ``bench/broad.py``'s numbers for the
   same estimator, without and with clock synchronisation.

Usage::

    python bench/validation.py [--data DIR] [--seeds 1,2,3] [--estimator madgwick]
        [--fused-estimator default] [--skip-sim] [--skip-broad]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.protocol import load_protocol
from motionlab.results import FusionEntry  # noqa: E402
from motionlab.segments import calibrate_segments
from motionlab.session import Session
from motionlab.simulate import simulate
from motionlab.simulate.errors import PRESETS, Preset, TimingModel
from motionlab.validation import validate
from motionlab.validation.optical import resample_quat, rigid_fit

HERE = Path(__file__).resolve().parent
DEFAULT_DATA = HERE.parents[0].parent / "shared" / "datasets" / "broad"
OFFSET_S, DRIFT_PPM = 0.137, 100.0
OPTICAL = {"marker_noise_m": 0.001, "occlusions_per_min": 6.0, "occlusion_mean_s": 0.3}


def _stand_in(truth, label: str, t: np.ndarray, seed: int) -> np.ndarray:
    q = resample_quat(truth.time, truth.sensors[label]["orientation"], t)
    rng = np.random.default_rng(seed)
    knots = np.linspace(t[0], t[-1], 30)
    wander = np.column_stack([np.interp(t, knots, rng.normal(0, 0.6, 30)) for _ in range(3)])
    return rot.mul(rot.from_rotvec(np.radians(wander)), q)


def simulated_case(seed: int, imu: str, estimator: str) -> dict:
    """Acceptance numbers of one simulated session (``imu``: stand-in, 9-D or 6-D)."""
    protocol = load_protocol("knee")
    if imu == "stand-in":
        preset = Preset("validation", **OPTICAL)
    else:
        preset = dataclasses.replace(PRESETS["typical"], timing=TimingModel(1e-4, 0.005, 3.0),
                                     **OPTICAL)  # fmt: skip
    session, truth = simulate(protocol, 150.0, seed, preset, markers=True)
    for step in protocol.calibration:
        s = truth.step(step.name)
        step.time_range = (s["start_s"], s["end_s"])
    session.results.calibration = calibrate_segments(session, protocol)
    fusion = {}
    for i, (label, s) in enumerate(session.sensors.items()):
        if imu == "stand-in":
            fusion[label] = FusionEntry("truth", _stand_in(truth, label, s.time, i))
        else:
            mag = s.mag if imu == "9-D" else None
            res = estimate(estimator, s.gyr, s.acc, mag, s.rate_hz, time=s.time)
            fusion[label] = FusionEntry(res.name, res.quat, magnetometer=mag is not None)
    session.results.fusion = fusion
    mode = "heading" if imu == "6-D" else "full"
    t0 = time.perf_counter()
    res = validate(session, protocol=protocol, mode=mode)
    seconds = time.perf_counter() - t0
    al = res.alignment
    y_true = truth.markers["lab_rotation"]
    if mode == "heading":  # only the vertical is shared: compare where the lab's z points
        up = rot.rotate(al["lab_to_earth"]["quat"], [0.0, 0, 1])
        rot_err = [np.arccos(np.clip(up @ rot.rotate(y_true, [0.0, 0, 1]), -1, 1))]
    else:
        rot_err = [rot.angle_between(al["lab_to_earth"]["quat"], y_true)]
    labels, segs = truth.markers["labels"], truth.markers["segments"]
    for label in session.sensors:
        idx = [i for i, (a, b) in enumerate(zip(labels, segs, strict=True))
               if b == label and "_C" in a]  # fmt: skip
        c = rigid_fit(truth.markers["local"][idx], res.optical[label]["shape_m"][None])[0][0]
        x_true = rot.mul(c, truth.sensors[label]["mounting"])
        rot_err.append(rot.angle_between(al["sensor_to_cluster"][label]["quat"], x_true))
    t = res.angles["time_s"]
    diffs, rmses = [], []
    for col, true_deg in truth.joint_angles.items():
        err = res.angles[col]["imu_deg"] - np.interp(t, truth.time, true_deg)
        direct = float(np.sqrt(np.nanmean(err**2)))
        diffs.append(res.angles[col]["rmse_deg"] - direct)
        rmses.append(res.angles[col]["rmse_deg"])
    ori = [res.orientation[k]["total_rmse_deg"] for k in session.sensors]
    return {
        "offset_ms": (res.sync["time_offset_s"] - OFFSET_S) * 1e3,
        "drift_ppm": res.sync["drift_ppm"] - DRIFT_PPM,
        "inliers": res.sync["inlier_ratio"],
        "rot_deg": float(np.degrees(np.max(rot_err))),
        "ori_deg": float(np.mean(ori)),
        "rmse_deg": float(np.mean(rmses)),
        "diff_deg": float(np.max(np.abs(diffs))),
        "seconds": seconds,
    }


def simulated_table(seeds: list[int], estimator: str) -> str:
    lines = [
        "| IMU side | seed | offset error (ms) | drift error (ppm) | inliers | worst rotation "
        "error (°) | mean orientation RMSE (°) | mean angle RMSE (°) | worst RMSE difference "
        "vs truth (°) | validate (s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for imu in ("stand-in", "9-D", "6-D"):
        name = imu if imu == "stand-in" else f"fused {imu} ({estimator})"
        for seed in seeds:
            r = simulated_case(seed, imu, estimator)
            lines.append(
                f"| {name} | {seed} | {r['offset_ms']:+.2f} | {r['drift_ppm']:+.1f} | "
                f"{r['inliers']:.2f} | {r['rot_deg']:.3f} | {r['ori_deg']:.2f} | "
                f"{r['rmse_deg']:.2f} | {r['diff_deg']:.3f} | {r['seconds']:.1f} |"
            )
    lines.append("")
    lines.append(
        "Targets: offset within ±5 ms (half an IMU sample at 100 Hz), drift within ±20 ppm,"
    )
    lines.append("rotations within 0.5°, RMSE difference within 0.2°.")
    return "\n".join(lines)


def _bench_broad():
    spec = importlib.util.spec_from_file_location("bench_broad", HERE / "broad.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def broad_table(data: Path, name: str) -> str:
    from motionlab.io.broad import read

    bench = _bench_broad()
    trials = bench.load_trials(data)
    if not trials:
        sys.exit(f"error: no *.hdf5 trials in {data}")
    expected = bench.run(trials, [name], {})[name]
    lines = [
        f"BROAD, estimator {name}, RMS over movement samples (°): bench/broad.py | validate "
        "--mode none --no-sync | validate --mode none (synchronised)\n",
        "| trial | total | heading | inclination | max abs diff (no sync) | offset found (ms) | "
        "drift (ppm) | total (sync) | heading (sync) | inclination (sync) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    keys = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")
    for tr, exp in zip(trials, expected, strict=True):
        rec = read(data / f"{tr['name']}.hdf5")
        ses = Session(sensors={"imu": rec.sensors[0]}, markers={"optical": rec.markers[0]})
        s = ses.sensors["imu"]
        q = estimate(name, s.gyr, s.acc, s.mag, tr["rate"], time=s.time).quat
        ses.results.fusion = {"imu": FusionEntry(name, q)}
        plain = validate(ses, mode="none", sync=False, movement_only=True).orientation["imu"]
        synced = validate(ses, mode="none", movement_only=True)
        so = synced.orientation["imu"]
        diff = max(abs(plain[k] - exp[k]) for k in keys)
        lines.append(
            f"| {tr['name']} | {exp[keys[0]]:.3f} | {exp[keys[1]]:.3f} | {exp[keys[2]]:.3f} | "
            f"{diff:.1e} | {synced['sync']['time_offset_s'] * 1e3:+.2f} | "
            f"{synced['sync']['drift_ppm']:+.1f} | {so[keys[0]]:.3f} | {so[keys[1]]:.3f} | "
            f"{so[keys[2]]:.3f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of BROAD *.hdf5")
    ap.add_argument("--seeds", default="1,2,3", help="simulation seeds")
    ap.add_argument("--estimator", default="madgwick", help="estimator for the BROAD table")
    ap.add_argument("--fused-estimator", default="default", help="estimator for simulations")
    ap.add_argument("--skip-sim", action="store_true")
    ap.add_argument("--skip-broad", action="store_true")
    args = ap.parse_args(argv)
    if not args.skip_sim:
        seeds = [int(s) for s in args.seeds.split(",") if s]
        print("Simulated knee sessions, 150 s, 5 IMUs (see the module docstring)\n")
        print(simulated_table(seeds, args.fused_estimator))
        print()
    if not args.skip_broad:
        print(broad_table(args.data, args.estimator))


if __name__ == "__main__":
    main()
