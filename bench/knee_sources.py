"""Where the knee errors of ``bench/real_world.py --protocols walk`` come from, per seed and angle.

For each seed the ``walk`` protocol is simulated as ``real_world.py`` does (random mountings,
``typical`` sensors, every IMU on its own clock, soft-tissue ``motion``) and analysed by the
product path (:func:`motionlab.pipeline.analyse`). Each knee angle's RMSE (deg) over the walk is
then shown next to variants that each remove one suspected source:

- ``as is``: the product against the simulator's truth; ``mean``: the mean error (a constant
  offset); ``sd``: the offset-free RMSE (standard deviation of the error);
- ``stand``: the mean error over the stand (the pose the product takes as neutral; the
  simulator's true standing knee angles are zero);
- ``clocks``: the same recording with the true sampling instants and no clock sync;
- ``impacts``: the same seed with ``soft_tissue="impacts"`` (no acceleration-driven sensor motion
  on the segment, only heel-strike ringing);
- ``no acc bias``: the same seed with the ``typical`` sensors' accelerometer bias (offset and
  walk) set to zero, everything else unchanged;
- ``true mnt``: the product's orientations and heading ties, but the sensors' true mountings in
  place of the calibrated ones (what is left is fusion, soft tissue and heading);
- ``func``: the product against the truth re-expressed with *functional* segment frames: each
  segment's y is its true vertical in the stand (as the product takes it from gravity), its z the
  knee axis fitted by the product's own hinge fit (soft-L1 Seel constraint) to the TRUE,
  error-free segment angular velocities over the walk; ``def``: that functional truth against
  the anatomical truth (the definitional difference between the two axes, no product in it);
  ``func svd`` / ``def svd``: the same with the functional axis taken as the dominant axis of
  the true relative angular velocity (SVD) instead of the hinge fit; ``func jcs`` / ``def jcs``:
  the same with the turn about the shank's long axis left out first (what the product's
  :func:`~motionlab.segments.movement.dominant_axes` estimates);
- ``ax th / ax sh``: the angle (deg) between the product's flexion axis (segment z, read
  through the true mounting) and the anatomical z / the true functional axis, on the thigh and
  the shank; ``vd``: the product's verdict of the hinge fit with its consistency (deg) and
  relative residual.

Needs no data files. Usage::

    python bench/knee_sources.py [--seeds 2,3,4,5,7,9] [--workers 2] [--all-cells] [--clocks]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from pool import worker_pool
from real_world import analyse_simulated, rmse, target, task_errors, with_true_mountings
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import decompose_joint
from motionlab.kinematics.joint_types import angle_columns
from motionlab.protocol import load_protocol
from motionlab.segments import sensor_for_segment
from motionlab.segments.hinge import hinge_axes
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset

DURATION_S = 74.0
KNEES = ("knee_r", "knee_l")


def _run(seed: int, tissue: str, true_clocks: bool, acc_bias: bool = True):
    """Simulate and analyse one session; ``(session, truth, protocol, stamps, task windows)``.
    ``acc_bias=False``: the ``typical`` sensors without accelerometer bias (offset and walk)."""
    protocol = load_protocol("walk")
    preset = get_preset("typical")
    if not acc_bias:
        acc = dataclasses.replace(preset.acc, bias_sigma=0.0, bias_walk=0.0)
        preset = dataclasses.replace(preset, acc=acc)
    session, truth = simulate(
        protocol, DURATION_S, seed, preset, mounting="random", soft_tissue=tissue
    )
    stamps, tasks = analyse_simulated(session, truth, protocol, true_clocks)
    return session, truth, protocol, stamps, tasks


def _body_rate(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angular velocity (N, 3) rad/s in the moving frame from orientations on ``t``."""
    q = rot.make_continuous(q)
    dq = np.gradient(q, t, axis=0)
    return 2.0 * rot.mul(rot.conj(q), dq)[:, 1:]


def _frame(z: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rotation (columns x, y, z) with y exact and z the given axis made perpendicular to it."""
    y = y / np.linalg.norm(y)
    z = z - (z @ y) * y
    z /= np.linalg.norm(z)
    return np.column_stack([np.cross(y, z), y, z])


def functional_truth(truth, protocol, tasks, how: str = "seel") -> tuple[dict, dict]:
    """Truth re-expressed with functional knee frames (see the module notes), and the axes.

    ``how``: ``seel`` (the Seel hinge fit on the true segment rates), ``svd`` (the dominant axis
    of the true relative angular velocity in the thigh frame; the shank's is the same axis
    through the stand, where the true knee angles are zero) or ``jcs`` (as ``svd`` with the turn
    about the shank's long axis left out, as :func:`motionlab.segments.movement.dominant_axes`).

    Returns ``({column: degrees on truth.time}, {segment: functional z in segment coords})``.
    """
    t = truth.time
    inside = np.zeros(len(t), bool)
    for a, b in tasks:
        inside |= (t >= a) & (t <= b)
    out, axes = {}, {}
    for name in KNEES:
        joint = protocol.joints[name]
        qp = truth.segments[joint.proximal]["orientation"]
        qd = truth.segments[joint.distal]["orientation"]
        wp, wd = _body_rate(t, qp)[inside], _body_rate(t, qd)[inside]
        step = max(1, int(inside.sum() // 20000))
        z = np.array([0.0, 0.0, 1.0])
        if how in ("svd", "jcs"):
            q_rel = rot.mul(rot.conj(qp), qd)[inside]
            w_rel = rot.rotate(q_rel, wd) - wp
            if how == "jcs":  # the turn about the shank's long axis y left out
                long_p = rot.rotate(q_rel, np.broadcast_to([0.0, 1.0, 0.0], (len(q_rel), 3)))
                w_rel -= long_p * np.einsum("ij,ij->i", w_rel, long_p)[:, None]
            jp = np.linalg.svd(w_rel[::step], full_matrices=False)[2][0]
            jd = jp.copy()
        else:
            jp, jd, _ = hinge_axes(wp[::step], wd[::step], z, z, loss="soft_l1", f_scale=0.1)
        jp, jd = jp * np.sign(jp[2]), jd * np.sign(jd[2])
        axes[joint.proximal], axes[joint.distal] = jp, jd
        y = np.array([0.0, 1.0, 0.0])  # the stand: every segment's y is vertical
        fp, fd = rot.from_matrix(_frame(jp, y)), rot.from_matrix(_frame(jd, y))
        ang = np.degrees(decompose_joint(rot.mul(qp, fp), rot.mul(qd, fd), joint))
        for k, (_, col) in enumerate(angle_columns(joint)):
            out[col] = ang[:, k]
    return out, axes


def _axis_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(a @ b) / np.linalg.norm(a), -1.0, 1.0))))


def diagnose(job: tuple[int, bool]) -> dict:
    """Every variant's RMSE per knee column of one seed (see the module notes)."""
    seed, clocks_too = job
    session, truth, protocol, stamps, tasks = _run(seed, "motion", False)
    err = task_errors(session, truth, protocol, stamps, tasks)
    cols = [c for c in err if c.startswith(KNEES)]
    row: dict = {"seed": seed, "cols": cols}
    row["as_is"] = {c: rmse(err[c]) for c in cols}
    row["mean"] = {c: float(np.nanmean(err[c])) for c in cols}
    row["sd"] = {c: float(np.nanstd(err[c])) for c in cols}
    stand = [(s["start_s"] + 0.5, s["end_s"] - 0.5) for s in truth.steps if s["kind"] == "static"]
    err_stand = task_errors(session, truth, protocol, stamps, stand)
    row["stand"] = {c: float(np.nanmean(err_stand[c])) for c in cols}
    # the truth about the functional axes
    func, fax = functional_truth(truth, protocol, tasks)
    anat = truth.joint_angles
    truth_f = dataclasses.replace(truth, joint_angles={**anat, **func})
    err_f = task_errors(session, truth_f, protocol, stamps, tasks)
    row["func"] = {c: rmse(err_f[c]) for c in cols}
    row["func_sd"] = {c: float(np.nanstd(err_f[c])) for c in cols}
    inside = np.zeros(len(truth.time), bool)
    for a, b in tasks:
        inside |= (truth.time >= a) & (truth.time <= b)
    row["def"] = {c: rmse((func[c] - anat[c])[inside]) for c in cols}
    svd, _ = functional_truth(truth, protocol, tasks, "svd")
    err_s = task_errors(session, dataclasses.replace(truth, joint_angles={**anat, **svd}), protocol,
                    stamps, tasks)  # fmt: skip
    row["func_svd"] = {c: rmse(err_s[c]) for c in cols}
    row["def_svd"] = {c: rmse((svd[c] - anat[c])[inside]) for c in cols}
    jcs, jax = functional_truth(truth, protocol, tasks, "jcs")
    err_j = task_errors(session, dataclasses.replace(truth, joint_angles={**anat, **jcs}), protocol,
                    stamps, tasks)  # fmt: skip
    row["func_jcs"] = {c: rmse(err_j[c]) for c in cols}
    row["def_jcs"] = {c: rmse((jcs[c] - anat[c])[inside]) for c in cols}
    # the product's axes against the anatomical and functional ones
    cal = session.results.calibration
    row["axes"], row["verdict"] = {}, {}
    for name in KNEES:
        joint = protocol.joints[name]
        for seg in (joint.proximal, joint.distal):
            label = sensor_for_segment(session, seg)
            m_true = truth.sensors[label]["mounting"]  # sensor -> segment
            q_mount = np.asarray(cal.segments[seg].mounting, float)  # segment -> sensor
            z_est = rot.rotate(rot.mul(m_true, q_mount), np.array([0.0, 0.0, 1.0]))
            y_est = rot.rotate(rot.mul(m_true, q_mount), np.array([0.0, 1.0, 0.0]))
            z, y = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
            f = _frame(fax[seg], y)[:, 2]  # the functional axis as the product frames it
            row["axes"][seg] = (_axis_deg(z_est, z), _axis_deg(z_est, f), _axis_deg(f, z),
                                _axis_deg(y_est, y))  # fmt: skip
        fit = cal.hinges.get(name)
        row["verdict"][name] = (
            (fit.verdict, float(fit.consistency_deg), float(fit.relative_residual))
            if fit is not None
            else ("?", np.nan, np.nan)
        )
    # the true mountings in place of the calibrated ones
    with_true_mountings(session, truth, protocol, KNEES)
    err_m = task_errors(session, truth, protocol, stamps, tasks)
    row["true_mnt"] = {c: rmse(err_m[c]) for c in cols}
    row["grade"] = {}
    for name in KNEES:
        g = cal.grades[name].grades
        for k, (_, col) in enumerate(angle_columns(protocol.joints[name])):
            row["grade"][col] = g[k]
    # soft tissue: impacts only
    s2, t2, p2, st2, tk2 = _run(seed, "impacts", False)
    e2 = task_errors(s2, t2, p2, st2, tk2)
    row["impacts"] = {c: rmse(e2[c]) for c in cols}
    s4, t4, p4, st4, tk4 = _run(seed, "motion", False, acc_bias=False)
    e4 = task_errors(s4, t4, p4, st4, tk4)
    row["no_acc_bias"] = {c: rmse(e4[c]) for c in cols}
    if clocks_too:
        s3, t3, p3, st3, tk3 = _run(seed, "motion", True)
        e3 = task_errors(s3, t3, p3, st3, tk3)
        row["clocks"] = {c: rmse(e3[c]) for c in cols}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=seeds_arg, default="2,3,4,5,7,9")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--all-cells", action="store_true", help="every knee cell, not only failing")
    ap.add_argument("--clocks", action="store_true", help="also run with perfect clocks")
    args = ap.parse_args()
    jobs = [(s, args.clocks) for s in args.seeds]
    with worker_pool(args.workers) as pool:
        rows = pool.map(diagnose, jobs)
    short = {"flexion": "flex", "adduction": "add", "rotation": "rot"}
    print("knee RMSE (deg) over the walk by variant; axes (deg) of the proximal and distal "
          "segment: product z vs anatomical z / product z vs functional z / functional z vs "
          "anatomical z / product y vs true y")  # fmt: skip
    print()
    head = "| seed | angle | tgt | as is | mean | sd | stand | clocks | impacts | no acc bias |"
    head += " true mnt | func | def | func svd | def svd | func jcs | def jcs |"
    print(head + " grade | axes prox e-a/e-f/f-a/y | axes dist | hinge fit |")
    print("|---:|---|---:|" + "---:|" * 14 + "---|---|---|---|")
    for r in rows:
        for c in r["cols"]:
            if not args.all_cells and r["as_is"][c] <= target(c):
                continue
            name = c[:6]
            kind = short.get(c.removesuffix("_deg").split("_")[-1], "?")
            p, d = ("thigh_" + name[-1], "shank_" + name[-1])
            ap_, ad = r["axes"][p], r["axes"][d]
            v = r["verdict"][name]
            clocks = f"{r['clocks'][c]:.2f}" if "clocks" in r else "-"
            print(
                f"| {r['seed']} | {name} {kind} | {target(c):.0f} | {r['as_is'][c]:.2f} | "
                f"{r['mean'][c]:+.2f} | {r['sd'][c]:.2f} | {r['stand'][c]:+.2f} | {clocks} | "
                f"{r['impacts'][c]:.2f} | "
                f"{r['no_acc_bias'][c]:.2f} | {r['true_mnt'][c]:.2f} | {r['func'][c]:.2f} | "
                f"{r['def'][c]:.2f} | {r['func_svd'][c]:.2f} | {r['def_svd'][c]:.2f} | "
                f"{r['func_jcs'][c]:.2f} | {r['def_jcs'][c]:.2f} | "
                f"{r['grade'][c]} | {'/'.join(f'{x:.1f}' for x in ap_)} | "
                f"{'/'.join(f'{x:.1f}' for x in ad)} | {v[0]} {v[1]:.1f}° {100 * v[2]:.0f}% |"
            )


if __name__ == "__main__":
    main()
