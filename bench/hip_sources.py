"""Where the hip angle errors come from: one calibrated frame at a time replaced by the truth's.

    python3 bench/hip_sources.py [--seeds 0-4] [--variants normal asymmetric]

Each run: ``simulate("walk", 60 s, seed, "typical" on one clock, gait=variant)`` and the ``run``
pipeline in memory without clock sync (as ``bench/gait.py --shared-clock``). Then the hip angles
(steady walk, worst side, RMSE in degrees) are recomputed with the product's calibration, without
the hip's flexion axis from the movement (:mod:`motionlab.segments.hip_axis`: the thigh's
knee-axis frame), and with the mounting of the pelvis, of both thighs, of both, or of every
segment replaced by the truth's (the sensor-to-segment rotation averaged over the stand; the
heading ties and the hip axis recomputed from there). Also printed: the calibrated frames'
errors about their long (vertical) axis in the stand (pelvis: the placement hint; thighs: the
knee axis from gait), the hip-axis turn the product measured, and the largest difference between
the simulator's hip truth and motionlab's own hip JCS applied to the truth segment orientations.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from motionlab import rotations as rot  # noqa: E402
from motionlab.binding import sensed_protocol  # noqa: E402
from motionlab.kinematics.joint_angles import decompose_joint  # noqa: E402
from motionlab.kinematics.session_angles import angle_table, session_segments  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.segments import hip_axes  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402
from motionlab.simulate.errors import get_preset  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from joint_angles import shared_clock  # noqa: E402
from seeds import seeds_arg  # noqa: E402

ANGLES = ("flexion", "adduction", "rotation")


def _mean_q(q: np.ndarray) -> np.ndarray:
    """Average orientation (largest eigenvector of Σ q qᵀ)."""
    q = rot.make_continuous(q)
    m = np.linalg.eigh(q.T @ q)[1][:, -1]
    return m if m[0] >= 0 else -m


def true_mounting(truth, seg: str, stand: tuple[float, float]) -> np.ndarray:
    """Segment → sensor rotation of the truth, averaged over the stand."""
    m = rot.mul(rot.conj(truth.sensors[seg]["orientation"]), truth.segments[seg]["orientation"])
    return _mean_q(m[(truth.time >= stand[0]) & (truth.time <= stand[1])])


def long_axis_error(estimate: np.ndarray, true: np.ndarray) -> float:
    """Turn (deg) of the estimated segment frame about its y axis, from the truth's."""
    e = rot.mul(rot.conj(true), estimate)
    e = e if e[0] >= 0 else -e
    return float(np.degrees(rot.to_rotvec(e[None])[0, 1]))


def hip_rmse(session, truth, orig, cal, protocol, step, with_axis=True) -> dict[str, float]:
    """Worst-side RMSE (deg) of each hip angle over the steady walk."""
    cal = copy.deepcopy(cal)
    cal.hip_axes = hip_axes(session, protocol, cal) if with_axis else {}
    ang = angle_table(session_segments(session, protocol, cal), protocol, cal)
    seg = "thigh_r"
    shift = session.sensors[seg].time[0] - orig[seg][0]
    tt = np.interp(ang["time_s"] - shift, orig[seg], truth.sensors[seg]["sample_time"])
    w = (tt > step["start_s"] + 3) & (tt < step["end_s"] - 3)
    out = {}
    for a in ANGLES:
        out[a] = max(
            float(
                np.sqrt(
                    np.nanmean(
                        (
                            ang[f"hip_{s}_{a}_deg"]
                            - np.interp(tt, truth.time, truth.joint_angles[f"hip_{s}_{a}_deg"])
                        )[w]
                        ** 2
                    )
                )
            )
            for s in "rl"
        )
    return out


def run_one(seed: int, variant: str) -> dict[str, object]:
    protocol = load_protocol("walk")
    session, truth = simulate(
        protocol, 60.0, seed, shared_clock(get_preset("typical")), gait=variant
    )
    orig = {k: s.time.copy() for k, s in session.sensors.items()}
    prepare_sensors(session)
    analyse(session, PipelineOptions(protocol, progress=False, clock_sync=False))
    protocol = sensed_protocol(protocol, session)
    cal = session.results.calibration
    stand = tuple(cal.steps["standing"])
    step = truth.step("walk")
    definition = 0.0
    for s in "rl":
        a = decompose_joint(
            truth.segments["pelvis"]["orientation"],
            truth.segments[f"thigh_{s}"]["orientation"],
            protocol.joints[f"hip_{s}"],
        )
        for i, name in enumerate(ANGLES):
            d = np.degrees(a[:, i]) - truth.joint_angles[f"hip_{s}_{name}_deg"]
            definition = max(definition, float(np.abs(d).max()))
    true_m = {seg: true_mounting(truth, seg, stand) for seg in cal.segments}
    errors = {
        seg: long_axis_error(np.asarray(cal.segments[seg].mounting), true_m[seg])
        for seg in ("pelvis", "thigh_r", "thigh_l")
    }

    def replaced(segs):
        c = copy.deepcopy(cal)
        for seg in segs:
            c.segments[seg] = dataclasses.replace(c.segments[seg], mounting=true_m[seg])
        return c

    rows = {
        "product": hip_rmse(session, truth, orig, cal, protocol, step),
        "knee-axis thigh (main)": hip_rmse(session, truth, orig, cal, protocol, step, False),
        "true pelvis": hip_rmse(session, truth, orig, replaced(["pelvis"]), protocol, step),
        "true thighs": hip_rmse(
            session, truth, orig, replaced(["thigh_r", "thigh_l"]), protocol, step
        ),
        "true pelvis + thighs": hip_rmse(
            session, truth, orig, replaced(["pelvis", "thigh_r", "thigh_l"]), protocol, step
        ),
        "true all, no hip axis": hip_rmse(
            session, truth, orig, replaced(list(cal.segments)), protocol, step, False
        ),
    }
    turns = {k: v.turn_deg for k, v in cal.hip_axes.items()}
    return {"rows": rows, "errors": errors, "turns": turns, "definition": definition}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-4")
    ap.add_argument("--variants", nargs="+", default=["normal", "asymmetric"])
    args = ap.parse_args()
    print(f"walk protocol, 60 s, preset typical on one clock, seeds {args.seeds}; hip RMSE (deg)")
    print("over the steady walk, worst side, per seed\n")
    for v in args.variants:
        res = [run_one(s, v) for s in args.seeds]
        print(f"## {v}\n")
        print("| frames | " + " | ".join(f"{a} per seed" for a in ANGLES[:2]) + " |")
        print("|---|---|---|")
        for name in res[0]["rows"]:
            cells = [" ".join(f"{r['rows'][name][a]:.2f}" for r in res) for a in ANGLES[:2]]
            print(f"| {name} | " + " | ".join(cells) + " |")
        print()
        for seg in ("pelvis", "thigh_r", "thigh_l"):
            vals = " ".join(f"{r['errors'][seg]:+.1f}" for r in res)
            print(f"  {seg} frame's turn about its long axis (deg): {vals}")
        for j in ("hip_r", "hip_l"):
            vals = " ".join(f"{r['turns'].get(j, float('nan')):+.1f}" for r in res)
            print(f"  {j} axis turn measured by the product (deg): {vals}")
        worst = max(r["definition"] for r in res)
        print(f"  truth hip angles vs motionlab's hip JCS on the truth segments: {worst:.1e} deg\n")


if __name__ == "__main__":
    main()
