"""motionlab's own C3D reader (numpy, no ezc3d object model) against ezc3d, bit for bit:
positions, residuals, parameters (labels, units, rates, model output lists), header values,
on C3D files written by ezc3d here (float storage with analogs and model outputs; the same
file rewritten as int16, DEC and MIPS) and on the real samples in ../shared (issue 16)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import ezc3d
import numpy as np
import pytest
from c3d_variants import convert, to_int16
from conftest import SHARED, needs_shared

from motionlab.errors import InputError
from motionlab.io import c3d
from motionlab.units import factor

LABELS = ["A22:RKNE", "A22:LKNE", "A22:RANK", "A22:LKneeAngles", "A22:RHipMoment"]


def _write(path: Path, frames: int = 30) -> None:
    """A Vicon-like C3D (mm) with 3 markers, an angle and a moment, 2 analog channels at
    10 samples per frame, residuals, a marker not seen (residual -1), a gap written as NaN."""
    rng = np.random.default_rng(5)
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = LABELS
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    f["parameters"]["POINT"]["SCALE"]["value"] = [-0.1]
    f["parameters"]["ANALOG"]["RATE"]["value"] = [1000.0]
    f["parameters"]["ANALOG"]["LABELS"]["value"] = ["emg1", "emg2"]
    f.add_parameter("POINT", "ANGLES", ["A22:LKneeAngles"])
    f.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
    f.add_parameter("POINT", "MOMENTS", ["A22:RHipMoment"])
    f.add_parameter("POINT", "MOMENT_UNITS", ["Nmm"])
    f.add_parameter("SUBJECTS", "USES_PREFIXES", 1)
    f.add_parameter("SUBJECTS", "LABEL_PREFIXES", ["A22:"])
    points = np.ones((4, len(LABELS), frames))
    points[:3] = rng.uniform(-3000, 3000, (3, len(LABELS), frames))
    points[:3, 3] = rng.uniform(-90, 90, (3, frames))  # deg
    points[:3, 1, 7] = np.nan  # a gap
    f["data"]["points"] = points
    residuals = rng.uniform(0.1, 3.0, (1, len(LABELS), frames)).round(1)
    residuals[0, 2, 11] = -1.0  # not seen
    f["data"]["meta_points"] = {
        "residuals": residuals,
        "camera_masks": rng.uniform(size=(7, len(LABELS), frames)) < 0.5,
    }
    f["data"]["analogs"] = rng.normal(size=(1, 2, 10 * frames))
    f.write(str(path))


def _same(path: Path, reference: Path | None = None) -> None:
    """Our reading of ``path`` equals ezc3d's reading of ``reference`` (default: ``path``)."""
    ref = ezc3d.c3d(str(reference or path))
    layout = c3d._layout(path)
    xyz, residuals = c3d._read_points(path, layout)
    points = np.transpose(ref["data"]["points"][:3], (2, 1, 0))
    ref_res = ref["data"]["meta_points"]["residuals"][0].T
    assert np.array_equal(xyz, points, equal_nan=True)
    assert np.array_equal(residuals, ref_res, equal_nan=True)
    for group, params in ref["parameters"].items():
        for name, p in params.items():
            if name == "__METADATA__" or name not in layout.parameters.get(group, {}):
                continue  # ezc3d adds the parameters a file lacks, with default values
            mine = layout.parameters[group][name]["value"]
            if isinstance(p["value"], list):
                assert mine == p["value"], (group, name)
            else:
                assert np.array_equal(mine, p["value"]), (group, name)
    header = ref["header"]
    assert layout.first_frame == header["points"]["first_frame"]
    assert layout.analog_channels == header["analogs"]["size"]
    # what read() makes of it: markers in m, model outputs in their unit, rates
    (m,) = c3d.read(path).markers
    point = ref["parameters"]["POINT"]
    assert m.attrs["nominal_rate_hz"] == point["RATE"]["value"][0]
    if "RATE" in ref["parameters"].get("ANALOG", {}):
        assert m.attrs["analog_rate_hz"] == ref["parameters"]["ANALOG"]["RATE"]["value"][0]
    unit = (point["UNITS"]["value"] or ["mm"])[0].strip()
    kinds = set()
    for key in ("ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS", "REACTIONS"):
        kinds |= {s.strip() for s in point.get(key, {}).get("value", [])}
    is_marker = np.array([lab.strip() not in kinds for lab in point["LABELS"]["value"]])
    invalid = (ref_res < 0) | np.isnan(points).any(axis=2)
    marker_xyz = np.where((invalid | np.all(points == 0, axis=2))[..., None], np.nan, points)
    assert np.array_equal(m.positions, marker_xyz[:, is_marker] * factor(unit, "length"),
                          equal_nan=True)  # fmt: skip
    outputs = [
        np.where(invalid[:, j, None], np.nan, points[:, j]) for j in np.flatnonzero(~is_marker)
    ]
    assert len(m.model_outputs) == len(outputs)
    for out, expected in zip(m.model_outputs.values(), outputs, strict=True):
        assert np.array_equal(out.data, expected, equal_nan=True)


def test_float_storage_with_analogs_and_model_outputs(tmp_path):
    _write(tmp_path / "f.c3d")
    _same(tmp_path / "f.c3d")
    (m,) = c3d.read(tmp_path / "f.c3d").markers
    assert m.labels == ["RKNE", "LKNE", "RANK"] and set(m.model_outputs) == {
        "LKneeAngles",
        "RHipMoment",
    }
    assert np.isnan(m.positions[7, 1]).all() and np.isnan(m.positions[11, 2]).all()
    assert m.attrs["n_analog_channels"] == 2 and m.attrs["analog_rate_hz"] == 1000.0


def test_int16_storage(tmp_path):
    _write(tmp_path / "f.c3d")
    path = tmp_path / "i.c3d"
    path.write_bytes(to_int16((tmp_path / "f.c3d").read_bytes(), 0.1))
    layout = c3d._layout(path)
    assert not layout.is_float and layout.frame_bytes == 2 * (4 * 5 + 20)
    _same(path)
    (m,) = c3d.read(path).markers
    (f,) = c3d.read(tmp_path / "f.c3d").markers
    np.testing.assert_allclose(m.positions, f.positions, atol=0.5e-4)  # 0.1 mm steps, in m
    assert np.isnan(m.positions[11, 2]).all()


@pytest.mark.parametrize("processor", [c3d.DEC, c3d.MIPS])
def test_dec_and_mips_floats(tmp_path, processor):
    _write(tmp_path / "f.c3d")
    path = tmp_path / "p.c3d"
    path.write_bytes(convert((tmp_path / "f.c3d").read_bytes(), processor))
    assert c3d._layout(path).processor == processor
    if processor == c3d.DEC:
        _same(path)  # ezc3d reads DEC
    _same(path, tmp_path / "f.c3d")  # ezc3d refuses MIPS: the Intel original is the reference


@needs_shared
@pytest.mark.parametrize("name", sorted(p.name for p in (SHARED / "formats" / "c3d").glob("*.c3d")))
def test_real_samples(name):
    _same(SHARED / "formats" / "c3d" / name)


def test_memory_is_the_result_not_the_file(tmp_path):
    """Python-level allocations (numpy reports its own to tracemalloc) while reading a 1.6 MB
    C3D with 60 markers and 10 analog channels: about the result (positions and residuals,
    float64), not ezc3d's ~11x the file."""
    n, frames = 60, 1200
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = [f"M{k:02d}" for k in range(n)]
    f["parameters"]["ANALOG"]["RATE"]["value"] = [1000.0]
    f["parameters"]["ANALOG"]["LABELS"]["value"] = [f"a{k}" for k in range(10)]
    points = np.ones((4, n, frames))
    points[:3] = np.random.default_rng(0).uniform(-500, 500, (3, n, frames))
    f["data"]["points"] = points
    f["data"]["analogs"] = np.zeros((1, 10, 10 * frames))
    f.write(str(tmp_path / "big.c3d"))
    size = (tmp_path / "big.c3d").stat().st_size
    tracemalloc.start()
    try:
        (m,) = c3d.read(tmp_path / "big.c3d").markers
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    result = m.positions.nbytes + m.residuals.nbytes
    assert m.positions.shape == (frames, n, 3) and size > 1.5e6
    assert peak < 1.5 * result + 5e6 and peak < 1.2 * size + 5e6, (peak, result, size)


def test_damaged_marker_values_are_gaps_and_a_damaged_block_is_refused(tmp_path):
    """The hostile-input audit wrote random bytes into a C3D's data block: it ingested with no
    flag, markers up to 3e35 m away. Coordinates beyond 100 m are gaps now, with a warning;
    a block that is mostly such values is refused."""
    _write(tmp_path / "f.c3d")
    f = ezc3d.c3d(str(tmp_path / "f.c3d"))
    points = f["data"]["points"]
    points[0, 0, 5] = 3e35
    points[2, 2, 9] = -2e5  # mm: 200 m
    f["data"]["points"] = points
    f.write(str(tmp_path / "d.c3d"))
    (m,) = c3d.read(tmp_path / "d.c3d").markers
    assert np.isnan(m.positions[5, 0]).all() and np.isnan(m.positions[9, 2]).all()
    assert np.nanmax(np.abs(m.positions)) < 3.01
    assert (
        "2 marker samples beyond 100 m of the origin set missing (damaged?)" in m.attrs["warnings"]
    )
    points[:3, :3] = 1e12
    f["data"]["points"] = points
    f.write(str(tmp_path / "x.c3d"))
    with pytest.raises(InputError, match=r"marker samples lie beyond 100 m .* damaged"):
        c3d.read(tmp_path / "x.c3d")
