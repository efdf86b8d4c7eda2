"""BROAD benchmark: every registered estimator on every BROAD trial, one Markdown table.

Errors follow the benchmark (Laidig et al., Data 2021): RMS over the ``movement`` samples of the
total, heading and inclination angle of ``q_est ⊗ conj(q_ref)``, NaN reference samples skipped.
All estimators run in 9-D (gyr + acc + mag); ``vqf_offline`` and ``vqf`` are the reference.

Usage::

    python bench/broad.py [--data DIR] [--filters a,b,...] [--param name.key=value ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import h5py
import numpy as np

from motionlab.fusion import available, estimate
from motionlab.validation.orientation_error import orientation_errors

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "datasets" / "broad"


def load_trials(data: Path) -> list[dict]:
    """Every ``*.hdf5`` BROAD trial in ``data``, sorted by name."""
    trials = []
    for path in sorted(data.glob("*.hdf5")):
        with h5py.File(path, "r") as f:
            trials.append(
                {
                    "name": path.stem,
                    "gyr": f["imu_gyr"][()],
                    "acc": f["imu_acc"][()],
                    "mag": f["imu_mag"][()],
                    "quat": f["opt_quat"][()],
                    "movement": f["movement"][()].astype(bool),
                    "rate": float(f.attrs["sampling_rate"]),
                }
            )
    return trials


def parse_overrides(items: list[str]) -> dict[str, dict[str, str]]:
    """``name.key=value`` strings → ``{name: {key: value}}``."""
    out: dict[str, dict[str, str]] = {}
    for item in items:
        key, _, value = item.partition("=")
        name, _, param = key.partition(".")
        if not value or not param:
            sys.exit(f"error: --param {item!r} is not name.key=value")
        out.setdefault(name, {})[param] = value
    return out


def run(trials: list[dict], names: list[str], overrides: dict) -> dict[str, list[dict]]:
    """Errors per estimator per trial (dicts of :func:`orientation_errors` plus ``seconds``)."""
    results: dict[str, list[dict]] = {}
    for name in names:
        rows = []
        for tr in trials:
            t0 = time.perf_counter()
            res = estimate(
                name, tr["gyr"], tr["acc"], tr["mag"], tr["rate"], **overrides.get(name, {})
            )
            seconds = time.perf_counter() - t0
            finite = bool(np.isfinite(res.quat).all())
            err = orientation_errors(res.quat, tr["quat"], tr["movement"])
            rows.append({**err, "seconds": seconds, "finite": finite})
        results[name] = rows
    return results


def table(trials: list[dict], results: dict[str, list[dict]]) -> str:
    """Markdown table: one row per estimator and trial, then one mean row per estimator."""
    lines = [
        "| estimator | trial | total RMSE (°) | heading RMSE (°) | inclination RMSE (°) | finite |",
        "|---|---|---:|---:|---:|---|",
    ]
    means = []
    for name, rows in results.items():
        for tr, r in zip(trials, rows, strict=True):
            lines.append(
                f"| {name} | {tr['name']} | {r['total_rmse_deg']:.2f} | "
                f"{r['heading_rmse_deg']:.2f} | {r['inclination_rmse_deg']:.2f} | "
                f"{'yes' if r['finite'] else 'NO'} |"
            )
        m = [
            np.mean([r[f"{k}_rmse_deg"] for r in rows]) for k in ("total", "heading", "inclination")
        ]
        means.append((name, m, max(r["total_rmse_deg"] for r in rows)))
    lines += [
        "",
        "| estimator | mean total (°) | mean heading (°) | mean inclination (°) "
        "| worst trial total (°) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, m, worst in sorted(means, key=lambda x: x[1][0]):
        lines.append(f"| {name} | {m[0]:.2f} | {m[1]:.2f} | {m[2]:.2f} | {worst:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of BROAD *.hdf5")
    ap.add_argument("--filters", default="", help="comma-separated estimators (default: all)")
    ap.add_argument("--param", action="append", default=[], help="name.key=value override")
    args = ap.parse_args(argv)
    trials = load_trials(args.data)
    if not trials:
        sys.exit(f"error: no *.hdf5 trials in {args.data}")
    names = [n for n in args.filters.split(",") if n] or list(available())
    for ref in ("vqf_offline", "vqf"):
        if ref in available() and ref not in names:
            names.append(ref)
    unknown = [n for n in names if n not in available()]
    if unknown:
        sys.exit(f"error: unknown estimator(s) {', '.join(unknown)}; have {', '.join(available())}")
    results = run(trials, names, parse_overrides(args.param))
    print(f"BROAD: {len(trials)} trials from {args.data}, 9-D, RMS over movement samples\n")
    print(table(trials, results))


if __name__ == "__main__":
    main()
