"""Optical readers: C3D (files written by ezc3d) and TRC."""

from pathlib import Path

import ezc3d
import numpy as np
import pytest
from conftest import DATA, SHARED, needs_shared

from motionlab.errors import InputError
from motionlab.io import c3d, detect_format, read_any, trc

TRC = DATA / "c3d" / "markers_20frames.trc"


def _write_c3d(path: Path, xyz: np.ndarray, residuals: np.ndarray, unit: str, rate: float) -> None:
    """A C3D file from (N, M, 3) positions and (N, M) residuals, both in ``unit``."""
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [rate]
    f["parameters"]["POINT"]["LABELS"]["value"] = [f"m{k}" for k in range(xyz.shape[1])]
    f["parameters"]["POINT"]["UNITS"]["value"] = [unit]
    f["parameters"]["POINT"]["SCALE"]["value"] = [-0.1]
    points = np.ones((4, xyz.shape[1], xyz.shape[0]))
    points[:3] = np.transpose(xyz, (2, 1, 0))
    f["data"]["points"] = points
    f["data"]["meta_points"] = {
        "residuals": residuals.T[None],
        "camera_masks": np.zeros((7, xyz.shape[1], xyz.shape[0]), dtype=bool),
    }
    f.write(str(path))


@pytest.fixture
def small_c3d(tmp_path):
    rng = np.random.default_rng(11)
    xyz = rng.uniform(-1500, 1500, (40, 3, 3))
    res = np.full((40, 3), 1.5)
    res[5, 1] = -1.0  # not seen
    xyz[9, 2] = 0.0  # a gap written as zeros
    path = tmp_path / "trial.c3d"
    _write_c3d(path, xyz, res, "mm", 200.0)
    return path, xyz


def test_c3d_mm(small_c3d):
    path, xyz = small_c3d
    assert detect_format(path) == "c3d"
    rec = read_any(path)
    (m,) = rec.markers
    assert m.name == "trial" and m.labels == ["m0", "m1", "m2"]
    assert m.rate_hz == pytest.approx(200.0) and m.attrs["nominal_rate_hz"] == 200.0
    assert m.positions.shape == (40, 3, 3) and m.source_units["positions"] == "mm"
    valid = np.ones((40, 3), dtype=bool)
    valid[5, 1] = valid[9, 2] = False
    assert (np.isnan(m.positions[..., 0]) == ~valid).all()
    assert np.isnan(m.residuals[~valid]).all()
    np.testing.assert_allclose(m.positions[valid], xyz[valid] / 1000.0, rtol=1e-6)  # float32
    np.testing.assert_allclose(m.residuals[valid], 0.0015, rtol=1e-6)


def test_c3d_metres(tmp_path):
    xyz = np.arange(2 * 5 * 3, dtype=float).reshape(5, 2, 3) / 7.0 + 0.5
    path = tmp_path / "m.c3d"
    _write_c3d(path, xyz, np.zeros((5, 2)), "m", 120.0)
    m = c3d.read(path).markers[0]
    np.testing.assert_allclose(m.positions, xyz, rtol=1e-6)
    assert m.source_units["positions"] == "m" and m.rate_hz == pytest.approx(120.0)


def test_c3d_errors(small_c3d, tmp_path):
    path, _ = small_c3d
    data = path.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: len(data) - 600])
    with pytest.raises(InputError, match="truncated"):
        c3d.read(cut)
    head_only = tmp_path / "head.c3d"
    head_only.write_bytes(data[:1000])
    with pytest.raises(InputError, match="truncated: the file ends inside its parameter section"):
        c3d.read(head_only)
    garbage = tmp_path / "garbage.c3d"
    garbage.write_bytes(b"\x02\x50" + bytes(510) + b"\x01\x50\x01\x54" + bytes(range(256)) * 4)
    assert c3d.sniff(garbage, garbage.read_bytes())
    with pytest.raises(InputError, match="garbage.c3d"):
        c3d.read(garbage)
    assert not c3d.sniff(TRC, TRC.read_bytes())
    text = b"xP" + b"a" * 1000  # a text file whose second byte is 'P'
    assert not c3d.sniff(path, text)


def test_trc_fixture():
    assert detect_format(TRC) == "trc"
    (m,) = read_any(TRC).markers
    assert m.n_markers == 51 and m.labels[:3] == ["ASISl", "ASISr", "PSISl"]
    assert m.labels[-1] == "boite_arriere_gauche"
    assert m.positions.shape == (20, 51, 3) and m.source_units["positions"] == "mm"
    assert m.rate_hz == pytest.approx(100.0) and m.time[0] == 0.0
    np.testing.assert_allclose(m.positions[0, 0], [0.7337041, 0.0809832, 0.1918668], rtol=1e-12)
    assert not np.isnan(m.positions).any()
    assert m.attrs["warnings"] == ["header announces 652 frames, the file holds 20"]


def _trc_text(rows: list[str], units: str = "m", frames: int = 3) -> str:
    head = [
        "PathFileType\t4\t(X/Y/Z)\tsmall.trc",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate",
        f"50\t50\t{frames}\t2\t{units}\t50",
        "Frame#\tTime\tA\t\t\tB",
        "\t\tX1\tY1\tZ1\tX2\tY2\tZ2",
        "",
    ]
    return "\n".join(head + rows) + "\n"


def test_trc_tab_missing_markers(tmp_path):
    path = tmp_path / "small.trc"
    rows = [
        "1\t0.00\t1.0\t2.0\t3.0\t4.0\t5.0\t6.0",
        "2\t0.02\t\t\t\t4.5\t5.5\t6.5",  # A not seen
        "3\t0.04\t1.2\t2.2\t3.2",  # B not seen, trailing cells omitted
    ]
    path.write_text(_trc_text(rows))
    m = trc.read(path).markers[0]
    assert m.labels == ["A", "B"] and "warnings" not in m.attrs
    np.testing.assert_array_equal(m.time, [0.0, 0.02, 0.04])
    np.testing.assert_array_equal(m.positions[0], [[1, 2, 3], [4, 5, 6]])
    assert np.isnan(m.positions[1, 0]).all() and np.isnan(m.positions[2, 1]).all()
    np.testing.assert_array_equal(m.positions[1, 1], [4.5, 5.5, 6.5])
    path.write_text(_trc_text(rows, units="mm"))
    np.testing.assert_allclose(trc.read(path).markers[0].positions[0, 1], [0.004, 0.005, 0.006])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (_trc_text(["1\t0\t1\t2\tx3\t4\t5\t6"]), r"line 7.*'x3'"),
        (_trc_text(["1\t0\t1\t2\t3\t4\t5\t6\t7\t8"]), r"line 7.*10 columns, expected 8"),
        (_trc_text(["1\t0\t1\t2\t3\t4\t5\t6"], units="inch"), r"Units.*unknown unit 'inch'"),
        ("PathFileType\t4\t(X/Y/Z)\tsmall.trc\nDataRate\n", r"the header ends.*truncated"),
        (_trc_text([]), "no data rows"),
    ],
)
def test_trc_errors(tmp_path, text, match):
    path = tmp_path / "bad.trc"
    path.write_text(text)
    with pytest.raises(InputError, match=match):
        trc.read(path)


SHARED_C3D = {
    # file: (rate Hz, markers, frames, largest |coordinate| in m)
    "optitrack_dec_int_walking.c3d": (160.0, 12, 3361, 0.931),
    "optitrack_motive_sprintbasket.c3d": (120.0, 26, 3678, 6.895),
    "vicon_nexus_markers_analogs.c3d": (100.0, 51, 580, 1.085),
    "vicon_nexus_walking2.c3d": (250.0, 44, 1249, 4.156),
}


@needs_shared
def test_shared_optical_files():
    folder = SHARED / "formats" / "c3d"
    assert sorted(p.name for p in folder.glob("*.c3d")) == sorted(SHARED_C3D)
    for name, (rate, n_markers, n_frames, largest) in SHARED_C3D.items():
        rec = read_any(folder / name)
        (m,) = rec.markers
        assert rec.format == "c3d"
        assert m.rate_hz == pytest.approx(rate, rel=1e-9), name
        assert m.n_markers == n_markers and m.positions.shape == (n_frames, n_markers, 3), name
        assert np.nanmax(np.abs(m.positions)) == pytest.approx(largest, abs=1e-3), name
    (m,) = read_any(folder / "markers.trc").markers
    assert m.n_markers == 51 and m.rate_hz == pytest.approx(100.0)
    assert m.positions.shape == (93, 51, 3) and np.nanmax(np.abs(m.positions)) < 2.0


def _write_model_c3d(path: Path, n: int = 30) -> dict[str, np.ndarray]:
    """A Vicon-like C3D (mm): markers A22:RKNE, A22:LKNE, a repeated A22:RKNE, and the model
    output A22:LKneeAngles (deg) listed in POINT:ANGLES; returns what was written."""
    rng = np.random.default_rng(3)
    data = {
        "RKNE": rng.uniform(-900, 900, (n, 3)),
        "LKNE": rng.uniform(-900, 900, (n, 3)),
        "RKNE_2": rng.uniform(-900, 900, (n, 3)),
        "LKneeAngles": np.column_stack([np.linspace(0, 57.86, n), np.full(n, -3.5), np.zeros(n)]),
    }
    labels = ["A22:RKNE", "A22:LKNE", "A22:RKNE", "A22:LKneeAngles"]
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = labels
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    f.add_parameter("POINT", "ANGLES", ["A22:LKneeAngles"])
    f.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
    points = np.ones((4, len(labels), n))
    points[:3] = np.transpose(np.stack(list(data.values()), axis=1), (2, 1, 0))
    f["data"]["points"] = points
    f.write(str(path))
    return data


def test_c3d_model_outputs_prefixes_duplicates(tmp_path):
    path = tmp_path / "pig.c3d"
    data = _write_model_c3d(path)
    (m,) = read_any(path).markers
    assert m.labels == ["RKNE", "LKNE", "RKNE_2"]  # prefix stripped, the repeat renamed
    np.testing.assert_allclose(m.positions[:, 0], data["RKNE"] / 1000.0, rtol=1e-5)
    np.testing.assert_allclose(m.positions[:, 2], data["RKNE_2"] / 1000.0, rtol=1e-5)
    (angle,) = m.model_outputs.values()
    assert (angle.name, angle.kind, angle.unit) == ("LKneeAngles", "angles", "deg")
    np.testing.assert_allclose(angle.data, data["LKneeAngles"], atol=1e-4)  # deg, not m
    assert np.isfinite(angle.data).all(), "a zero angle is a value, not a gap"
    assert m.attrs["subjects"] == ["A22"] and m.attrs["label_prefixes"]["LKNE"] == "A22:"
    assert m.attrs["duplicate_labels"] == {"RKNE": 2} and m.attrs["flags"]["duplicate_labels"]
    assert any("RKNE appears 2 times" in w for w in m.attrs["warnings"])


def test_c3d_model_outputs_in_session_and_info(tmp_path):
    from click.testing import CliRunner

    from motionlab.cli import main
    from motionlab.session import load_session

    _write_model_c3d(tmp_path / "pig.c3d")
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(main, ["ingest", str(tmp_path / "pig.c3d"), "-o", str(out)])
    assert res.exit_code == 0, res.output
    (m,) = load_session(out).markers.values()
    assert m.model_outputs["LKneeAngles"].unit == "deg" and m.n_markers == 3
    info = CliRunner().invoke(main, ["info", str(out)])
    assert "model outputs, angles: 1 (deg): LKneeAngles" in info.output
    assert "duplicate_labels" in info.output and "subjects (label prefixes stripped): A22" in (
        info.output
    )
    ref = CliRunner().invoke(main, ["info", str(out), "--json"])
    assert '"angles"' in ref.output


def test_c3d_unit_parameter_absent_is_assumed(tmp_path):
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [50.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = ["RHipMoment", "M1"]
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    f.add_parameter("POINT", "MOMENTS", ["RHipMoment"])
    points = np.ones((4, 2, 5))
    points[:3] = 1200.0
    f["data"]["points"] = points
    f.write(str(tmp_path / "mom.c3d"))
    (m,) = read_any(tmp_path / "mom.c3d").markers
    mom = m.model_outputs["RHipMoment"]
    assert mom.kind == "moments" and mom.unit == "Nmm" and mom.data[0, 0] == pytest.approx(1200)
    assert "POINT:MOMENT_UNITS absent; Nmm assumed" in m.attrs["warnings"]
    assert m.labels == ["M1"]


@needs_shared
def test_shared_c3d_prefixes():
    folder = SHARED / "formats" / "c3d"
    (m,) = read_any(folder / "vicon_nexus_markers_analogs.c3d").markers
    assert "ASISr" in m.labels and m.attrs["subjects"] == ["Daphnee", "boite"]
    assert not m.model_outputs and not m.attrs["flags"]["duplicate_labels"]
    (m,) = read_any(folder / "optitrack_motive_sprintbasket.c3d").markers
    assert "WheelchairL:Marker1" in m.labels and "ArmL:Marker1" in m.labels  # kept: they'd merge
