"""Library arguments → command-line flags, for the error messages.

The library's :class:`~motionlab.errors.InputError` names the function argument at fault
(``argument="force"``) and spells it as Python does in its text (``pass force=True to replace
it``, ``rate=500 Hz is ...``, where ``argument rate``). The CLI's error handler rewrites those
spellings into the flag of :data:`FLAGS` (``pass --force to replace it``, ``--rate 500 Hz is
...``, where ``--rate``), so the library never mentions a flag and the user always reads one.
"""

from __future__ import annotations

import dataclasses

from motionlab.errors import InputError
from motionlab.pipeline import RUN_OPTIONS, PipelineOptions


def _run_flags() -> tuple[dict[str, str], dict[str, str]]:
    """The flags of the run options (:data:`motionlab.pipeline.RUN_OPTIONS`): a boolean that
    is off by default is set by its positive flag (``--magnetometer``), one that is on by
    default by its negative flag (``--no-clock-sync``, ``--quiet``)."""
    flags, negative = {}, {}
    for f in dataclasses.fields(PipelineOptions):
        option = RUN_OPTIONS[f.name]
        if option.kind == "bool":
            on, off = option.flag.split("/")
            if f.default:
                negative[f.name] = off
            else:
                flags[f.name] = on
        elif option.kind == "off":
            negative[f.name] = option.flag
        else:
            flags[f.name] = option.flag
    return flags, negative


_RUN_FLAGS, _RUN_NEGATIVE = _run_flags()

#: library argument: the flag that sets it (``name=True`` becomes the flag alone); the run
#: options' from their table
FLAGS = _RUN_FLAGS | {
    "angle_map": "--angle-map",
    "duration": "--duration",
    "gait": "--gait",
    "gap_max": "--gap-max",
    "gyr_sampling": "--gyr-sampling",
    "height": "--height",
    "kinds": "--kind",
    "knee_model": "--knee-model",
    "marker_map": "--markers",
    "method": "--method",
    "mode": "--mode",
    "mounting": "--mounting",
    "outdir": "-o",
    "preset": "--preset",
    "rate": "--rate",
    "rate_hz": "--rate",
    "reference_kind": "--reference-kind",
    "retry": "--retry",
    "scheduler": "--scheduler",
    "sensors": "--sensor",
    "soft_tissue": "--soft-tissue",
    "workers": "--workers",
}
#: ``name=False`` of a boolean argument whose flag is a negative one
NEGATIVE = _RUN_NEGATIVE | {
    "calibrated": "--no-calibration",
    "clock": "--no-sync",
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
