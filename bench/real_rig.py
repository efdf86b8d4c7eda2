"""Real rig (RING trial 1): hinge and ball joint angles of ``motionlab run`` against optical.

The rig (``motionlab/protocols/examples/ring_rig.yaml``): seg1 free, seg2 on a ball joint, then
hinges about x (hinge23), y (hinge34) and z (hinge45). For each IMU mounting (``imu_rigid.csv``,
``imu_nonrigid.csv``, 40 Hz) and for 6-D (default) and 9-D (``--magnetometer``) fusion, the
product is run through its CLI (``python -m motionlab.cli run``) and its angle columns, read
from the run's ``session.h5`` (``<joint>_angle_deg`` for a hinge, ``<joint>_{z,x,y}_deg`` for the
ball joint; ``csv/`` leaves an angle ``not determined`` empty, the bench measures it), are
compared with the optical angles from ``omc.csv`` (30 Hz): ``q_rel = q_prox* ⊗ q_dist``
decomposed with the hinge axis first (x → XYZ, y → YZX, z → ZXY; the ball joint ZXY).

Clock: one offset per mounting, first from the gyroscope speeds ‖ω‖ of all five IMUs against
the optical angular speeds (search ±0.2 s, ``validation.joint_reference.fit_clock_offset``), then
refined within ±0.1 s on the by-hand 6-D hinge angles (:func:`angle_offset`: the gyroscope
samples are interval averages, so orientations lag the speeds by about half a sample); every
variant is compared at that one offset.
IMU angles are interpolated onto the optical samples; optical gaps (NaN) are skipped.

References computed here from library pieces ("by hand"): each IMU fused alone
(``estimate("default")`` 6-D, and VQF offline 9-D when ``vqf`` is installed), hinge axes from
Seel's fit over the whole recording (``segments.hinge.hinge_axes``), the mounting the smallest
rotation taking the fitted axis onto the segment axis, and the angle about the axis of
``(q_p m_p)* ⊗ (q_d m_d)``. For 6-D the distal heading is first aligned to the proximal one by the
hinge constraint (``segments.heading.heading_from_hinge`` over 10 s windows every 5 s); the 9-D
rows use the magnetometer's common heading as is. Per segment, the heading error of each sensor
orientation against optical after a constant alignment (``validation.align``: mode ``heading``
for 6-D, ``full`` for 9-D), mean removed.

A failing ``motionlab run`` (e.g. a joint type this version lacks) is reported in its rows and
the rest of the bench goes on.

Usage (from the repository root)::

    python3 bench/real_rig.py [--data ../shared/datasets/ring/trial1] [--skip-run] [--keep DIR]
                              [--estimators ekf,ukf,kf]
"""

from __future__ import annotations

import argparse
import functools
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the package of this checkout, not an installed one

from motionlab import rotations as rot  # noqa: E402
from motionlab.errors import InputError  # noqa: E402
from motionlab.fusion import estimate  # noqa: E402
from motionlab.io import generic  # noqa: E402
from motionlab.kinematics.joint_angles import decompose  # noqa: E402
from motionlab.protocol import axis_vector  # noqa: E402
from motionlab.rotations import angular_velocity  # noqa: E402
from motionlab.segments.heading import apply_heading, heading_from_hinge, heading_track  # noqa: E402
from motionlab.segments.hinge import hinge_axes  # noqa: E402
from motionlab.sensor_map import load_sensor_map  # noqa: E402
from motionlab.validation.align import align  # noqa: E402
from motionlab.validation.joint_reference import (  # noqa: E402
    agreement_metrics,
    fit_clock_offset,
    read_orientation_csv,
    wrap_deg,
)
from motionlab.validation.optical import resample_quat  # noqa: E402

DEFAULT_DATA = ROOT.parent / "shared" / "datasets" / "ring" / "trial1"
EXAMPLES = ROOT / "motionlab" / "protocols" / "examples"
PROTOCOL = EXAMPLES / "ring_rig.yaml"
MAP = EXAMPLES / "ring_map.yaml"
MOUNTINGS = ("imu_rigid.csv", "imu_nonrigid.csv")
SEGMENTS = ("seg1", "seg2", "seg3", "seg4", "seg5")
HINGES = {"hinge23": ("seg2", "seg3", "x"), "hinge34": ("seg3", "seg4", "y"),
          "hinge45": ("seg4", "seg5", "z")}  # fmt: skip
BALL = ("ball12", "seg1", "seg2", "ZXY")
HEADING_WINDOW_S, HEADING_STEP_S = 10.0, 5.0


def read_imu(path: Path) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]], float]:
    """Time (s), per segment ``{acc, gyr, mag}`` (SI, mag in assumed µT) and rate (Hz)."""
    rec = generic.read(path, load_sensor_map(MAP).reader)
    s0 = rec.sensors[0]
    data = {s.label: {"acc": s.acc, "gyr": s.gyr, "mag": s.mag} for s in rec.sensors}
    return s0.time, data, float(s0.rate_hz)


def clock_offset(t_imu, imu, t_opt, q_opt) -> tuple[float, float]:
    """Offset (s, ``t_opt = t_imu + d``) from angular speeds of all segments, and its r."""
    speeds_imu, speeds_opt = [], []
    for seg in SEGMENTS:
        speeds_imu.append(np.linalg.norm(imu[seg]["gyr"], axis=1))
        tm, w = angular_velocity(t_opt, q_opt[seg])
        speeds_opt.append(np.interp(t_opt, tm, np.linalg.norm(w, axis=1)))
        speeds_opt[-1][~np.isfinite(q_opt[seg]).all(axis=1)] = np.nan
    return fit_clock_offset(t_imu, np.column_stack(speeds_imu), t_opt, np.column_stack(speeds_opt))


def angle_offset(t_imu, hand: dict, t_opt, ref: dict, around: float) -> float:
    """Offset (s, ``t_opt = t_imu + d``) minimising the mean offset-free RMSE of the by-hand 6-D
    hinge angles, within ±0.1 s of ``around`` (1 ms steps). Orientations integrate gyroscope
    samples that are interval averages, so they lag the angular speeds by about half a sample:
    the angles, not the speeds, set the offset at which angles are compared."""
    best, best_cost = around, np.inf
    for lag in np.arange(around - 0.1, around + 0.1 + 5e-4, 0.001):
        costs = []
        for j, ang in hand.items():
            e = on_optical(t_imu, ang, t_opt, lag) - ref[j]
            e = e[np.isfinite(e)]
            costs.append(np.sqrt(np.mean((e - e.mean()) ** 2)) if len(e) > 10 else np.inf)
        if np.mean(costs) < best_cost:
            best, best_cost = float(lag), float(np.mean(costs))
    return best


def on_optical(t_imu: np.ndarray, values: np.ndarray, t_opt: np.ndarray, offset: float):
    """IMU-clock series interpolated at the optical samples (NaN outside)."""
    return np.interp(t_opt - offset, t_imu, values, left=np.nan, right=np.nan)


def run_product(
    csv: Path, outdir: Path, magnetometer: bool, estimator: str = "default"
) -> tuple[Path | None, str]:
    """``motionlab run`` through the CLI; (csv folder, "") or (None, one-line failure)."""
    cmd = [sys.executable, "-m", "motionlab.cli", "run", "--protocol", str(PROTOCOL), "--map",
           str(MAP), str(csv), "-o", str(outdir), "--force", "--quiet",
           "--filter", estimator]  # fmt: skip
    if magnetometer:
        cmd.append("--magnetometer")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    try:
        p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    except subprocess.TimeoutExpired:
        return None, "timed out after 900 s"
    if p.returncode != 0 or not (outdir / "csv").is_dir():
        lines = [ln for ln in (p.stderr + p.stdout).strip().splitlines() if ln.strip()]
        last = lines[-1].removeprefix("error: ") if lines else f"exit code {p.returncode}"
        return None, last[:160]
    return outdir / "csv", ""


@functools.cache
def _run_angles(session_path: Path) -> dict[str, np.ndarray]:
    """The angle columns the run computed, ``time_s`` among them (from its session file)."""
    from motionlab.session import load_session

    table = load_session(session_path).results.angles
    return {c: np.asarray(v, float) for c, v in table.columns().items()}


def product_column(csv_dir: Path, column: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(time_s, values) of an angle column as the run computed it, or None: read from its
    session file, as the CSV tables leave an angle ``not determined`` empty and the bench
    measures it anyway (its grade beside it)."""
    angles = _run_angles(csv_dir.parent / "session.h5")
    if column not in angles:
        return None
    return angles["time_s"], angles[column]


def grades(csv_dir: Path | None) -> dict[str, str]:
    """``{column: grade}`` from ``csv/grades.csv`` when the run wrote one."""
    path = csv_dir / "grades.csv" if csv_dir else None
    if path is None or not path.is_file():
        return {}
    df = pd.read_csv(path)
    return dict(zip(df["column"].astype(str), df["grade"].astype(str), strict=False))


def shortest_arc(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Quaternion of the smallest rotation taking unit ``u`` onto unit ``v``."""
    u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
    q = np.array([1.0 + u @ v, *np.cross(u, v)])
    if q[0] < 1e-9:  # opposite: any perpendicular axis
        perp = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
        q = np.array([0.0, *perp])
    return q / np.linalg.norm(q)


def hinge_by_hand(t, imu, quats, rate, prox, dist, axis, align_heading: bool) -> np.ndarray:
    """Hinge angle (deg) from per-sensor orientations, Seel's axes and (6-D) hinge heading."""
    e = axis_vector(axis)
    j_p, j_d, _ = hinge_axes(imu[prox]["gyr"], imu[dist]["gyr"], e, e)
    # mounting m (segment → sensor coordinates) takes the segment axis onto the fitted axis
    q_p = rot.mul(quats[prox], shortest_arc(e, j_p))
    q_d = rot.mul(quats[dist], shortest_arc(e, j_d))
    if align_heading:
        win, step = int(HEADING_WINDOW_S * rate), int(HEADING_STEP_S * rate)
        starts = range(0, max(len(t) - win, 0) + 1, step)
        times = [t[s + win // 2] for s in starts]
        deltas = [heading_from_hinge(q_p[s : s + win], q_d[s : s + win], e, e) for s in starts]
        q_d = apply_heading(q_d, heading_track(np.array(times), np.array(deltas), t))
    return np.degrees(decompose(q_p, q_d, "hinge", axis=axis)[:, 0])


def fuse_all(imu: dict, rate: float, has_vqf: bool) -> dict[str, dict[str, np.ndarray]]:
    """Each sensor fused alone: default 6-D, default 9-D and (with vqf) VQF offline 9-D."""
    variants = {"default 6-D": ("default", False), "default 9-D": ("default", True)}
    if has_vqf:
        variants["VQF offline 9-D"] = ("vqf_offline", True)
    return {
        label: {
            s: estimate(
                name, imu[s]["gyr"], imu[s]["acc"], imu[s]["mag"] if mag else None, rate
            ).quat
            for s in SEGMENTS
        }
        for label, (name, mag) in variants.items()
    }


def signed_heading_rmse(q_est: np.ndarray, q_ref: np.ndarray) -> float:
    """RMS (deg) of the earth-frame heading error about its circular mean."""
    e = rot.mul(q_est, rot.conj(q_ref))
    e = e * np.where(e[:, :1] < 0, -1.0, 1.0)
    h = np.degrees(2 * np.arctan2(e[:, 3], e[:, 0]))
    h = h[np.isfinite(h)]
    mean = np.degrees(np.angle(np.mean(np.exp(1j * np.radians(h)))))
    return float(np.sqrt(np.mean(wrap_deg(h - mean) ** 2)))


def heading_errors(quats, t_imu, t_opt, q_opt, offset, mode: str) -> dict[str, float]:
    """Per segment heading error (deg RMS, offset-free) after a constant alignment."""
    pairs = {s: (resample_quat(t_imu + offset, quats[s], t_opt), q_opt[s]) for s in SEGMENTS}
    rate = 1.0 / float(np.median(np.diff(t_opt)))
    al = align(pairs, mode=mode, rate=rate)
    return {s: signed_heading_rmse(a, al.reference(s, b)) for s, (a, b) in pairs.items()}


def fmt(x: float, nd: int = 1) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{x:.{nd}f}"


def row(mounting, variant, column, m, grade="n/a", note="") -> str:
    sign = "flipped" if m["flipped"] else "+"
    cells = [mounting, variant, column, fmt(m["rmse_deg"]), fmt(m["rmse_offset_free_deg"]),
             fmt(m["max_abs_offset_free_deg"]), fmt(m["r"], 3), sign, grade, note]  # fmt: skip
    return "| " + " | ".join(cells) + " |"


def failed_row(mounting, variant, column, message) -> str:
    return f"| {mounting} | {variant} | {column} | {message} |  |  |  |  |  |  |"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of trial 1")
    ap.add_argument("--skip-run", action="store_true", help="only the by-hand references")
    ap.add_argument("--keep", type=Path, help="keep the runs' outputs in this folder")
    ap.add_argument(
        "--estimators",
        default="",
        help="comma-separated other estimators to add as 6-D runs (e.g. ekf,ukf,kf)",
    )
    args = ap.parse_args(argv)
    omc = args.data / "omc.csv"
    if not omc.is_file() or not all((args.data / m).is_file() for m in MOUNTINGS):
        print(f"error: no RING trial in {args.data} (needs omc.csv, {', '.join(MOUNTINGS)}); "
              "give --data DIR", file=sys.stderr)  # fmt: skip
        return 2
    try:
        import vqf  # noqa: F401

        has_vqf = True
    except ImportError:
        has_vqf = False
    t_opt, q_opt = read_orientation_csv(omc)
    ref_hinge = {
        j: np.degrees(decompose(q_opt[p], q_opt[d], "hinge", axis=a)[:, 0])
        for j, (p, d, a) in HINGES.items()
    }
    ref_ball = np.degrees(decompose(q_opt[BALL[1]], q_opt[BALL[2]], "ball", sequence=BALL[3]))
    header = ("| mounting | variant | column | RMSE (deg) | RMSE offset-free | max abs offset-free "
              "| r | sign | grade | note |\n|---|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    rows, heading_rows, clocks = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        for mounting in MOUNTINGS:
            name = mounting.removesuffix(".csv").removeprefix("imu_")
            t_imu, imu, rate = read_imu(args.data / mounting)
            speed_offset, r_clock = clock_offset(t_imu, imu, t_opt, q_opt)
            fused = fuse_all(imu, rate, has_vqf)
            hand = {
                j: hinge_by_hand(t_imu, imu, fused["default 6-D"], rate, p, d, a, True)
                for j, (p, d, a) in HINGES.items()
            }
            offset = angle_offset(t_imu, hand, t_opt, ref_hinge, speed_offset)
            clocks.append(
                f"- {name}: optical = IMU + {offset * 1000:.0f} ms from the hinge angles "
                f"(from the angular speeds: {speed_offset * 1000:.0f} ms, r = {r_clock:.3f})"
            )
            variants = [] if args.skip_run else [
                ("run 6-D", False, "default"), ("run 9-D", True, "default"),
                *((f"run {e} 6-D", False, e) for e in filter(None, args.estimators.split(","))),
            ]  # fmt: skip
            for variant, mag, estimator in variants:
                out = work / f"{name}_{variant.replace(' ', '_')}"
                csv_dir, error = run_product(args.data / mounting, out, mag, estimator)
                g = grades(csv_dir)
                cols = [(f"{j}_angle_deg", ref_hinge[j]) for j in HINGES]
                cols += [
                    (f"{BALL[0]}_{c.lower()}_deg", ref_ball[:, k]) for k, c in enumerate(BALL[3])
                ]
                if csv_dir is None:  # one row for the whole run
                    rows.append(failed_row(name, variant, "all", f"run failed: {error}"))
                    continue
                for column, ref in cols:
                    found = product_column(csv_dir, column)
                    if found is None:
                        rows.append(failed_row(name, variant, column, "no such column in csv/"))
                        continue
                    est = on_optical(found[0], found[1], t_opt, offset)
                    m = agreement_metrics(est, ref)
                    note = "metrics after flipping the sign" if m["flipped"] else ""
                    rows.append(row(name, variant, column, m, g.get(column, "n/a"), note))
            for label, six_d in (("by hand (default 6-D)", "default 6-D"),
                                 ("VQF offline 9-D", "VQF offline 9-D")):  # fmt: skip
                if six_d not in fused:
                    rows.append(failed_row(name, label, "all", "skipped: vqf not installed"))
                    continue
                for j, (p, d, a) in HINGES.items():
                    try:
                        ang = hinge_by_hand(t_imu, imu, fused[six_d], rate, p, d, a, "6-D" in six_d)
                    except InputError as exc:
                        rows.append(failed_row(name, label, f"{j}_angle_deg", f"failed: {exc}"))
                        continue
                    m = agreement_metrics(on_optical(t_imu, ang, t_opt, offset), ref_hinge[j])
                    note = "metrics after flipping the sign" if m["flipped"] else ""
                    rows.append(row(name, label, f"{j}_angle_deg", m, "n/a", note))
            for label, quats in fused.items():
                mode = "heading" if "6-D" in label else "full"
                try:
                    err = heading_errors(quats, t_imu, t_opt, q_opt, offset, mode)
                except InputError as exc:
                    heading_rows.append(f"| {name} | {label} | alignment failed: {exc} |")
                    continue
                cells = " | ".join(fmt(err[s]) for s in SEGMENTS)
                heading_rows.append(f"| {name} | {label} ({mode}) | {cells} |")
    print("## RING trial 1: joint angles against optical\n")
    print("Clock offset:")
    print("\n".join(clocks) + "\n")
    print(header)
    print("\n".join(rows))
    print("\nby hand: Seel hinge axes over the whole recording; 6-D heading aligned by the hinge "
          "constraint (10 s windows); 9-D without heading alignment.\n")  # fmt: skip
    print("## Heading error per segment (deg RMS, mean removed, after constant alignment)\n")
    print("| mounting | orientation (alignment) | " + " | ".join(SEGMENTS) + " |")
    print("|---|---|" + "---|" * len(SEGMENTS))
    print("\n".join(heading_rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
