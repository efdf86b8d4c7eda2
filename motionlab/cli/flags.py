"""Library arguments → command-line flags, for the error messages.

The library's :class:`~motionlab.errors.InputError` names the function argument at fault
(``argument="force"``) and spells it as Python does in its text (``pass force=True to replace
it``, ``rate=500 Hz is ...``, where ``argument rate``). The CLI's error handler rewrites those
spellings into the flag of :data:`FLAGS` (``pass --force to replace it``, ``--rate 500 Hz is
...``, where ``--rate``), so the library never mentions a flag and the user always reads one.
"""

from __future__ import annotations

from motionlab.errors import InputError

#: library argument: the flag that sets it (``name=True`` becomes the flag alone)
FLAGS = {
    "angle_map": "--angle-map",
    "calibration_dir": "--calibration",
    "duration": "--duration",
    "estimator": "--filter",
    "force": "--force",
    "gait": "--gait",
    "gap_max": "--gap-max",
    "gyr_sampling": "--gyr-sampling",
    "height": "--height",
    "kinds": "--kind",
    "knee_model": "--knee-model",
    "magnetometer": "--magnetometer",
    "map_path": "--map",
    "marker_map": "--markers",
    "method": "--method",
    "mode": "--mode",
    "mounting": "--mounting",
    "orientation": "--orientation",
    "outdir": "-o",
    "preset": "--preset",
    "protocol": "--protocol",
    "rate": "--rate",
    "rate_hz": "--rate",
    "reference": "--reference",
    "reference_kind": "--reference-kind",
    "retry": "--retry",
    "scheduler": "--scheduler",
    "soft_tissue": "--soft-tissue",
    "workers": "--workers",
}
#: ``name=False`` of a boolean argument whose flag is a negative one
NEGATIVE = {
    "calibrated": "--no-calibration",
    "clock": "--no-sync",
    "clock_sync": "--no-clock-sync",
}


def _flag(name: str, value: str | None) -> str:
    """The flag of argument ``name`` given ``value`` (``None``: the argument itself)."""
    if value == "False" and name in NEGATIVE:
        return NEGATIVE[name]
    flag = FLAGS.get(name, NEGATIVE.get(name, f"--{name.replace('_', '-')}"))
    if value in (None, "", "True", "False"):
        return flag.split("/")[0]
    return f"{flag.split('/')[0]} {value.strip(chr(39))}"


def to_flags(text: str | None, arguments: tuple[str, ...]) -> str | None:
    """``text`` with each of ``arguments`` spelled as its flag: ``name=value`` →
    ``--flag value``, ``name=True`` → ``--flag``, ``argument name`` → ``--flag``."""
    if not text:
        return text
    return InputError(text, argument=arguments).respelled(_flag).message


def cli_error(exc: InputError) -> InputError:
    """The error as the CLI shows it: its arguments spelled as flags (:func:`to_flags`)."""
    return exc.respelled(_flag)
