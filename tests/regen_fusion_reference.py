"""Regenerate the pinned estimator outputs in ``tests/data/fusion_reference.npz``.

    python3 tests/regen_fusion_reference.py              # outputs again, same input signal
    python3 tests/regen_fusion_reference.py --new-signal # also draw the input signal again

``tests/test_fusion_reference.py`` runs every registered estimator (the optional VQF backend
excepted: it is not ours and may be absent) with its default parameters on the stored signal,
6-D and 9-D, and compares the quaternions with the stored ones to 1e-10. The signal is stored
beside the outputs (not drawn in the test) so a change of numpy's random streams cannot move it.

Regenerating is legitimate only when an estimator's output is *meant* to change: a deliberate
change of a model or of a default parameter, or a new estimator. Then commit the new file
together with that change and say in the commit message which estimators moved and by how much
(this script prints the largest change per estimator). A refactoring — renaming, moving code,
repacking parameters, unit conversions — must pass the test unchanged: never regenerate to make
it pass.

The signal (:func:`make_signal`): 2.8 s at 100 Hz; the sensor lies still for 1.9 s (the rest
detectors and the start-up phases see it), then turns about all three axes with a varying rate,
with a linear-acceleration burst at 2.2–2.4 s and a magnetic disturbance (a 25 µT offset) at
2.45–2.75 s; gyroscope bias (0.02, −0.01, 0.015) rad/s, white noise on all channels (seeded).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from motionlab import rotations as rot  # noqa: E402
from motionlab.fusion import available, estimate  # noqa: E402

PATH = ROOT / "tests" / "data" / "fusion_reference.npz"
SEED = 13
RATE = 100.0
SECONDS = 2.8
OPTIONAL_MODULES = ("motionlab.fusion.vqf_backend",)  # backends not pinned (third-party code)
#: the pinned samples: every 10th, ending with the last (28 of 280). Each sample depends on all
#: before it, so a change anywhere shows; about 1 kB per estimator and dimension
PINNED = slice(9, None, 10)


def make_signal(seed: int = SEED) -> dict[str, np.ndarray]:
    """The input signal: ``gyr`` (rad/s), ``acc`` (m/s²), ``mag`` (µT), N×3, at :data:`RATE`."""
    rng = np.random.default_rng(seed)
    n = int(round(SECONDS * RATE))
    t = np.arange(n) / RATE
    moving = np.clip((t - 1.9) / 0.2, 0.0, 1.0)  # ramps in over 0.2 s after the rest
    omega = moving[:, None] * np.column_stack(
        [1.2 * np.sin(2.1 * t), 0.8 * np.cos(3.3 * t), 1.5 * np.sin(1.7 * t + 0.4)]
    )
    quat = rot.integrate_gyro(rot.from_axis_angle([0.3, -0.5, 1.0], 0.8), omega, 1.0 / RATE)
    dip = np.deg2rad(62.0)
    field = 47.0 * np.array([0.0, np.cos(dip), -np.sin(dip)])
    lin = np.zeros((n, 3))
    lin[(t >= 2.2) & (t < 2.4)] = [2.5, -1.5, 1.0]  # m/s², earth frame
    dist = np.zeros((n, 3))
    dist[(t >= 2.45) & (t < 2.75)] = [25.0, 0.0, 10.0]  # µT, earth frame
    acc = rot.rotate(rot.conj(quat), np.array([0.0, 0.0, 9.81]) + lin)
    mag = rot.rotate(rot.conj(quat), field + dist)
    bias = np.array([0.02, -0.01, 0.015])
    return {
        "gyr": omega + bias + 0.004 * rng.standard_normal((n, 3)),
        "acc": acc + 0.03 * rng.standard_normal((n, 3)),
        "mag": mag + 0.4 * rng.standard_normal((n, 3)),
    }


def pinned() -> list[str]:
    """The estimators whose outputs are pinned: every registered one but the optional backends."""
    return [k for k, e in available().items() if e.run.__module__ not in OPTIONAL_MODULES]


def key(name: str, dims: int) -> str:
    """The npz key of an estimator's quaternions, 6-D or 9-D."""
    return f"{name}_{dims}d"


def run(name: str, sig: dict[str, np.ndarray], dims: int) -> np.ndarray:
    """Quaternions of estimator ``name`` with its defaults at the :data:`PINNED` samples
    (28, 4), signs continuous from a first sample with w ≥ 0."""
    mag = sig["mag"] if dims == 9 else None
    quat = rot.make_continuous(estimate(name, sig["gyr"], sig["acc"], mag, RATE).quat)
    return (quat if quat[0, 0] >= 0 else -quat)[PINNED]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--new-signal", action="store_true", help="draw the input signal again")
    args = ap.parse_args()
    old = dict(np.load(PATH)) if PATH.exists() else {}
    fresh = args.new_signal or not old
    sig = make_signal() if fresh else {k: old[k] for k in ("gyr", "acc", "mag")}
    out: dict[str, np.ndarray] = dict(sig)
    for name in pinned():
        for dims in (6, 9):
            q = run(name, sig, dims)
            out[key(name, dims)] = q
            if key(name, dims) in old and not fresh:
                change = np.abs(q - old[key(name, dims)]).max()
                print(f"{key(name, dims):16s} largest change {change:.3g}")
            else:
                print(f"{key(name, dims):16s} new")
    np.savez_compressed(PATH, **out)
    print(f"wrote {PATH.relative_to(ROOT)} ({PATH.stat().st_size / 1024:.0f} kB)")


if __name__ == "__main__":
    main()
