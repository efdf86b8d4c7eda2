"""The gyroscope's unit against the accelerometer's tilt (``qc.gyr_scale``) on every real recording.

For each real sensor with an accelerometer and a gyroscope, the ingest's check
(``qc.check_stream``, after the clock repair, as ``motionlab ingest`` runs it) on the data as
read, then on the same data with the gyroscope multiplied by 180/π (a °/s gyroscope read as
rad/s) and by π/180 (a rad/s gyroscope read as °/s). Per row: the best scale (1 for the unit as
read, 0.0175 = π/180 for °/s read as rad/s, 57.3 for the reverse), how many times better
each wrong-unit hypothesis explains the tilt than the unit as read (``deg_fit``, ``rad_fit``),
the gravity turn the accelerometer saw over the windows used, and the verdict:
``refused`` (≥ ``qc.SCALE_REFUSE``, or the turn budget; ``motionlab ingest`` exits 2),
``warning`` (≥ ``qc.SCALE_DOUBT``), ``warn unchecked`` (a gyroscope read as °/s that the
recording cannot tell from rad/s: ``qc.gyr_unit_unchecked``, a warning), ``pass``, or ``no
evidence`` (too few slow windows). The ÷57.3 case is read as °/s (rad/s values under a °/s
header), the ×57.3 case as rad/s; as read, each stream keeps the unit its reader gave.

Recordings (README of ``../shared``): ``datasets/broad`` (8 BROAD trials), ``datasets/human``
(the qmt full-body .mat, 16 sensors; the imt DOT csv files), ``datasets/trunk`` (x-IMU3
folders, every device), ``datasets/ring`` (both files, with the shipped ring map), and the
vendor files of ``formats/`` that hold both channels.

Usage::

    python3 bench/gyr_units.py [--data ../shared] [--axes] [--simulated] [--cut SECONDS]

``--axes``: the accelerometer's columns permuted (yzx, yxz) or one flipped, the gyroscope as read
(a wrong column map's axes are not a unit). ``--simulated``: every shipped protocol through the
simulator instead of ../shared. ``--cut 3``: every recording cut into 3-s excerpts (at most 60
per sensor), the verdicts counted per case (the rows not printed): what a short file gets.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import scipy.io as sio
import yaml

from motionlab import qc, timebase
from motionlab.errors import InputError
from motionlab.io import read_any
from motionlab.session import SensorStream

ROOT = Path(__file__).resolve().parents[1]
SIM_PROTOCOLS = ("knee", "walk", "elbow", "arm", "lumbar", "lumbar_seated", "upper_body_children")
THREE_MINUTES = 18000  # samples: 3 minutes at 100 Hz, the speed's yardstick
RING_MAP = ROOT / "motionlab" / "protocols" / "examples" / "ring_map.yaml"


def recordings(shared: Path) -> Iterator[tuple[str, SensorStream]]:
    """``(recording, stream)`` for every real sensor with an accelerometer and a gyroscope."""
    ring = yaml.safe_load(RING_MAP.read_text())["reader"]
    paths: list[tuple[Path, dict | None]] = []
    paths += [(f, None) for f in sorted((shared / "datasets/broad").glob("*.hdf5"))]
    paths += [(f, None) for f in sorted((shared / "datasets/human/imt_dot").glob("*/*.csv"))]
    paths += [(d, None) for d in sorted((shared / "datasets/trunk").glob("*/*/imu"))]
    paths += [(f, ring) for f in sorted((shared / "datasets/ring/trial1").glob("imu_*.csv"))]
    paths += [(f, None) for f in sorted((shared / "formats").glob("*/*.*"))
              if f.suffix.lower() in (".txt", ".csv")]  # fmt: skip
    mat = shared / "datasets/human/qmt_full_body/full_body_example_data.mat"
    m = sio.loadmat(mat, squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float)
    for name in sorted(k for k in m if not k.startswith("_") and k != "t"):
        d = m[name]
        yield (
            "human/qmt_full_body",
            SensorStream(
                label=name,
                time=t - t[0],
                acc=np.asarray(d.acc, float),
                gyr=np.asarray(d.gyr, float),
            ),
        )
    for path, options in paths:
        try:
            rec = read_any(path, options)
        except InputError:
            continue  # not a recording of sensors (an .sto, a licence)
        name = str(path.relative_to(shared)).removeprefix("datasets/").removesuffix("/imu")
        for s in rec.sensors:
            if s.acc is not None and s.gyr is not None and len(s.time) > 10:
                yield name, s


def simulated() -> Iterator[tuple[str, SensorStream]]:
    """Every shipped protocol simulated (``motionlab simulate``): presets ``typical`` at 100 Hz
    (nominal mounting) and ``harsh`` at 50 Hz (random mounting), 170 s, seed 1."""
    from motionlab.simulate import simulate

    for protocol in SIM_PROTOCOLS:
        for preset, rate, mounting in (("typical", 100.0, "nominal"), ("harsh", 50.0, "random")):
            session, _ = simulate(protocol, duration=170.0, seed=1, preset=preset,
                                  rate_hz=rate, mounting=mounting)  # fmt: skip
            for s in session.sensors.values():
                yield f"simulated {protocol} {preset} {rate:g} Hz", s


def verdict(stream: SensorStream) -> tuple[dict | None, str]:
    """The ingest's scale check of ``stream`` (its clock repaired) and its verdict."""
    found = qc.check_stream(stream, 0.1)
    flags, scale = found["flags"], found.get("gyr_scale")
    if flags.get("gyr_unit_unchecked"):
        return scale, "warn unchecked"
    if scale is None:
        return None, "no evidence"
    finding = qc.gyr_unit_finding(scale)
    if flags["gyr_unit_mismatch"]:
        return scale, f"refused {finding}"
    return scale, f"warn {finding}" if flags["gyr_unit_doubt"] else "pass"


def excerpts(stream: SensorStream, seconds: float, most: int = 60) -> Iterator[SensorStream]:
    """``stream`` cut into consecutive ``seconds``-long pieces (at most ``most``)."""
    t = stream.time - stream.time[0]
    for i in range(min(int(t[-1] // seconds), most)):
        keep = (t >= i * seconds) & (t < (i + 1) * seconds)
        if keep.sum() >= 10:
            yield dataclasses.replace(stream, time=stream.time[keep], acc=stream.acc[keep],
                                      gyr=stream.gyr[keep], mag=None, quat=None,
                                      extra={})  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared", help="the shared folder")
    ap.add_argument("--axes", action="store_true",
                    help="instead: the accelerometer's axes permuted or flipped (not the "
                         "gyroscope's): what a wrong column map gives")  # fmt: skip
    ap.add_argument("--simulated", action="store_true",
                    help="instead of ../shared: every shipped protocol simulated")  # fmt: skip
    ap.add_argument("--cut", type=float, default=None, metavar="SECONDS",
                    help="cut each recording into excerpts this long; print the counts "
                         "only")  # fmt: skip
    args = ap.parse_args()
    if not args.simulated and not (args.data / "datasets").is_dir():
        sys.exit(f"{args.data}/datasets not found: give --data DIR")
    cases = {"as read": 1.0, "×57.3": 180 / math.pi, "÷57.3": math.pi / 180}
    if args.axes:
        cases = {"acc yzx": 1.0, "acc yxz": 1.0, "acc -x": 1.0}
    head = f"{'recording':<44} {'sensor':<16}"
    columns = f"{'scale':>8} {'free':>7} {'deg_fit':>8} {'rad_fit':>8} {'miss°':>6} {'tilt°':>6}"
    if not args.cut:
        print(head + "".join(f" | {c:<8} {columns} {'verdict':<13}" for c in cases))
    counts: dict[str, dict[str, int]] = {c: {} for c in cases}
    slowest = 0.0
    read = {"×57.3": "rad/s", "÷57.3": "deg/s"}
    for name, raw in simulated() if args.simulated else recordings(args.data):
        stream, _ = timebase.repair_clock(raw)
        if args.cut:
            for piece in excerpts(stream, args.cut):
                for case, factor in cases.items():
                    unit = read.get(case, piece.source_units.get("gyr", "rad/s"))
                    units = {**piece.source_units, "gyr": unit}
                    v = verdict(dataclasses.replace(piece, gyr=piece.gyr * factor,
                                                    source_units=units))[1]  # fmt: skip
                    counts[case][v] = counts[case].get(v, 0) + 1
            continue
        row = f"{name[:44]:<44} {raw.label[:16]:<16}"
        for case, factor in cases.items():
            acc = {"acc yzx": stream.acc[:, [1, 2, 0]], "acc yxz": stream.acc[:, [1, 0, 2]],
                   "acc -x": stream.acc * [-1, 1, 1]}.get(case, stream.acc)  # fmt: skip
            units = {**stream.source_units, "gyr": read[case]} if case in read else None
            changed = dataclasses.replace(stream, gyr=stream.gyr * factor, acc=acc)
            if units:
                changed = dataclasses.replace(changed, source_units=units)
            s, v = verdict(changed)
            counts[case][v] = counts[case].get(v, 0) + 1
            if s is None:
                row += f" | {case:<8} {'':>8} {'':>7} {'':>8} {'':>8} {'':>6} {'':>6} {v:<13}"
            else:
                miss = s["miss_deg"]["as_read"]
                row += (f" | {case:<8} {s['scale']:8.4g} {s['axes_free_scale']:7.3g} "
                        f"{s['deg_s_fit']:8.3g} {s['rad_s_fit']:8.3g} "
                        f"{miss:6.1f} {s['tilt_deg']:6.0f} {v:<13}")  # fmt: skip
        print(row, flush=True)
        t0 = time.perf_counter()
        qc.gyr_scale(stream.time, stream.acc, stream.gyr)
        if len(stream.time) >= 10000:  # shorter ones are their fixed costs, not a rate
            slowest = max(slowest, (time.perf_counter() - t0) * THREE_MINUTES / len(stream.time))
    for case, c in counts.items():
        print(f"{case}: " + ", ".join(f"{v} {n}" for v, n in sorted(c.items())))
    if args.cut:
        return
    print(
        f"qc.gyr_scale on the recordings of ≥ 10000 samples: at most {1e3 * slowest:.0f} ms per "
        "18000 samples (3 min at 100 Hz)"
    )


if __name__ == "__main__":
    main()
