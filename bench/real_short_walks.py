"""Short real walks: the real full-body walk of ``../shared/datasets/human/qmt_full_body`` cut as a
clinic records it (a stand, then 10-20 s of walking with a turn or none), only the five
lower-body sensors, run as ``motionlab run --protocol walk`` runs it, and compared with the whole
recording's own result.

There is no optical reference; the whole recording (a quiet stand at 0.5-4.6 s, sitting down,
a seated rest, standing up, then 45 s of walking from 55 s with a 180° turn at 75-77 s and the
start of another at 98 s) is the best estimate there is, so each cut's differences from it
measure what a short walk costs. The whole recording is the better estimate for a reason a
short walk cannot have: its rests in two poses (standing and sitting) give each sensor's
accelerometer bias, which moves its knee_l flexion by +1.4° and its hips by up to 2°. Per cut:

- the grades of each knee and hip (flexion / ab-adduction / rotation), the whole recording's and
  the cut's;
- each knee's per-stride flexion range (median), the whole recording's over the same strides
  and the cut's;
- knee and hip flexion of the cut against the whole recording's over the walk's samples: RMSE,
  mean, and the RMSE with the cut's own stand as the zero (less the whole recording's mean
  over the cut's calibration stand: the walker stood a little differently each time, up to
  4.6° in a shank's inclination between the stands of this recording); a wrong pelvis forward
  direction shows in the hips, and column ``pelvis fwd`` gives the angle between the whole
  recording's forward direction of the pelvis (from its turns) and the cut's (its first steps);
- the cadence (steps/min, both sides) of the cut against the whole recording's over the same
  strides (the kept strides that lie within the cut's walk);
- the strides each rejects within the cut's walk, and of them as a ``turn`` (a turn's strides
  have a low swing: either may reject one as ``start/stop`` before it asks about the turn).

The cuts (times of the recording, s). The stand: the one just before the walk (52.1-54.9 s, the
walker swaying: 40-90 mrad/s RMS on the thighs), that one after the stands following the
standing up (44.7-48.6 s twice: 10.6 s, swaying), the quiet first stand twice and then the one
before the walk (11.6 s), or the recording as it is from 44.6 s (a stand, a shuffle, a stand).
The walk: from its own start at 55 s, or a later span (with a turn or none) joined to the walk's
first steps: the first 2-4 s of the walk, then the span from within ±1 s of its nominal start,
cut where the five segments' inclinations (the whole recording's fused orientations) are
closest, i.e. at the same phase of a later stride, so that the sensors see no jump their
gyroscopes did not measure (column ``jump``: the largest inclination change where the cut's
pieces join; a stand-to-walk cut mid-walk would jump 30° or more on some segment).

Usage::

    python bench/real_short_walks.py [--data ../shared] [--only A,B,...]
"""

from __future__ import annotations

import argparse
import copy
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_people import qmt_session, stride_ranges  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab.errors import InputError  # noqa: E402
from motionlab.kinematics.angle_filter import as_metrics_take  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse  # noqa: E402
from motionlab.segments.sensors import sensor_orientation  # noqa: E402
from motionlab.session import Session  # noqa: E402

STAND_PRE = [(52.1, 54.9)]  # the stand just before the walk (swaying: 40-90 mrad/s RMS)
STAND_LONG = [(44.7, 48.6), (44.7, 48.6), (52.1, 54.9)]  # the stands after standing up
STAND_QUIET = [(0.2, 4.6), (0.2, 4.6), (52.1, 54.9)]  # the quiet first stand (3-10 mrad/s)
STAND_AS_RECORDED = [(44.6, 55.0)]  # stand, shuffle, stand, as recorded
WALK_START_S = 55.0
INITIATION_S = (57.0, 59.0)  # the real walk's first steps end within this, at a junction
MATCH_S = 1.0  # the mid-walk piece starts within this of its nominal time
SEGMENTS = ("pelvis", "thigh_r", "shank_r", "thigh_l", "shank_l")


@dataclass(frozen=True)
class Cut:
    """One short walk: a name, what it is, the stand's pieces (s) and the walk's span (s): from
    the walk's own start at 55 s, or, later, after the walk's first steps."""

    name: str
    what: str
    stand: list[tuple[float, float]]
    walk: tuple[float, float]


CUTS = [
    Cut("A", "2.8-s stand, walk 55-65 (straight)", STAND_PRE, (55.0, 65.0)),
    Cut("B", "10.6-s stand, walk 55-69 (straight)", STAND_LONG, (55.0, 69.0)),
    Cut("C", "11.6-s quiet stand, walk 55-69 (straight)", STAND_QUIET, (55.0, 69.0)),
    Cut("D", "as recorded 44.6-69 (stand, shuffle, stand, walk)", STAND_AS_RECORDED, (55.0, 69.0)),
    Cut("E", "11.6-s quiet stand, walk 55-75 (straight, 20 s)", STAND_QUIET, (55.0, 75.0)),
    Cut("F", "10.6-s stand, walk 55-80 (turn at 75-77)", STAND_LONG, (55.0, 80.0)),
    Cut("G", "11.6-s quiet stand, first steps, walk 65-77 (ends in the turn)", STAND_QUIET,
        (65.0, 77.0)),
    Cut("H", "10.6-s stand, first steps, walk 70-82 (turn mid-walk)", STAND_LONG, (70.0, 82.0)),
    Cut("I", "11.6-s quiet stand, first steps, walk 70-82 (turn mid-walk)", STAND_QUIET,
        (70.0, 82.0)),
    Cut("J", "2.8-s stand, first steps, walk 72-86 (turn mid-walk)", STAND_PRE, (72.0, 86.0)),
    Cut("K", "11.6-s quiet stand, first steps, walk 80-92 (straight, way back)", STAND_QUIET,
        (80.0, 92.0)),
    Cut("L", "10.6-s stand, first steps, walk 88-100 (turn at the end)", STAND_LONG,
        (88.0, 100.0)),
]  # fmt: skip


def _run(session: Session) -> Session:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analyse(session, PipelineOptions(protocol="walk", progress=False))
    return session


def inclinations(session: Session) -> np.ndarray:
    """(N, 5, 3): the earth's up in each lower-body sensor's frame, from a fused session."""
    up = np.array([0.0, 0.0, 1.0])
    return np.stack([
        rot.rotate(rot.conj(sensor_orientation(session, seg)), np.broadcast_to(up, (n, 3)))
        for seg in SEGMENTS for n in [session.sensors[seg].n_samples]
    ], axis=1)  # fmt: skip


def _tilt(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (deg) between unit vectors along the last axis."""
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def walk_pieces(t: np.ndarray, up: np.ndarray, walk: tuple[float, float]) -> list[tuple]:
    """The walk's pieces (s): ``walk`` itself from the walk's own start; for a later span, the
    walk's first steps (55 s to within ``INITIATION_S``) and then the span from within
    ``MATCH_S`` of its start, joined where the five segments' inclinations (``up``, from the
    whole recording's fusion) are closest (least largest angle): the same phase of a later
    stride, so that the sensors see no jump the gyroscopes did not measure."""
    if walk[0] <= WALK_START_S:
        return [walk]
    i = np.flatnonzero((t >= INITIATION_S[0]) & (t <= INITIATION_S[1]))
    j = np.flatnonzero(np.abs(t - walk[0]) <= MATCH_S)
    cost = _tilt(up[i][:, None], up[j][None, :]).max(axis=2)
    a, b = np.unravel_index(np.argmin(cost), cost.shape)
    return [(WALK_START_S, float(t[i[a]])), (float(t[j[b]]), walk[1])]


def cut_session(base: Session, pieces: list[tuple[float, float]]) -> tuple[Session, np.ndarray]:
    """``base``'s sensors made of the time ``pieces`` (s) one after another on a new 100 Hz
    clock from 0 s, and the recording's time of each new sample."""
    session = copy.deepcopy(base)
    origin = None
    for st in session.sensors.values():
        parts = [(st.time >= a) & (st.time < b) for a, b in pieces]
        origin = np.concatenate([st.time[k] for k in parts])
        st.acc = np.concatenate([st.acc[k] for k in parts])
        st.gyr = np.concatenate([st.gyr[k] for k in parts])
        st.time = np.arange(len(st.acc)) / 100.0
    return session, origin


def junctions(t: np.ndarray, up: np.ndarray, pieces: list[tuple]) -> float:
    """The largest inclination jump (deg) of any segment where two pieces join."""
    out = [0.0]
    for (_, b), (c, _) in zip(pieces[:-1], pieces[1:], strict=True):
        i, j = np.searchsorted(t, b) - 1, np.searchsorted(t, c)
        out.append(float(_tilt(up[i], up[j]).max()))
    return max(out)


def _to_origin(origin: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    return x if origin is None else np.interp(x, np.arange(len(origin)) / 100.0, origin)


def _inside(pieces: list[tuple], a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each span ``a``-``b`` (recording time) lies within one of ``pieces``."""
    return np.any([(a >= p) & (b <= q) for p, q in pieces], axis=0)


def strides_within(session: Session, pieces: list[tuple], origin=None) -> tuple:
    """The session's strides lying within ``pieces`` (recording time; ``origin`` maps the
    session's time to it): their durations (s), kept flags and rejection reasons."""
    table = session.results.gait.strides
    start = np.asarray(table.start_s, float)
    dur = np.asarray(table.stride_time_s, float)
    a, b = _to_origin(origin, start), _to_origin(origin, start + dur)
    sel = _inside(pieces, a, b) & (np.abs(b - a - dur) < 0.02)
    return dur[sel], np.asarray(table.kept, bool)[sel], np.asarray(table.reason, object)[sel]


def cadence(session: Session, pieces: list[tuple], origin=None) -> tuple[float, int]:
    """Cadence (steps/min, 120 / mean stride time) of the kept strides within ``pieces``, and
    how many."""
    dur, kept, _ = strides_within(session, pieces, origin)
    return (120.0 / float(dur[kept].mean()) if kept.any() else np.nan), int(kept.sum())


def rejected(session: Session, pieces: list[tuple], origin=None) -> str:
    """The strides within ``pieces`` that the gait analysis rejected, and of them as a turn
    (``"3 (2 turn)"``): a turn stride may be rejected for its low swing (``start/stop``) first."""
    _, kept, reason = strides_within(session, pieces, origin)
    return f"{int(np.sum(~kept))} ({int(np.sum(reason == 'turn'))} turn)"


def angle_diff(full: Session, cut: Session, origin: np.ndarray, column: str, pieces) -> tuple:
    """RMSE and mean (deg) of the cut's ``column`` less the whole recording's over the walk's
    common samples (``pieces``, recording time), and the same with the cut's own zero: less the
    whole recording's mean of ``column`` over the samples of the cut's calibration stand (a
    person stands a little differently each time: that much of the difference is the stand's)."""
    ta, x = np.asarray(cut.results.angles.time), np.asarray(cut.results.angles.data[column])
    o = _to_origin(origin, ta)
    tf, xf = np.asarray(full.results.angles.time), np.asarray(full.results.angles.data[column])
    sel = _inside(pieces, o, o) & np.isfinite(x)
    d = x[sel] - np.interp(o[sel], tf, xf)
    d = d[np.isfinite(d)]
    stand = cut.results.calibration.steps.get("standing")
    if not len(d) or not stand:
        return np.nan, np.nan, np.nan
    k = (ta >= stand[0]) & (ta <= stand[1])
    d0 = d + float(np.nanmean(np.interp(o[k], tf, xf)))
    return float(np.sqrt(np.mean(d**2))), float(np.mean(d)), float(np.sqrt(np.mean(d0**2)))


def full_ranges(full: Session, side: str, pieces: list[tuple]) -> np.ndarray:
    """The whole recording's per-stride knee flexion ranges (deg) of strides within
    ``pieces``, from the angle low-passed as the metrics take it (as :func:`stride_ranges`)."""
    gait, angles = full.results.gait, full.results.angles
    t = np.asarray(angles.time)
    x = as_metrics_take(angles, f"knee_{side}_flexion_deg")
    ic = np.asarray(gait.events[side].ic, float)
    ok = [(a, b) for a, b in zip(ic[:-1], ic[1:], strict=True) if 0.6 <= b - a <= 1.8]
    return np.asarray([np.ptp(x[(t >= a) & (t <= b)]) for a, b in ok
                       if _inside(pieces, np.array(a), np.array(b))])  # fmt: skip


def forward_axis(session: Session) -> np.ndarray | None:
    """The pelvis sensor's forward direction the calibration took from the walk (sensor frame),
    ``None`` where it kept the placement hint's."""
    rec = session.results.calibration.segments["pelvis"].axes.get("movement:turns")
    return None if rec is None else np.asarray(rec.sensor_axis, float)


def _g(grades) -> str:
    return "/".join({"determined": "D", "weak": "w", "not determined": "n"}.get(g, "?")
                    for g in grades.grades)  # fmt: skip


def _n(x, d: int = 1) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{x:.{d}f}"


def _med(x: np.ndarray) -> str:
    return _n(float(np.median(x)) if len(x) else np.nan, 0)


JOINTS = ("knee_r", "knee_l", "hip_r", "hip_l")
LEGEND = (
    "grades flexion/ab-adduction/rotation (D determined, w weak, n not determined), whole "
    "recording → cut; range: median per-stride knee flexion range (deg), whole recording over "
    "the same strides → cut; Δ: the cut's flexion less the whole recording's over the walk's "
    "samples, RMSE (mean) and the RMSE with the cut's stand as the zero, deg; cadence "
    "(steps/min) over the kept strides within the cut's walk (their number); rejected: strides "
    "the gait analysis rejected within the cut's walk (of them as a turn); pelvis fwd: angle "
    "between the pelvis's forward directions from the walk, whole and cut; jump: the largest "
    "inclination jump (deg) where the cut's pieces join"
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent
                    / "shared")  # fmt: skip
    ap.add_argument("--only", default="", help="comma-separated cut names (A, B, ...)")
    args = ap.parse_args()
    folder = args.data / "datasets" / "human" / "qmt_full_body"
    if not folder.is_dir():
        raise SystemExit(f"no {folder}: give --data (the shared folder)")
    base, _ = qmt_session(folder, "walk")
    t = base.sensors["pelvis"].time
    full = _run(copy.deepcopy(base))
    up = inclinations(full)
    g = {j: _g(full.results.calibration.grades[j]) for j in JOINTS}
    only = set(filter(None, args.only.split(",")))
    print(LEGEND)
    print()
    print(
        "| cut | what | walk s | jump ° | knee r | knee l | hip r | hip l | range r | range l "
        "| Δknee r | Δknee l | Δhip r | Δhip l | pelvis fwd ° | cadence whole → cut "
        "| rejected whole → cut |"
    )
    print("|---|---|---:|---:|---|---|---|---|---|---|---|---|---|---|---:|---|---|")
    whole = [(WALK_START_S, float(t[-1]) + 0.01)]
    print(f"| whole | 2.8-s stand, walk 55-100 | 45 | 0 | {' | '.join(g.values())} | "
          f"{_med(full_ranges(full, 'r', whole))} | {_med(full_ranges(full, 'l', whole))} "
          f"| | | | | | {_n(cadence(full, whole)[0])} ({cadence(full, whole)[1]}) "
          f"| {rejected(full, whole)} |")  # fmt: skip
    for cut in CUTS:
        if only and cut.name not in only:
            continue
        walk = walk_pieces(t, up, cut.walk)
        pieces = [*cut.stand, *walk]
        session, origin = cut_session(base, pieces)
        head = (f"| {cut.name} | {cut.what} | {sum(b - a for a, b in walk):.1f} | "
                f"{junctions(t, up, pieces):.1f} |")  # fmt: skip
        try:
            _run(session)
        except InputError as exc:
            print(f"{head} refused: {exc} |||||||||||")
            continue
        cal = session.results.calibration
        cells = [f"{g[j]} → {_g(cal.grades[j])}" if j in cal.grades else "–" for j in JOINTS]
        for s in "rl":
            mine = stride_ranges(session, f"knee_{s}_flexion_deg", s)
            cells.append(f"{_med(full_ranges(full, s, walk))} → {_med(mine)}")
        for col in JOINTS:
            rmse, mean, own = angle_diff(full, session, origin, f"{col}_flexion_deg", walk)
            cells.append(f"{_n(rmse)} ({_n(mean)}) {_n(own)}")
        fa, fc = forward_axis(full), forward_axis(session)
        fwd = np.nan if fa is None or fc is None else np.degrees(np.arccos(np.clip(fa @ fc, -1, 1)))
        cells.append(_n(fwd))
        (cf, nf), (cc, nc) = cadence(full, walk), cadence(session, walk, origin)
        cells.append(f"{_n(cf)} ({nf}) → {_n(cc)} ({nc})")
        cells.append(f"{rejected(full, walk)} → {rejected(session, walk, origin)}")
        print(f"{head} {' | '.join(cells)} |")
        for line in cal.warnings:
            if line.startswith(("pelvis", "hip")):
                print(f"|  | {line} ||||||||||||||||")


if __name__ == "__main__":
    main()
