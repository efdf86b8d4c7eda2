"""Real people seated (trunk data set): lumbar angles of the ``lumbar_seated`` protocol against
OptiTrack, with the x-IMU3's own fusion and VQF 9-D as peers.

Data: ``../shared/datasets/trunk/<subject>/<task>/`` (``imu/``: an x-IMU3 export, a folder per
device; ``optitrack.csv``: Motive CSV 1.23 at 120 Hz). No licence: read from ../shared only.
These five trials are the **tuning set** of the trunk calibration's numbers
(``segments/trunk_axes.py``); they are not an independent test.

For every trial the product is run in memory as ``motionlab run <trial>/imu --map MAP
--protocol lumbar_seated`` does (``pipeline.analyse``: clock sync, fusion, calibration, angles),
three times: default 6-D fusion (the product), ``orientation="vendor"`` (the x-IMU3's
``Quaternion.csv``, its own 9-D fusion) and VQF offline 9-D (``estimator="vqf_offline"``,
magnetometer on; skipped when ``vqf`` is not installed). The map: ``Back`` → thorax, ``Chest``
(at the lower back) → pelvis, ``Chair`` → chair (``protocols/examples/trunk_map.yaml``).

Optical reference (``back`` relative to ``low_back``):

- **flips, jumps and gaps:** a frame whose orientation is more than ``FLIP_DEG`` plus
  ``FLIP_RATE_DEG_S`` × the time since the last good frame away from the last good frame is a
  flip (Motive swapping markers) and is left out, as are gaps (empty cells) and **jumps**: frames
  more than ``JUMP_DEG`` from the body's smooth path over ``JUMP_WINDOW_S`` (Motive
  switching between two marker solutions for a few frames, under the flip test's 15°: the
  ``low_back`` body of the Aag trials, :func:`jumps`); the IMU angles are compared where the
  optical body is good;
- **clock:** optical = IMU + d, from the angular speeds of back, low_back and the chair (IMU
  ``Back``, ``Chest``, ``Chair``), searched over ±``CLOCK_SEARCH_S`` by correlation
  (``validation.joint_reference.fit_clock_offset``), then refined within ±0.1 s on the lumbar
  rotation-from-rest angle (IMU orientations lag the speeds by about half a sample); the IMUs
  among themselves are on the clock the product's clock sync gives them (``Back`` on
  ``Chest``'s by the spine rule, ``clocksync/joint_centre.py``, where it is reliable: the
  vendor's synchronised stamps differ by 10–18 ms);
- **anatomical frame:** y = the lab's vertical (Motive's Y), z = the horizontal direction from
  the left to the right upper arm's rigid body (``l_arm`` → ``r_arm``) over the IMU's rest,
  x = y × z; both bodies take this frame at the rest (the zero of the angles, as the IMU's).
  This frame is built from neither the IMUs' axes nor the movement's: it can move the split
  between flexion and lateral bending (an arm line θ off the true mediolateral axis mixes about
  sin θ of one into the other) and the axial rotation's zero, but not the **rotation from the
  rest** (the angle of ``R_rest⁻¹ R(t)`` of the joint), which is the same in every frame and is
  reported alongside.

Metrics per trial and plane: RMSE, offset-free RMSE (mean difference removed), r (no flipping:
a sign error is an error), and the product's grade. Medians over the trials. The trunk against
the chair (``trunk_lean_*``): OptiTrack ``back`` relative to the wheelchair's body
(``rolstoel``) in the same decomposition, its flexion, lateral bending and axial rotation
against the forward lean, sideways lean and rotation against the chair, and its rotation from
the rest (``lean from rest``, frame-free as the lumbar one). Per trial, the **split turn**
(:func:`split_turn`): the turn about the vertical that best carries the product's (flexion,
lateral bending) — and (forward, sideways lean) — onto the optical ones, i.e. how far the
optical frame's lateral axis lies from the product's flexion axis; a large turn with a small
rotation from the rest is a disagreement of frames, not of orientations.

Usage (from the repository root)::

    python3 bench/real_trunk.py [--data ../shared/datasets/trunk] [--start-moving]
                                [--estimators ekf,ukf,kf]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from real_rig import fmt, on_optical  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab.ingest import ingest  # noqa: E402
from motionlab.kinematics.joint_angles import decompose  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse  # noqa: E402
from motionlab.rotations import angular_velocity  # noqa: E402
from motionlab.timebase import take  # noqa: E402
from motionlab.validation.joint_reference import fit_clock_offset  # noqa: E402

DEFAULT_DATA = ROOT.parent / "shared" / "datasets" / "trunk"
MAP = ROOT / "protocols" / "examples" / "trunk_map.yaml"
PROTOCOL = "lumbar_seated"
PLANES = ("flexion", "lateral_bending", "axial_rotation")
LEANS = ("forward", "sideways", "rotation")  # as the lumbar decomposition orders them
FLIP_DEG = 15.0
FLIP_RATE_DEG_S = 400.0
JUMP_DEG = 2.0  # a frame this far from its body's smooth path is a jump …
JUMP_WINDOW_S = 0.2  # … over this window (a jump lasting up to half of it is caught)
CLOCK_SEARCH_S = 3.0
#: two RMSEs closer than this (deg) are level: the bench cannot rank them
LEVEL_DEG = 0.05
#: Motive's Y-up lab frame → Z-up: +90° about x (Y → Z, Z → -Y)
Y_UP_TO_Z_UP = np.array([np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0])
#: the open estimators a user would pick instead (the issue's peers); the rest are motionlab's
PEERS = ("x-IMU3 own fusion (9-D)", "VQF offline 9-D")
VARIANTS = {
    "motionlab 6-D": {},
    "motionlab 9-D": {"magnetometer": True},
    "x-IMU3 own fusion (9-D)": {"orientation": "vendor"},
    "VQF offline 9-D": {"estimator": "vqf_offline", "magnetometer": True},
}


def read_motive(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Time (s), ``{rigid body: quaternion (N, 4) [w, x, y, z], Z-up}`` and ``{rigid body:
    position (N, 3) m, Z-up}`` from a Motive CSV export (format 1.23); NaN where empty."""
    head = pd.read_csv(path, header=None, skiprows=2, nrows=5, dtype=str, keep_default_na=False)
    kinds, names, fields, axes = (head.iloc[i].tolist() for i in (0, 1, 3, 4))
    data = pd.read_csv(path, header=None, skiprows=7, low_memory=False).to_numpy(float)
    t = data[:, 1]
    quats: dict[str, np.ndarray] = {}
    pos: dict[str, np.ndarray] = {}
    for name in dict.fromkeys(n for n, k in zip(names, kinds, strict=True) if k == "Rigid Body"):
        cols = {(f, a): j for j, (n, k, f, a) in enumerate(zip(names, kinds, fields, axes,
                strict=True)) if n == name and k == "Rigid Body"}  # fmt: skip
        q = data[:, [cols[("Rotation", a)] for a in "WXYZ"]]
        p = data[:, [cols[("Position", a)] for a in "XYZ"]]
        quats[name] = rot.mul(Y_UP_TO_Z_UP, q)
        pos[name] = rot.rotate(Y_UP_TO_Z_UP, p)
    return t, quats, pos


def good_frames(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Frames of a rigid body that are neither gaps nor flips (see the module notes)."""
    ok = np.isfinite(q).all(axis=1) & (np.linalg.norm(q, axis=1) > 0.5)
    good = np.zeros(len(t), bool)
    last = None
    for i in np.flatnonzero(ok):
        if last is not None:
            d = float(np.degrees(rot.angle_between(q[i], q[last])))
            if d > FLIP_DEG + FLIP_RATE_DEG_S * (t[i] - t[last]):
                continue
        good[i] = True
        last = i
    if good.sum() < 0.5 * ok.sum():  # started on a flipped stretch: track from the other end
        return good_frames(t[::-1], q[::-1])[::-1]
    return good


def jumps(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Frames (bool) of a rigid body's orientation ``q`` (N, 4; NaN in gaps) more than
    :data:`JUMP_DEG` from the body's smooth path: a marker solution held for a few frames,
    which a trunk or a wheelchair cannot follow. The path is a local quadratic over
    :data:`JUMP_WINDOW_S` (Savitzky–Golay, on the sign-continuous quaternions of the finite
    frames, normalised) through the frames not flagged: flagged frames are bridged linearly
    and the path refitted until the flags settle (a jump first pulls the path towards it and
    flags its neighbours too). A smooth movement stays within 0.7° of it
    (200°/s turning with a ±40° swing at 1 Hz: ``tests/test_trunk_seated.py``), where the
    running median's curvature left 2.1°."""
    from scipy.signal import savgol_filter

    ok = np.isfinite(q).all(axis=1)
    out = np.zeros(len(t), bool)
    fs = 1.0 / float(np.median(np.diff(t)))
    size = 2 * int(round(0.5 * JUMP_WINDOW_S * fs)) + 1
    if ok.sum() <= size:
        return out
    qc = rot.make_continuous(q[ok])
    idx = np.arange(len(qc))
    flagged = np.zeros(len(qc), bool)
    for _ in range(10):
        x = qc.copy()
        if flagged.any():
            for k in range(4):
                x[flagged, k] = np.interp(idx[flagged], idx[~flagged], qc[~flagged, k])
        path = savgol_filter(x, size, 2, axis=0)
        path /= np.linalg.norm(path, axis=1, keepdims=True)
        new = np.degrees(rot.angle(rot.mul(rot.conj(path), qc))) > JUMP_DEG
        if np.array_equal(new, flagged):
            break
        flagged = new
    out[ok] = flagged
    return out


def speed(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angular speed (rad/s) of an orientation series at ``t`` (NaN where ``q`` is)."""
    ok = np.isfinite(q).all(axis=1)
    out = np.full(len(t), np.nan)
    if ok.sum() > 3:
        tm, w = angular_velocity(t[ok], rot.make_continuous(q[ok]))
        out[ok] = np.interp(t[ok], tm, np.linalg.norm(w, axis=1))
    return out


def rest_angle(angles_deg: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """The joint's rotation angle (deg) away from its mean over ``rest`` (bool), from lumbar
    angles (flexion, lateral bending, axial rotation, deg): frame-independent. NaN throughout
    when no finite sample lies in ``rest`` (the mean of no orientation is none, not a turn of
    180°)."""
    from motionlab.kinematics.joint_angles import compose

    ok = np.isfinite(angles_deg).all(axis=1)
    if not (rest & ok).any():
        return np.full(len(ok), np.nan)
    q = np.full((len(ok), 4), np.nan)
    q[ok] = compose(np.radians(angles_deg[ok]), "lumbar")
    q0 = rot.mean(rot.make_continuous(q[rest & ok]))
    out = np.full(len(q), np.nan)
    out[ok] = np.degrees(rot.angle(rot.mul(rot.conj(np.broadcast_to(q0, q[ok].shape)), q[ok])))
    return out


def metrics(est: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """RMSE, offset-free RMSE and r (deg; no flipping) on the samples where both are finite."""
    ok = np.isfinite(est) & np.isfinite(ref)
    if ok.sum() < 10:
        return {"rmse": np.nan, "free": np.nan, "r": np.nan}
    d = est[ok] - ref[ok]
    r = float(np.corrcoef(est[ok], ref[ok])[0, 1]) if np.std(est[ok]) > 0 else np.nan
    return {
        "rmse": float(np.sqrt(np.mean(d**2))),
        "free": float(np.sqrt(np.mean((d - d.mean()) ** 2))),
        "r": r,
    }


def split_turn(est: np.ndarray, ref: np.ndarray) -> float:
    """The turn (deg) about the vertical that best carries the estimate's first two angles
    (flexion, lateral bending; forward, sideways lean) onto the reference's, offset-free: how
    far apart the two frames' horizontal axes lie (the product's flexion axis against the
    optical arm line). NaN with fewer than 10 common samples."""
    from scipy.optimize import minimize_scalar

    ok = np.isfinite(est[:, :2]).all(axis=1) & np.isfinite(ref[:, :2]).all(axis=1)
    if ok.sum() < 10:
        return float("nan")
    e, r = est[ok, :2], ref[ok, :2]

    def cost(theta: float) -> float:
        c, s = np.cos(theta), np.sin(theta)
        d = np.column_stack([c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1]]) - r
        return float(np.sum((d - d.mean(axis=0)) ** 2))

    return float(np.degrees(minimize_scalar(cost, bounds=(-np.pi / 2, np.pi / 2),
                                            method="bounded").x))  # fmt: skip


def run_variant(
    imu: Path, variant: dict, start_s: float | None = None
) -> tuple[np.ndarray, pd.DataFrame, dict, tuple, dict]:
    """In-memory ``motionlab run``: time (s), the lumbar angle columns, grades by column, the
    rest (s) and the trunk calibration's summary; with ``start_s`` on the recording cut to
    start there (session time, s)."""
    session = ingest([imu], MAP)
    if start_s is not None:
        for label, stream in session.sensors.items():
            session.sensors[label] = take(stream, np.flatnonzero(stream.time >= start_s))
    analyse(session, PipelineOptions(protocol=PROTOCOL, progress=False, **variant))
    table = session.results.angles
    cols = {c: np.asarray(v, float) for c, v in table.columns().items()}
    cal = session.results.calibration
    grades = {}
    from motionlab.kinematics.joint_types import angle_columns
    from motionlab.protocol import load_protocol

    joints = load_protocol(PROTOCOL).joints
    for joint, g in cal.grades.items():
        if joint in joints:
            cols_j = [c for _, c in angle_columns(joints[joint])]
            grades.update(zip(cols_j, g.grades, strict=True))
    return cols["time_s"], cols, grades, tuple(cal.steps["rest"]), cal.grades["lumbar"].trunk


def imu_speeds(imu: Path) -> tuple[np.ndarray, np.ndarray]:
    """Session time (s) and the angular speeds (rad/s) of Back, Chest and Chair."""
    session = ingest([imu], MAP)
    by_seg = {s.segment: s for s in session.sensors.values()}
    t = by_seg["thorax"].time
    cols = [np.interp(t, by_seg[s].time, np.linalg.norm(by_seg[s].gyr, axis=1))
            for s in ("thorax", "pelvis", "chair")]  # fmt: skip
    return t, np.column_stack(cols)


def arm_line(pos, rest_opt: np.ndarray) -> np.ndarray | None:
    """The subject's right (lab, horizontal unit vector): from the left to the right upper
    arm's rigid body over the rest; ``None`` when the right arm is not tracked then."""
    arms = rest_opt & np.isfinite(pos["r_arm"]).all(axis=1) & np.isfinite(pos["l_arm"]).all(axis=1)
    if arms.sum() < max(10, 0.5 * rest_opt.sum()):
        return None
    right = np.mean(pos["r_arm"][arms] - pos["l_arm"][arms], axis=0)
    return np.array([right[0], right[1], 0.0]) / np.hypot(right[0], right[1])


def in_chair(quats, rest_opt: np.ndarray, v: np.ndarray, to_chair: bool) -> np.ndarray:
    """``v`` carried from the lab into the wheelchair body's frame (``to_chair``) or back, with
    the wheelchair's mean orientation over the rest."""
    q = quats["rolstoel"][rest_opt]
    q0 = rot.mean(rot.make_continuous(q[np.isfinite(q).all(axis=1)]))
    return rot.rotate(rot.conj(q0) if to_chair else q0, v)


def lateral_axis(quats, pos, rest_opt: np.ndarray, chair_right: np.ndarray | None):
    """The subject's right (lab, horizontal unit vector) and how it was found: the arm line
    (:func:`arm_line`), else the wheelchair's right as the arm lines of the other trials saw
    it (``chair_right``, in the wheelchair body's frame: everyone sits facing forward)."""
    z = arm_line(pos, rest_opt)
    if z is not None:
        return z, "arm line"
    if chair_right is None:
        raise ValueError("no trial tracks both arms: no anatomical frame")
    z = in_chair(quats, rest_opt, chair_right, to_chair=False)
    return np.array([z[0], z[1], 0.0]) / np.hypot(z[0], z[1]), "wheelchair's right"


def optical_angles(t_opt, quats, pos, rest_opt: np.ndarray, chair_right=None, proximal="low_back"):
    """Lumbar-style angles (deg: flexion, lateral bending, axial rotation) of ``back`` relative
    to ``proximal`` (``low_back``; ``rolstoel``, the wheelchair, for the trunk's lean) in the
    anatomical frame of :func:`lateral_axis` (zero at the rest), and how the frame was found."""
    q_b, q_l = quats["back"], quats[proximal]
    z, how = lateral_axis(quats, pos, rest_opt, chair_right)
    y = np.array([0.0, 0.0, 1.0])
    frame = rot.from_matrix(np.column_stack([np.cross(y, z), y, z]))  # anatomical → lab
    segs = []
    for q in (q_l, q_b):
        ok = rest_opt & np.isfinite(q).all(axis=1)
        m = rot.mul(rot.conj(rot.mean(rot.make_continuous(q[ok]))), frame)  # anat → body
        segs.append(rot.mul(q, np.broadcast_to(m, q.shape)))
    return np.degrees(decompose(segs[0], segs[1], "lumbar")), how


def common_rest(t_imu, sp_imu, t_opt_on_imu, quats, rest_s, span) -> tuple[float, float]:
    """The reference rest (IMU clock, s) of the comparison: the product's rest when the optical
    bodies cover it, else the stillest second (:func:`motionlab.segments.trunk_axes.find_rest`)
    of the IMUs where they do (the optical recording stops before the product's rest) and the
    product's recording does (``span``: its first and last sample, s; a cut recording has no
    angles before its cut, and a rest there compared the product's mean over no sample)."""
    from motionlab.segments.trunk_axes import find_rest

    seen = np.isfinite(quats["back"]).all(axis=1) & np.isfinite(quats["low_back"]).all(axis=1)
    t_seen = t_opt_on_imu[seen]
    inside = (t_seen >= rest_s[0]) & (t_seen <= rest_s[1])
    if inside.sum() >= 0.8 * (rest_s[1] - rest_s[0]) * 120:
        return rest_s
    cover = (t_imu >= max(t_seen[0], span[0]) + 0.2) & (t_imu <= min(t_seen[-1], span[1]) - 0.2)
    a, b, _ = find_rest(t_imu[cover], sp_imu[cover][:, :2].mean(axis=1) * 180 / np.pi)
    return float(t_imu[cover][a]), float(t_imu[cover][b - 1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the trunk data set")
    ap.add_argument(
        "--start-moving",
        action="store_true",
        help="cut a trial whose rest starts the recording to 0.5 s after that rest (a recording "
        "that starts in movement, its rest elsewhere or none)",
    )
    ap.add_argument(
        "--estimators",
        default="",
        help="comma-separated other estimators to add as 6-D rows (e.g. ekf,ukf,kf; "
        "'motionlab fuse --list')",
    )
    args = ap.parse_args(argv)
    for name in filter(None, args.estimators.split(",")):
        VARIANTS[f"{name} 6-D"] = {"estimator": name}
    trials = sorted(p.parent for p in args.data.glob("*/*/optitrack.csv"))
    if not trials:
        print(f"error: no trials in {args.data} (<subject>/<task>/optitrack.csv); give --data",
              file=sys.stderr)  # fmt: skip
        return 2
    try:
        import vqf  # noqa: F401
    except ImportError:
        VARIANTS.pop("VQF offline 9-D")
        print("(vqf is not installed: no VQF rows)\n")
    rows, notes = measure(trials, VARIANTS, args.start_moving)
    print_tables(rows, notes)
    return 0


def measure(
    trials: list[Path], variants: dict[str, dict], start_moving: bool = False
) -> tuple[list[dict], list[str]]:
    """Per trial folder (``<subject>/<task>``, holding ``imu/`` and ``optitrack.csv``), variant
    (``{label: PipelineOptions keywords}``, ``motionlab 6-D`` among them: its rest and clock
    offset are the comparison's) and angle: a row ``{trial, variant, angle, grade, rmse, free,
    r}`` (deg), and the notes on clocks, rests and frames; ``start_moving``: as
    ``--start-moving``."""
    rows: list[dict] = []
    notes = []
    seen = []  # the arm lines in the wheelchair's frame (the first second as rest)
    for trial in trials:
        t_opt, quats, pos = read_motive(trial / "optitrack.csv")
        z = arm_line(pos, t_opt < 1.0)
        if z is not None:
            seen.append(in_chair(quats, t_opt < 1.0, z, to_chair=True))
    chair_right = np.mean(seen, axis=0) if seen else None
    for trial in trials:
        name = f"{trial.parent.name}/{trial.name}"
        t_opt, quats, pos = read_motive(trial / "optitrack.csv")
        flips, jumped = {}, {}
        for body in ("back", "low_back", "rolstoel"):  # flips, jumps and gaps left out, once
            good = good_frames(t_opt, quats[body])
            flips[body] = int((np.isfinite(quats[body]).all(axis=1) & ~good).sum())
            quats[body] = np.where(good[:, None], quats[body], np.nan)
            jump = jumps(t_opt, quats[body])
            jumped[body] = int(jump.sum())
            quats[body] = np.where(jump[:, None], np.nan, quats[body])
        t_imu, sp_imu = imu_speeds(trial / "imu")
        sp_opt = np.column_stack([speed(t_opt, quats[b]) for b in ("back", "low_back", "rolstoel")])
        coarse, r_clock = fit_clock_offset(t_imu, sp_imu, t_opt, sp_opt, CLOCK_SEARCH_S, 0.005)
        runs, start_s = {}, None
        if start_moving:
            rest = run_variant(trial / "imu", variants["motionlab 6-D"])[3]
            if rest[0] - t_imu[0] < 0.5:
                start_s = rest[1] + 0.5
                notes.append(f"- {name}: cut to start at {start_s:.1f} s (its rest {rest[0]:.1f}–"
                             f"{rest[1]:.1f} s started the recording)")  # fmt: skip
        for label, variant in variants.items():
            try:
                runs[label] = run_variant(trial / "imu", variant, start_s)
            except Exception as exc:  # a failing variant is a row, the bench goes on
                notes.append(f"- {name}, {label}: failed: {str(exc)[:150]}")
        if "motionlab 6-D" not in runs:
            continue
        t, cols, grades, rest_s, summary = runs["motionlab 6-D"]
        rest_s = common_rest(t_imu, sp_imu, t_opt - coarse, quats, rest_s, (t[0], t[-1]))
        # refine the offset on the rotation from rest (frame-free on both sides)
        best, best_cost, best_ref, best_how = coarse, np.inf, None, ""
        for lag in np.arange(coarse - 0.1, coarse + 0.1001, 0.002):
            rest_opt = (t_opt - lag >= rest_s[0]) & (t_opt - lag <= rest_s[1])
            if rest_opt.sum() < 10:
                continue
            ref, how = optical_angles(t_opt, quats, pos, rest_opt, chair_right)
            ref_rest = rest_angle(ref, rest_opt)
            est = rest_angle(np.column_stack([cols[f"lumbar_{p}_deg"] for p in PLANES]),
                             (t >= rest_s[0]) & (t <= rest_s[1]))  # fmt: skip
            m = metrics(on_optical(t, est, t_opt, lag), ref_rest)
            if m["free"] < best_cost:
                best, best_cost, best_ref, best_how = float(lag), m["free"], ref, how
        own = runs["motionlab 6-D"][3]
        notes.append(
            f"- {name}: optical = IMU + {best:.3f} s (speeds {coarse:.3f} s, r = {r_clock:.2f}); "
            f"rest {own[0]:.1f}–{own[1]:.1f} s (compared from {rest_s[0]:.1f}–{rest_s[1]:.1f} s); "
            f"flexion axis: one-sided "
            f"{summary.sign_ratio:.1f}× ({summary.axis_ratio:.1f}× the other axis), "
            f"thorax {summary.excursion_deg[0]:.0f}/{summary.excursion_deg[1]:.0f}°; "
            f"heading agreement {summary.heading_rho:.2f}; optical frame: {best_how}; "
            f"flipped frames left out: {', '.join(f'{k} {v}' for k, v in flips.items())}; "
            f"jumps: {', '.join(f'{k} {v}' for k, v in jumped.items())}"
        )
        rest_opt = (t_opt - best >= rest_s[0]) & (t_opt - best <= rest_s[1])
        ref_rest = rest_angle(best_ref, rest_opt)
        for label, (tv, cv, gv, _, _) in runs.items():
            angles = np.column_stack([cv[f"lumbar_{p}_deg"] for p in PLANES])
            for k, plane in enumerate(PLANES):
                m = metrics(on_optical(tv, angles[:, k], t_opt, best), best_ref[:, k])
                rows.append({"trial": name, "variant": label, "angle": plane,
                             "grade": gv.get(f"lumbar_{plane}_deg", "n/a"), **m})  # fmt: skip
            est = rest_angle(angles, (tv >= rest_s[0]) & (tv <= rest_s[1]))
            m = metrics(on_optical(tv, est, t_opt, best), ref_rest)
            rows.append({"trial": name, "variant": label, "angle": "rotation from rest",
                         "grade": "", **m})  # fmt: skip
            on_opt = np.column_stack([on_optical(tv, a, t_opt, best) for a in angles.T])
            turns = [f"lumbar {split_turn(on_opt, best_ref):+.0f}°"]
            if "trunk_lean_forward_deg" in cv:  # the trunk against the wheelchair
                lean, _ = optical_angles(t_opt, quats, pos, rest_opt, chair_right, "rolstoel")
                leans = np.column_stack([cv[f"trunk_lean_{w}_deg"] for w in LEANS])
                for k, what in enumerate(LEANS):
                    col = f"trunk_lean_{what}_deg"
                    m = metrics(on_optical(tv, leans[:, k], t_opt, best), lean[:, k])
                    rows.append({"trial": name, "variant": label, "angle": f"lean {what}",
                                 "grade": gv.get(col, "n/a"), **m})  # fmt: skip
                est = rest_angle(leans, (tv >= rest_s[0]) & (tv <= rest_s[1]))
                m = metrics(on_optical(tv, est, t_opt, best), rest_angle(lean, rest_opt))
                rows.append({"trial": name, "variant": label, "angle": "lean from rest",
                             "grade": "", **m})  # fmt: skip
                lean_opt = np.column_stack([on_optical(tv, a, t_opt, best) for a in leans.T])
                turns.append(f"lean {split_turn(lean_opt, lean):+.0f}°")
            if label == "motionlab 6-D":
                notes.append(
                    f"- {name}: the optical frame's lateral axis lies from the "
                    f"product's flexion axis by {', '.join(turns)} (split turn)"
                )
    return rows, notes


def print_tables(rows: list[dict], notes: list[str]) -> None:
    """The bench's tables: every row, the medians per variant, the rotation from rest against
    the peers and the worst angle graded determined."""
    df = pd.DataFrame(rows)
    print("## Lumbar angles of real seated trunk movements against OptiTrack\n")
    print("Clock offsets and what the calibration found:\n")
    print("\n".join(notes) + "\n")
    print("| trial | variant | angle | RMSE (deg) | offset-free RMSE | r | grade |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['trial']} | {r['variant']} | {r['angle']} | {fmt(r['rmse'])} | "
              f"{fmt(r['free'])} | {fmt(r['r'], 2)} | {r['grade']} |")  # fmt: skip
    print("\n### Medians over the trials (offset-free RMSE deg / r)\n")
    angles = [*PLANES, "rotation from rest", *(f"lean {w}" for w in LEANS), "lean from rest"]
    print("| variant | " + " | ".join(angles) + " |")
    print("|---|" + "---|" * len(angles))
    for label in dict.fromkeys(r["variant"] for r in rows):
        cells = []
        for a in angles:
            sel = df[(df.variant == label) & (df.angle == a)] if len(df) else df
            sel = sel[np.isfinite(sel.free)] if len(sel) else sel
            cells.append(f"{fmt(sel.free.median())} / {fmt(sel.r.median(), 2)}" if len(sel)
                         else "–")  # fmt: skip
        print(f"| {label} | " + " | ".join(cells) + " |")
    if len(df):  # the frame-free figure the issue compares with the peers, to the hundredth
        rest = df[(df.angle == "rotation from rest") & np.isfinite(df.free)]
        med = rest.groupby("variant").free.median()
        ours = med.get("motionlab 6-D", np.nan)
        peers = med[[k for k in med.index if k in PEERS]]
        ahead = bool(len(peers)) and bool((peers - ours >= LEVEL_DEG).all())
        print("\nRotation from rest, median offset-free RMSE (deg): "
              + ", ".join(f"{k} {v:.2f}" for k, v in med.items())
              + f" — motionlab 6-D ahead of every peer (by {LEVEL_DEG:g}° or more): "
              + ("yes" if ahead else "no"))  # fmt: skip
        by_trial = rest.pivot_table(index="trial", columns="variant", values="free")
        for peer in peers.index:
            d = by_trial[peer] - by_trial["motionlab 6-D"]
            print(f"  against {peer}: median {peers[peer] - ours:+.2f}, mean "
                  f"{by_trial[peer].mean() - by_trial['motionlab 6-D'].mean():+.2f}; per trial "
                  f"ahead on {(d >= LEVEL_DEG).sum()}, level on {(d.abs() < LEVEL_DEG).sum()}, "
                  f"behind on {(d <= -LEVEL_DEG).sum()} of {d.notna().sum()}")  # fmt: skip
    det = df[(df.variant == "motionlab 6-D") & (df.grade == "determined")
             & (df.angle != "rotation from rest")] if len(df) else df  # fmt: skip
    if len(det):
        worst = det.loc[det.free.idxmax()]
        print(f"\nGraded determined: {len(det)} angles, offset-free RMSE up to "
              f"{worst.free:.1f}° ({worst.trial}, {worst.angle}).")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
