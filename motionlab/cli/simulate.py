"""``motionlab simulate``: a synthetic session with an exact truth, from a protocol file."""

from __future__ import annotations

from pathlib import Path

import click

from motionlab.atomic import check_output
from motionlab.errors import InputError
from motionlab.lock import session_lock
from motionlab.protocol import resolve_protocol_path
from motionlab.session import save_session
from motionlab.simulate import GAIT_VARIANTS, MOUNTINGS, save_truth, simulate, write_truth_csv
from motionlab.simulate.errors import PRESETS, SOFT_TISSUE
from motionlab.simulate.markers import write_c3d


@click.command("simulate")
@click.option("--protocol", "protocol", required=True, help="Protocol YAML file or packaged name.")
@click.option("--duration", type=float, default=60.0, show_default=True, help="Length (s).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("-o", "--output", required=True, help="Session file to write (HDF5).")
@click.option("--truth", "truth_path", help="Also write the truth file (HDF5).")
@click.option("--truth-csv", "truth_csv", help="Also write the truth as CSV tables into DIR.")
@click.option("--markers", "markers_path", help="Also write optical markers as C3D.")
@click.option("--session-markers", is_flag=True, help="Put the markers into the session too.")
@click.option("--preset", default="typical", show_default=True,
              help=f"Sensor errors: {', '.join(PRESETS)}.")  # fmt: skip
@click.option("--mounting", default="nominal", show_default=True,
              help="Sensor placement: nominal (the protocol's sensor_axes, within 30°), random "
                   "(any orientation, anywhere on the segment) or surface (anywhere on the "
                   "segment, flat on the skin, any turn).")  # fmt: skip
@click.option("--soft-tissue", "soft_tissue", default=None,
              help="Sensor motion on the segment: impacts (ringing after heel strikes), motion "
                   "(also following the segment's acceleration, and slipping with --preset "
                   "loose) or skin (motion plus the skin's shift with the joint angles and after "
                   "heel strikes). Default: the preset's (motion for loose, skin for skin, else "
                   "impacts).")  # fmt: skip
@click.option("--knee-model", "knee_model", type=click.Choice(["simple", "anatomical"]),
              default="simple", show_default=True,
              help="The knee: simple (flexion with couplings in proportion to it) or anatomical "
                   "(screw-home rotation and varus with flexion, varying from stride to stride: "
                   "not a hinge, as a real knee).")  # fmt: skip
@click.option("--gait", default=None,
              help="Gait variant of the walking tasks, with gait events and pelvis angles in the "
                   "truth: normal, asymmetric (right stance longer, unequal steps), slow (90 "
                   "steps/min) or slow_asymmetric.")  # fmt: skip
@click.option("--stride-cv", "stride_cv", type=click.FloatRange(0.0, 1 / 3, max_open=True),
              default=None,
              help="Stride-to-stride variation of the walking tasks' stride time, a fraction "
                   "(default 0.025: a healthy adult's 1-3 %, the real 16-IMU walker's 2.6 %; 0: "
                   "every stride alike, the metronome of versions before).")  # fmt: skip
@click.option("--gyr-sampling", "gyr_sampling", type=click.Choice(["point", "interval"]),
              default="point", show_default=True,
              help="Gyroscope samples: the rate at the stamp (point) or the mean rate over the "
                   "interval ending at the stamp (interval, as MEMS sensors give).")  # fmt: skip
@click.option("--height", type=float, default=1.75, show_default=True, help="Body height (m).")
@click.option("--rate", type=float, default=100.0, show_default=True, help="IMU rate (Hz).")
@click.option("--no-calibration", is_flag=True, help="Skip the protocol's calibration steps.")
@click.option("--force", is_flag=True, help="Replace existing outputs.")
def command(
    protocol: str,
    duration: float,
    seed: int,
    output: str,
    truth_path: str | None,
    truth_csv: str | None,
    markers_path: str | None,
    session_markers: bool,
    preset: str,
    mounting: str,
    soft_tissue: str | None,
    knee_model: str,
    gait: str | None,
    stride_cv: float | None,
    gyr_sampling: str,
    height: float,
    rate: float,
    no_calibration: bool,
    force: bool,
) -> None:
    """Simulate a recording of PROTOCOL: IMU signals, optical markers and the exact truth.

    The subject performs the protocol's calibration steps, then its tasks, for DURATION
    seconds; the same seed gives the same bytes. Presets: clean, typical, harsh (sensor errors)
    loose (typical sensors on a loose strap: soft tissue moving the sensor by a few degrees
    with the segment's acceleration, and a slow slip of a few degrees) and skin (typical sensors
    on skin that moves over the bone as on real walks). With --mounting random
    every sensor sits anywhere on its segment in any orientation; the truth holds the true
    mounting, the sensor's orientation over time and its motion on the segment (wobble).

    \b
    Example:
      motionlab simulate --protocol protocols/knee.yaml --duration 180 --seed 1 -o sim.h5 \\
          --truth truth.h5 --truth-csv truth/ --markers markers.c3d --preset typical
      motionlab simulate --protocol knee --duration 60 --no-calibration -o gait.h5
      motionlab simulate --protocol walk --duration 70 --seed 3 --mounting random \\
          --preset loose -o walk.h5 --truth truth.h5
      motionlab simulate --protocol walk --duration 74 --mounting random --preset skin \\
          --knee-model anatomical -o real_walk.h5 --truth truth.h5
      motionlab simulate --protocol walk --duration 600 --gait slow --stride-cv 0.05 -o var.h5
    """
    if preset not in PRESETS:
        raise InputError(
            f"unknown preset {preset!r}",
            where="--preset",
            remedy=f"use one of {', '.join(PRESETS)}",
        )
    choices = ((mounting, MOUNTINGS, "--mounting"),
               (soft_tissue or "impacts", SOFT_TISSUE, "--soft-tissue"))  # fmt: skip
    if gait is not None:
        choices += ((gait, GAIT_VARIANTS, "--gait"),)
    for value, allowed, option in choices:
        if value not in allowed:
            raise InputError(f"unknown value {value!r}", where=option,
                             remedy=f"use one of {', '.join(allowed)}")  # fmt: skip
    resolve_protocol_path(protocol)
    protocol_file = protocol if Path(protocol).is_file() else None
    outputs: list[str] = []
    for path in (output, truth_path, markers_path):
        if path:  # never over the protocol, nor one output over another
            check_output(path, force, inputs=[protocol_file, *outputs])
            outputs.append(path)
    if truth_csv and Path(truth_csv).exists() and not Path(truth_csv).is_dir():
        raise InputError("is not a folder", truth_csv, remedy="give a folder for the CSV tables")
    if stride_cv is not None:  # the variant's options with it (the plain walk's without one)
        gait_arg: str | dict | None = GAIT_VARIANTS[gait or "normal"] | {"stride_cv": stride_cv}
    else:
        gait_arg = gait
    session, truth = simulate(
        protocol,
        duration,
        seed,
        preset,
        height=height,
        rate_hz=rate,
        markers=bool(markers_path or session_markers),
        calibration=not no_calibration,
        mounting=mounting,
        soft_tissue=soft_tissue,
        knee_model=knee_model,
        gait=gait_arg,
        gyr_sampling=gyr_sampling,
        progress=lambda text: click.echo(text, err=True),  # 30 min of walking takes 45 s
    )
    optical = session.markers.get("optical")
    if optical is not None and not session_markers:
        del session.markers["optical"]
    with session_lock(output):  # one writer at a time (a stage command may be on it)
        save_session(session, output, force=force)
    written = [output]
    if truth_path:
        save_truth(truth, truth_path, force=force)
        written.append(truth_path)
    if truth_csv:
        written += [str(p) for p in write_truth_csv(truth, truth_csv, force=force)]
    if markers_path:
        write_c3d(optical, markers_path, force=force)
        written.append(markers_path)
    n = sum(s.n_samples for s in session.sensors.values())
    click.echo(
        f"simulated {len(session.sensors)} sensors, {n} samples, {len(truth.steps)} steps "
        f"({duration:g} s, seed {seed}, preset {preset}) -> {', '.join(written)}"
    )
