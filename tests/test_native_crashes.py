"""Damaged files that crash native readers (ezc3d, libhdf5) in-process are refused with one
line and exit 2 (issue 16): the C3D parameter section is walked before ezc3d reads it, ezc3d
runs in a forked child, and every HDF5 file is probed in a forked child before it is read."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import ezc3d
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from conftest import SHARED, needs_shared  # noqa: E402
from test_input_boundaries import XSENS, cli, refused  # noqa: E402

from motionlab import isolated  # noqa: E402
from motionlab.errors import InputError  # noqa: E402
from motionlab.io import read_any  # noqa: E402

SHARED_C3D = SHARED / "formats" / "c3d"

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="the guards need os.fork")


@pytest.fixture(autouse=True)
def isolate(monkeypatch):
    """The guards on, even if an earlier test left a thread running in this process (a Dask
    client's event loop), which turns them off for safety outside the tests."""
    monkeypatch.setattr(isolated, "can_isolate", lambda: True)


def _crash() -> None:
    os.kill(os.getpid(), signal.SIGSEGV)


def _fail() -> None:
    raise InputError("bad", "f.c3d", "byte 9")


def test_a_crash_in_the_child_is_an_input_error_and_results_come_back():
    with pytest.raises(InputError) as exc:
        isolated.call_isolated(_crash, path=Path("x.c3d"), what="ezc3d")
    assert exc.value.line().startswith("x.c3d: ezc3d crashed reading it (SIGSEGV)")
    assert isolated.call_isolated(np.arange, 5, path=Path("x"), what="t").tolist() == [
        0,
        1,
        2,
        3,
        4,
    ]
    with pytest.raises(InputError, match="byte 9"):  # the child's own errors come back as they are
        isolated.call_isolated(_fail, path=Path("x"), what="t")


def _c3d_with_analogs(path: Path) -> bytes:
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = ["a", "b", "c"]
    f["parameters"]["ANALOG"]["RATE"]["value"] = [1000.0]
    f["parameters"]["ANALOG"]["LABELS"]["value"] = ["emg1", "emg2"]
    points = np.ones((4, 3, 40))
    points[:3] = np.random.default_rng(1).uniform(-500, 500, (3, 3, 40))
    f["data"]["points"] = points
    f["data"]["analogs"] = np.random.default_rng(2).normal(size=(1, 2, 400))
    f.write(str(path))
    return path.read_bytes()


def _set(data: bytes, at: int, value: int) -> bytes:
    b = bytearray(data)
    b[at] = value
    return bytes(b)


def test_damaged_c3d_records_are_refused_with_their_byte(tmp_path):
    data = _c3d_with_analogs(tmp_path / "good.c3d")
    assert read_any(tmp_path / "good.c3d").markers[0].positions.shape == (40, 3, 3)
    rate = data.find(b"RATE\t") + 4 + 2  # POINT:RATE: name, offset → its data type byte
    scale = data.find(b"SCALE", data.find(b"GEN_SCALE") + 9)  # ANALOG:SCALE's name
    used = data.find(b"USED")
    analog_used = data.find(b"USED", data.find(b"ANALOG")) + 4 + 2 + 2  # after type and dims
    assert data[analog_used : analog_used + 2] == b"\x02\x00"
    cases = {  # each of the first two crashes ezc3d (SIGSEGV) when it reads the file itself
        "dims.c3d": (_set(data, rate + 1, 0xB2), f"byte {rate + 1}", "RATE has -78 dimensions"),
        "scale.c3d": (_set(data, scale + 4, ord("X")), "ANALOG:SCALE", "absent"),
        "type.c3d": (_set(data, rate, 0), f"byte {rate}", "RATE has data type 0"),
        "group0.c3d": (_set(data, used - 1, 0), f"byte {used - 1}", "group id 0"),
        "desc.c3d": (_set(data, rate + 2 + 4, 0x90), "RATE has a description of negative"),
        "chain.c3d": (_set(data, rate - 2, data[rate - 2] + 1), "the chain says"),
        "used.c3d": (_set(data, analog_used, 3), "ANALOG:SCALE", "2 value(s), expected 3"),
    }
    for name, (mutated, *expect) in cases.items():
        (tmp_path / name).write_bytes(mutated)
        refused(cli(tmp_path, "ingest", name, "-o", "o.h5"), name, "damaged parameter", *expect)
        assert not (tmp_path / "o.h5").exists()
        assert (tmp_path / name).read_bytes() == mutated


@needs_shared
def test_the_byte_flipped_c3d_org_sample_that_crashed_ezc3d(tmp_path):
    """``c3d/flip/vicon_nexus_markers_analogs/10`` of ``bench/faults.py``: byte 706, the
    dimension count of SUBJECTS:IS_STATIC, 0 → 0xB2, made ezc3d segfault."""
    data = bytearray((SHARED_C3D / "vicon_nexus_markers_analogs.c3d").read_bytes())
    data[706] ^= 0xB2
    (tmp_path / "in.c3d").write_bytes(bytes(data))
    refused(cli(tmp_path, "ingest", "in.c3d", "-o", "o.h5"), "in.c3d byte 706",
            "IS_STATIC has -78 dimensions")  # fmt: skip


def test_an_hdf5_file_that_crashes_the_probe_is_refused_by_every_reader(tmp_path, monkeypatch):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    assert cli(tmp_path, "ingest", "in.txt", "-o", "s.h5").exit_code == 0
    isolated._PROBED.clear()
    monkeypatch.setattr(isolated, "_probe_hdf5", lambda path: _crash())  # as libhdf5 does
    for args in (
        ["info", "s.h5"],
        ["fuse", "s.h5", "-o", "o.h5"],
        ["ingest", "s.h5", "-o", "o.h5"],
    ):
        refused(cli(tmp_path, *args), "s.h5: the HDF5 library crashed reading it (SIGSEGV)")
    assert not (tmp_path / "o.h5").exists()


def test_the_probe_runs_once_per_file_version(tmp_path, monkeypatch):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    assert cli(tmp_path, "ingest", "in.txt", "-o", "s.h5").exit_code == 0
    isolated._PROBED.clear()
    calls = []
    real = isolated.call_isolated
    monkeypatch.setattr(isolated, "call_isolated", lambda *a, **k: calls.append(1) or real(*a, **k))
    isolated.check_hdf5(tmp_path / "s.h5")
    isolated.check_hdf5(tmp_path / "s.h5")
    assert len(calls) == 1
    os.utime(tmp_path / "s.h5", ns=(1, 1))  # another version of the file: probed again
    isolated.check_hdf5(tmp_path / "s.h5")
    assert len(calls) == 2


def test_sensorcal_and_batch_refuse_an_output_folder_holding_an_input(tmp_path):
    raw = tmp_path / "raw"
    raw.mkdir()
    (raw / "still.txt").write_bytes(XSENS.read_bytes())
    for out in ("raw", "."):
        line = refused(cli(tmp_path, "sensorcal", "raw/still.txt", "-o", out, "--force"),
                       "holds the input still.txt")  # fmt: skip
        assert "inputs are never overwritten" in line
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nsessions:\n  - {subject: S01, visit: v1, files: raw/still.txt}\n"
    )
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    refused(cli(tmp_path, "batch", "study.yaml", "-o", "raw", "--force"), "raw: the output folder",
            "still.txt")  # fmt: skip
    refused(cli(tmp_path, "batch", "study.yaml", "-o", ".", "--force"), "study.yaml")
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_session_text_that_is_not_utf8_is_refused_with_its_key(tmp_path):
    """A byte flip inside a text attribute (bench seed 3, ``session/info/52``): h5py decodes it
    to surrogates, which made ``info`` fail printing them (exit 1)."""
    import h5py

    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    assert cli(tmp_path, "ingest", "in.txt", "-o", "s.h5").exit_code == 0
    with h5py.File(tmp_path / "s.h5", "r+") as f:
        g = f["sensors"][next(iter(f["sensors"]))]
        g.attrs.create("label", b"shank\xd6", dtype=h5py.string_dtype("utf-8"))
    for args in (["info", "s.h5"], ["fuse", "s.h5", "-o", "o.h5"]):
        refused(cli(tmp_path, *args), "s.h5 key /sensors/in/@label", "not valid UTF-8")


def _sleep() -> None:
    import time

    time.sleep(30)


def test_a_reader_that_does_not_finish_is_killed_and_refused(monkeypatch):
    """A damaged session made libhdf5 loop reading an attribute (a hang, not a crash)."""
    import time

    monkeypatch.setattr(isolated, "BASE_S", 0.5)
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="did not finish reading it in 0 s: the file is damaged"):
        isolated.call_isolated(_sleep, path=Path("x.h5"), what="the HDF5 library")
    assert time.perf_counter() - t0 < 5


def test_session_objects_of_the_wrong_kind_name_their_key(tmp_path):
    """A byte flip turned /provenance into a named datatype (exit 1: no ``asstr``)."""
    import h5py

    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    assert cli(tmp_path, "ingest", "in.txt", "-o", "s.h5").exit_code == 0
    with h5py.File(tmp_path / "s.h5", "r+") as f:
        del f["provenance"]
        f["provenance"] = np.dtype("f8")
        f["sensors/in/extra"] = np.zeros(3)
    refused(cli(tmp_path, "info", "s.h5"), "s.h5 key /sensors/in/extra", "not be opened as a group")
    with h5py.File(tmp_path / "s.h5", "r+") as f:
        del f["sensors/in/extra"]
    refused(cli(tmp_path, "info", "s.h5"), "s.h5 key /provenance", "cannot be opened as a dataset")
