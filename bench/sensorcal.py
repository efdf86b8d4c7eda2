"""Sensor-calibration accuracy: simulated truth (Monte Carlo) and the real BROAD recordings.

Tables (Markdown):

1. Ellipsoid fit vs coverage: magnetometer with random soft iron (σ 0.05), hard iron (σ 20 µT)
   and 0.3 µT noise, samples within a cap of directions; errors of offset and matrix.
2. Multi-position accelerometer: 12 random poses (norm solver) and the six axis poses (nominal
   solver), pose means with 1 mm/s² noise; errors of bias, scale, misalignment.
3. Allan deviation: white noise 0.007 °/s/√Hz and rate random walk 0.002 °/s/√s (1 h, 100 Hz);
   ratio of the read-off value to the truth.
4. BROAD: drift of the gyroscope integrated over 10 s stretches from the optical orientation,
   without and with the bias from the rest windows; magnetometer ellipsoid quality.

Usage::

    python bench/sensorcal.py [--data DIR] [--trials N]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import h5py
import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.sensorcal import allan_analysis, fit_ellipsoid, gyro_bias, multiposition

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "datasets" / "broad"
DEG = np.pi / 180


def cap_directions(n: int, cap_deg: float, rng: np.random.Generator) -> np.ndarray:
    z = rng.uniform(np.cos(np.radians(cap_deg)), 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    r = np.sqrt(1 - z**2)
    return np.column_stack((r * np.cos(phi), r * np.sin(phi), z))


def stats(values: list[float]) -> str:
    v = np.asarray(values)
    return f"{np.median(v):.3g} / {np.percentile(v, 95):.3g}"


def ellipsoid_table(trials: int) -> None:
    print("\n### Ellipsoid fit vs coverage (median / 95th percentile over trials)\n")
    print("| cap | coverage | offset error µT | matrix error (max abs) | residual RMS µT | fails |")
    print("|---|---|---|---|---|---|")
    for cap in (180, 120, 90, 75, 60):
        off, mat, rms, covs, fails = [], [], [], [], 0
        for seed in range(trials):
            rng = np.random.default_rng(seed)
            a = np.eye(3) + rng.normal(0.0, 0.05, (3, 3))
            a = (a + a.T) / 2
            o = rng.normal(0.0, 20.0, 3)
            y = 50.0 * cap_directions(2000, cap, rng) @ a.T + o + rng.normal(0, 0.3, (2000, 3))
            try:
                fit = fit_ellipsoid(y, norm=50.0)
            except InputError:
                fails += 1
                continue
            off.append(np.abs(fit.offset - o).max())
            mat.append(np.abs(fit.matrix - np.linalg.inv(a)).max())
            rms.append(fit.residual_rms)
            covs.append(fit.coverage)
        row = [stats(off), stats(mat), stats(rms)] if off else ["-"] * 3
        cov = f"{np.median(covs):.2f}" if covs else "-"
        print(f"| {cap}° | {cov} | " + " | ".join(row) + f" | {fails}/{trials} |")


def multiposition_table(trials: int) -> None:
    print("\n### Multi-position accelerometer (median / 95th percentile over trials)\n")
    print("| solver | poses | bias error mm/s² | scale error ppm | misalignment error mrad |")
    print("|---|---|---|---|---|")
    g = 9.80665
    axes = np.vstack((np.eye(3), -np.eye(3))) * g
    for solver in ("norm", "nominal"):
        eb, es, em = [], [], []
        for seed in range(trials):
            rng = np.random.default_rng(100 + seed)
            s = 1 + rng.normal(0, 0.01, 3)
            m = rng.normal(0, 0.01, (3, 3))
            np.fill_diagonal(m, 0)
            if solver == "norm":
                m = np.tril(m)
                u = rng.normal(size=(12, 3))
                f = g * u / np.linalg.norm(u, axis=1, keepdims=True)
            else:
                f = axes
            b = rng.normal(0, 0.15, 3)
            y = f @ ((np.eye(3) + m) @ np.diag(s)).T + b + rng.normal(0, 1e-3, f.shape)
            fit = multiposition(y, method=solver)
            eb.append(1e3 * np.abs(fit.bias - b).max())
            es.append(1e6 * np.abs(fit.scale - s).max())
            em.append(1e3 * np.abs(fit.misalignment - m).max())
        print(f"| {solver} | {len(f)} | {stats(eb)} | {stats(es)} | {stats(em)} |")


def allan_table(trials: int) -> None:
    print("\n### Allan deviation read-off / truth (min, median, max over trials × 3 axes)\n")
    print("| term | truth | min | median | max |")
    print("|---|---|---|---|---|")
    rate, n = 100.0, 360_000
    density, walk = 0.007 * DEG, 0.002 * DEG
    white, rrw = [], []
    for seed in range(trials):
        rng = np.random.default_rng(200 + seed)
        y = rng.normal(0, density * np.sqrt(rate), (n, 3))
        y += np.cumsum(rng.normal(0, walk / np.sqrt(rate), (n, 3)), axis=0)
        res = allan_analysis(y, rate)
        white.extend(res.white / density)
        rrw.extend(res.random_walk / walk)
    for name, truth, v in (
        ("white N", "0.007 °/s/√Hz", white),
        ("rate random walk K", "0.002 °/s/√s", rrw),
    ):
        print(f"| {name} | {truth} | {np.min(v):.3f} | {np.median(v):.3f} | {np.max(v):.3f} |")


def drift(gyr: np.ndarray, quat: np.ndarray, rate: float, bias: np.ndarray, window: float = 10.0):
    """Median drift (°/s) of the gyroscope integrated from the optical orientation.

    Over consecutive ``window``-s stretches with a valid optical reference, ``gyr − bias`` is
    integrated from the optical orientation at the start; the angle to the optical orientation
    at the end, divided by ``window``, is that stretch's drift rate.
    """
    n = int(window * rate)
    out = []
    for k in range(0, len(gyr) - n, n):
        ref = quat[k : k + n]
        if not np.isfinite(ref).all():
            continue
        q = rot.integrate_gyro(ref[0], gyr[k : k + n - 1] - bias, 1.0 / rate)
        out.append(rot.angle_between(q[-1], ref[-1]) / DEG / window)
    return float(np.median(out)) if out else float("nan")


def broad_table(data: Path) -> None:
    paths = sorted(data.glob("*.hdf5"))
    if not paths:
        print(f"\n(no BROAD trials in {data})")
        return
    print("\n### BROAD: gyro drift vs optical without / with the rest-window bias; mag fit\n")
    print(
        "| trial | rest s | bias °/s | drift °/s raw → corrected | "
        "mag coverage | field µT | |m| std raw → fitted µT | offset µT |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for path in paths:
        with h5py.File(path, "r") as f:
            gyr, acc, mag = f["imu_gyr"][()], f["imu_acc"][()], f["imu_mag"][()]
            quat, rate = f["opt_quat"][()], float(f.attrs["sampling_rate"])
        gb = gyro_bias(gyr, acc, rate)
        raw, corrected = drift(gyr, quat, rate, np.zeros(3)), drift(gyr, quat, rate, gb.bias)
        try:
            fit = fit_ellipsoid(mag[:: max(1, len(mag) // 20000)])
            norm = np.linalg.norm(fit.apply(mag), axis=1)
            magtxt = (
                f"{fit.coverage:.2f} | {fit.norm:.1f} | "
                f"{np.linalg.norm(mag, axis=1).std():.2f} → {norm.std():.2f} | "
                + " ".join(f"{v:+.2f}" for v in fit.offset)
            )
        except InputError as exc:
            magtxt = f"— | — | — | {exc.message}"
        vec = " ".join(f"{v:+.3f}" for v in gb.bias / DEG)
        print(f"| {path.stem} | {gb.rest_s:.0f} | {vec} | {raw:.3f} → {corrected:.3f} | {magtxt} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="BROAD folder")
    parser.add_argument("--trials", type=int, default=20, help="Monte Carlo trials per row")
    args = parser.parse_args()
    t0 = time.perf_counter()
    ellipsoid_table(args.trials)
    multiposition_table(args.trials)
    allan_table(max(2, args.trials // 4))
    broad_table(args.data)
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
