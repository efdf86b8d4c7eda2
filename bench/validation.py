"""Validation against optical motion capture: the acceptance numbers, as Markdown tables.

1. Simulated knee sessions (packaged protocol, 150 s) with markers at 120 Hz on a camera clock
   0.137 s ahead and 100 ppm fast, random sensor mountings, 1 mm marker noise and occlusions
   (0.3 s, 6 per minute per marker). Three IMU sides: ``stand-in`` (true orientations times a
   smooth ~1° error: checks the validation itself, mode ``full``), ``fused 9-D`` (the
   ``typical`` sensor error preset with ideal IMU clocks, fused with the magnetometer by
   ``--fused-estimator``, mode ``full``: the preset's uncalibrated hard and soft iron make the
   fused headings wrong by several degrees, which the alignment absorbs) and ``fused 6-D``
   (the same without the magnetometer, mode ``heading``) and ``fused 6-D, interval gyroscope``
   (the same with gyroscope samples that are interval averages, as real MEMS gyroscopes
   report: ``simulate(gyr_sampling="interval")``; the sync models them as such, see
   motionlab/validation/time_alignment.py; the row ``... modelled as point samples`` shows the
   old half-sample error). Reported: clock offset and drift errors (the drift with its
   standard error and whether the recording determined it), the clock's standard errors at
   the centre and the ends of the recording, the largest error of the lab → earth (in heading
   mode: its tilt) and sensor → cluster rotations, and the largest difference between the
   joint-angle RMSE that ``validate`` reports and the RMSE against the simulator's truth.
2. BROAD trials: ``validate`` with mode ``none`` against ``bench/broad.py``'s numbers for the
   same estimator, without and with clock synchronisation.
3. The RING rig (``../shared/datasets/ring``, no licence: read in place, nothing copied): IMU
   (40 Hz, interval-averaged gyroscopes) against the optical segment quaternions (30 Hz) given
   as a segment CSV, clocks not aligned to the sample: the offset found with the gyroscope
   modelled as interval averages, as point samples, and from the orientations, against the
   offset that minimises the orientation error (a scan).
4. The trunk recordings (``../shared/datasets/trunk``, x-IMU3 + OptiTrack, no licence: read in
   place; the Motive CSV's rigid-body quaternions go to a temporary segment CSV): the thorax
   (``Back`` vs ``back``) and lower back (``Chest`` vs ``low_back``) IMUs, clocks unsynchronised
   by about an hour, 9-18 s per trial: too short for 10 s windows, so the global offset.

Usage::

    python bench/validation.py [--data DIR] [--seeds 1,2,3] [--estimator madgwick]
        [--fused-estimator default] [--skip-sim] [--skip-broad] [--skip-ring] [--skip-trunk]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.protocol import load_protocol
from motionlab.results import FusionEntry  # noqa: E402
from motionlab.segments import calibrate_segments
from motionlab.session import Session, estimate_rate
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
    sampling = "interval" if "interval" in imu else "point"
    session, truth = simulate(protocol, 150.0, seed, preset, markers=True, gyr_sampling=sampling)
    if imu.endswith("as point"):  # the old sync: interval averages taken as point samples
        for s in session.sensors.values():
            s.attrs["gyr_sampling"] = "point"
    for step in protocol.calibration:
        s = truth.step(step.name)
        step.time_range = (s["start_s"], s["end_s"])
    # the calibration reads the default estimator 6-D (what it fused by itself before it
    # refused unfused sensors: the table is unchanged); the orientations validated are the case's
    session.results.fusion = {
        label: FusionEntry("default", estimate("default", s.gyr, s.acc, None,
                                               estimate_rate(s.time), time=s.time).quat)
        for label, s in session.sensors.items()
    }  # fmt: skip
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
    mode = "heading" if imu.startswith("6-D") else "full"
    t0 = time.perf_counter()
    res = validate(session, protocol=protocol, mode=mode)
    seconds = time.perf_counter() - t0
    al = res.alignment
    y_true = truth.markers["lab_rotation"]
    if mode == "heading":  # only the vertical is shared: compare where the lab's z points
        up = rot.rotate(al.lab_to_earth.quat, [0.0, 0, 1])
        rot_err = [np.arccos(np.clip(up @ rot.rotate(y_true, [0.0, 0, 1]), -1, 1))]
    else:
        rot_err = [rot.angle_between(al.lab_to_earth.quat, y_true)]
    labels, segs = truth.markers["labels"], truth.markers["segments"]
    for label in session.sensors:
        idx = [i for i, (a, b) in enumerate(zip(labels, segs, strict=True))
               if b == label and "_C" in a]  # fmt: skip
        c = rigid_fit(truth.markers["local"][idx], res.optical[label].shape_m[None])[0][0]
        x_true = rot.mul(c, truth.sensors[label]["mounting"])
        rot_err.append(rot.angle_between(al.sensor_to_cluster[label].quat, x_true))
    t = res.angles.time_s
    diffs, rmses = [], []
    for col, true_deg in truth.joint_angles.items():
        entry = res.angles.columns[col]
        err = entry.imu_deg - np.interp(t, truth.time, true_deg)
        direct = float(np.sqrt(np.nanmean(err**2)))
        diffs.append(entry.rmse_deg - direct)
        rmses.append(entry.rmse_deg)
    ori = [res.orientation.sensors[k].total_rmse_deg for k in session.sensors]
    return {
        "offset_ms": (res.sync.time_offset_s - OFFSET_S) * 1e3,
        "drift_ppm": res.sync.drift_ppm - DRIFT_PPM,
        "drift_se_ppm": res.sync.drift_se_ppm,
        "drift_grade": res.sync.drift_grade,
        "inliers": res.sync.inlier_ratio,
        "se_ms": res.sync.standard_error_s * 1e3,
        "ends_se_ms": res.sync.ends_standard_error_s * 1e3,
        "grade": res.sync.grade,
        "rot_deg": float(np.degrees(np.max(rot_err))),
        "ori_deg": float(np.mean(ori)),
        "rmse_deg": float(np.mean(rmses)),
        "diff_deg": float(np.max(np.abs(diffs))),
        "seconds": seconds,
    }


SIDES = ("stand-in", "9-D", "6-D", "6-D interval", "6-D interval as point")


def simulated_table(seeds: list[int], estimator: str, sides: tuple = SIDES) -> str:
    lines = [
        "| IMU side | seed | offset error (ms) | drift error ± standard error (ppm), grade | "
        "inliers | standard error at the centre, ends (ms), grade | worst rotation error (°) | "
        "mean orientation RMSE (°) | mean angle RMSE (°) | worst RMSE difference vs truth (°) | "
        "validate (s) |",
        "|---|---|---:|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for imu in sides:
        name = imu if imu == "stand-in" else f"fused {imu} ({estimator})"
        name = name.replace("interval", "interval gyroscope").replace("as point", "modelled as "
                            "point samples")  # fmt: skip
        for seed in seeds:
            r = simulated_case(seed, imu, estimator)
            lines.append(
                f"| {name} | {seed} | {r['offset_ms']:+.2f} | {r['drift_ppm']:+.1f} ± "
                f"{r['drift_se_ppm']:.1f}, {r['drift_grade']} | {r['inliers']:.2f} | "
                f"{r['se_ms']:.2f}, {r['ends_se_ms']:.2f}, {r['grade']} | {r['rot_deg']:.3f} | "
                f"{r['ori_deg']:.2f} | "
                f"{r['rmse_deg']:.2f} | {r['diff_deg']:.3f} | {r['seconds']:.1f} |"
            )
    lines.append("")
    lines.append(
        "Targets: offset within ±5 ms (half an IMU sample at 100 Hz; ±2 ms with interval "
        "gyroscopes), drift within ±20 ppm,"
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
        plain = validate(ses, mode="none", sync=False, movement_only=True)
        synced = validate(ses, mode="none", movement_only=True)
        # the stored statistics by name, as bench/broad.py's rows name them
        plain_deg = plain.orientation.sensors["imu"].to_tree()
        so = synced.orientation.sensors["imu"].to_tree()
        diff = max(abs(plain_deg[k] - exp[k]) for k in keys)
        lines.append(
            f"| {tr['name']} | {exp[keys[0]]:.3f} | {exp[keys[1]]:.3f} | {exp[keys[2]]:.3f} | "
            f"{diff:.1e} | {synced.sync.time_offset_s * 1e3:+.2f} | "
            f"{synced.sync.drift_ppm:+.1f} | {so[keys[0]]:.3f} | {so[keys[1]]:.3f} | "
            f"{so[keys[2]]:.3f} |"
        )
    return "\n".join(lines)


def ring_table(folder: Path) -> str:
    """Sync on the RING rig (module docstring, item 3); the segment CSV goes to a temporary
    folder and is deleted."""
    import tempfile

    import pandas as pd

    from motionlab.session import SensorStream
    from motionlab.validation.segment_csv import read_segment_csv, segment_map

    lines = [
        "RING rig trial 1: IMU 40 Hz vs optical segment quaternions 30 Hz (5 segments, 6-D "
        "fusion, mode heading)\n",
        "| IMUs | sync | offset (ms, at t=0) | drift (ppm) | offset at mid-recording (ms) | "
        "standard error (ms), grade | mean total RMSE (°) |",
        "|---|---|---:|---:|---:|---|---:|",
    ]
    omc = pd.read_csv(folder / "omc.csv", comment="#")
    table = {"time": np.arange(len(omc)) / 30.0}
    for n in range(1, 6):
        for c in "wxyz":
            table[f"seg{n}_q{c}"] = omc[f"seg{n}_quat_{c}"].to_numpy(float)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "segments.csv"
        pd.DataFrame(table).to_csv(path, index=False)
        ref = read_segment_csv(path)
    for kind in ("rigid", "nonrigid"):
        imu = pd.read_csv(folder / f"imu_{kind}.csv", comment="#")
        ses = Session()
        for n in range(1, 6):
            g = imu[[f"seg{n}_gyr_{a}" for a in "xyz"]].to_numpy(float)
            a = imu[[f"seg{n}_acc_{a}" for a in "xyz"]].to_numpy(float)
            t = np.arange(len(g)) / 40.0
            ses.sensors[f"seg{n}"] = SensorStream(label=f"seg{n}", time=t, acc=a, gyr=g)
            q = estimate("default", g, a, None, 40.0, time=t).quat
            ses.results.fusion[f"seg{n}"] = FusionEntry("default", q, magnetometer=False)
        mmap = segment_map(ref, [], list(ses.sensors), "body")
        mid = 0.5 * len(imu) / 40.0
        runs = (("gyroscope, interval averages", "gyroscope", "interval"),
                ("gyroscope, point samples (old)", "gyroscope", "point"),
                ("orientation", "orientation", "interval"))  # fmt: skip
        for name, source, sampling in runs:
            for s in ses.sensors.values():
                s.attrs["gyr_sampling"] = sampling
            res = validate(ses, ref, mmap, None, "heading", sync_on=source)
            sy = res.sync
            rmse = np.mean([res.orientation.sensors[k].total_rmse_deg for k in ses.sensors])
            at_mid = sy.time_offset_s + sy.drift_ppm * 1e-6 * mid
            lines.append(
                f"| {kind} | {name} | {sy.time_offset_s * 1e3:+.1f} | {sy.drift_ppm:+.0f} | "
                f"{at_mid * 1e3:+.1f} | {sy.standard_error_s * 1e3:.2f}, {sy.grade} | "
                f"{rmse:.3f} |"
            )
        scan = []
        base = ref.time.copy()
        for off in np.arange(0.0, 0.0601, 0.002):
            ref.time = base - off
            res = validate(ses, ref, mmap, None, "heading", sync=False)
            scan.append((np.mean([res.orientation.sensors[k].total_rmse_deg
                                  for k in ses.sensors]), off))  # fmt: skip
        ref.time = base
        best, off = min(scan)
        lines.append(f"| {kind} | scan (no drift), 2 ms steps | | | {off * 1e3:+.1f} | | "
                     f"{best:.3f} |")  # fmt: skip
    return "\n".join(lines)


def _motive_segments(src: Path, dst: Path, bodies: dict[str, str]) -> None:
    """A segment CSV from a Motive (OptiTrack) CSV export: ``bodies`` rigid body → segment."""
    import pandas as pd

    raw = pd.read_csv(src, header=None, skiprows=2, low_memory=False)
    kind, name, what, comp = (raw.iloc[i] for i in (0, 1, 3, 4))
    data = raw.iloc[5:].apply(pd.to_numeric, errors="coerce")
    out = {"time": data[1].to_numpy(float)}
    for body, seg in bodies.items():
        for c in "WXYZ":
            j = next(i for i in range(len(name)) if kind[i] == "Rigid Body" and name[i] == body
                     and what[i] == "Rotation" and comp[i] == c)  # fmt: skip
            out[f"{seg}_q{c.lower()}"] = data[j].to_numpy(float)
    pd.DataFrame(out).to_csv(dst, index=False)


def trunk_table(folder: Path) -> str:
    """Sync on the trunk recordings (module docstring, item 4)."""
    import tempfile

    from motionlab.errors import InputError
    from motionlab.io import read_any
    from motionlab.validation.segment_csv import read_segment_csv, segment_map

    pairs = {"Back": "back", "Chest": "low_back"}
    lines = [
        "Trunk (x-IMU3 vs OptiTrack rigid bodies, 6-D fusion, mode heading, body frames)\n",
        "| trial | s | sync on | offset (s) | standard error (ms), grade | how | total RMSE "
        "Back, Chest (°) |",
        "|---|---:|---|---:|---|---|---|",
    ]
    for trial in sorted(folder.glob("*/*")):
        ses = Session()
        for dev in sorted((trial / "imu").iterdir()):
            label = dev.name.split()[0]
            if label in pairs:
                s = read_any(dev / "Inertial.csv").sensors[0]
                s.label = s.segment = label
                ses.sensors[label] = s
                q = estimate("default", s.gyr, s.acc, None, s.rate_hz, time=s.time).quat
                ses.results.fusion[label] = FusionEntry("default", q, magnetometer=False)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "segments.csv"
            _motive_segments(trial / "optitrack.csv", path, {v: k for k, v in pairs.items()})
            ref = read_segment_csv(path)
        mmap = segment_map(ref, [], list(ses.sensors), "body")
        t = ses.sensors["Back"].time
        for source in ("gyroscope", "orientation"):
            try:
                res = validate(ses, ref, mmap, None, "heading", sync_on=source)
            except InputError as exc:
                lines.append(f"| {trial.parent.name}/{trial.name} | | {source} | {exc} | | | |")
                continue
            sy = res.sync
            how = sy.fallback or f"{sy.method}, {sy.n_windows} windows"
            rmse = ", ".join(f"{res.orientation.sensors[k].total_rmse_deg:.2f}" for k in pairs)
            lines.append(
                f"| {trial.parent.name}/{trial.name} | {t[-1] - t[0]:.0f} | {source} | "
                f"{sy.time_offset_s:+.4f} | {sy.standard_error_s * 1e3:.2f}, "
                f"{sy.grade} | {how} | {rmse} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of BROAD *.hdf5")
    ap.add_argument("--seeds", type=seeds_arg, default="1,2,3", help="simulation seeds")
    ap.add_argument("--estimator", default="madgwick", help="estimator for the BROAD table")
    ap.add_argument("--fused-estimator", default="default", help="estimator for simulations")
    ap.add_argument("--skip-sim", action="store_true")
    ap.add_argument("--skip-broad", action="store_true")
    ap.add_argument("--skip-ring", action="store_true")
    ap.add_argument("--skip-trunk", action="store_true")
    ap.add_argument("--sides", default=",".join(SIDES), help="simulated IMU sides")
    args = ap.parse_args(argv)
    if not args.skip_sim:
        seeds = args.seeds
        print("Simulated knee sessions, 150 s, 5 IMUs (see the module docstring)\n")
        sides = tuple(x for x in args.sides.split(",") if x)
        print(simulated_table(seeds, args.fused_estimator, sides))
        print()
    if not args.skip_broad:
        print(broad_table(args.data, args.estimator))
    ring = args.data.parent / "ring" / "trial1"
    if not args.skip_ring and ring.is_dir():
        print()
        print(ring_table(ring))
    trunk = args.data.parent / "trunk"
    if not args.skip_trunk and trunk.is_dir():
        print()
        print(trunk_table(trunk))


if __name__ == "__main__":
    main()
