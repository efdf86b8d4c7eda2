"""The pelvis's forward direction from the walk: its first steps against its turns, per seed.

    python3 bench/pelvis_forward.py [--seeds 0-19] [--preset skin] [--workers 2]

Each seed: ``bench/real_world.py``'s walk (74 s, random mountings, the anatomical knee, own
clocks) through the product path twice: as shipped (the first steps first,
:mod:`motionlab.segments.walk_forward`) and with the first steps giving nothing, so that the
turns are used. Printed per seed: the method the calibration took, and how far (deg) the pelvis
frame's forward direction lies from the truth's about the measured vertical (the truth: the
sensor-to-pelvis rotation averaged over the stand), and the turns' spread. ``–``: the method
gave no direction (the placement hint was kept).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from pool import worker_pool
from real_world import analyse_simulated, simulator_options  # noqa: E402
from seeds import seeds_arg  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.segments import walk_forward  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402

DURATION_S = 74.0


def forward_error(seed: int, preset: str, turns_only: bool) -> tuple[str, float, float]:
    """The method the calibration took for the pelvis's forward direction, its error (deg,
    about the measured vertical; NaN when the hint was kept) and the turns' spread (deg)."""
    protocol = load_protocol("walk")
    session, truth = simulate(protocol, DURATION_S, seed, mounting="random",
                              **simulator_options(preset, False))  # fmt: skip
    shipped = walk_forward.forward_from_start
    if turns_only:  # this job's calibration only (the pool's processes are the bench's own)
        walk_forward.forward_from_start = lambda *a, **k: walk_forward.ForwardDirection(False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            analyse_simulated(session, truth, protocol)
    finally:
        walk_forward.forward_from_start = shipped
    cal = session.results.calibration
    rec = cal.segments["pelvis"].axes.get("movement:turns")
    if rec is None:
        return "hint", float("nan"), float("nan")
    return rec.method, forward_error_deg(cal, truth), rec.spread_deg


def forward_error_deg(cal, truth) -> float:
    """The angle (deg) between the calibrated pelvis frame's forward direction and the truth's
    (the sensor-to-pelvis rotation averaged over the stand), about the measured vertical."""
    mounting = np.asarray(cal.segments["pelvis"].mounting)
    stand = cal.steps["standing"]
    sel = (truth.time >= stand[0]) & (truth.time <= stand[1])
    m = rot.mul(rot.conj(truth.sensors["pelvis"]["orientation"][sel]),
                truth.segments["pelvis"]["orientation"][sel])  # fmt: skip
    x_true = rot.rotate(m, np.array([1.0, 0.0, 0.0])).mean(axis=0)
    x_est = rot.rotate(mounting, np.array([1.0, 0.0, 0.0]))
    up = rot.rotate(mounting, np.array([0.0, 1.0, 0.0]))
    h = [v - (v @ up) * up for v in (x_true, x_est)]
    cos = h[0] @ h[1] / np.linalg.norm(h[0]) / np.linalg.norm(h[1])
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def run_job(job: tuple[int, str, bool]) -> tuple[int, bool, tuple[str, float, float]]:
    seed, preset, turns_only = job
    return seed, turns_only, forward_error(seed, preset, turns_only)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-19")
    ap.add_argument("--preset", default="skin")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    jobs = [(s, args.preset, t) for s in args.seeds for t in (False, True)]
    with worker_pool(args.workers) as pool:
        out = {(s, t): r for s, t, r in pool.map(run_job, jobs)}
    print(f"walk {DURATION_S:g} s, preset {args.preset}, random mountings, seeds {args.seeds}\n")
    print("| seed | as shipped: method | error (deg) | turns only: error (deg) "
          "| turns' spread (deg) |")  # fmt: skip
    print("|---:|---|---:|---:|---:|")
    shipped, turns = [], []
    for s in args.seeds:
        method, err, _ = out[(s, False)]
        _, t_err, spread = out[(s, True)]
        shipped.append(err)
        turns.append(t_err)
        cells = [f"{v:.1f}" if np.isfinite(v) else "–" for v in (err, t_err, spread)]
        print(f"| {s} | {method} | {cells[0]} | {cells[1]} | {cells[2]} |")
    for name, v in (("as shipped", shipped), ("turns only", turns)):
        v = np.asarray(v)
        ok = np.isfinite(v)
        if ok.any():
            print(f"\n{name}: median {np.median(v[ok]):.1f}°, worst {v[ok].max():.1f}°, "
                  f"over 5° on {int((v[ok] > 5).sum())} of {int(ok.sum())} seeds")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
