"""Clocks left after the sync on simulated walks: the network solve against the per-pair choice.

    python3 bench/clock_network.py [--seeds 0-4] [--kinds normal,asymmetric,real_world]

For each seed, ``simulate("walk", ...)`` with every IMU on its own clock (``typical``): ``normal``
and ``asymmetric`` are bench/gait.py's sessions (60 s, tissue ringing after heel strikes),
``real_world`` is bench/real_world.py's (74 s, random mountings, tissue that also moves with the
segment). Each session is synced twice from the same recorded stamps:

- ``network``: :func:`motionlab.clocksync.synchronise` (every clock at once,
  :mod:`motionlab.clocknet`);
- ``per pair``: the sync tree with :func:`motionlab.clocksync.choose` on every pair (joint
  centre when it agrees with the impact lag, else the impact lag), each sensor against its
  reference's corrected clock: the code the network replaced, step for step.

Printed per seed, in ms, the largest clock difference left over the recording (10 s trimmed at
each end) against the simulator's true sampling instants: shank_r–shank_l (the gait events' step
times), thigh–shank per side (the knees), pelvis–thigh per side (the hips); then which
measurements the network set aside or reported as disagreeing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from motionlab import clocksync as cs  # noqa: E402
from motionlab.binding import sensor_for_segment  # noqa: E402
from motionlab.pipeline import prepare_sensors  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from seeds import seeds_arg  # noqa: E402

PAIRS = {
    "sr-sl": ("shank_l", "shank_r"),
    "knee r": ("thigh_r", "shank_r"),
    "knee l": ("thigh_l", "shank_l"),
    "hip r": ("pelvis", "thigh_r"),
    "hip l": ("pelvis", "thigh_l"),
}


def _per_pair(session, protocol) -> None:
    """The sync tree with ``choose`` on every pair, each sensor against its reference's corrected
    clock (the code the network replaced, step for step), in place."""
    moved = {}
    for ref_seg, seg in cs.sync_tree(session, protocol):
        ref = sensor_for_segment(session, ref_seg)
        label = sensor_for_segment(session, seg)
        a, b = session.sensors[ref], session.sensors[label]
        fit = cs.choose(cs.estimate_clock(a, b), cs.impact_clock(a, b))
        use = fit if fit.status == "applied" else None
        if fit.status.startswith("not reliable"):
            use = moved.get(ref)
        if use is not None:
            cs.stage._apply(session, label, use)
            moved[label] = use


def run_one(kind: str, seed: int) -> dict:
    protocol = load_protocol("walk")
    if kind == "real_world":
        session, truth = simulate(
            protocol, 74.0, seed, "typical", mounting="random", soft_tissue="motion"
        )
    else:
        session, truth = simulate(protocol, 60.0, seed, "typical", gait=kind)
    stamps = {k: s.time.copy() for k, s in session.sensors.items()}
    prepare_sensors(session)
    prepared = dict(session.sensors)
    row: dict = {"kind": kind, "seed": seed}
    for name, sync in (("per pair", _per_pair), ("network", cs.synchronise)):
        ses = dataclasses.replace(session, sensors=dict(prepared))
        fits = sync(ses, protocol)
        grid = np.linspace(truth.time[0] + 10.0, truth.time[-1] - 10.0, 2000)  # true time (s)
        err = {}
        for k, s in ses.sensors.items():
            true = np.interp(prepared[k].time, stamps[k], truth.sensors[k]["sample_time"])
            err[k] = np.interp(grid, true, s.time - true)  # synced minus true (s)
        row[name] = {p: 1e3 * float(np.max(np.abs(err[b] - err[a]))) for p, (a, b) in PAIRS.items()}
        if name == "network":
            row["notes"] = [
                f"{f.sensor}: {part}"
                for f in fits
                for part in f.other.split("; ")
                if part.startswith(("set aside", "disagreeing"))
            ]
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-4")
    ap.add_argument("--kinds", default="normal,asymmetric,real_world")
    args = ap.parse_args()
    rows = [run_one(k, s) for k in args.kinds.split(",") for s in args.seeds]
    print("largest clock difference left over the walk (ms), per pair | network")
    print()
    print("| session | " + " | ".join(PAIRS) + " |")
    print("|---|" + "---:|" * len(PAIRS))
    for r in rows:
        cells = [f"{r['per pair'][p]:.1f} \\| {r['network'][p]:.1f}" for p in PAIRS]
        print(f"| {r['kind']} {r['seed']} | " + " | ".join(cells) + " |")
    for kind in dict.fromkeys(r["kind"] for r in rows):
        mine = [r for r in rows if r["kind"] == kind]
        worst = [max(r["per pair"][p] for r in mine) for p in PAIRS]
        new = [max(r["network"][p] for r in mine) for p in PAIRS]
        worst = [f"{a:.1f} \\| {b:.1f}" for a, b in zip(worst, new, strict=True)]
        print(f"| **{kind} worst** | " + " | ".join(worst) + " |")
    print()
    for r in rows:
        for note in r["notes"]:
            print(f"- {r['kind']} {r['seed']}: {note}")


if __name__ == "__main__":
    main()
