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

from motionlab.kinematics import gait_events as ge  # noqa: E402

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared")
    args = ap.parse_args()
    path = args.data / FILE
    if not path.exists():
        sys.exit(f"{path}: not found; give the shared data folder with --data DIR")
    c = ezc3d.c3d(str(path))
    par = c["parameters"]
    labels = par["POINT"]["LABELS"]["value"]
    rate = float(par["POINT"]["RATE"]["value"][0])
    pts = c["data"]["points"][:3] / 1000.0  # (3, M, N) mm → m
    n = pts.shape[2]
    t = np.arange(n) / rate

    def marker(name: str) -> np.ndarray:
        return pts[:, labels.index(name), :].T

    sacrum = (marker("RPSI") + marker("LPSI")) / 2
    v = np.nanmean(np.diff(sacrum, axis=0), axis=0)
    fwd = np.array([v[0], v[1], 0.0]) / np.hypot(v[0], v[1])
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
        for name, det in (("ic", ev.ic), ("fc", ev.fc)):
            refs = [("force plate", np.array([plates[side][0 if name == "ic" else 1]]))]
            refs.append(("Zeni kinematic", zeni[name]))
            for ref_name, ref in refs:
                for x in ref[np.isfinite(ref)]:
                    d = det - x
                    if len(d) and np.min(np.abs(d)) < 0.3:
                        err = 1e3 * d[np.argmin(np.abs(d))]
                        rows.append((side, name.upper(), ref_name, x, err))
    print(f"{path.name}: {n / rate:.1f} s at {rate:g} Hz; detector error (detected − reference)\n")
    print(f"{'side':<5}{'event':<6}{'reference':<16}{'time s':>8}{'error ms':>10}")
    for side, ev_name, ref, x, d in rows:
        print(f"{side:<5}{ev_name:<6}{ref:<16}{x:8.3f}{d:10.0f}")
    for side, (angle, ratio) in hip_axes(marker, rate).items():
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
