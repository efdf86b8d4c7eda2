"""The gait event detector on a real walk: Vicon ``walking2`` (OpenSim's test trial, 250 Hz
markers, two force plates at 2 kHz; ``../shared/formats/c3d/vicon_nexus_walking2.c3d``).

    python3 bench/gait_real.py [--data DIR]

No IMU was worn, so each shank's tibia marker cluster (``RTB1-3``, ``LTB1-3``) stands in for a
gyroscope: its orientation per frame (Kabsch fit to the first complete frame), the angular
velocity from ``Ṙ Rᵀ`` (central differences), its sagittal component (about the body's right,
positive when the lower end swings forward). :func:`motionlab.kinematics.gait_events.detect`
runs on it unchanged. References: the force plates (contact where the vertical force exceeds
20 N above the resting level; which foot from the heel markers) and the kinematic rule of Zeni
et al. (2008) that the simulator's truth uses (heel farthest in front of / toe ``MT2`` farthest
behind the mid-PSIS). Plate 2 is struck by the left forefoot (the heel lands before the plate's
edge), and the right heel lands 2 cm before plate 1: a plate's initial contact counts only when
the heel marker lies inside the plate's corners at mid-stance (neither does here).

Step and stride length, walking speed (:mod:`motionlab.kinematics.spatiotemporal`'s leg model):
the thigh (``RTH1-3``) and tibia clusters stand in for the thigh and shank sensors, each
segment's axes fixed in its cluster from the joint centres (``HJC``, ``KJC``, ``AJC``) and the
femoral condyles / malleoli at one reference frame (as a calibration would), its lengths the
median joint-centre distances. Reference: the heel markers' forward displacement between their
own Zeni initial contacts (a step: the landing heel minus the other heel at its contact) and the
mid-PSIS's mean forward speed over each stride. The model is evaluated at the detector's and at
the Zeni initial contacts. The 1.25 foot-roll factor of the model was taken from this walk.

It also prints where each hip's relative rotation (thigh from hip and knee joint centres and
femoral condyles, pelvis from ASIS and PSIS) has its dominant axis in the pelvis frame: a heading
tie that assumed that axis to be the pelvis's medio-lateral axis (the hip's JCS flexion axis)
would be off by that angle on this walker, whose adduction rate follows the flexion rate.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import ezc3d
import numpy as np
from scipy.signal import find_peaks

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from motionlab import rotations as rot  # noqa: E402
from motionlab.kinematics import gait_events as ge  # noqa: E402
from motionlab.kinematics import spatiotemporal as sp  # noqa: E402

FILE = "formats/c3d/vicon_nexus_walking2.c3d"
FORCE_N = 20.0


def _rotation(ref: np.ndarray, cur: np.ndarray) -> np.ndarray:
    """R with ``cur ≈ R ref`` (rows: markers), least squares (Kabsch)."""
    a, b = ref - ref.mean(0), cur - cur.mean(0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def sagittal_rate(cluster: np.ndarray, rate: float, left: np.ndarray) -> np.ndarray:
    """Sagittal angular velocity (rad/s, + = lower end forward) of a marker cluster (N, M, 3)."""
    n = len(cluster)
    ok = np.all(np.isfinite(cluster), axis=(1, 2))
    ref = cluster[np.flatnonzero(ok)[0]]
    R = np.full((n, 3, 3), np.nan)
    for k in np.flatnonzero(ok):
        R[k] = _rotation(ref, cluster[k])
    w = np.full(n, np.nan)
    for k in range(1, n - 1):
        if ok[k - 1] and ok[k + 1]:
            W = (R[k + 1] - R[k - 1]) * rate / 2 @ R[k].T
            w[k] = -np.dot([W[2, 1], W[0, 2], W[1, 0]], left)
    return w


def segment_quats(cluster: np.ndarray, ref: int, axes: np.ndarray) -> np.ndarray:
    """(N, 4) segment → lab orientations of a marker cluster (N, M, 3) whose segment axes (3×3,
    columns x, y, z in the lab) are known at frame ``ref``; NaN where a marker is missing."""
    q = np.full((len(cluster), 4), np.nan)
    for k in np.flatnonzero(np.all(np.isfinite(cluster), axis=(1, 2))):
        q[k] = rot.from_matrix(_rotation(cluster[ref], cluster[k]) @ axes)
    return q


def _frame(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(N, 3, 3) frames, columns x, y, z, from a forward-ish ``x`` and a right-ish ``z``."""
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    x = x - np.sum(x * z, axis=1, keepdims=True) * z
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def hip_axes(marker, rate: float) -> dict[str, tuple[float, float]]:
    """Per side, the dominant axis of the hip's relative angular velocity in the pelvis frame:
    its angle from the pelvis z about the vertical (deg) and the second/first singular value
    (the rates low-passed at 6 Hz like the gait events')."""
    ra, la, rp, lp = (marker(k) for k in ("RASI", "LASI", "RPSI", "LPSI"))
    pelvis = _frame((ra + la - rp - lp) / 2, ra - la)
    out = {}
    for side, pre in (("r", "R"), ("l", "L")):
        hjc, kjc, lat, med = (marker(pre + k) for k in ("HJC", "KJC", "LFC", "MFC"))
        y = hjc - kjc
        thigh = _frame(np.cross(y, lat - med if pre == "R" else med - lat), lat - med)
        rel = np.einsum("nji,njk->nik", pelvis, thigh)
        ok = np.all(np.isfinite(rel), axis=(1, 2))
        ok[1:-1] &= ok[:-2] & ok[2:]
        k = np.flatnonzero(ok[1:-1]) + 1
        W = (rel[k + 1] - rel[k - 1]) * rate / 2 @ np.transpose(rel[k], (0, 2, 1))
        w = ge.lowpass(np.column_stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]]).T, rate).T
        _, sv, vt = np.linalg.svd(w, full_matrices=False)
        a = vt[0] * np.sign(vt[0][2])
        out[side] = (float(np.degrees(np.arctan2(a[0], a[2]))), float(sv[1] / sv[0]))
    return out


def _stance(side: str, zeni: dict, ev: ge.SideEvents) -> list[tuple]:
    """``(side, IC s, Zeni stance %, detector stance %)`` of each stride with all its events."""
    rows = []
    for a, b in zip(zeni["ic"][:-1], zeni["ic"][1:], strict=True):
        fc = zeni["fc"][(zeni["fc"] > a) & (zeni["fc"] < b)]
        want = ((ev.ic, a), (ev.fc, fc[0] if len(fc) else np.nan), (ev.ic, b))
        found = [x[np.argmin(np.abs(x - y))] if len(x) else np.nan for x, y in want]
        if len(fc) == 1 and np.all(np.isfinite(found)):
            d0, d1, d2 = found
            rows.append((side, a, 100 * (fc[0] - a) / (b - a), 100 * (d1 - d0) / (d2 - d0)))
    return rows


def _lengths(marker, rate, left, fwd, sacrum, zeni_ic, det_ic) -> list[tuple]:
    """Rows ``(what, side, time s, reference, model at detected IC, model at Zeni IC)`` for
    steps, strides (m) and stride speeds (m/s); see the module docstring."""
    n = len(sacrum)
    t = np.arange(n) / rate
    jc = np.flatnonzero(np.all(np.isfinite(marker("RKJC")) & np.isfinite(marker("LKJC")), axis=1))
    reach = {}
    for side, pre in (("r", "R"), ("l", "L")):
        sign = 1.0 if side == "r" else -1.0
        quats, length = [], []
        for cl, prox, dist, lat, med in (
            ("TH", "HJC", "KJC", "LFC", "MFC"),
            ("TB", "KJC", "AJC", "LMAL", "MMAL"),
        ):
            cluster = np.stack([marker(f"{pre}{cl}{i}") for i in (1, 2, 3)], axis=1)
            ok = np.all(np.isfinite(cluster), axis=(1, 2))
            ref = jc[ok[jc]][len(jc[ok[jc]]) // 2]
            y = marker(pre + prox)[ref] - marker(pre + dist)[ref]
            z = sign * (marker(pre + lat)[ref] - marker(pre + med)[ref])
            y /= np.linalg.norm(y)
            x = np.cross(y, z)
            x /= np.linalg.norm(x)
            axes = np.column_stack([x, y, np.cross(x, y)])
            quats.append(segment_quats(cluster, ref, axes))
            d = np.linalg.norm(marker(pre + prox) - marker(pre + dist), axis=1)
            length.append(float(np.nanmedian(d)))
        reach[side] = (t, sp.leg_reach(quats[0], quats[1], *length))

    def step(side: str, x: float) -> float:
        return sp._step(reach, side, x)

    def near(det: np.ndarray, x: float) -> float:
        d = np.abs(det - x)
        return float(det[np.argmin(d)]) if len(d) and d.min() < 0.15 else np.nan

    def heel(side: str, x: float) -> float:
        h = marker(("R" if side == "r" else "L") + "CAL")
        return float(np.interp(x, t, h @ fwd, left=np.nan, right=np.nan))

    rows = []
    events = sorted((x, s) for s in "rl" for x in zeni_ic[s])
    for (x0, s0), (x1, s1) in zip(events[:-1], events[1:], strict=True):
        if s0 == s1:
            continue
        ref = heel(s1, x1) - heel(s0, x0)
        rows.append(("step", s1, x1, ref, step(s1, near(det_ic[s1], x1)), step(s1, x1)))
    for s in "rl":
        o = "l" if s == "r" else "r"
        for a, b in zip(zeni_ic[s][:-1], zeni_ic[s][1:], strict=True):
            inner = zeni_ic[o][(zeni_ic[o] > a) & (zeni_ic[o] < b)]
            if len(inner) != 1:
                continue
            ref = heel(s, b) - heel(s, a)
            da, db, di = near(det_ic[s], a), near(det_ic[s], b), near(det_ic[o], inner[0])
            model = step(o, di) + step(s, db)
            model_z = step(o, inner[0]) + step(s, b)
            rows.append(("stride", s, a, ref, model, model_z))
            m = (t >= a) & (t <= b)
            speed = float(np.nanmean(np.gradient(sacrum @ fwd, t)[m]))
            rows.append(("speed", s, a, speed, model / (db - da), model_z / (b - a)))
    return [r for r in rows if np.isfinite(r[3])]


def walk_markers(path: Path):
    """The C3D walk's ``(c3d, t (s), rate (Hz), marker, sacrum, fwd)``: ``marker(name)`` the
    (N, 3) trajectory in m, ``sacrum`` the mid-PSIS, ``fwd`` the horizontal walking direction."""
    c = ezc3d.c3d(str(path))
    labels = c["parameters"]["POINT"]["LABELS"]["value"]
    rate = float(c["parameters"]["POINT"]["RATE"]["value"][0])
    pts = c["data"]["points"][:3] / 1000.0  # (3, M, N) mm → m
    t = np.arange(pts.shape[2]) / rate

    def marker(name: str) -> np.ndarray:
        return pts[:, labels.index(name), :].T

    sacrum = (marker("RPSI") + marker("LPSI")) / 2
    v = np.nanmean(np.diff(sacrum, axis=0), axis=0)
    fwd = np.array([v[0], v[1], 0.0]) / np.hypot(v[0], v[1])
    return c, t, rate, marker, sacrum, fwd


def evaluate(path: Path) -> dict:
    """The walk's numbers: ``events`` rows ``(side, IC|FC, reference, time s, error ms)``,
    ``stance`` and ``lengths`` rows (:func:`_stance`, :func:`_lengths`), ``hips``
    (:func:`hip_axes`) and ``seconds``, ``rate``."""
    c, t, rate, marker, sacrum, fwd = walk_markers(path)
    par = c["parameters"]
    n = len(t)
    left = np.cross([0.0, 0.0, 1.0], fwd)
    an = c["data"]["analogs"][0]
    alab = par["ANALOG"]["LABELS"]["value"]
    arate = float(par["ANALOG"]["RATE"]["value"][0])
    corners = np.asarray(par["FORCE_PLATFORM"]["CORNERS"]["value"]) / 1000.0  # (3, 4, plates)
    plates = {}
    for i, p in enumerate(("1", "2")):
        fz = an[alab.index(f"Fz{p}")]
        load = np.abs(fz - np.median(fz[: int(arate)])) > FORCE_N
        edges = np.flatnonzero(np.diff(load.astype(int))) + 1
        on, off = edges[0] / arate, edges[-1] / arate
        k = int(round((on + off) / 2 * rate))
        side = "r" if marker("RCAL")[k, 2] < marker("LCAL")[k, 2] else "l"
        heel = marker("RCAL" if side == "r" else "LCAL")[k, :2]
        lo, hi = corners[:2, :, i].min(axis=1), corners[:2, :, i].max(axis=1)
        heel_on_plate = bool(np.all((heel >= lo) & (heel <= hi)))
        plates[side] = (on if heel_on_plate else np.nan, off)
    rows = []
    zeni_ic, det_ic = {}, {}
    stance: list[tuple] = []
    for side, pre in (("r", "R"), ("l", "L")):
        cl = np.stack([marker(f"{pre}TB{i}") for i in (1, 2, 3)], axis=1)
        w = sagittal_rate(cl, rate, left)
        good = np.flatnonzero(np.isfinite(w))
        tt = t[good[0] : good[-1] + 1]
        ww = np.interp(tt, t[np.isfinite(w)], w[np.isfinite(w)])
        ev = ge.detect(tt, ww)
        toe = -((marker(f"{pre}MT2") - sacrum) @ fwd)
        heel = (marker(f"{pre}CAL") - sacrum) @ fwd
        zeni = {}
        for name, x in (("fc", toe), ("ic", heel)):
            k, _ = find_peaks(np.where(np.isfinite(x), x, -9.0), prominence=0.1)
            zeni[name] = t[k]
        zeni_ic[side], det_ic[side] = zeni["ic"], ev.ic
        stance.extend(_stance(side, zeni, ev))
        for name, det in (("ic", ev.ic), ("fc", ev.fc)):
            refs = [("force plate", np.array([plates[side][0 if name == "ic" else 1]]))]
            refs.append(("Zeni kinematic", zeni[name]))
            for ref_name, ref in refs:
                for x in ref[np.isfinite(ref)]:
                    d = det - x
                    if len(d) and np.min(np.abs(d)) < 0.3:
                        err = 1e3 * d[np.argmin(np.abs(d))]
                        rows.append((side, name.upper(), ref_name, x, err))
    lengths = _lengths(marker, rate, left, fwd, sacrum, zeni_ic, det_ic)
    return {"events": rows, "stance": stance, "lengths": lengths,
            "hips": hip_axes(marker, rate), "seconds": n / rate, "rate": rate}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared")
    args = ap.parse_args()
    path = args.data / FILE
    if not path.exists():
        sys.exit(f"{path}: not found; give the shared data folder with --data DIR")
    res = evaluate(path)
    rows, stance, lengths = res["events"], res["stance"], res["lengths"]
    print(f"{path.name}: {res['seconds']:.1f} s at {res['rate']:g} Hz; detector error "
          "(detected − reference)\n")  # fmt: skip
    print(f"{'side':<5}{'event':<6}{'reference':<16}{'time s':>8}{'error ms':>10}")
    for side, ev_name, ref, x, d in rows:
        print(f"{side:<5}{ev_name:<6}{ref:<16}{x:8.3f}{d:10.0f}")
    print("\nstance (% of the stride): detector against Zeni's events")
    for side, a, ref, det in stance:
        print(f"  {side} stride from {a:.3f} s: Zeni {ref:5.1f} %, detector {det:5.1f} % "
              f"({det - ref:+.1f} points)")  # fmt: skip
    print(f"\nstep/stride length (m), speed (m/s): model ({sp.LENGTH_MODEL.split(',')[0]}) "
          "against the heel markers and the mid-PSIS")  # fmt: skip
    print(f"{'what':<8}{'side':<5}{'IC s':>7}{'heels':>8}{'model':>8}{'err %':>7}"
          f"{'at Zeni IC':>11}{'err %':>7}")  # fmt: skip
    for what, side, x, ref, model, model_z in lengths:
        print(f"{what:<8}{side:<5}{x:7.3f}{ref:8.3f}{model:8.3f}{100 * (model / ref - 1):7.1f}"
              f"{model_z:11.3f}{100 * (model_z / ref - 1):7.1f}")  # fmt: skip
    for what in ("step", "stride", "speed"):
        e = [100 * (r[4] / r[3] - 1) for r in lengths if r[0] == what]
        ez = [100 * (r[5] / r[3] - 1) for r in lengths if r[0] == what]
        raw = [100 * (r[5] / r[3] / sp.FOOT_ROLL_FACTOR - 1) for r in lengths if r[0] == what]
        if e:
            print(f"{what}: error median {np.nanmedian(e):+.1f} % (range {np.nanmin(e):+.1f} to "
                  f"{np.nanmax(e):+.1f}), at the Zeni ICs {np.nanmedian(ez):+.1f} % (range "
                  f"{np.nanmin(ez):+.1f} to {np.nanmax(ez):+.1f}; without the foot-roll factor "
                  f"{np.nanmedian(raw):+.1f} %) (n={len(e)})")  # fmt: skip
    for side, (angle, ratio) in res["hips"].items():
        print(f"hip {side}: dominant relative axis {angle:+.1f}° from the pelvis z about the "
              f"vertical (second/first singular value {ratio:.2f})")  # fmt: skip
    for ev_name in ("IC", "FC"):
        for ref in ("force plate", "Zeni kinematic"):
            d = [r[4] for r in rows if r[1] == ev_name and r[2] == ref]
            if d:
                print(f"{ev_name} vs {ref}: median {np.median(d):.0f} ms, "
                      f"median |err| {np.median(np.abs(d)):.0f} ms (n={len(d)})")  # fmt: skip


if __name__ == "__main__":
    main()
