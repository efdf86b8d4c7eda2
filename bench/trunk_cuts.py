"""Real people seated, recordings cut as they come: does the ``lumbar_seated`` protocol run, and do
its angles stay put, when the five trunk trials are cut to start or end in movement, keep a short
rest only, or keep a part of the recording?

Each trial of ``../shared/datasets/trunk/`` is cut in several ways (:func:`cuts`: from the still
stretches at its start and end, by the mean angular speed of ``Back`` and ``Chest`` over 0.5 s
under 15°/s); every cut is written as an x-IMU3 export (each device's time-stamped CSVs cut by
their ``Timestamp (us)``, the other files copied) into a temporary folder, never touching the data
set, and analysed as ``motionlab run <cut>/imu --map protocols/examples/trunk_map.yaml --protocol
lumbar_seated`` does (``ingest`` + ``pipeline.analyse``, default 6-D fusion). A cut the product
refuses is run once more through the CLI to check the refusal is one line with exit 2 (a rest
and 1 s of movement must be refused: too little trunk movement).

Per cut: the rest the calibration chose, the grades, the offset-free RMSE against OptiTrack (as
``bench/real_trunk.py`` compares: its clock offset, flips, jumps and anatomical frame; the
comparison's zero the product's rest where the optical bodies see it, else the stillest second
both cover), and how far the angles moved from the recording as recorded: the offset-free RMS
difference (deg) between the cut's angles and the whole recording's over the samples both hold.
These five trials are the tuning set of the trunk calibration; cutting them does not make them an
independent test.

Usage (from the repository root)::

    python3 bench/trunk_cuts.py [--data ../shared/datasets/trunk] [--trials Aag/pivot_hs ...]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import real_trunk as rt  # noqa: E402
from real_rig import fmt, on_optical  # noqa: E402
from scipy.ndimage import uniform_filter1d  # noqa: E402

from motionlab.errors import InputError  # noqa: E402
from motionlab.ingest import ingest  # noqa: E402
from motionlab.pipeline import PipelineOptions, analyse  # noqa: E402
from motionlab.validation.joint_reference import fit_clock_offset  # noqa: E402

STILL_DEG_S = 15.0  # the trunk sensors' mean speed (0.5 s) under this is a still stretch
SHORT_REST_S = (1.2, 0.6)  # "short rest" cuts keep this much of a rest (s)
MARGIN_S = 0.5  # a cut "in movement" starts or stops this far from the rest
PLANES = rt.PLANES
COLUMNS = [f"lumbar_{p}_deg" for p in PLANES]


def still_ends(t: np.ndarray, speed_deg_s: np.ndarray) -> tuple[float | None, float | None]:
    """The end of the still stretch that starts the recording and the start of the one that
    ends it (s; ``None`` where the recording starts or ends in movement, or the stretch is under
    0.5 s)."""
    fs = 1.0 / float(np.median(np.diff(t)))
    still = uniform_filter1d(speed_deg_s, max(int(round(0.5 * fs)), 1)) < STILL_DEG_S
    lead = trail = None
    if still[0]:
        k = int(np.argmin(still)) if not still.all() else len(t) - 1
        lead = float(t[k]) if t[k] - t[0] >= 0.5 else None
    if still[-1]:
        k = len(t) - 1 - int(np.argmin(still[::-1])) if not still.all() else 0
        trail = float(t[k]) if t[-1] - t[k] >= 0.5 else None
    return lead, trail


def cuts(t: np.ndarray, speed_deg_s: np.ndarray) -> dict[str, tuple[float, float]]:
    """The cuts of a recording (name → session time span, s) that its still ends allow."""
    t0, t1 = float(t[0]), float(t[-1])
    lead, trail = still_ends(t, speed_deg_s)
    out = {"as recorded": (t0, t1)}
    if lead is not None:
        out["start moving"] = (lead + MARGIN_S, t1)
        out["rest and 1 s of movement"] = (t0, lead + 1.0)  # too little movement: refused
        for short in SHORT_REST_S:
            if lead - t0 >= short + 0.5:
                out[f"{short:g} s rest at start"] = (lead - short, t1)
    if trail is not None:
        out["end moving"] = (t0, trail - MARGIN_S)
        for short in SHORT_REST_S:
            if t1 - trail >= short + 0.5:
                out[f"{short:g} s rest at end"] = (t0, trail + short)
    if lead is not None and trail is not None:
        out["moving throughout"] = (lead + MARGIN_S, trail - MARGIN_S)
    length = t1 - t0
    out["first 60 %"] = (t0, t0 + 0.6 * length)
    out["last 60 %"] = (t1 - 0.6 * length, t1)
    out["middle 60 %"] = (t0 + 0.2 * length, t1 - 0.2 * length)
    return out


def _stamps_zero(imu: Path, session) -> float:
    """The absolute time (s) of the session's zero: ``Back``'s first stamp less its session
    time."""
    folder = next(p for p in imu.iterdir() if p.name.startswith("Back "))
    with open(folder / "Inertial.csv") as f:
        f.readline()
        first = float(f.readline().split(",")[0]) * 1e-6
    return first - float(session.sensors["Back"].time[0])


def write_cut(imu: Path, out: Path, zero_s: float, span: tuple[float, float]) -> Path:
    """``imu`` (an x-IMU3 trial folder) cut to ``span`` (session time, s; ``zero_s`` the
    session's zero in the stamps' time) into ``out/imu``; the data set is only read."""
    dest = out / "imu"
    lo, hi = (zero_s + span[0]) * 1e6, (zero_s + span[1]) * 1e6
    for device in sorted(p for p in imu.iterdir() if p.is_dir()):
        (dest / device.name).mkdir(parents=True)
        for f in device.iterdir():
            target = dest / device.name / f.name
            if f.suffix != ".csv":
                shutil.copyfile(f, target)
                continue
            lines = f.read_text().splitlines(keepends=True)
            if not lines or not lines[0].startswith("Timestamp (us)"):
                shutil.copyfile(f, target)
                continue
            kept = [ln for ln in lines[1:] if ln.strip() and lo <= float(ln.split(",")[0]) <= hi]
            target.write_text(lines[0] + "".join(kept))
    return dest


def run_cut(imu: Path) -> tuple[dict | None, str, float]:
    """The product on a cut export: (angles and calibration, "", zero) or (None, refusal, 0)."""
    try:
        session = ingest([imu], rt.MAP)
        zero = _stamps_zero(imu, session)
        analyse(session, PipelineOptions(protocol=rt.PROTOCOL, progress=False))
    except InputError as exc:
        return None, str(exc), 0.0
    cols = {c: np.asarray(v, float) for c, v in session.results.angles.columns().items()}
    cal = session.results.calibration
    return {"t": cols["time_s"], "angles": np.column_stack([cols[c] for c in COLUMNS]),
            "grades": cal.grades["lumbar"].grades, "rest": tuple(cal.steps["rest"]),
            "trunk": cal.grades["lumbar"].trunk}, "", zero  # fmt: skip


def cli_refusal(imu: Path, out: Path) -> tuple[int, int, str]:
    """``motionlab run`` on a cut the library refused: exit code, stderr lines, the last line."""
    cmd = [sys.executable, "-m", "motionlab", "run", str(imu), "--map", str(rt.MAP),
           "--protocol", rt.PROTOCOL, "-o", str(out / "out"), "--quiet"]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    return res.returncode, len(lines), lines[-1] if lines else ""


class Optical:
    """OptiTrack of one trial as ``bench/real_trunk.py`` prepares it (flips, jumps and gaps left
    out; the clock offset from the speeds, refined on the whole recording's rotation from rest)."""

    def __init__(self, trial: Path, chair_right: np.ndarray | None) -> None:
        self.t, self.quats, self.pos = rt.read_motive(trial / "optitrack.csv")
        for body in ("back", "low_back", "rolstoel"):
            good = rt.good_frames(self.t, self.quats[body])
            q = np.where(good[:, None], self.quats[body], np.nan)
            self.quats[body] = np.where(rt.jumps(self.t, q)[:, None], np.nan, q)
        self.t_imu, self.sp_imu = rt.imu_speeds(trial / "imu")
        sp_opt = np.column_stack(
            [rt.speed(self.t, self.quats[b]) for b in ("back", "low_back", "rolstoel")]
        )
        self.coarse, _ = fit_clock_offset(
            self.t_imu, self.sp_imu, self.t, sp_opt, rt.CLOCK_SEARCH_S, 0.005
        )
        self.offset = self.coarse
        self.chair_right = chair_right

    def refine(self, full: dict) -> None:
        """The clock offset refined on the whole recording's rotation from rest."""
        best = np.inf
        for lag in np.arange(self.coarse - 0.1, self.coarse + 0.1001, 0.002):
            m = self.compare(full, lag)["rotation from rest"]
            if m["free"] < best:
                best, self.offset = m["free"], float(lag)

    def compare(self, run: dict, lag: float | None = None) -> dict[str, dict]:
        """Offset-free RMSE etc. of a run's angles (per plane and the rotation from rest)."""
        lag = self.offset if lag is None else lag
        t = run["t"]
        rest_s = rt.common_rest(self.t_imu, self.sp_imu, self.t - self.coarse, self.quats,
                                run["rest"], (t[0], t[-1]))  # fmt: skip
        rest_opt = (self.t - lag >= rest_s[0]) & (self.t - lag <= rest_s[1])
        ref, _ = rt.optical_angles(self.t, self.quats, self.pos, rest_opt, self.chair_right)
        out = {}
        for k, plane in enumerate(PLANES):
            out[plane] = rt.metrics(on_optical(t, run["angles"][:, k], self.t, lag), ref[:, k])
        est = rt.rest_angle(run["angles"], (t >= rest_s[0]) & (t <= rest_s[1]))
        out["rotation from rest"] = rt.metrics(
            on_optical(t, est, self.t, lag), rt.rest_angle(ref, rest_opt)
        )
        out["compared from"] = rest_s
        return out


def moved(full: dict, cut: dict) -> list[float]:
    """Offset-free RMS difference (deg) per plane between a cut's angles and the whole
    recording's, over the cut's samples."""
    out = []
    for k in range(len(PLANES)):
        ref = np.interp(cut["t"], full["t"], full["angles"][:, k], left=np.nan, right=np.nan)
        d = cut["angles"][:, k] - ref
        d = d[np.isfinite(d)]
        out.append(float(np.sqrt(np.mean((d - d.mean()) ** 2))) if len(d) > 10 else np.nan)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=rt.DEFAULT_DATA, help="the trunk data set")
    ap.add_argument("--trials", nargs="*", help="subject/task names (default: all)")
    args = ap.parse_args(argv)
    trials = sorted(p.parent for p in args.data.glob("*/*/optitrack.csv"))
    if args.trials:
        trials = [p for p in trials if f"{p.parent.name}/{p.name}" in args.trials]
    if not trials:
        print(f"error: no trials in {args.data} (<subject>/<task>/optitrack.csv); give --data",
              file=sys.stderr)  # fmt: skip
        return 2
    seen = []
    for trial in sorted(p.parent for p in args.data.glob("*/*/optitrack.csv")):
        t_opt, quats, pos = rt.read_motive(trial / "optitrack.csv")
        z = rt.arm_line(pos, t_opt < 1.0)
        if z is not None:
            seen.append(rt.in_chair(quats, t_opt < 1.0, z, to_chair=True))
    chair_right = np.mean(seen, axis=0) if seen else None
    print("## The lumbar_seated protocol on the five trunk trials cut in several ways\n")
    print(
        "| trial | cut (s) | rest (s) | flexion axis | grades | flexion / lateral / axial "
        "(offset-free RMSE, deg) | from rest | moved from as recorded (deg) | refusal |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    counts = {"ran": 0, "refused": 0}
    worst: dict[str, float] = {}
    for trial in trials:
        name = f"{trial.parent.name}/{trial.name}"
        opt = Optical(trial, chair_right)
        session = ingest([trial / "imu"], rt.MAP)
        zero = _stamps_zero(trial / "imu", session)
        speed = np.degrees(opt.sp_imu[:, :2].mean(axis=1))
        full = None
        for label, span in cuts(opt.t_imu, speed).items():
            with tempfile.TemporaryDirectory(prefix="trunk_cut_") as tmp:
                imu = write_cut(trial / "imu", Path(tmp), zero, span)
                run, why, cut_zero = run_cut(imu)
                if run is None:
                    code, nlines, line = cli_refusal(imu, Path(tmp))
            cell = f"{label} {span[0]:.1f}–{span[1]:.1f}"
            if run is None:
                counts["refused"] += 1
                print(f"| {name} | {cell} | | | | | | | exit {code}, {nlines} line(s): "
                      f"{line[:160]} |")  # fmt: skip
                continue
            counts["ran"] += 1
            shift = cut_zero - zero  # the cut's session time on the whole recording's
            run["t"] = run["t"] + shift
            run["rest"] = (run["rest"][0] + shift, run["rest"][1] + shift)
            if full is None:  # "as recorded" comes first
                full = run
                opt.refine(full)
            m = opt.compare(run)
            mv = moved(full, run)
            grades = "/".join(g[:3] for g in run["grades"])
            free = " / ".join(fmt(m[p]["free"]) for p in PLANES)
            for k, p in enumerate(PLANES):
                if run["grades"][k] == "determined" and np.isfinite(mv[k]):
                    worst[p] = max(worst.get(p, 0.0), mv[k])
            tr = run["trunk"]
            axis = (f"energy {tr.energy_ratio:.1f}×, one-sided "
                    f"{'/'.join(f'{x:.1f}' for x in tr.one_sided)}, {tr.excursion_deg[0]:.0f}/"
                    f"{tr.excursion_deg[1]:.0f}°")  # fmt: skip
            rest = f"{run['rest'][0]:.1f}–{run['rest'][1]:.1f} ({tr.rest_speed_deg_s:.1f}°/s)"
            print(f"| {name} | {cell} | {rest} | {axis} | "
                  f"{grades} | "
                  f"{free} | {fmt(m['rotation from rest']['free'])} | "
                  f"{' / '.join(fmt(x) for x in mv)} | |")  # fmt: skip
        sys.stdout.flush()
    print(f"\n{counts['ran']} cuts ran, {counts['refused']} refused. The most a `determined` "
          "angle moved from the recording as recorded (offset-free RMS, deg): "
          + ", ".join(f"{p} {v:.1f}" for p, v in worst.items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
