"""The pelvis in gait, real against simulated, and the legs' sides it tells.

    python3 bench/gait_pelvis.py [--data ../shared] [--seeds 0-5]

For the real 16-IMU walk of ``../shared/datasets/human/qmt_full_body`` (the ``walk`` protocol's
five sensors, ``bench/real_people.py``'s session) and for ``bench/real_world.py``'s simulated
walks (74 s, random mountings, the ``skin`` preset), through the product path
(``pipeline.analyse``), averaged over the right strides the gait analysis kept (10 bins from
the right heel strike):

- the pelvis sensor's sideways acceleration (m/s², towards the pelvis's right, in the walking
  frame: the pelvis heading averaged over a stride), its vertical acceleration (gravity taken
  off) and the pelvis's obliquity (deg, the right side up, less its mean);
- the mean sideways acceleration over 10-50 % of each side's stride (its stance; the ground
  pushes the body back towards the other foot, so negative on the right, positive on the left);
- the correlation the legs' side check uses (:func:`motionlab.segments.walk_checks.
  sway_swing_correlation`), as mapped and, for the real walk, with the legs' sides swapped;
- how much each thigh and shank turns about the walking direction (frontal plane: the pelvis's
  obliquity, hip ab/adduction) beside its swing across it (RMS ratio, :func:`frontal_ratio`).

The real walk needs ``../shared`` (its licence: MIT); without it only the simulated rows print.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from real_world import DURATION_S, analyse_simulated, simulator_options  # noqa: E402
from seeds import seeds_arg  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab.binding import sensor_for_segment  # noqa: E402
from motionlab.dsp import butter, sosfiltfilt  # noqa: E402
from motionlab.kinematics.pelvis import walking_heading  # noqa: E402
from motionlab.kinematics.session_angles import session_segments  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.segments import streams_of, walk_checks  # noqa: E402
from motionlab.simulate import simulate  # noqa: E402
from motionlab.units import STANDARD_GRAVITY  # noqa: E402

BINS = 10


def profiles(session) -> dict[str, np.ndarray]:
    """Right-stride averages (``BINS`` bins) of the pelvis sensor's sideways and vertical
    acceleration (m/s²) and the pelvis obliquity (deg, less its mean); and per side the mean
    sideways acceleration over 10-50 % of that side's strides (``stance_r``, ``stance_l``)."""
    protocol = load_protocol("walk")
    cal, gait = session.results.calibration, session.results.gait
    t_p, q_p = session_segments(session, protocol, cal, segments=["pelvis"])["pelvis"]
    label = sensor_for_segment(session, "pelvis")
    s = session.sensors[label]
    acc = rot.rotate(session.results.fusion[label].quat, s.acc) - [0.0, 0.0, STANDARD_GRAVITY]
    acc = np.column_stack([np.interp(t_p, s.time, acc[:, k]) for k in range(3)])
    st = gait.strides
    stride_s = float(np.median(st.stride_time_s[st.kept]))
    h = walking_heading(q_p, 1.0 / float(np.median(np.diff(t_p))), stride_s)
    right = np.column_stack([np.sin(h), -np.cos(h), np.zeros_like(h)])
    sig = {
        "sideways": np.einsum("ij,ij->i", acc, right),
        "vertical": acc[:, 2],
        "obliquity": np.interp(t_p, gait.pelvis.time_s, gait.pelvis.pelvis_obliquity_deg),
    }
    out = {}
    grid = np.linspace(0.0, 1.0, BINS, endpoint=False)
    for side in "rl":
        sel = st.kept & (st.side == side)
        rows = {k: [] for k in sig}
        for a, d in zip(st.start_s[sel], st.stride_time_s[sel], strict=True):
            m = (t_p >= a) & (t_p < a + d)
            for k, x in sig.items():
                rows[k].append(np.interp(grid, (t_p[m] - a) / d, x[m]))
        mean = {k: np.mean(v, axis=0) for k, v in rows.items()}
        out[f"stance_{side}"] = float(mean["sideways"][1:5].mean())
        if side == "r":
            out |= mean
            out["obliquity"] = mean["obliquity"] - mean["obliquity"].mean()
    return out


def frontal_ratio(session) -> str:
    """Per thigh and shank (r, l): the RMS of the segment's angular velocity about the walking
    direction over its RMS about the horizontal across it, over the kept strides (segment
    frames of the product, the walking direction of the pelvis), low-passed at 3 Hz."""
    protocol = load_protocol("walk")
    cal, st = session.results.calibration, session.results.gait.strides
    segs = ["pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l"]
    poses = session_segments(session, protocol, cal, segments=segs)
    t_p, q_p = poses["pelvis"]
    stride_s = float(np.median(st.stride_time_s[st.kept]))
    heading = walking_heading(q_p, 1.0 / float(np.median(np.diff(t_p))), stride_s)
    out = []
    for seg in segs[1:]:
        t, q = poses[seg]
        q = rot.make_continuous(q)
        tm, w = rot.angular_velocity(t, q)
        w = rot.rotate(q[:-1], w)  # earth frame
        h = np.interp(tm, t_p, heading)
        fs = 1.0 / float(np.median(np.diff(tm)))
        sos = butter(2, 3.0, fs=fs)
        ok = np.isfinite(w).all(axis=1)
        w = sosfiltfilt(sos, np.where(ok[:, None], w, 0.0), axis=0)
        along = w[:, 0] * np.cos(h) + w[:, 1] * np.sin(h)
        across = -w[:, 0] * np.sin(h) + w[:, 1] * np.cos(h)
        inside = np.zeros(len(tm), bool)
        for a, d in zip(st.start_s[st.kept], st.stride_time_s[st.kept], strict=True):
            inside |= (tm >= a) & (tm < a + d)
        out.append(np.sqrt(np.mean(along[inside] ** 2) / np.mean(across[inside] ** 2)))
    return " / ".join(f"{v:.2f}" for v in out)


def correlation(session) -> float:
    """The legs' side check's correlation on an analysed session."""
    cal = session.results.calibration
    streams = streams_of(session, load_protocol("walk"))
    mounting = np.asarray(cal.segments["pelvis"].mounting, float)
    return walk_checks.sway_swing_correlation(session, streams, mounting, cal.steps["standing"][1])[
        0
    ]


def row(name: str, session) -> str:
    p = profiles(session)
    cells = [" ".join(f"{v:+.1f}" for v in p[k]) for k in ("sideways", "vertical", "obliquity")]
    side = f"{p['stance_r']:+.2f} / {p['stance_l']:+.2f}"
    return (f"| {name} | {cells[0]} | {cells[1]} | {cells[2]} | {side} | "
            f"{correlation(session):+.2f} | {frontal_ratio(session)} |")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared")
    ap.add_argument("--seeds", type=seeds_arg, default="0-5")
    args = ap.parse_args(argv)
    print("| walk | sideways acc. by right-stride tenth (m/s²) | vertical acc. (m/s²) | "
          "obliquity (deg) | stance r / l (m/s²) | side check | about the walking direction / "
          "across it: thighs r, l, shanks r, l |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    from real_people import qmt_session

    qmt = args.data / "datasets" / "human" / "qmt_full_body"
    if (qmt / "full_body_example_data.mat").is_file():
        session, _ = qmt_session(qmt, "walk")
        swapped = copy.deepcopy(session)
        analyse(session, PipelineOptions("walk", progress=False))
        print(row("real 16-IMU walk", session))
        for seg in ("thigh", "shank"):  # the legs' sides swapped in the map
            a, b = swapped.sensors[f"{seg}_r"], swapped.sensors[f"{seg}_l"]
            a.segment, b.segment = f"{seg}_l", f"{seg}_r"
        limit, walk_checks.SIDES_CORR = walk_checks.SIDES_CORR, -np.inf  # measured, not refused
        try:
            analyse(swapped, PipelineOptions("walk", progress=False))
        finally:
            walk_checks.SIDES_CORR = limit
        print(f"| real, legs swapped in the map | | | | | {correlation(swapped):+.2f} | |")
    else:
        print(f"(no real walk: {qmt} holds no full_body_example_data.mat)")
    protocol = load_protocol("walk")
    for seed in args.seeds:
        session, truth = simulate(protocol, DURATION_S["walk"], seed, mounting="random",
                                  **simulator_options("skin", False))  # fmt: skip
        analyse_simulated(session, truth, protocol)
        print(row(f"simulated, seed {seed}", session))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
