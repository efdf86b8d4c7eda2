"""Packet-loss gaps cut into the real 16-IMU walk: the rotation each bridge misses.

The walk of ``../shared/datasets/human/qmt_full_body`` (five lower-body Xsens sensors, 100 Hz,
no packet lost) has test gaps of 3, 7 and 14 samples cut at seeded random places of its walking
(55-100 s: straight walking, a 180° turn, the start of another); the cut samples are the truth.
Per sensor and gap length, the rotation (deg, the norm of the missed rate summed over the gap)
that each bridge of :mod:`motionlab.fusion.timegrid` misses, median / 90th percentile / RMS:

- ``line`` and ``cubic``: the straight line and the cubic Hermite through the samples either side;
- ``pattern``: the recorded stretch within ``PATTERN_SEARCH_S`` whose surroundings
  (``PATTERN_CONTEXT_S`` either side) match the gap's best, shifted to meet the gap's ends;
- ``chosen``: what the fusion does (:func:`~motionlab.fusion.timegrid.gap_noise` with
  ``choose``: whichever of the three its own test gaps around the gap say misses least), and
  how often it took the pattern.

``--trunk``: the same on three real seated trunk trials of ``../shared/datasets/trunk`` (x-IMU3
``Back`` and ``Chest``, 50 Hz, each sensor's longest stretch without a lost packet): movement
that does not repeat, where the pattern should be taken seldom and cost nothing.

Usage::

    python bench/gap_bridges.py [--data ../shared] [--tests 200] [--trunk]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_people import qmt_session  # noqa: E402

from motionlab.fusion.timegrid import (  # noqa: E402
    _pattern,
    _pattern_sources,
    gap_grid,
    gap_noise,
    with_patterns,
)

LENGTHS = (3, 7, 14)  # samples cut
WALK_S = (55.0, 100.0)  # the real recording's walking (s from its start)
TRUNK_TRIALS = ("Aag/pivot_hs", "Aag/trunkmovement_ls", "Danique/trunkmovement_hs")


def missed(gyr: np.ndarray, rate: float, a: int, m: int) -> dict[str, float]:
    """Rotation (deg) each bridge misses on the gap of ``m`` samples after sample ``a``: the
    recording with those samples dropped, put on its grid and bridged as the fusion does
    (:class:`~motionlab.fusion.timegrid.GapGrid`, :func:`gap_noise`, :func:`with_patterns`)."""
    t = np.arange(len(gyr)) / rate
    keep = np.ones(len(gyr), bool)
    keep[a + 1 : a + m + 1] = False
    grid = gap_grid(t[keep], rate)
    recorded = np.zeros(len(grid.time), bool)
    recorded[grid.index] = True
    noise = gap_noise(grid.time, grid.vectors(gyr[keep]), recorded, rate, choose=True)
    csum = np.r_[0, np.cumsum(recorded)]
    source = _pattern_sources(gyr, np.array([a]), m, csum, rate)[0]
    bridges = {
        "line": grid.vectors(gyr[keep], np.ones(len(grid.time), bool)),
        "cubic": grid.vectors(gyr[keep], np.zeros(len(grid.time), bool)),
        "chosen": with_patterns(grid.vectors(gyr[keep], noise.linear), noise),
    }
    true = gyr[~keep].sum(0) / rate
    out = {k: np.linalg.norm(true - b[~recorded].sum(0) / rate) for k, b in bridges.items()}
    out["pattern"] = np.linalg.norm(true - _pattern(gyr, a, m, source).sum(0) / rate) if (
        source >= 0) else np.nan  # fmt: skip
    out = {k: float(np.degrees(v)) for k, v in out.items()}
    return out | {"took pattern": float(len(noise.patterns) > 0)}


def table(streams: dict[str, tuple[np.ndarray, float, tuple[float, float]]], tests: int) -> None:
    """Print one row per sensor and gap length."""
    print("| sensor | gap | line | cubic | pattern | chosen | pattern taken |")
    print("|---|---:|---|---|---|---|---:|")
    rng = np.random.default_rng(0)
    for label, (gyr, rate, (lo_s, hi_s)) in streams.items():
        for m in LENGTHS:
            starts = rng.integers(int(lo_s * rate), int(hi_s * rate) - m - 2, tests)
            rows = [missed(gyr, rate, int(a), m) for a in starts]
            cells = []
            for key in ("line", "cubic", "pattern", "chosen"):
                v = np.array([r[key] for r in rows])
                v = v[np.isfinite(v)]
                rms = np.sqrt(np.mean(v**2))
                cells.append(f"{np.median(v):.1f} / {np.percentile(v, 90):.1f} / {rms:.1f}")
            took = np.mean([r["took pattern"] for r in rows])
            print(f"| {label} | {m} ({m / rate * 1000:.0f} ms) | " + " | ".join(cells)
                  + f" | {took:.0%} |")  # fmt: skip


def trunk_streams(folder: Path) -> dict[str, tuple[np.ndarray, float, tuple[float, float]]]:
    """``Back`` and ``Chest`` of :data:`TRUNK_TRIALS`, each its longest stretch without a gap
    (from 1 s in to 1 s before its end), as :func:`table` takes them."""
    from motionlab.ingest import ingest

    if not folder.exists():
        sys.exit(f"{folder}: not found; give --data, the folder holding datasets/trunk")
    sensor_map = Path(__file__).resolve().parents[1] / "protocols/examples/trunk_map.yaml"
    print("Real seated trunk trials (x-IMU3 Back and Chest, 50 Hz)\n")
    streams = {}
    for trial in TRUNK_TRIALS:
        session = ingest([folder / trial / "imu"], sensor_map)
        for label in ("Back", "Chest"):
            t = np.asarray(session.sensors[label].time)
            rate = 1.0 / float(np.median(np.diff(t)))
            edges = np.r_[0, np.flatnonzero(np.diff(t) > 1.5 / rate) + 1, len(t)]
            i = int(np.argmax(np.diff(edges)))
            lo, hi = int(edges[i]), int(edges[i + 1])
            gyr = np.asarray(session.sensors[label].gyr, float)[lo:hi]
            streams[f"{trial} {label}"] = (gyr, rate, (1.0, (hi - lo) / rate - 1.0))
    return streams


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=Path("../shared"))
    ap.add_argument("--tests", type=int, default=200)
    ap.add_argument("--trunk", action="store_true", help="the seated trunk trials instead")
    args = ap.parse_args()
    print("Rotation (deg) missed per test gap, median / 90th percentile / RMS\n")
    if args.trunk:
        table(trunk_streams(args.data / "datasets" / "trunk"), args.tests // 2)
        return
    folder = args.data / "datasets" / "human" / "qmt_full_body"
    if not folder.exists():
        sys.exit(f"{folder}: not found; give --data, the folder holding datasets/human")
    session, _ = qmt_session(folder, "walk")
    streams = {}
    for label, s in session.sensors.items():
        rate = 1.0 / float(np.median(np.diff(s.time)))
        streams[label] = (np.asarray(s.gyr, float), rate, WALK_S)
    print("Real 16-IMU walk (five lower-body sensors, 100 Hz, 55-100 s)\n")
    table(streams, args.tests)


if __name__ == "__main__":
    main()
