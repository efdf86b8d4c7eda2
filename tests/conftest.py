"""Shared test fixtures. ``SHARED`` is the optional reference-data folder beside the project."""

import os
from pathlib import Path
from types import ModuleType

import h5py
import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.io import read_any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
SHARED = Path(os.environ.get("MOTIONLAB_SHARED", ROOT.parent / "shared"))

needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared is not present")


def bench_module(name: str) -> ModuleType:
    """The bench script ``bench/<name>.py`` as a module (tests use its reference code; loaded
    once, registered in ``sys.modules`` as its dataclasses need)."""
    import importlib.util
    import sys

    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def data_dir() -> Path:
    return DATA


def generic_reader(mag: bool = False) -> dict:
    """The ``reader`` entry of a sensor map for the tests' CSV files: columns ``t`` (s),
    ``ax..az`` (m/s²), ``gx..gz`` (rad/s), with ``mag`` also ``mx..mz`` (µT)."""
    reader = {
        "format": "generic",
        "delimiter": ",",
        "time": {"column": "t", "unit": "s"},
        "acc": {"columns": ["ax", "ay", "az"], "unit": "m/s^2"},
        "gyr": {"columns": ["gx", "gy", "gz"], "unit": "rad/s"},
    }
    if mag:
        reader["mag"] = {"columns": ["mx", "my", "mz"], "unit": "uT"}
    return reader


def assert_other_hdf5_refused(path: Path, reader: ModuleType, match: str) -> None:
    """An HDF5 file at ``path`` without the ``reader``'s layout: its ``sniff`` says no, and
    :func:`read_any` with the format forced refuses it with an ``InputError`` matching
    ``match``."""
    with h5py.File(path, "w") as f:
        f["something"] = np.zeros(3)
    assert not reader.sniff(path, path.read_bytes()[:65536])
    with pytest.raises(InputError, match=match):
        read_any(path, {"format": reader.FORMAT})
