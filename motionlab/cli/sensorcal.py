"""``motionlab sensorcal``: gyroscope bias, accelerometer and magnetometer corrections, noise."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from motionlab.atomic import refuse_folder_holding_inputs
from motionlab.cli.paths import INPUT_FILE
from motionlab.errors import InputError
from motionlab.io import read_any
from motionlab.sensorcal import calfile, stage
from motionlab.session import SensorStream, is_session_file, load_session
from motionlab.units import STANDARD_GRAVITY

_DEG = 180.0 / np.pi


def load_streams(path: str | Path) -> dict[str, SensorStream]:
    """The inertial sensors of a session file or of any vendor file ``read_any`` knows."""
    path = Path(path)
    if path.is_file() and is_session_file(path):
        return load_session(path).sensors
    return {s.label: s for s in read_any(path).sensors}


def _vec(v: np.ndarray, fmt: str = "{:+.4f}") -> str:
    return "[" + " ".join(fmt.format(x) for x in v) + "]"


def _describe(r: stage.KindResult) -> list[str]:
    """Lines for people (degrees, with units)."""
    f = r.fit
    if r.kind == "gyro":
        return [
            f"gyro      bias {_vec(f.bias * _DEG)} deg/s ± {_vec(f.std_error * _DEG)}",
            f"          rest {f.rest_s:.1f} s in {len(f.windows)} window(s), window spread "
            f"{_vec(f.spread * _DEG)} deg/s",
        ]
    if r.kind in ("acc", "mag"):
        unit = "m/s^2" if r.kind == "acc" else "uT"
        lines = [
            f"{r.kind:<9} offset {_vec(f.offset, '{:+.3f}')} {unit}  "
            f"field norm {f.norm:.3f} {unit}",
            f"          residual RMS {f.residual_rms:.4f} {unit}  coverage {f.coverage:.0%}  "
            f"matrix diag {_vec(np.diag(f.matrix))}",
        ]
        if r.kind == "mag" and not 25.0 <= f.norm <= 65.0:
            lines.append("          warning: field norm outside the Earth's 25–65 uT — disturbed?")
        return lines
    if r.kind == "multipos":
        off = f.misalignment[~np.eye(3, dtype=bool)]
        return [
            f"multipos  {f.method}, {f.n_poses} poses: bias {_vec(f.bias)} m/s^2  "
            f"scale {_vec(f.scale, '{:.5f}')}",
            f"          largest misalignment {np.abs(off).max() * _DEG:.3f} deg  "
            f"residual RMS {f.residual_rms:.4f} m/s^2",
        ]
    lines = []
    for ch, res in r.noise.items():
        if ch == "gyr":
            scale = (_DEG * 60.0, _DEG * 3600.0, _DEG * 3600.0 * 60.0)
            units = ("deg/sqrt(h)", "deg/h", "deg/h/sqrt(h)")
        else:
            scale = (60.0, 1e6 / STANDARD_GRAVITY, 3600.0 * 60.0)
            units = ("m/s/sqrt(h)", "ug", "m/s/h/sqrt(h)")
        lines.append(
            f"allan {ch}  white {_vec(res.white * scale[0], '{:.4g}')} {units[0]}  "
            f"bias instability {_vec(res.bias_instability * scale[1], '{:.4g}')} {units[1]}"
            + ("" if res.bias_instability_flat.all() else " (≤, from the minimum)")
        )
        lines.append(
            f"          rate random walk {_vec(res.random_walk * scale[2], '{:.4g}')} {units[2]}"
            f"  ({res.duration_s:.0f} s recorded)"
        )
    return lines


@click.command("sensorcal")
@click.argument("source", type=INPUT_FILE)
@click.option("--sensor", "labels", multiple=True, help="Sensor label (repeat; default: all).")
@click.option(
    "--kind",
    "kinds",
    multiple=True,
    type=click.Choice(stage.KINDS),
    help="What to calibrate (repeat; default: every kind the data support, except allan).",
)
@click.option(
    "-o", "--output", "caldir", required=True,
    help="Calibration folder (not one that is or holds the recording).",
)  # fmt: skip
@click.option("--force", is_flag=True, help="Replace calibrations already in the files.")
@click.option(
    "--gravity", type=float, default=STANDARD_GRAVITY, show_default=True, help="Local g, m/s²."
)
@click.option("--field-norm", type=float, help="Local geomagnetic field, µT (default: measured).")
def command(
    source: str,
    labels: tuple[str, ...],
    kinds: tuple[str, ...],
    caldir: str,
    force: bool,
    gravity: float,
    field_norm: float | None,
) -> None:
    """Calibrate each sensor of SOURCE (a session or a vendor file) and file it by serial.

    Writes CALDIR/<serial>.yaml (gyroscope bias, accelerometer and magnetometer offset and
    matrix, Allan noise figures) and prints the quality figures. `motionlab fuse
    --calibration CALDIR` applies it.

    \b
    Example:
      motionlab sensorcal still_then_turns.txt -o calibration
      motionlab sensorcal session.h5 --sensor shank_r --kind mag -o calibration --force
      motionlab sensorcal one_hour_still.txt --kind allan -o calibration
    """
    out = Path(caldir)
    if out.exists() and not out.is_dir():
        raise InputError("is a file, expected a folder", out, remedy="give a folder for -o")
    if not out.exists() and not out.parent.is_dir():
        raise InputError("folder does not exist", out.parent, remedy="create it first")
    refuse_folder_holding_inputs(out, [source])
    given = (("--gravity", gravity, "9.81"), ("--field-norm", field_norm, "50"))
    for flag, value, example in given:
        if value is not None and not 0 < value < float("inf"):  # nan, inf, 0, negative
            raise InputError(
                f"is {value:g}, not a positive number", where=flag, remedy=f"e.g. {flag} {example}"
            )
    streams = load_streams(source)
    unknown = [lab for lab in labels if lab not in streams]
    if unknown:
        raise InputError(
            f"no sensor {', '.join(unknown)}",
            source,
            remedy=f"sensors are {', '.join(streams) or 'none'}",
        )
    if not streams:
        raise InputError("holds no inertial sensor", source)
    pending = []
    for label in labels or streams:
        s = streams[label]
        results, skipped = stage.calibrate_sensor(s, kinds, gravity, field_norm)
        key = calfile.calibration_key(s)
        existing = calfile.find_calibration(out, key) if out.is_dir() else None
        target = calfile.calibration_path(out, key)
        cal = stage.merge(existing, s, results, source, force, target)
        pending.append((label, cal, results, skipped))
    for label, cal, results, skipped in pending:
        path = calfile.save_calibration(cal, out, force=True)
        kind = "serial" if streams[label].serial else "file's label"
        click.echo(f"{label} ({kind} {cal.serial}) -> {path}")
        for r in results:
            for line in _describe(r):
                click.echo(f"  {line}")
        for kind, why in skipped.items():
            click.echo(f"  {kind:<9} skipped: {why}")
