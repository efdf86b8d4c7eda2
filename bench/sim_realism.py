"""Is the simulated knee as hard as a real one? Seel's hinge fit on real and simulated walks.

For each knee (thigh and shank gyroscopes on one clock) this prints what the product's hinge fit
from movement (:func:`motionlab.segments.movement.fit_hinge`, soft-L1, 6 Hz low-pass) leaves:
its ``relative_residual`` (RMS residual / RMS perpendicular rate; the verdict's limits are 0.35
for ``determined`` and 0.6 for ``weak``) and ``consistency_deg`` (the largest angle between the
axis of a quarter of the movement and the whole fit), together with the ranges that say whether
two walks are alike: the per-stride range of the flexion angle about the fitted axis (the
integral of the relative rate about it, drift removed above 0.3 Hz; no calibration needed) and
the RMS angular speed (deg/s) of thigh and shank.

Rows:

- **real** (skipped without ``../shared``): the two Xsens DOT knee recordings of
  ``datasets/human/imt_dot`` (60 Hz; thigh ``femur.csv``, shank ``tibia.csv``), the walking part
  (``WALK_FROM``) and the whole recording; the 16-IMU ``qmt_full_body`` recording (100 Hz),
  both legs, the rhythmic part (``QMT_RHYTHMIC_S``) and 40-140 s.
- **simulated**: the walk of ``bench/real_world.py`` (the ``walk`` protocol, 74 s, random
  mountings, ``typical`` sensor errors) with the former simulator (``knee_model="simple"``,
  ``soft_tissue="motion"`` at the ``typical`` level, as ``real_world.py`` ran before) and with the
  realistic one (``knee_model="anatomical"``, preset ``skin``), over the gait task.

Usage::

    python bench/sim_realism.py [--seeds 0-2] [--data ../shared]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.signal import butter, find_peaks, sosfiltfilt
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.io import read_any
from motionlab.segments.movement import fit_hinge, relative_sign
from motionlab.session import estimate_rate
from motionlab.simulate import simulate
from motionlab.timebase import interp_columns

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared"
DOT = "datasets/human/imt_dot"
QMT = "datasets/human/qmt_full_body/full_body_example_data.mat"
#: where the walking starts in the DOT recordings (s from the first sample; from the thigh's
#: angular speed: sitting and leg movements before, steady strides after)
WALK_FROM = {"knee_tracking1": 30.0, "knee_tracking2": 24.0}
QMT_RHYTHMIC_S = (96.0, 140.0)
QMT_WHOLE_S = (40.0, 140.0)
SIM_DURATION_S = 74.0  # as bench/real_world.py
#: the simulators compared: (label, simulate() keyword arguments)
SIMULATORS = (
    ("old sim (simple knee, typical)", {"preset": "typical", "soft_tissue": "motion"}),
    ("new sim (anatomical knee, preset skin)", {"preset": "skin", "knee_model": "anatomical"}),
)


def knee_numbers(t1, g1, q1, t2, g2, q2) -> dict:
    """Hinge-fit residual, consistency, per-stride flexion range and angular speeds of one knee.

    ``t*`` (s), ``g*`` (rad/s, sensor frame), ``q*`` (sensor → earth, any heading) of the thigh
    (1) and the shank (2); the shank is taken onto the thigh's samples.
    """
    prior = np.array([0.0, 0.0, 1.0])
    fit = fit_hinge("knee", (t1, g1, q1), (t2, g2, q2), prior, prior)
    sel = (t1 >= t2[0]) & (t1 <= t2[-1])
    t = t1[sel]
    rate = estimate_rate(t)
    a, b = g1[sel], interp_columns(t, t2, g2)
    s, _ = relative_sign(q1[sel], rot.resample(t2, q2, t), fit.axis_proximal, fit.axis_distal)
    flex_rate = b @ (s * fit.axis_distal) - a @ fit.axis_proximal
    angle = np.cumsum(flex_rate) / rate
    angle = sosfiltfilt(butter(2, 0.3, "highpass", fs=rate, output="sos"), angle)
    return {
        "residual": fit.relative_residual,
        "consistency_deg": fit.consistency_deg,
        "stride_range_deg": stride_range(np.degrees(angle), rate),
        "thigh_rms_deg_s": float(np.degrees(np.sqrt(np.mean(np.sum(a**2, axis=1))))),
        "shank_rms_deg_s": float(np.degrees(np.sqrt(np.mean(np.sum(b**2, axis=1))))),
    }


def stride_range(angle: np.ndarray, rate: float) -> float:
    """Median peak-to-trough range (deg) per stride of a flexion angle; the stride period from
    the autocorrelation (0.7-2.5 s), strides cut at the swing peaks."""
    x = angle - angle.mean()
    ac = np.correlate(x, x, "full")[len(x) - 1 :]
    lo, hi = int(0.7 * rate), min(int(2.5 * rate), len(x) - 1)
    if hi <= lo:
        return float("nan")
    period = lo + int(np.argmax(ac[lo:hi]))
    sign = 1.0 if np.mean(x**3) >= 0 else -1.0  # the swing peak is the skewed side
    peaks, _ = find_peaks(sign * x, distance=int(0.7 * period))
    ranges = [np.ptp(x[a:b]) for a, b in zip(peaks[:-1], peaks[1:], strict=True)]
    return float(np.median(ranges)) if ranges else float("nan")


def fused(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """6-D orientation (sensor → earth, arbitrary heading) with the default estimator."""
    return estimate("default", gyr, acc, None, rate=estimate_rate(t), time=t).quat


def real_rows(data: Path) -> list[tuple[str, dict]]:
    """Rows of the real recordings (empty when ``data`` lacks them)."""
    rows = []
    for name, start in WALK_FROM.items():
        folder = data / DOT / name
        if not folder.is_dir():
            continue
        th, sh = (read_any(folder / f).sensors[0] for f in ("femur.csv", "tibia.csv"))
        t0 = th.time[0]
        qs = [fused(s.time, s.gyr, s.acc) for s in (th, sh)]
        for part, (a, b) in (("walk", (start, np.inf)), ("whole", (-np.inf, np.inf))):
            m1 = (th.time - t0 >= a) & (th.time - t0 <= b)
            m2 = (sh.time - t0 >= a) & (sh.time - t0 <= b)
            nums = knee_numbers(th.time[m1], th.gyr[m1], qs[0][m1],
                                sh.time[m2], sh.gyr[m2], qs[1][m2])  # fmt: skip
            rows.append((f"real DOT {name} ({part})", nums))
    if (data / QMT).is_file():
        import scipy.io

        mat = scipy.io.loadmat(data / QMT, squeeze_me=True, struct_as_record=False)
        t = np.asarray(mat["t"], float)
        for side in ("left", "right"):
            th, sh = mat[f"upper_leg_{side}"], mat[f"lower_leg_{side}"]
            for part, (a, b) in (("rhythmic", QMT_RHYTHMIC_S), ("whole", QMT_WHOLE_S)):
                m = (t >= a) & (t <= b)
                nums = knee_numbers(t[m], th.gyr[m], th.quat[m], t[m], sh.gyr[m], sh.quat[m])
                rows.append((f"real qmt {side} ({part})", nums))
    return rows


def sim_rows(seeds: list[int]) -> list[tuple[str, dict]]:
    """Rows of the simulated walks, both knees of every seed, per simulator."""
    rows = []
    for label, kwargs in SIMULATORS:
        for seed in seeds:
            session, truth = simulate("walk", SIM_DURATION_S, seed, mounting="random", **kwargs)
            task = next(s for s in truth.steps if s["phase"] == "task")
            for side in "rl":
                streams = [session.sensors[f"{k}_{side}"] for k in ("thigh", "shank")]
                cut = []
                for k, s in zip(("thigh", "shank"), streams, strict=True):
                    tt = truth.sensors[f"{k}_{side}"]["sample_time"]
                    m = (tt >= task["start_s"]) & (tt <= task["end_s"])
                    cut.append((s.time[m], s.gyr[m], fused(s.time, s.gyr, s.acc)[m]))
                nums = knee_numbers(*cut[0], *cut[1])
                flex = truth.joint_angles[f"knee_{side}_flexion_deg"]
                on = (truth.time >= task["start_s"]) & (truth.time <= task["end_s"])
                nums["true_range_deg"] = stride_range(flex[on], 1.0 / np.diff(truth.time[:2])[0])
                rows.append((f"{label} seed {seed} {side}", nums))
    return rows


def print_table(rows: list[tuple[str, dict]]) -> None:
    print("| recording | residual | consistency (°) | stride range (°) | thigh RMS (°/s) | "
          "shank RMS (°/s) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|")
    for name, n in rows:
        rng = f"{n['stride_range_deg']:.0f}"
        if "true_range_deg" in n:
            rng += f" (truth {n['true_range_deg']:.0f})"
        print(f"| {name} | {n['residual']:.2f} | {n['consistency_deg']:.1f} | {rng} | "
              f"{n['thigh_rms_deg_s']:.0f} | {n['shank_rms_deg_s']:.0f} |")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-2")
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--no-sim", action="store_true", help="only the real recordings")
    args = ap.parse_args()
    rows = real_rows(args.data)
    if not rows:
        print(f"(no real recordings under {args.data}: the real rows are left out)")
    if not args.no_sim:
        rows += sim_rows(args.seeds)
    print_table(rows)


if __name__ == "__main__":
    main()
