"""Benchmark: ``motionlab.ingest`` against plain ``pandas.read_csv`` on the same files.

Generates a file set in x-io CSV style (default: 8 sensors, 1 hour, 100 Hz, gyroscope in deg/s,
accelerometer in g, magnetometer in µT, a few dropped samples), then times in the same run

- ``pandas.read_csv`` of every file (the floor: parsing only),
- ``motionlab.ingest.ingest`` of the set (detection, parsing, unit conversion, clock repair,
  quality checks, gap filling, common clock), and ``save_session`` separately,

and prints a table with ratio = read_csv time / ingest time (target ≥ 0.5: ingest at most 2×
slower than parsing alone). With ``../shared`` present (or ``--data DIR``, the shared folder,
read only) the real x-io example file is timed too.

Usage::

    python bench/ingest.py                      # files in a temporary folder
    python bench/ingest.py --out /tmp/ingest    # keep (and reuse) the generated files there
    python bench/ingest.py --minutes 10 --sensors 4
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from motionlab.ingest import ingest
from motionlab.io import read_any
from motionlab.session import save_session

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
HEADER = ["Time (s)"] + [
    f"{q} {a} ({u})"
    for q, u in (("Gyroscope", "deg/s"), ("Accelerometer", "g"), ("Magnetometer", "uT"))
    for a in "XYZ"
]


def generate(folder: Path, sensors: int, minutes: float, rate: float, seed: int = 0) -> list[Path]:
    """Write (or reuse) one x-io style CSV per sensor; returns the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    n = int(minutes * 60 * rate)
    paths = []
    for k in range(sensors):
        path = folder / f"imu{k}_{sensors}x{minutes:g}min_{rate:g}Hz.csv"
        paths.append(path)
        if path.exists():
            continue
        rng = np.random.default_rng(seed + k)
        t = np.arange(n) / rate + 0.3 * k + 1e-5 * rng.standard_normal(n)
        keep = np.ones(n, bool)
        keep[rng.integers(1, n - 1, size=20)] = False  # dropped samples: short gaps to fill
        phase = 2 * np.pi * 0.9 * t[:, None] + rng.uniform(0, 2 * np.pi, 3)
        gyr = 120.0 * np.sin(phase) + rng.normal(0, 0.5, (n, 3))
        acc = np.array([0.0, 0.0, 1.0]) + 0.3 * np.cos(phase) + rng.normal(0, 0.01, (n, 3))
        mag = np.array([15.0, 20.0, -40.0]) + rng.normal(0, 0.3, (n, 3))
        data = pd.DataFrame(np.column_stack([t, gyr, acc, mag])[keep], columns=HEADER)
        data.to_csv(path, index=False, float_format="%.8g")
    return paths


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def measure(label: str, paths: list[Path], repeat: int, out: Path) -> dict:
    rows = sum(sum(1 for _ in open(p, "rb")) - 1 for p in paths)
    mb = sum(p.stat().st_size for p in paths) / 1e6
    t_pd = _best(lambda: [pd.read_csv(p) for p in paths], repeat)
    t_read = _best(lambda: [read_any(p) for p in paths], repeat)
    session = None

    def run():
        nonlocal session
        session = ingest(paths, command="bench")

    t_ing = _best(run, repeat)
    t_save = _best(lambda: save_session(session, out, force=True), 1)
    return dict(label=label, files=len(paths), rows=rows, mb=mb, t_pd=t_pd, t_read=t_read,
                t_ing=t_ing, t_save=t_save)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="folder for the generated files (kept)")
    ap.add_argument("--data", type=Path, default=SHARED, help="the shared data folder (read)")
    ap.add_argument("--sensors", type=int, default=8)
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        t0 = time.perf_counter()
        paths = generate(folder, args.sensors, args.minutes, args.rate)
        print(f"files ready in {time.perf_counter() - t0:.1f} s ({folder})")
        results = [
            measure(
                f"{args.sensors} x {args.minutes:g} min @ {args.rate:g} Hz",
                paths,
                args.repeat,
                Path(tmp) / "s.h5",
            )
        ]
        real = args.data / "formats" / "xio" / "sensor_data.csv"
        if real.is_file():
            results.append(measure("x-io example (real)", [real], args.repeat, Path(tmp) / "r.h5"))

    print()
    print(f"{'file set':<28} {'files':>5} {'rows':>9} {'MB':>7} {'read_csv s':>10} "
          f"{'readers s':>9} {'ingest s':>9} {'ratio':>6} {'save s':>7}")  # fmt: skip
    for r in results:
        ratio = r["t_pd"] / r["t_ing"]
        print(
            f"{r['label']:<28} {r['files']:>5} {r['rows']:>9} {r['mb']:>7.1f} {r['t_pd']:>10.2f}"
            f" {r['t_read']:>9.2f} {r['t_ing']:>9.2f} {ratio:>6.2f} {r['t_save']:>7.2f}"
        )
    print("\nratio = read_csv time / ingest time; target ≥ 0.5")
    print("readers = motionlab.io.read_any alone (part of ingest)")


if __name__ == "__main__":
    main()
