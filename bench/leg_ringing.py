"""Do the simulated legs ring after heel strikes as real ones do? Accelerometer and gyroscope
above 10 Hz while walking, on real and simulated walks.

A real leg sensor rings on its strap and soft tissue after each heel strike (a shank spike of
about 5 g, then 10-20 Hz ringing on thigh and shank); a simulated segment moves smoothly. Per
sensor, over its walking samples (the gyroscope's 1-s RMS above 1 rad/s; 0.3 rad/s for the
pelvis): ``‖a‖`` in g (5th, 50th, 95th, 99th percentile), the RMS of the accelerometer's and
the gyroscope's vector high-passed at 10 Hz (4th-order Butterworth, zero phase; m/s², rad/s)
and, for the gyroscope, its 99th percentile.

Then the heel strikes' clock lag (:func:`motionlab.clocksync.impacts.impact_clock`) between
sensors on **one clock**, where it should be 0: the real full-body recording's sensors share
one radio clock, the simulated ones are given one (the ``skin`` preset without clock offsets).
A lag is the bias that each sensor's own ringing puts into the heel-strike clock sync
(docs/simulator.md, "The legs ring after heel strikes").

Rows:

- **real qmt** (skipped without ``../shared``): the 16-IMU ``qmt_full_body`` recording (Xsens,
  100 Hz), both legs and the pelvis (``hip``). The simulator's ringing was set on it.
- **real DOT** (skipped without ``../shared``): the two Xsens DOT knee recordings (60 Hz),
  from ``WALK_FROM``; not used to set anything (the 10-Hz high-pass keeps 10-24 Hz there).
- **sim**: the ``walk`` protocol with the ``skin`` preset and the anatomical knee (as
  ``bench/real_world.py``), random mountings.

Usage::

    python bench/leg_ringing.py [--data ../shared] [--seeds 0-2]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import scipy.io
from joint_angles import shared_clock
from scipy.signal import butter, sosfiltfilt
from seeds import seeds_arg

from motionlab.clocksync.impacts import impact_clock
from motionlab.io import read_any
from motionlab.pipeline import prepare_sensors
from motionlab.session import SensorStream, Session
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared"
QMT = "datasets/human/qmt_full_body/full_body_example_data.mat"
QMT_SENSORS = {"hip": "pelvis", "upper_leg_right": "thigh_r", "lower_leg_right": "shank_r",
               "upper_leg_left": "thigh_l", "lower_leg_left": "shank_l"}  # fmt: skip
DOT = "datasets/human/imt_dot"
WALK_FROM = {"knee_tracking1": 30.0, "knee_tracking2": 24.0}  # as bench/sim_realism.py
HIGH_HZ = 10.0
WALKING_RAD_S = {"pelvis": 0.3}  # the gyroscope's 1-s RMS above which a sample is walking
LEGS_RAD_S = 1.0
LAG_PAIRS = (("pelvis", "thigh_r"), ("pelvis", "thigh_l"), ("thigh_r", "shank_r"),
             ("thigh_l", "shank_l"), ("thigh_r", "thigh_l"), ("shank_r", "shank_l"))  # fmt: skip


def ringing(stream: SensorStream) -> dict[str, float]:
    """The row's numbers for one sensor (see the module docstring)."""
    rate = stream.rate_hz
    seg = stream.label
    w = np.linalg.norm(stream.gyr, axis=1)
    n = max(1, int(round(rate)))
    limit = WALKING_RAD_S.get(seg, LEGS_RAD_S)
    walking = np.sqrt(np.convolve(w**2, np.ones(n) / n, "same")) > limit
    sos = butter(4, HIGH_HZ, "highpass", fs=rate, output="sos")
    acc_hf = np.linalg.norm(sosfiltfilt(sos, stream.acc, axis=0), axis=1)[walking]
    gyr_hf = np.linalg.norm(sosfiltfilt(sos, stream.gyr, axis=0), axis=1)[walking]
    g = np.linalg.norm(stream.acc, axis=1)[walking] / 9.81
    out = {f"p{q}": float(np.percentile(g, q)) for q in (5, 50, 95, 99)}
    out |= {
        "acc_hf": float(np.sqrt(np.mean(acc_hf**2))),
        "gyr_hf": float(np.sqrt(np.mean(gyr_hf**2))),
        "gyr_hf_p99": float(np.percentile(gyr_hf, 99)),
        "walking_s": walking.sum() / rate,
    }
    return out


def lags(session: Session) -> str:
    """The heel strikes' lag (ms) of each pair of ``LAG_PAIRS`` present; ``refused`` where the
    method did not trust it."""
    cells = []
    for a, b in LAG_PAIRS:
        if a in session.sensors and b in session.sensors:
            fit = impact_clock(session.sensors[a], session.sensors[b])
            refused = fit.status.startswith("not")  # "not reliable: …", "not enough …"
            cells.append(f"{a}–{b} refused" if refused else f"{a}–{b} {1000 * fit.offset_s:+.1f}")
    return "; ".join(cells)


def print_rows(name: str, streams: list[SensorStream]) -> None:
    """One table row per sensor of the recording ``name``."""
    for s in streams:
        r = ringing(s)
        print(f"| {name} | {s.label} | {r['walking_s']:.0f} | {r['p5']:.2f} / {r['p50']:.2f} / "
              f"{r['p95']:.2f} / {r['p99']:.2f} | {r['acc_hf']:.2f} | {r['gyr_hf']:.2f} | "
              f"{r['gyr_hf_p99']:.1f} |")  # fmt: skip


def real_sessions(data: Path) -> list[tuple[str, Session]]:
    """``(name, session)`` of the real walks found under ``data`` (none without it)."""
    out = []
    if (data / QMT).is_file():
        mat = scipy.io.loadmat(data / QMT, squeeze_me=True, struct_as_record=False)
        t = np.asarray(mat["t"], float)
        session = Session()
        for name, seg in QMT_SENSORS.items():
            d = mat[name]
            session.sensors[seg] = SensorStream(label=seg, time=t - t[0],
                                                acc=np.asarray(d.acc, float),
                                                gyr=np.asarray(d.gyr, float))  # fmt: skip
        prepare_sensors(session)
        out.append(("real qmt", session))
    for name, start in WALK_FROM.items():
        folder = data / DOT / name
        if not folder.is_dir():
            continue
        session = Session()
        for file, seg in (("femur.csv", "thigh_r"), ("tibia.csv", "shank_r")):
            s = read_any(folder / file).sensors[0]
            keep = s.time - s.time[0] >= start
            session.sensors[seg] = SensorStream(label=seg, time=s.time[keep], acc=s.acc[keep],
                                                gyr=s.gyr[keep])  # fmt: skip
        prepare_sensors(session)
        out.append((f"real DOT {name}", session))
    return out


def sim_session(seed: int) -> Session:
    """The simulated walk of ``seed`` (preset ``skin`` on one clock, random mountings)."""
    session, _ = simulate("walk", 74.0, seed, shared_clock(get_preset("skin")), mounting="random",
                          knee_model="anatomical")  # fmt: skip
    prepare_sensors(session)
    return session


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--seeds", type=seeds_arg, default=[0, 1, 2])
    args = ap.parse_args()
    rows = real_sessions(args.data)
    rows += [(f"sim seed {seed}", sim_session(seed)) for seed in args.seeds]
    print("| recording | sensor | walking (s) | ‖a‖ (g) p5 / p50 / p95 / p99 | acc > 10 Hz RMS "
          "(m/s²) | gyr > 10 Hz RMS (rad/s) | gyr > 10 Hz p99 (rad/s) |")  # fmt: skip
    print("|---|---|---:|---|---:|---:|---:|")
    for name, session in rows:
        print_rows(name, list(session.sensors.values()))
    print("\nheel-strike clock lag (ms) between sensors on one clock (0 is right):")
    for name, session in rows:
        print(f"- {name}: {lags(session)}")


if __name__ == "__main__":
    main()
