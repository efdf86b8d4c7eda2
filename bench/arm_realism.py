"""Is the simulated arm as hard as a real one? The elbow's two-axis fit on real and simulated arms.

For each elbow this prints what the product's two-axis fit from movement
(:func:`motionlab.segments.movement.fit_two_dof`, through ``analyse`` with the ``arm`` protocol)
leaves: ``relative_residual`` (RMS residual / RMS relative rate), ``consistency_deg`` (the largest
angle between a part's axes and the whole fit's) and the verdict, with what the arm does: the
elbow's range (angle between the stand's long axes, 5th-95th percentile), the upper-arm sensor's
axial rotation relative to the thorax (5-95 % range), its rate about its own long axis as a
share of its rate, and its RMS angular speed.

Rows:

- **real** (skipped without ``../shared``): the 16-IMU ``qmt_full_body`` recording read as
  ``bench/real_people.py`` reads it (stand 0.5-4.3 s); ranges from the vendor's 9-D orientations.
- **simulated**: the ``arm`` protocol (74 s, random mountings, preset ``skin``), its own free
  movement and, with ``--real-like``, a free movement shaped like the real recording's (elbows
  near straight, 12-28°; humeral rotation ±35°; shoulder flexion and abduction 0-20°; pronation
  ±25°; every channel at 0.7-1.2 Hz), with the upper-arm skin following the stated fraction of
  the humerus' axial rotation (``simulate.STA_HUMERAL_FOLLOW``) or, with ``--follow 1``, the bone.

Usage::

    python bench/arm_realism.py [--seeds 0-2] [--real-like] [--follow F] [--data ../shared]
"""

from __future__ import annotations

import argparse
import warnings
from importlib import import_module
from pathlib import Path

import numpy as np
from real_people import qmt_session
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.simulate import simulate, tasks
from motionlab.simulate.tasks import Block

sim = import_module("motionlab.simulate")  # the package: motionlab.simulate is the function

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared"
QMT = "datasets/human/qmt_full_body"
REAL_STAND_S = (0.5, 4.3)
SIM_STAND_S = (3.5, 7.5)
SIM_DURATION_S = 74.0  # as bench/real_world.py
#: the real-like free movement: (channel, centre, half range) in deg, and its frequencies (Hz)
REAL_LIKE = [(f"elbow_{s}_0", 20.0, 8.0) for s in "rl"]
REAL_LIKE += [(f"elbow_{s}_2", 0.0, 25.0) for s in "rl"]
REAL_LIKE += [(f"shoulder_{s}_0", 10.0, 10.0) for s in "rl"]
REAL_LIKE += [(f"shoulder_{s}_1", -10.0, 10.0) for s in "rl"]
REAL_LIKE += [(f"shoulder_{s}_2", 0.0, 35.0) for s in "rl"]
REAL_LIKE += [("lumbar_0", 3.0, 5.0), ("lumbar_1", 0.0, 4.0), ("lumbar_2", 0.0, 8.0)]
REAL_LIKE_HZ = (0.7, 1.2)


def real_like_free_arm(body, name, phase, duration, reps, options, seed: int = 0) -> Block:
    """``tasks.free_arm`` with the real recording's movement (:data:`REAL_LIKE`)."""
    rng = np.random.default_rng([seed, 7])
    fn = tasks.wandering(body, REAL_LIKE, REAL_LIKE_HZ, duration, rng)
    return Block(name, "free_arm", phase, duration, fn, generator="free_arm_real_like")


def _twist(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Twist angle (deg) of rotations ``q`` about ``axis`` (their own frame)."""
    return np.degrees(2 * np.arctan2(q[:, 1:] @ axis, q[:, 0]))


def ranges(t, q_thorax, q_arm, q_fore, g_arm, u, f, stand, part) -> dict:
    """What the arm does over ``part`` (bool mask): see the module docstring."""
    rel_s = rot.mul(rot.conj(q_thorax), q_arm)
    d_s = rot.mul(rot.conj(rot.mean(rel_s[stand])), rel_s)
    axial = np.unwrap(np.radians(_twist(d_s, u)))
    rel_e = rot.mul(rot.conj(q_arm), q_fore)
    elbow = np.degrees(np.arccos(np.clip(rot.rotate(rel_e, f) @ u, -1.0, 1.0)))
    g = g_arm[part]
    speed = np.sqrt(np.mean(np.sum(g**2, axis=1)))
    return {
        "elbow": np.percentile(elbow[part], [5, 95]),
        "axial": float(np.degrees(np.ptp(np.percentile(axial[part], [5, 95])))),
        "share": float(np.sqrt(np.mean((g @ u) ** 2)) / speed),
        "speed": float(np.degrees(speed)),
    }


def _stand_axis(stream, stand_s) -> np.ndarray:
    sel = (stream.time >= stand_s[0]) & (stream.time < stand_s[1])
    a = np.mean(stream.acc[sel], axis=0)
    return a / np.linalg.norm(a)


def rows_of(session, orientations, stand_s, part_s, label) -> list[tuple[str, dict]]:
    """One row per elbow of an analysed session."""
    out = []
    for side in "rl":
        arm, fore = session.sensors[f"upperarm_{side}"], session.sensors[f"forearm_{side}"]
        n = min(len(arm.time), len(fore.time), len(orientations["thorax"]))
        t = arm.time[:n]
        stand = (t >= stand_s[0]) & (t < stand_s[1])
        part = (t >= part_s[0]) & (t < part_s[1])
        u, f = _stand_axis(arm, stand_s), _stand_axis(fore, stand_s)
        q = [orientations[k][:n] for k in ("thorax", f"upperarm_{side}", f"forearm_{side}")]
        row = ranges(t, *q, arm.gyr[:n], u, f, stand, part)
        fit = session.results.calibration.hinges[f"elbow_{side}"]
        row |= {"residual": fit.relative_residual, "parts": fit.consistency_deg,
                "verdict": fit.verdict}  # fmt: skip
        out.append((f"{label} {side}", row))
    return out


def real_rows(data: Path) -> list[tuple[str, dict]]:
    folder = data / QMT
    if not folder.exists():
        print(f"(no real rows: {folder} not found)")
        return []
    session, vendor = qmt_session(folder, "arm")
    analyse(session, PipelineOptions(protocol="arm", progress=False))
    return rows_of(session, vendor, REAL_STAND_S, (5.0, 100.0), "real qmt (5-100 s)")


def sim_rows(seeds: list[int], real_like: bool, follow: float | None) -> list[tuple[str, dict]]:
    if real_like:
        tasks.free_arm = real_like_free_arm
    if follow is not None:
        sim.STA_HUMERAL_FOLLOW, sim.STA_HUMERAL_FOLLOW_SD = (follow, follow), 0.0
    kind = "real-like" if real_like else "protocol"
    kind += f", follow {follow:g}" if follow is not None else ""
    out = []
    for seed in seeds:
        session, truth = simulate("arm", SIM_DURATION_S, seed, "skin", mounting="random")
        prepare_sensors(session)
        analyse(session, PipelineOptions(protocol="arm", progress=False))
        q = {k: v["orientation"] for k, v in truth.sensors.items()}
        out += rows_of(session, q, SIM_STAND_S, (11.0, 71.0), f"sim {kind} seed {seed}")
    return out


def print_table(rows: list[tuple[str, dict]]) -> None:
    print(
        "| elbow | residual | parts (°) | verdict | elbow 5-95 % (°) | upper-arm axial "
        "range (°) | axial share of rate | upper-arm RMS (°/s) |"
    )
    print("|---|---:|---:|---|---|---:|---:|---:|")
    for label, r in rows:
        print(f"| {label} | {r['residual']:.2f} | {r['parts']:.1f} | {r['verdict']} | "
              f"{r['elbow'][0]:.0f}-{r['elbow'][1]:.0f} | {r['axial']:.0f} | {r['share']:.2f} | "
              f"{r['speed']:.0f} |")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default="0-2")
    ap.add_argument("--real-like", action="store_true", help="the real recording's movement")
    ap.add_argument("--follow", type=float, default=None, help="fraction followed (1: the bone)")
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print_table(real_rows(args.data) + sim_rows(args.seeds, args.real_like,
                                                args.follow))  # fmt: skip


if __name__ == "__main__":
    main()
