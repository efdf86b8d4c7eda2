"""OpenSense reads motionlab's exported ``.sto`` and runs IMU inverse kinematics on it.

Needs OpenSim's Python package (``pip install opensim``; optional, not a motionlab
dependency): without it the bench says so and exits 0.

A right-knee session (the small test protocol: thigh and shank IMUs, 40 s with 20 s of gait)
is simulated with the ``clean`` preset and analysed by ``motionlab run --magnetometer`` (9-D,
so both IMUs share one heading, as OpenSense assumes); ``motionlab export --to sto`` writes the
orientations. A two-body OpenSim model is built in code (ground → femur_r by a free joint,
femur_r → tibia_r by a pin joint about z, coordinate ``knee_angle_r``, negative in flexion as
in gait2392); ``IMUPlacer`` places ``femur_r_imu`` and ``tibia_r_imu`` from the first
frame (the subject stands, as the model's default pose) with OpenSense's default
``sensor_to_opensim_rotations = -π/2 0 0``; ``IMUInverseKinematicsTool`` solves the whole
file. Reported: OpenSense's ``knee_angle_r`` against motionlab's ``knee_r_flexion_deg`` and
against the simulator's truth (RMS difference, r).

Usage::

    python bench/opensense.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))


def _model(path: Path, osim) -> None:
    """Ground → femur_r (free) → tibia_r (pin about z: knee_angle_r)."""
    model = osim.Model()
    model.setName("knee_r_opensense_bench")
    femur = osim.Body("femur_r", 9.3, osim.Vec3(0, -0.17, 0), osim.Inertia(0.1, 0.03, 0.1))
    tibia = osim.Body("tibia_r", 3.7, osim.Vec3(0, -0.19, 0), osim.Inertia(0.05, 0.005, 0.05))
    hip = osim.FreeJoint("ground_femur_r", model.getGround(), osim.Vec3(0, 0.9, 0),
                         osim.Vec3(0), femur, osim.Vec3(0), osim.Vec3(0))  # fmt: skip
    knee = osim.PinJoint("knee_r", femur, osim.Vec3(0, -0.41, 0), osim.Vec3(0),
                         tibia, osim.Vec3(0), osim.Vec3(0))  # fmt: skip
    knee.updCoordinate().setName("knee_angle_r")
    # a pin turns about +z (right): the shank's -y swings forward, i.e. flexion is negative
    # here (as gait2392's knee_angle_r; Rajagopal's custom knee flips it): read as −flexion
    knee.updCoordinate().setRangeMin(-math.radians(150))
    knee.updCoordinate().setRangeMax(math.radians(10))
    for body in (femur, tibia):
        model.addBody(body)
    model.addJoint(hip)
    model.addJoint(knee)
    model.finalizeConnections()
    model.printToXML(str(path))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, help="keep the files in this folder")
    args = ap.parse_args(argv)
    try:
        import opensim as osim
    except ImportError:
        print("OpenSim's Python package is not installed (pip install opensim): skipped")
        return
    from click.testing import CliRunner
    from test_pipeline import PROTOCOL

    from motionlab.cli import main as cli
    from motionlab.io.opensim import read_mot
    from motionlab.session import load_session, save_session
    from motionlab.simulate import simulate

    root = Path(tempfile.mkdtemp(prefix="opensense-")) if args.keep is None else args.keep
    root.mkdir(parents=True, exist_ok=True)
    os.chdir(root)  # OpenSim writes its opensim.log into the working folder
    (root / "knee_small.yaml").write_text(yaml.safe_dump(PROTOCOL))
    session, truth = simulate(root / "knee_small.yaml", 40.0, 5, "clean", rate_hz=100.0,
                              mounting_max_deg=10.0, gyr_sampling="interval")  # fmt: skip
    save_session(session, root / "sim.h5", force=True)
    runner = CliRunner()
    for argv_ in (
        ["run", "--protocol", str(root / "knee_small.yaml"), str(root / "sim.h5"), "-o",
         str(root / "out"), "--magnetometer", "--no-clock-sync", "--quiet", "--force"],
        ["export", str(root / "out" / "session.h5"), "--to", "sto", "-o",
         str(root / "orientations.sto"), "--force"],
    ):  # fmt: skip
        res = runner.invoke(cli, argv_)
        if res.exit_code != 0:
            sys.exit(f"motionlab {argv_[0]} failed: {res.output}")
    _model(root / "model.osim", osim)
    rotations = osim.Vec3(-math.pi / 2, 0, 0)
    placer = osim.IMUPlacer()
    placer.set_model_file(str(root / "model.osim"))
    placer.set_orientation_file_for_calibration(str(root / "orientations.sto"))
    placer.set_sensor_to_opensim_rotations(rotations)
    placer.run(False)
    placer.getCalibratedModel().printToXML(str(root / "calibrated.osim"))
    ik = osim.IMUInverseKinematicsTool()
    ik.set_model_file(str(root / "calibrated.osim"))
    ik.set_orientations_file(str(root / "orientations.sto"))
    ik.set_sensor_to_opensim_rotations(rotations)
    ik.set_results_directory(str(root / "ik"))
    sto_time = load_session(root / "out" / "session.h5").results.angles.time
    ik.set_time_range(0, float(sto_time[0]))  # the tool's default range is not the whole file
    ik.set_time_range(1, float(sto_time[-1]))
    ik.run(False)
    (mot,) = list((root / "ik").glob("ik_*.mot"))
    header, table = read_mot(mot)
    ses = load_session(root / "out" / "session.h5")
    t = np.asarray(ses.results.angles.time)
    ours = np.asarray(ses.results.angles.data["knee_r_flexion_deg"])
    theirs = np.interp(t, table["time"].to_numpy(), table["knee_angle_r"].to_numpy())
    if header.get("inDegrees", "no") != "yes":
        theirs = np.degrees(theirs)
    theirs = -theirs  # the pin joint's +z turn is extension (see _model)
    true = np.interp(t, truth.time, truth.joint_angles["knee_r_flexion_deg"])

    def compare(a, b):
        ok = np.isfinite(a) & np.isfinite(b)
        return float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2))), float(np.corrcoef(a[ok], b[ok])[0, 1])

    print(f"OpenSim {osim.GetVersion()}: IMUPlacer + IMUInverseKinematicsTool on {mot.name} "
          f"({len(table)} frames)\n")  # fmt: skip
    print("| knee flexion | RMS difference (°) | r |")
    print("|---|---:|---:|")
    for name, a, b in (("OpenSense vs motionlab", theirs, ours), ("OpenSense vs truth", theirs,
                       true), ("motionlab vs truth", ours, true)):  # fmt: skip
        rms, r = compare(a, b)
        print(f"| {name} | {rms:.2f} | {r:.4f} |")
    if args.keep is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
