"""Make the example sessions that ``motionlab demo`` runs (``motionlab/data/demo/``).

Two simulated sessions of one simulated subject (``motionlab.simulate``, preset ``typical``,
random sensor mountings up to 30°), each with optical markers recorded in the session:

- ``knee.h5``: the knee protocol (pelvis, thighs, shanks): its calibration steps, then gait,
  squats and sit-to-stand;
- ``elbow.h5``: the elbow protocol (thorax, upper arms, forearms): its calibration steps, then
  reaching and hand-to-mouth.

To keep the wheel small (< 2 MB for both) the IMUs run at 60 Hz and the cameras at 20 Hz (the
validation's clock sync and joint-angle RMSE on seeds 7-9 were as good as at 100/120 Hz), the
landmark markers are seen during the standing pose only (then taken off, as in an anatomical
calibration with marker clusters), and the float arrays are stored with their mantissa rounded
(sensor channels to 12 bits, relative error ≤ 1.2e-4, under half the simulated sensors'
quantisation step at full scale; marker positions to 13 bits, ≤ 0.5 mm here, under half the
marker noise; time stamps exact) and gzip-compressed. h5py reads them like any other session.
The rests between blocks are the simulator's default: 3 s of stillness, plus 2 s where the next
block starts in another pose (sitting down, standing up).

Usage::

    python bench/make_demo.py [--out motionlab/data/demo] [--seed 7]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import h5py
import numpy as np

from motionlab.session import save_session
from motionlab.simulate import simulate
from motionlab.simulate.markers import OpticalSystem

MANTISSA_BITS = {"sensors": 12, "markers": 13}  # by top-level group; time stays exact
EXAMPLES = {
    # name: (protocol, duration s, session date)
    "knee": ("knee", 150.0, "2024-05-02"),
    "elbow": ("elbow", 180.0, "2024-05-02"),
}
IMU_HZ = 60.0
MARKER_HZ = 20.0
REST_S = 3.0  # still time between blocks (s), a change of pose comes on top
SUBJECT = {"id": "DEMO-01", "height_m": 1.75, "note": "simulated subject"}


def round_mantissa(a: np.ndarray, bits: int) -> np.ndarray:
    """``a`` (float64) with the mantissa rounded to ``bits`` bits; NaN and inf kept."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    u = a.view(np.uint64).copy()
    drop = np.uint64(52 - bits)
    half = np.uint64(1) << (drop - np.uint64(1))
    keep = ~((np.uint64(1) << drop) - np.uint64(1))
    finite = np.isfinite(a)
    u[finite] = (u[finite] + half) & keep
    return u.view(np.float64)


def _copy(src: h5py.Group, dst: h5py.Group, bits: int | None = None) -> None:
    """Copy a session tree; float datasets (but time) rounded to ``bits`` and compressed."""
    for key, value in src.attrs.items():
        dst.attrs[key] = value
    for name, item in src.items():
        if isinstance(item, h5py.Group):
            sub = MANTISSA_BITS.get(name, bits) if src.name == "/" else bits
            _copy(item, dst.create_group(name, track_order=True), sub)
            continue
        data = item[()]
        if isinstance(data, np.ndarray) and data.dtype == np.float64 and data.size > 64:
            if bits is not None and name != "time":
                data = round_mantissa(data, bits)
            ds = dst.create_dataset(
                name, data=data, compression="gzip", compression_opts=9, shuffle=True
            )
        else:
            ds = dst.create_dataset(name, data=data, dtype=item.dtype)
        for key, value in item.attrs.items():
            ds.attrs[key] = value


def make(name: str, out: Path, seed: int) -> Path:
    protocol, duration, date = EXAMPLES[name]
    optical = OpticalSystem(rate_hz=MARKER_HZ)
    session, truth = simulate(
        protocol,
        duration,
        seed,
        "typical",
        rate_hz=IMU_HZ,
        markers=True,
        optical=optical,
        rest_s=REST_S,
    )
    m = session.markers["optical"]
    # landmarks only during the standing pose (then taken off), as in an anatomical calibration
    standing = next(s for s in truth.steps if s["name"] == "standing")
    frame_time = truth.markers["frame_time"]
    off = (frame_time < standing["start_s"]) | (frame_time > standing["end_s"])
    landmark = np.array([kind == "landmark" for kind in truth.markers["kinds"]])
    positions = m.positions.copy()
    positions[np.ix_(off, landmark)] = np.nan
    residuals = None
    if m.residuals is not None:
        residuals = m.residuals.copy()
        residuals[np.ix_(off, landmark)] = np.nan
    session.markers["optical"] = dataclasses.replace(m, positions=positions, residuals=residuals)
    session.metadata["subject"] = dict(SUBJECT)
    session.metadata["session"] = {"date": date, "visit": "visit 1", "protocol": protocol}
    session.metadata["demo"] = f"bench/make_demo.py --seed {seed}"
    path = out / f"{name}.h5"
    with tempfile.TemporaryDirectory() as tmp:
        full = Path(tmp) / "full.h5"
        save_session(session, full)
        with h5py.File(full, "r") as src, h5py.File(path, "w", track_order=True) as dst:
            _copy(src, dst)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--out", default=str(Path(__file__).resolve().parents[1] / "motionlab" / "data" / "demo")
    )
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    total = 0
    for name in EXAMPLES:
        path = make(name, out, args.seed)
        size = path.stat().st_size
        total += size
        print(f"{path}  {size / 1e6:.2f} MB")
    print(f"total {total / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
