"""motionlab: clinical motion analysis with wearable inertial sensors.

Conventions (fixed, see docs/architecture.md): SI units inside the code, Hamilton quaternions
scalar first ``[w, x, y, z]`` mapping sensor-frame vectors into the ENU earth frame, ISB segment
frames, first array dimension is time.

The Python API (README "From Python"; ``examples/knee_from_python.py``) is a thin re-export of
the functions the commands call, imported on first use so that ``import motionlab`` stays
light:

- data: :class:`Session`, :class:`SensorStream`, :class:`MarkerSet`, :func:`load_session`,
  :func:`save_session`, :func:`read_any` (one file → :class:`Recording`), :func:`ingest`
  (files → one session), :func:`load_protocol`, :func:`simulate`;
- stages (each adds its results to ``session.results`` and returns them, as the commands do):
  :func:`sync`, :func:`fuse` (or :func:`estimate` for one sensor's arrays), :func:`calibrate`,
  :func:`angles`, :func:`metrics`, :func:`validate`;
- the whole analysis: :func:`run_pipeline` with :class:`PipelineOptions` (files → output
  folder), :func:`analyse` (a session in memory);
- out: :func:`load_views` and :func:`write_report` (PDF/CSV), :func:`session_tables` (the CSV
  tables as pandas frames), :func:`export_session` (sto, mot, c3d, json), :func:`results_json`
  (the results as a JSON-able dict);
- :class:`InputError`: what every function raises for bad input (its message names the place).
"""

import sys
from importlib import import_module
from types import ModuleType
from typing import Any

#: public name → module that defines it (imported on first use)
_EXPORTS = {
    "Session": "motionlab.session",
    "SensorStream": "motionlab.session",
    "MarkerSet": "motionlab.session",
    "load_session": "motionlab.session",
    "save_session": "motionlab.session",
    "read_any": "motionlab.io",
    "Recording": "motionlab.io",
    "ingest": "motionlab.ingest",
    "load_protocol": "motionlab.protocol",
    "Protocol": "motionlab.protocol",
    "simulate": "motionlab.simulate",
    "estimate": "motionlab.fusion",
    "sync": "motionlab.stages",
    "fuse": "motionlab.stages",
    "calibrate": "motionlab.stages",
    "angles": "motionlab.stages",
    "metrics": "motionlab.stages",
    "validate": "motionlab.stages",
    "run_pipeline": "motionlab.pipeline",
    "analyse": "motionlab.pipeline",
    "PipelineOptions": "motionlab.pipeline",
    "load_views": "motionlab.report",
    "write_report": "motionlab.report",
    "session_tables": "motionlab.report",
    "export_session": "motionlab.export",
    "results_json": "motionlab.export",
    "InputError": "motionlab.errors",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version

        try:
            value = version("motionlab")
        except PackageNotFoundError:  # running from a source tree that was not installed
            value = "0.0.0+unknown"
    elif name in _EXPORTS:
        value = getattr(import_module(_EXPORTS[name]), name)
    else:
        raise AttributeError(f"module 'motionlab' has no attribute {name!r}")
    globals()[name] = value  # later look-ups skip this function
    return value


class _Package(ModuleType):
    """The package's module type: the import system binds every submodule it loads to the
    package under its name, which put the module ``motionlab.ingest`` (``motionlab.simulate``)
    where the function ``motionlab.ingest`` (``simulate``) belongs once a stage had imported
    it; such a binding is left out, so the name stays the function (``import
    motionlab.simulate as sim`` then gives the function too: import the module's names from
    it)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _EXPORTS and isinstance(value, ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
