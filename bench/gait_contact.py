"""The shank and thigh around initial and final contact: the simulator against a real walk.

    python3 bench/gait_contact.py [--data DIR] [--variants normal asymmetric slow]

Physical evidence for the simulated gait kinematics, independent of the event detector: the
sagittal angular velocity ``ω`` (rad/s, + = lower end forward) of the shank and the thigh around
each kinematic (Zeni et al. 2008) initial contact (IC) and final contact (FC):

- ``zc IC ms``: the shank's downward zero crossing (end of its forward swing) minus IC;
- ``decel``: the shank's deceleration through that zero, ``−dω/dt`` at the crossing (rad/s²),
  and ``decel T²`` that times the squared median stride time (rad: the same motion at another
  cadence scales ``decel`` by the squared stride frequency);
- ``peak decel``: the largest ``−dω/dt`` from 150 ms before to 50 ms after IC, and ``at ms``
  where it lies relative to IC;
- ``swing peak``: the largest shank ``ω`` (rad/s) before IC, and ``at ms`` relative to IC;
- ``thigh zc ms``: the thigh's downward zero crossing (its forward swing ends) minus IC; on the
  real walk from the thigh cluster, which sits on soft tissue: it turns backward ≈110 ms before
  IC while the joint centres say the knee still moves forward relative to the hip at IC, so
  only indicative;
- ``min FC ms``: the shank's minimum (fastest backward rotation) minus FC, ``up FC ms`` its next
  upward zero crossing minus FC, ``rise``: ``dω/dt`` there (rad/s²).

Also the sagittal hip and knee flexion (deg) at instants of the stride around contact: on the
real walk from the joint centres (``HJC``, ``KJC``, ``AJC``; thigh and shank angles from the
vertical in the walking plane, the pelvis's from ASIS/PSIS; hip = thigh + anterior pelvic tilt,
knee = thigh − shank; so the hip is relative to the pelvis's marker tilt, about 19° here, and
only its changes compare), per steady stride from Zeni IC to IC; simulated: the templates
(:mod:`motionlab.simulate.motion`).

Every quantity on ``ω`` low-passed at 15 Hz (2nd-order Butterworth, zero phase: the markers'
noise allows no more) and, for the zero crossings, at the detector's 6 Hz too (``@6Hz``).
Real: Vicon ``walking2`` (``bench/gait_real.py``: tibia and thigh marker clusters as virtual
gyroscopes at 250 Hz, Zeni on the heel / MT2 markers and the mid-PSIS; the events of the stop,
the stride starting after 2.5 s, are left out: its IC comes 24 ms after the shank's last swing
peak). Simulated: the walk protocol's gait task with the named variant, the segments' exact body
angular velocity (:func:`motionlab.simulate.chain.derivatives`) sampled at 250 Hz like the real
walk, Zeni on the simulated feet (:mod:`motionlab.simulate.gait_truth`), steady strides.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np
from scipy.signal import find_peaks

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from motionlab.kinematics import gait_events as ge  # noqa: E402
from motionlab.protocol import load_protocol  # noqa: E402
from motionlab.simulate import GAIT_VARIANTS, _with_gait  # noqa: E402
from motionlab.simulate.body import Body  # noqa: E402
from motionlab.simulate.chain import derivatives, segment_poses  # noqa: E402
from motionlab.simulate.gait_truth import gait_truth  # noqa: E402
from motionlab.simulate.timeline import plan  # noqa: E402

RATE = 250.0  # Hz, as the real walk's markers
STOP_S = 2.5  # real walk: the stride starting after this is the stop (bench/gait_real.py)
FILTER_HZ = 15.0
COLUMNS = (
    "zc IC ms", "zc@6Hz IC ms", "decel", "decel T²", "peak decel", "at ms", "swing peak",
    "swing at ms", "thigh zc ms", "min FC ms", "up FC ms", "up@6Hz FC ms", "rise",
)  # fmt: skip


def _cross(t: np.ndarray, w: np.ndarray, lo: float, hi: float, down: bool) -> float:
    """First zero crossing (s) of ``w`` in ``[lo, hi]``, downward or upward; NaN if none."""
    m = np.flatnonzero((t >= lo) & (t <= hi))
    if len(m) < 2:
        return np.nan
    a, b = w[m[:-1]], w[m[1:]]
    k = np.flatnonzero((a >= 0) & (b < 0) if down else (a < 0) & (b >= 0))
    if not len(k):
        return np.nan
    i = m[k[0]]
    return float(t[i] + w[i] / (w[i] - w[i + 1]) * (t[i + 1] - t[i]))


def contact_features(
    t: np.ndarray, shank: np.ndarray, thigh: np.ndarray, ic: np.ndarray, fc: np.ndarray
) -> list[dict[str, float]]:
    """One row of :data:`COLUMNS` per event (module docstring), from the shank and thigh
    sagittal ``ω`` (rad/s) on the regular time base ``t`` (s) and the events (s): IC rows
    (``event`` 0) fill the IC columns, FC rows (``event`` 1) the FC columns, the rest NaN."""
    rate = 1.0 / float(np.median(np.diff(t)))
    w = ge.lowpass(shank, rate, FILTER_HZ)
    w6 = ge.lowpass(shank, rate)
    th = ge.lowpass(thigh, rate, FILTER_HZ)
    dw = np.gradient(w, t)
    stride = float(np.median(np.diff(ic))) if len(ic) > 1 else np.nan
    rows = []
    for x in ic:
        if x - 0.4 < t[0] or x + 0.2 > t[-1]:
            continue
        r = dict.fromkeys(COLUMNS, np.nan) | {"event": 0.0, "time": float(x)}
        zc = _cross(t, w, x - 0.15, x + 0.15, True)
        r["zc IC ms"] = 1e3 * (zc - x)
        r["zc@6Hz IC ms"] = 1e3 * (_cross(t, w6, x - 0.15, x + 0.15, True) - x)
        r["decel"] = float(-np.interp(zc, t, dw))
        r["decel T²"] = r["decel"] * stride**2
        m = (t >= x - 0.15) & (t <= x + 0.05)
        k = np.argmax(-dw[m])
        r["peak decel"], r["at ms"] = float(-dw[m][k]), 1e3 * (t[m][k] - x)
        m = (t >= x - 0.4) & (t <= x)
        k = np.argmax(w[m])
        r["swing peak"], r["swing at ms"] = float(w[m][k]), 1e3 * (t[m][k] - x)
        r["thigh zc ms"] = 1e3 * (_cross(t, th, x - 0.3, x + 0.15, True) - x)
        rows.append(r)
    for f in fc:
        if f - 0.2 < t[0] or f + 0.3 > t[-1]:
            continue
        r = dict.fromkeys(COLUMNS, np.nan) | {"event": 1.0, "time": float(f)}
        m = (t >= f - 0.2) & (t <= f + 0.1)
        k = np.argmin(w[m])
        r["min FC ms"] = 1e3 * (t[m][k] - f)
        up = _cross(t, w, t[m][k], f + 0.3, False)
        r["up FC ms"] = 1e3 * (up - f)
        r["up@6Hz FC ms"] = 1e3 * (_cross(t, w6, f - 0.1, f + 0.3, False) - f)
        r["rise"] = float(np.interp(up, t, dw))
        rows.append(r)
    return rows


def simulated(variant: str = "normal", duration: float = 30.0, seed: int = 0) -> list[dict]:
    """:func:`contact_features` of both legs on the steady part of a simulated walk."""
    proto = _with_gait(load_protocol("walk"), GAIT_VARIANTS[variant])
    body = Body(1.75)
    timeline = plan(proto, body, duration, seed, calibration=False)
    walk = next(s for s in timeline.steps() if s["phase"] == "task")
    t = np.arange(walk["start_s"] + 2.5, walk["end_s"] - 2.5, 1.0 / RATE)
    g = gait_truth(body, timeline, t)
    rows = []
    for side in "rl":
        w = {}
        for seg in (f"shank_{side}", f"thigh_{side}"):
            poses = lambda tt, s=seg: segment_poses(body, timeline.channels(tt), [s])[s]  # noqa: E731
            w[seg] = derivatives(poses, t)[2][:, 2]
        ic, fc = (g[f"{e}_{side}"][g[f"{e}_{side}_steady"]] for e in ("ic", "fc"))
        for r in contact_features(t, w[f"shank_{side}"], w[f"thigh_{side}"], ic, fc):
            rows.append({"side": side, **r})
    return rows


def _gait_real():
    """``bench/gait_real.py`` as a module (its C3D reader and virtual sensors)."""
    here = Path(__file__).parent
    spec = importlib.util.spec_from_file_location("gait_real", here / "gait_real.py")
    gr = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gr)
    return gr


def real(data: Path) -> list[dict]:
    """:func:`contact_features` of both legs of Vicon ``walking2`` (steady strides)."""
    gr = _gait_real()
    _, t, rate, marker, sacrum, fwd = gr.walk_markers(data / gr.FILE)
    left = np.cross([0.0, 0.0, 1.0], fwd)
    rows = []
    for side, pre in (("r", "R"), ("l", "L")):
        w = {}
        for seg in ("TB", "TH"):
            cl = np.stack([marker(f"{pre}{seg}{i}") for i in (1, 2, 3)], axis=1)
            w[seg] = gr.sagittal_rate(cl, rate, left)
        ok = np.isfinite(w["TB"]) & np.isfinite(w["TH"])
        good = np.flatnonzero(ok)
        sl = slice(good[0], good[-1] + 1)
        tt = t[sl]
        shank, thigh = (np.interp(tt, t[ok], w[k][ok]) for k in ("TB", "TH"))
        ev = {}
        for name, x in (("fc", -((marker(f"{pre}MT2") - sacrum) @ fwd)),
                        ("ic", (marker(f"{pre}CAL") - sacrum) @ fwd)):  # fmt: skip
            k, _ = find_peaks(np.where(np.isfinite(x), x, -9.0), prominence=0.1)
            ev[name] = t[k]
        for r in contact_features(tt, shank, thigh, ev["ic"], ev["fc"]):
            before = ev["ic"][ev["ic"] < r["time"] - 0.05]
            if (before[-1] if len(before) else r["time"]) < STOP_S:
                rows.append({"side": side, **r})
    return rows


PERCENT = np.array([0, 4, 8, 12, 70, 80, 86, 90, 94, 96, 98, 100])


def real_angles(data: Path) -> list[tuple[str, float, np.ndarray, np.ndarray]]:
    """``(side, IC s, hip (deg), knee (deg))`` at :data:`PERCENT` of each steady real stride."""
    gr = _gait_real()
    _, t, _, marker, sacrum, fwd = gr.walk_markers(data / gr.FILE)
    up = np.array([0.0, 0.0, 1.0])

    def angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # a → b forward of straight down
        d = b - a
        return np.degrees(np.arctan2(d @ fwd, -(d @ up)))

    asis = (marker("RASI") + marker("LASI")) / 2
    tilt = np.degrees(np.arctan2(-((asis - sacrum) @ up), (asis - sacrum) @ fwd))
    out = []
    for side, pre in (("r", "R"), ("l", "L")):
        thigh = angle(marker(pre + "HJC"), marker(pre + "KJC"))
        shank = angle(marker(pre + "KJC"), marker(pre + "AJC"))
        heel = (marker(f"{pre}CAL") - sacrum) @ fwd
        k, _ = find_peaks(np.where(np.isfinite(heel), heel, -9.0), prominence=0.1)
        ic = t[k]
        for a, b in zip(ic[:-1], ic[1:], strict=True):
            if a >= STOP_S:
                continue
            tt = a + PERCENT / 100 * (b - a)
            vals = []
            for x in (thigh + tilt, thigh - shank):
                ok = np.isfinite(x)
                vals.append(np.where(tt <= t[ok][-1], np.interp(tt, t[ok], x[ok]), np.nan))
            out.append((side, float(a), *vals))
    return out


def _print_angles(rows) -> None:
    from motionlab.simulate import motion

    print("## sagittal hip and knee flexion (deg) at % of the stride")
    print(f"{'':<22}" + "".join(f"{p:6.0f}" for p in PERCENT))
    for side, a, hip, knee in rows:
        for name, x in (("hip", hip), ("knee", knee)):
            print(f"real {side} {a:.3f} s {name:<5}" + "".join(f"{y:6.1f}" for y in x))
    basis = motion.gait_basis(2 * np.pi * PERCENT / 100)
    for name in ("hip", "knee"):
        x = np.degrees(motion.gait_curve(name, basis))
        print(f"{'simulated ' + name:<22}" + "".join(f"{y:6.1f}" for y in x))
    print()


def _print(title: str, rows: list[dict]) -> None:
    print(f"## {title} (n = {len(rows)})")
    print("    " + " ".join(f"{c:>12}" for c in COLUMNS))
    if len(rows) <= 12:
        for r in rows:
            cells = " ".join(f"{r[c]:12.1f}" for c in COLUMNS)
            print(f"{r['side']:<4}{cells}  at {r['time']:.3f} s")
    for name, fn in (("min", np.nanmin), ("med", np.nanmedian), ("max", np.nanmax)):
        print(f"{name:<4}" + " ".join(f"{fn([r[c] for r in rows]):12.1f}" for c in COLUMNS))
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared")
    ap.add_argument("--variants", nargs="+", default=["normal", "asymmetric", "slow"])
    args = ap.parse_args()
    if (args.data / "formats/c3d/vicon_nexus_walking2.c3d").exists():
        _print("real: Vicon walking2", real(args.data))
        _print_angles(real_angles(args.data))
    else:
        print(f"{args.data}: no walking2.c3d; the real walk is skipped\n")
    for v in args.variants:
        _print(f"simulated: {v}", simulated(v))


if __name__ == "__main__":
    main()
