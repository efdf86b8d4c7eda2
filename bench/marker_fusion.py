"""IMU + marker fusion (Liu 2010): error while the markers are seen, in occlusion gaps, IMU-only.

1. Simulated knee session (``tests/marker_fusion_sim.py``, the acceptance scenario): markers at
   120 Hz on their own clock (0.137 s, 100 ppm), 1 mm noise, 30 % of the frames hidden in blocks
   of 1–5 s; the IMU errors of the ``typical`` preset without the ones sensor calibration
   removes (``--preset typical`` keeps them: then the magnetometers' hard iron turns the earth
   frame's heading). Errors against the simulator's true sensor orientation (RMS, deg) on the
   samples whose markers are shown / hidden, and of the same filter on the IMU alone in the
   hidden blocks; then the registration's errors (clock, sensor → cluster, lab → earth).
2. BROAD (``--data``): the optical orientation (already aligned, Laidig et al. 2021) as two
   reference vectors (its x and y axes, assumed 0.3° noise), hidden in the same kind of blocks.
   The clock between gyroscope and optical orientation and the gyroscope bias come from the
   registration (coarse sync, then :func:`~motionlab.fusion.marker_registration.register_sensor`;
   the rotation is left at the identity, as BROAD is aligned), so the fused estimate at sample k
   is the orientation at optical time ``τ(t_k)`` and is compared with the optical orientation there;
   the IMU-only estimate is compared at ``t_k`` (as ``bench/broad.py``). Errors over the
   ``movement`` samples. Where the reference is shown the estimate is compared with its own
   input (as Liu's Table 8 does); the gaps are the real test.

Usage::

    python bench/marker_fusion.py [--data DIR] [--filters a,b] [--seeds 1,2] [--preset NAME]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from broad import DEFAULT_DATA, load_trials  # noqa: E402
from marker_fusion_sim import (  # noqa: E402
    CALIBRATED,
    acceptance_session,
    cluster_error,
    evaluate,
    hidden_blocks,
    rms,
    truth_at_samples,
)
from seeds import seeds_arg  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab.fusion import estimate  # noqa: E402
from motionlab.fusion.marker_registration import (  # noqa: E402
    register_sensor,
    session_references,
)
from motionlab.fusion.markers import MarkerReferences  # noqa: E402
from motionlab.simulate.errors import get_preset  # noqa: E402
from motionlab.validation.optical import resample_quat  # noqa: E402
from motionlab.validation.time_alignment import synchronise  # noqa: E402

FILTERS = ("liu_gn", "ekf", "ukf", "particle")
BROAD_SIGMA = np.deg2rad(0.3)


def registration_table(session, truth, fused) -> list[str]:
    """Per sensor: clock error (ms, worst over the record), sensor → cluster error (deg)."""
    y_true = truth.markers["lab_rotation"]
    lab = next(iter(fused.values())).lab_to_earth
    y_err = np.degrees(rot.angle_between(lab.quat, y_true))
    lines = [
        f"lab → earth error {y_err:.3f}° (vertical: {lab.vertical_axis})",
        "| sensor | clock error max (ms) | sensor → cluster error (°) | marker noise (mm) |",
        "|---|---|---|---|",
    ]
    for label, rec in fused.items():
        _, t_opt = truth_at_samples(session, truth, label)
        t_est = rec.time_offset_s + (1 + rec.drift_ppm * 1e-6) * session.sensors[label].time
        x_err = cluster_error(session, truth, label, rec.sensor_to_cluster)
        clock = 1e3 * np.abs(t_est - t_opt).max()
        lines.append(f"| {label} | {clock:.2f} | {x_err:.3f} | {rec.marker_noise_mm:.2f} |")
    return lines


def simulated(filters, seeds, duration, preset) -> list[str]:
    lines = [
        f"## Simulated knee session, {duration:.0f} s, preset {preset.name}, seeds {seeds}",
        "",
        "| filter | sensor | seed | shown (°) | hidden (°) | IMU-only, hidden (°) | "
        "IMU-only, all (°) |",
        "|---|---|---|---|---|---|---|",
    ]
    summary = {name: [] for name in filters}
    reg_lines = []
    for seed in seeds:
        session, truth, hidden = acceptance_session(duration, seed, preset=preset)
        t0 = time.perf_counter()
        refs, fused = session_references(session)
        reg_lines += [f"seed {seed}: registration {time.perf_counter() - t0:.1f} s", ""]
        reg_lines += registration_table(session, truth, fused) + [""]
        for name in filters:
            for label, e in evaluate(session, truth, hidden, refs, name).items():
                summary[name].append(e)
                lines.append(
                    f"| {name} | {label} | {seed} | {e['visible']:.3f} | {e['gaps']:.3f} | "
                    f"{e['imu_only_gaps']:.3f} | {e['imu_only']:.3f} |"
                )
    lines += [
        "",
        "| filter | shown, worst (°) | shown, mean (°) | hidden, mean (°) | "
        "IMU-only hidden, mean (°) | hidden ≤ IMU-only |",
        "|---|---|---|---|---|---|",
    ]
    for name, rows in summary.items():
        vis = [r["visible"] for r in rows]
        gaps = [r["gaps"] for r in rows]
        alone = [r["imu_only_gaps"] for r in rows]
        ok = sum(g <= a for g, a in zip(gaps, alone, strict=True))
        lines.append(
            f"| {name} | {max(vis):.3f} | {np.mean(vis):.3f} | {np.mean(gaps):.3f} | "
            f"{np.mean(alone):.3f} | {ok}/{len(rows)} |"
        )
    return lines + ["", "### Registration", ""] + reg_lines


_CLOCKS: dict[str, object] = {}


def _clock(tr: dict):
    """The registration of a BROAD trial's gyroscope with its optical orientation (cached)."""
    if tr["name"] not in _CLOCKS:
        t = np.arange(len(tr["gyr"])) / tr["rate"]
        coarse = synchronise([(t, tr["gyr"])], [(t, tr["quat"])]).model
        _CLOCKS[tr["name"]] = register_sensor(
            t, tr["gyr"], t, tr["quat"], coarse.offset_s, coarse.drift
        )
    return _CLOCKS[tr["name"]]


def broad(filters, data: Path, seed: int) -> list[str]:
    trials = load_trials(data)
    if not trials:
        return [f"(no BROAD trials in {data})"]
    lines = [
        "## BROAD: optical orientation as two reference vectors, 30 % hidden in 1–5 s blocks",
        "",
        "clock offset (ms) of the optical orientation found by the registration: "
        + ", ".join(f"{tr['name'][:2]} {1e3 * _clock(tr).offset_s:.2f}" for tr in trials),
        "",
        "| filter | trial | shown (°) | hidden (°) | IMU-only, hidden (°) | seconds |",
        "|---|---|---|---|---|---|",
    ]
    body = np.eye(3)[:2]
    for name in filters:
        means = []
        for k, tr in enumerate(trials):
            t = np.arange(len(tr["gyr"])) / tr["rate"]
            reg = _clock(tr)
            ref = resample_quat(t, tr["quat"], reg.to_reference(t))
            hidden = hidden_blocks(t, 0.3, np.random.default_rng(seed + k))
            earth = rot.rotate(ref[:, None], body)
            earth[hidden] = np.nan
            refs = MarkerReferences(body, earth, np.full(2, BROAD_SIGMA), reg.gyro_bias)
            t0 = time.perf_counter()
            fused = estimate(name, tr["gyr"], tr["acc"], tr["mag"], tr["rate"], references=refs)
            seconds = time.perf_counter() - t0
            alone = estimate(name, tr["gyr"], tr["acc"], tr["mag"], tr["rate"])
            ok = tr["movement"] & np.isfinite(tr["quat"]).all(axis=1) & np.isfinite(ref).all(1)
            e_f = np.degrees(rot.angle_between(fused.quat, ref))
            e_a = np.degrees(rot.angle_between(alone.quat, tr["quat"]))
            row = (rms(e_f, ok & ~hidden), rms(e_f, ok & hidden), rms(e_a, ok & hidden))
            means.append(row)
            lines.append(
                f"| {name} | {tr['name']} | {row[0]:.3f} | {row[1]:.3f} | {row[2]:.3f} | "
                f"{seconds:.1f} |"
            )
        m = np.mean(means, axis=0)
        lines.append(f"| {name} | **mean** | {m[0]:.3f} | {m[1]:.3f} | {m[2]:.3f} | |")
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="BROAD folder")
    ap.add_argument("--filters", default=",".join(FILTERS))
    ap.add_argument("--seeds", type=seeds_arg, default="1,2,3")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--preset", default=CALIBRATED.name, help="typical-calibrated or a preset")
    ap.add_argument("--no-broad", action="store_true", help="only the simulated session")
    args = ap.parse_args(argv)
    filters = [f for f in args.filters.split(",") if f]
    seeds = args.seeds
    preset = CALIBRATED if args.preset == CALIBRATED.name else get_preset(args.preset)
    print("\n".join(simulated(filters, seeds, args.duration, preset)))
    if not args.no_broad:
        print()
        print("\n".join(broad(filters, args.data, seeds[0])))


if __name__ == "__main__":
    main()
