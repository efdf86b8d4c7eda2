"""Simulated seated trunk sessions (``lumbar_seated``) over several seeds: lumbar angles
against the simulator's truth (issue 28: ≤ 1.5° per plane).

Each seed: ``motionlab simulate --protocol lumbar_seated`` (sitting still, flexion, lateral
bending and rotation in one continuous block, then everyday movement; 40 s, preset
``typical``, 50 Hz unless told), run as ``motionlab run --protocol lumbar_seated`` does; RMSE
(deg) per plane over the trunk block, the truth's zero at the product's rest (as
``tests/test_trunk_seated.py``).

Usage (from the repository root)::

    python3 bench/seated_trunk_sim.py [--seeds 0-9] [--rate 50] [--preset typical]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from motionlab.pipeline import PipelineOptions, analyse  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402

PLANES = ("flexion", "lateral_bending", "axial_rotation")


def seed_list(text: str) -> list[int]:
    """``"0-9"`` or ``"0,2,5"`` → seeds."""
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def run_seed(seed: int, rate: float, preset: str) -> dict[str, float | str]:
    """RMSE (deg) per plane over the trunk block, and the grades."""
    session, truth = simulate("lumbar_seated", duration=40, seed=seed, preset=preset,
                              rate_hz=rate)  # fmt: skip
    analyse(session, PipelineOptions(protocol="lumbar_seated", progress=False, clock_sync=False))
    cols = session.results.angles.columns()
    cal = session.results.calibration
    t = np.asarray(cols["time_s"], float)
    rest = cal.steps["rest"]
    block = truth.step("trunk_movement")
    inside = (t >= block["start_s"]) & (t <= block["end_s"])
    at_rest = (t >= rest[0]) & (t <= rest[1])
    out: dict[str, float | str] = {}
    for plane in PLANES:
        ref = np.interp(t, truth.time, truth.joint_angles[f"lumbar_{plane}_deg"])
        e = (np.asarray(cols[f"lumbar_{plane}_deg"], float) - (ref - ref[at_rest].mean()))[inside]
        out[plane] = float(np.sqrt(np.mean(e**2)))
    out["grades"] = "/".join(g[:3] for g in cal.grades["lumbar"]["grades"])
    out["drift"] = str(cal.grades["lumbar"]["trunk"].get("heading_drift_from"))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--rate", type=float, default=50.0)
    ap.add_argument("--preset", default="typical")
    args = ap.parse_args(argv)
    rows = []
    print(f"## Simulated seated sessions ({args.preset}, {args.rate:g} Hz): RMSE (deg)\n")
    print("| seed | flexion | lateral bending | axial rotation | grades | heading drift from |")
    print("|---|---|---|---|---|---|")
    for seed in seed_list(args.seeds):
        r = run_seed(seed, args.rate, args.preset)
        rows.append(r)
        print(f"| {seed} | " + " | ".join(f"{r[p]:.2f}" for p in PLANES)
              + f" | {r['grades']} | {r['drift']} |", flush=True)  # fmt: skip
    arr = np.array([[r[p] for p in PLANES] for r in rows])
    print("| median | " + " | ".join(f"{x:.2f}" for x in np.median(arr, axis=0)) + " | | |")
    print("| worst | " + " | ".join(f"{x:.2f}" for x in arr.max(axis=0)) + " | | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
