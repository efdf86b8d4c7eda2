"""Where the elbow errors of ``bench/real_world.py --protocols arm`` come from, per seed.

For each seed the ``arm`` protocol is simulated as ``real_world.py`` does (random mountings, the
``skin`` preset: ``typical`` sensors, every IMU on its own clock, the upper-arm sensor following
only part of the humerus' axial rotation) and analysed by the product path
(:func:`motionlab.pipeline.analyse`). Each elbow flexion's RMSE (deg) over the free movement is
shown next to variants that each remove one suspected source:

- ``as is``: the product against the simulator's truth; ``mean``: its mean error; the grade;
- ``ax``: the angle (deg) between the product's segment axes and the true ones (read through the
  true mounting): upper arm z (the flexion axis) and y (the long axis, from gravity), forearm y
  (the pronation axis) and z (the flexion axis in the stand);
- ``true mnt``: the product's orientations and heading ties, the sensors' true mountings in place
  of the calibrated ones (what is left: fusion, skin, heading ties);
- ``skin``: no product at all: the angles from the simulator's exact sensor orientations (skin
  motion included) through the true mountings (what the skin alone costs);
- ``follow 1``: the same seed with the upper-arm skin following the humerus' axial rotation
  fully (``STA_HUMERAL_FOLLOW = (1, 1)``, no spread), through the product;
- ``exact`` (``--exact``): the two-axis fit (:func:`motionlab.segments.movement.fit_two_dof`,
  as the product calls it) on the simulator's exact sensor orientations and their rates, no
  fusion, noise, clocks or heading offsets: its parts' disagreement (deg) and its axes' angles
  (deg) to the true upper-arm z and forearm y; what the fit's model leaves when everything
  before it is perfect;
- ``lag R²`` (``--exact``): the share of the variance of the upper-arm skin's lag rate (the
  humerus' rate about its long axis minus its sensor's, from the simulator's bone and sensor
  orientations) that the fit's model of it, ``k`` times the sensor's rate about its stand long
  axis, explains at the best ``k``: over the whole movement and over the samples with the upper
  arm within 30° of hanging;
- ``clocks`` (``--clocks``): the same recording with the true sampling instants and no sync;
- ``incl``: no calibration and no heading: each sensor's fused orientation turned about the
  vertical to its true heading (what is left of the fusion: its inclination), through the true
  mountings; between ``skin`` and ``true mnt`` it shows what the inclination costs and what the
  heading ties cost;
- ``--ideal-sensors``: every variant on sensors without biases, scale factors or misalignments
  (noise, clocks and skin as before): what is left when the fusion has nothing to estimate.

Needs no data files. Usage::

    python bench/elbow_sources.py [--seeds 0-9] [--workers 2] [--clocks] [--no-follow] [--exact]
                                  [--ideal-sensors]
"""

from __future__ import annotations

import argparse
import dataclasses
from importlib import import_module

import numpy as np
from joint_angles import joint_clocks
from pool import worker_pool
from real_world import analyse_simulated, rmse, task_errors, with_true_mountings
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.protocol import axis_vector, load_protocol
from motionlab.segments import movement, sensor_for_segment
from motionlab.segments.placement import hinge_spec
from motionlab.segments.sensors import sensor_orientation
from motionlab.simulate import simulate

sim = import_module("motionlab.simulate")  # the package: motionlab.simulate is the function
sensor_errors = import_module("motionlab.simulate.errors")

DURATION_S = 74.0
ELBOWS = ("elbow_r", "elbow_l")
COLS = tuple(f"{e}_flexion_deg" for e in ELBOWS)


def _run(seed: int, true_clocks: bool = False, follow_all: bool = False):
    """Simulate and analyse one ``arm`` session; ``(session, truth, protocol, stamps, tasks)``."""
    saved = sim.STA_HUMERAL_FOLLOW, sim.STA_HUMERAL_FOLLOW_SD
    if follow_all:  # this worker's simulator only
        sim.STA_HUMERAL_FOLLOW, sim.STA_HUMERAL_FOLLOW_SD = (1.0, 1.0), 0.0
    try:
        protocol = load_protocol("arm")
        session, truth = simulate(
            protocol, DURATION_S, seed, "skin", mounting="random", knee_model="anatomical"
        )
    finally:
        sim.STA_HUMERAL_FOLLOW, sim.STA_HUMERAL_FOLLOW_SD = saved
    stamps, tasks = analyse_simulated(session, truth, protocol, true_clocks)
    return session, truth, protocol, stamps, tasks


def ideal_sensors() -> None:
    """This process's ``skin`` preset without sensor biases, scale factors or misalignments."""
    skin = sensor_errors.PRESETS["skin"]
    perfect = {"bias_sigma": 0.0, "bias_walk": 0.0, "scale_sigma": 0.0, "misalignment_sigma": 0.0}
    sensor_errors.PRESETS["skin"] = dataclasses.replace(
        skin,
        gyr=dataclasses.replace(skin.gyr, **perfect),
        acc=dataclasses.replace(skin.acc, **perfect),
    )


def _axis_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a), -1.0, 1.0))))


def _skin_only(truth, protocol, session, tasks) -> dict[str, float]:
    """RMSE of the angles from the exact sensor orientations through the true mountings."""
    t = truth.time
    inside = np.zeros(len(t), bool)
    for a, b in tasks:
        inside |= (t >= a) & (t <= b)
    out = {}
    for name in ELBOWS:
        joint = protocol.joints[name]
        q = []
        for seg in (joint.proximal, joint.distal):
            s = truth.sensors[sensor_for_segment(session, seg)]
            q.append(rot.mul(s["orientation"], rot.conj(s["mounting"])))
        ang = joint_angles(q[0], q[1], joint)
        col = f"{name}_flexion_deg"
        out[col] = rmse((ang[col] - truth.joint_angles[col])[inside])
    return out


def _inclination_only(truth, protocol, session, stamps, tasks) -> dict[str, float]:
    """RMSE of the angles from the fused orientations turned to their sensors' true headings,
    through the true mountings (the fusion's inclination error and the skin)."""
    t = truth.time
    inside = np.zeros(len(t), bool)
    for a, b in tasks:
        inside |= (t >= a) & (t <= b)
    clocks = joint_clocks(session, truth, stamps, protocol)
    up = np.array([0.0, 0.0, 1.0])
    out = {}
    for name in ELBOWS:
        joint = protocol.joints[name]
        q = []
        for seg in (joint.proximal, joint.distal):
            label = sensor_for_segment(session, seg)
            s = truth.sensors[label]
            t_true = clocks[name](session.sensors[label].time)
            q_fused = sensor_orientation(session, label)
            ok = np.flatnonzero(np.isfinite(q_fused).all(axis=1))  # not in packet losses
            # the clock's map holds its ends flat beyond the span it knows: one sample each
            t_true, first = np.unique(t_true[ok], return_index=True)
            fused = rot.resample(t_true, q_fused[ok][first], t)
            heading = rot.twist_angle(rot.mul(s["orientation"], rot.conj(fused)), up)
            q.append(rot.mul(rot.mul(rot.from_axis_angle(up, heading), fused),
                             rot.conj(s["mounting"])))  # fmt: skip
        col = f"{name}_flexion_deg"
        out[col] = rmse((joint_angles(q[0], q[1], joint)[col] - truth.joint_angles[col])[inside])
    return out


def _rates(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angular rate (rad/s, sensor frame) of orientations ``q`` sampled at ``t``."""
    dq = rot.mul(rot.conj(q[:-1]), q[1:])
    w = 2.0 * dq[:, 1:] * np.sign(dq[:, :1]) / np.diff(t)[:, None]
    return np.vstack([w, w[-1:]])


def _exact(truth, protocol, session, name: str, tasks) -> dict:
    """The two-axis fit on the exact sensor orientations, and the lag model's share (R²)."""
    joint = protocol.joints[name]
    t = truth.time
    step = next(s for s in truth.steps if s["kind"] == "static")
    reference = (step["start_s"] + 0.5, step["end_s"] - 0.5)
    sides, true_axes = [], []
    for seg, axis in ((joint.proximal, "z"), (joint.distal, "y")):
        s = truth.sensors[sensor_for_segment(session, seg)]
        sides.append((t, _rates(t, s["orientation"]), s["orientation"]))
        true_axes.append(rot.rotate(rot.conj(s["mounting"]), axis_vector(axis)))
    prior_1 = protocol.segments[joint.proximal].nominal_mounting().T @ axis_vector(
        hinge_spec(joint)[0]
    )
    prior_2 = protocol.segments[joint.distal].nominal_mounting().T @ axis_vector("y")
    fit = movement.fit_two_dof(name, *sides, prior_1, prior_2, reference, axial_lag=True)
    # the lag: the bone's rate about its long axis minus the sensor's (bone frame), per sample
    s = truth.sensors[sensor_for_segment(session, joint.proximal)]
    q_seg = rot.mul(s["orientation"], rot.conj(s["mounting"]))
    rel = rot.mul(rot.conj(truth.segments[joint.proximal]["orientation"]), q_seg)
    lag = np.diff(np.unwrap(2.0 * np.arctan2(rel[:, 2], rel[:, 0])))
    stand = (t >= reference[0]) & (t <= reference[1])
    long_s = rot.rotate(rot.conj(rot.mean(s["orientation"][stand])), np.array([0.0, 0.0, 1.0]))
    spin = _rates(t, s["orientation"])[:-1] @ long_s * np.diff(t)
    hanging = rot.rotate(s["orientation"][:-1], long_s)[:, 2] >= np.cos(np.radians(30.0))
    inside = np.zeros(len(t) - 1, bool)
    for a, b in tasks:
        inside |= (t[:-1] >= a) & (t[:-1] <= b)
    r2 = []
    for sel in (inside, inside & hanging):
        k = -(spin[sel] @ lag[sel]) / (spin[sel] @ spin[sel])
        r2.append(1.0 - np.var(lag[sel] + k * spin[sel]) / np.var(lag[sel]))
    return {
        "cons": fit.consistency_deg,
        "ua_z": _axis_deg(fit.axis_proximal, true_axes[0]),
        "fa_y": _axis_deg(fit.axis_distal, true_axes[1]),
        "r2": tuple(r2),
    }


def diagnose(job: tuple[int, bool, bool, bool]) -> dict:
    """Every variant's RMSE per elbow flexion of one seed (see the module notes)."""
    seed, clocks_too, follow_too, exact_too, ideal = job
    if ideal:
        ideal_sensors()
    session, truth, protocol, stamps, tasks = _run(seed)
    err = task_errors(session, truth, protocol, stamps, tasks)
    row: dict = {"seed": seed}
    row["as_is"] = {c: rmse(err[c]) for c in COLS}
    row["mean"] = {c: float(np.nanmean(err[c])) for c in COLS}
    cal = session.results.calibration
    row["grade"] = {f"{n}_flexion_deg": cal.grades[n].grades[0] for n in ELBOWS}
    row["fit"] = {}
    for n in ELBOWS:
        f = cal.hinges.get(n)
        row["fit"][n] = (
            (f.verdict, f.consistency_deg, f.relative_residual, f.sign) if f else ("?",) * 4
        )
    row["axes"] = {}
    ex, ey, ez = np.eye(3)
    for name in ELBOWS:
        joint = protocol.joints[name]
        for seg, axes in ((joint.proximal, (ez, ey)), (joint.distal, (ey, ez))):
            m_true = truth.sensors[sensor_for_segment(session, seg)]["mounting"]
            q = rot.mul(m_true, np.asarray(cal.segments[seg].mounting, float))
            row["axes"][seg] = tuple(_axis_deg(rot.rotate(q, a), a) for a in axes)
    row["skin"] = _skin_only(truth, protocol, session, tasks)
    row["incl"] = _inclination_only(truth, protocol, session, stamps, tasks)
    if exact_too:
        row["exact"] = {n: _exact(truth, protocol, session, n, tasks) for n in ELBOWS}
    with_true_mountings(session, truth, protocol, ELBOWS)
    err_m = task_errors(session, truth, protocol, stamps, tasks)
    row["true_mnt"] = {c: rmse(err_m[c]) for c in COLS}
    if follow_too:
        e = task_errors(*_run(seed, follow_all=True))
        row["follow1"] = {c: rmse(e[c]) for c in COLS}
    if clocks_too:
        e = task_errors(*_run(seed, true_clocks=True))
        row["clocks"] = {c: rmse(e[c]) for c in COLS}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-9")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--clocks", action="store_true", help="also with perfect clocks")
    ap.add_argument("--no-follow", action="store_true", help="skip the full-follow variant")
    ap.add_argument("--exact", action="store_true", help="also the fit on exact orientations")
    ap.add_argument("--ideal-sensors", action="store_true",
                    help="sensors without biases, scale factors or misalignments")  # fmt: skip
    args = ap.parse_args()
    jobs = [
        (s, args.clocks, not args.no_follow, args.exact, args.ideal_sensors) for s in args.seeds
    ]
    with worker_pool(args.workers) as pool:
        rows = pool.map(diagnose, jobs)
    for side, col in zip("rl", COLS, strict=True):
        ua, fa = f"upperarm_{side}", f"forearm_{side}"
        print(f"\nelbow_{side} flexion, RMSE (deg); axes: angle (deg) to the true segment axis")
        head = "| seed | as is | mean | grade | fit (cons°, res) | ua z | ua y | fa y | fa z |"
        head += " true mnt | incl | skin |"
        extra = [k for k in ("follow1", "clocks") if k in rows[0]]
        head += "".join(f" {k} |" for k in extra)
        if "exact" in rows[0]:
            head += " exact: cons / ua z / fa y | lag R² (all / hanging) |"
        print(head)
        print("|---:" * (head.count("|") - 1) + "|")
        for r in rows:
            v, cons, res, _ = r["fit"][f"elbow_{side}"]
            cells = [
                f"{r['as_is'][col]:.2f}", f"{r['mean'][col]:+.2f}", r["grade"][col],
                f"{v} ({cons:.0f}, {res:.2f})",
                f"{r['axes'][ua][0]:.1f}", f"{r['axes'][ua][1]:.1f}",
                f"{r['axes'][fa][0]:.1f}", f"{r['axes'][fa][1]:.1f}",
                f"{r['true_mnt'][col]:.2f}", f"{r['incl'][col]:.2f}", f"{r['skin'][col]:.2f}",
            ] + [f"{r[k][col]:.2f}" for k in extra]  # fmt: skip
            if "exact" in r:
                x = r["exact"][f"elbow_{side}"]
                cells += [f"{x['cons']:.1f} / {x['ua_z']:.1f} / {x['fa_y']:.1f}",
                          f"{x['r2'][0]:.2f} / {x['r2'][1]:.2f}"]  # fmt: skip
            print(f"| {r['seed']} | " + " | ".join(cells) + " |")
        for key in ("as_is", "true_mnt", "incl", "skin", *extra):
            vals = [r[key][col] for r in rows]
            print(f"{key}: mean {np.mean(vals):.2f}, max {np.max(vals):.2f}")


if __name__ == "__main__":
    main()
