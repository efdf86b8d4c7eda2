"""motionlab from Python: the bundled knee demo, stage by stage, as a notebook would run it.

Usage::

    python examples/knee_from_python.py [OUTDIR]

Loads the simulated knee session shipped with the package (5 IMUs and optical markers), puts
the IMUs on one clock, fuses the sensors, calibrates them to the segments with the ``knee``
protocol, computes the joint angles and metrics, validates against the markers, and writes the
angles as an OpenSim ``.mot`` and the results as JSON into OUTDIR (default: a new temporary
folder). The session file itself is only read.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import motionlab as ml

DEMO = Path(ml.__file__).resolve().parent / "data" / "demo" / "knee.h5"


def main(outdir: Path) -> dict:
    session = ml.load_session(DEMO)  # the demo as ingest left it: sensors and markers
    print(f"{len(session.sensors)} sensors: {', '.join(session.sensors)}")

    ml.sync(session, "knee")  # the IMUs on one clock, as 'motionlab run' does first
    ml.fuse(session)  # 6-D fusion, the default of 'motionlab run'
    calibration = ml.calibrate(session, "knee")  # sensor-to-segment, from the protocol's poses
    angles = ml.angles(session)  # degrees, one column per angle
    ml.metrics(session)
    validation = ml.validate(session)  # against the session's own markers

    flexion = np.asarray(angles.data["knee_r_flexion_deg"])
    print(f"calibration ok: {calibration.ok}")
    print(f"right knee flexion: {np.nanmin(flexion):.1f} to {np.nanmax(flexion):.1f} deg")
    sync = validation.sync
    print(f"clock offset {sync.time_offset_s * 1e3:.1f} ms ({sync.grade})")
    for col in ("knee_r_flexion_deg", "knee_l_flexion_deg"):
        entry = validation.angles.columns[col]  # an AngleAgreement
        print(f"{col}: RMSE {entry.rmse_deg:.2f} deg, r {entry.r:.3f} against the markers")

    outdir.mkdir(parents=True, exist_ok=True)
    print(ml.export_session(session, "mot", outdir / "knee_angles.mot", force=True))
    print(ml.export_session(session, "json", outdir / "knee_results.json", force=True))
    return ml.results_json(session)


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="motionlab-"))
    main(out)
    print(f"wrote {out}")
