"""Session file: save → load is bit-exact (arrays, NaN, text, bool masks, results, provenance)."""

import json

import h5py
import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.results import (
    AngleTable,
    FusionEntry,
    HeadingCorrection,
    JointGrades,
    Results,
    SegmentCalibration,
    SegmentRecord,
)
from motionlab.session import (
    MarkerSet,
    SensorStream,
    Session,
    estimate_rate,
    load_session,
    save_session,
    sha256_file,
)


def make_session(tmp_path) -> Session:
    rng = np.random.default_rng(7)
    n = 257
    t = np.arange(n) / 285.7 + 0.1
    acc = rng.normal(size=(n, 3))
    acc[5:9, 1] = np.nan
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    imu = SensorStream(
        label="shank_r",
        time=t,
        acc=acc,
        gyr=rng.normal(size=(n, 3)),
        mag=rng.normal(size=(n, 3)) * 40,
        quat=quat,
        serial="00B421ED",
        vendor="Xsens",
        segment="shank",
        side="r",
        source_units={"acc": "m/s^2", "gyr": "deg/s", "mag": "a.u."},
        extra={
            "movement": rng.random(n) > 0.5,
            "packet_counter": np.arange(n, dtype=np.uint16),
            "free_acc": rng.normal(size=(n, 3)).astype(np.float32),
        },
        qc={"gaps": [[1.0, 1.5]], "flags": {"gaps": True, "acc_saturated": False}, "nan": None},
        attrs={"start_s": 1234.5, "note": "µT, ° and ü survive"},
    )
    gyr_only = SensorStream(label="thigh", time=t.copy(), gyr=np.zeros((n, 3)))
    pos = rng.normal(size=(100, 2, 3))
    pos[10:20, 0] = np.nan
    markers = MarkerSet(
        name="vicon",
        time=np.arange(100) / 100.0,
        labels=["LKNE", "RKNE"],
        positions=pos,
        residuals=np.abs(rng.normal(size=(100, 2))) * 1e-3,
        rigid_bodies={"shank": quat[:100]},
        source_units={"positions": "mm"},
        attrs={"rate_hz": 100.0},
    )
    src = tmp_path / "input.txt"
    src.write_text("raw data")
    s = Session(
        sensors={"shank_r": imu, "thigh": gyr_only},
        markers={"vicon": markers},
        metadata={"subject": {"id": "P1", "height_m": 1.8}, "session": {"date": "2024-05-02"}},
        results=Results(
            fusion={
                "shank_r": FusionEntry(
                    "madgwick",
                    quat,
                    {"beta": 0.1},
                    magnetometer=False,
                    gyro_bias=np.tile([1e-3, -2e-3, np.nan], (n, 1)),
                    rest=rng.random(n) > 0.5,
                )
            },
            calibration=SegmentCalibration(
                "knee",
                steps={"stand": [0.1, 0.5], "squat": None},
                segments={"shank_r": SegmentRecord(quat[0], "procrustes")},
                warnings=["µT, ° and ü survive"],
                grades={"knee_r": JointGrades(["determined"] * 3, [""] * 3)},
                protocol_path="knee.yaml",
            ),
            angles=AngleTable(
                t, {"knee_r_flexion_deg": rng.normal(size=n)}, events={"stand": (0.1, 0.5)}
            ),
            heading={"knee_r": HeadingCorrection("steps", 0)},
            # a stage this motionlab does not know (a newer one wrote it) is kept as it is
            more={
                "future": {
                    "columns": np.array(["knee_flexion_deg", "knee_varus_deg"]),
                    "valid": np.array([True, False, True]),
                    "counts": np.arange(5, dtype=np.int32),
                    "summary": {"rom_deg": 61.25, "cycles": [1, 2, 3], "ok": True},
                }
            },
        ),
    )
    s.add_provenance("motionlab ingest input.txt -o s.h5", {"rate_hz": None}, [src])
    return s


def assert_same(a, b):
    """Equal values, dtypes and shapes; NaN equal to NaN."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b)
        for k in a:
            assert_same(a[k], b[k])
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape
        if a.dtype.kind == "f":
            np.testing.assert_array_equal(a.view(np.uint8), b.view(np.uint8))  # bit-exact
        else:
            np.testing.assert_array_equal(a, b)
    else:
        assert a == b


def test_round_trip_bit_exact(tmp_path):
    s = make_session(tmp_path)
    path = tmp_path / "s.h5"
    save_session(s, path)
    back = load_session(path)
    assert list(back.sensors) == ["shank_r", "thigh"]
    for label, a in s.sensors.items():
        b = back.sensors[label]
        for name in ("time", "acc", "gyr", "mag", "quat"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None) == (y is None)
            if x is not None:
                assert_same(x, y)
        assert_same(a.extra, b.extra)
        for name in ("label", "serial", "vendor", "segment", "side", "source_units", "attrs"):
            assert getattr(a, name) == getattr(b, name)
        assert a.qc == b.qc
    ma, mb = s.markers["vicon"], back.markers["vicon"]
    for name in ("time", "positions", "residuals"):
        assert_same(getattr(ma, name), getattr(mb, name))
    assert_same(ma.rigid_bodies, mb.rigid_bodies)
    assert (ma.labels, ma.source_units, ma.attrs) == (mb.labels, mb.source_units, mb.attrs)
    assert back.metadata == s.metadata
    assert_same(s.results.to_tree(), back.results.to_tree())
    assert back.results.more["future"]["columns"].dtype.kind == "U"
    assert back.results.more["future"]["valid"].dtype == bool
    assert back.results.fusion["shank_r"].magnetometer is False
    assert back.results.calibration.steps["squat"] is None
    assert back.results.angles.units == {"knee_r_flexion_deg": "deg"}
    assert back.results.angles.events == {"stand": (0.1, 0.5)}
    assert back.provenance == s.provenance
    assert back.provenance[0]["inputs"] == {str(tmp_path / "input.txt"): sha256_file(
        tmp_path / "input.txt")}  # fmt: skip


def test_second_round_trip_gives_the_same_file_content(tmp_path):
    s = make_session(tmp_path)
    save_session(s, tmp_path / "a.h5")
    save_session(load_session(tmp_path / "a.h5"), tmp_path / "b.h5")
    a, b = load_session(tmp_path / "a.h5"), load_session(tmp_path / "b.h5")
    assert_same(a.results.to_tree(), b.results.to_tree())
    assert_same(a.sensors["shank_r"].extra, b.sensors["shank_r"].extra)
    assert a.provenance == b.provenance


def test_file_is_self_describing(tmp_path):
    save_session(make_session(tmp_path), tmp_path / "s.h5")
    with h5py.File(tmp_path / "s.h5") as f:
        assert f.attrs["format"] == "motionlab-session"
        assert f["sensors/shank_r/gyr"].attrs["unit"] == "rad/s"
        assert f["sensors/shank_r/time"].attrs["unit"] == "s"
        assert "w,x,y,z" in f["sensors/shank_r/quat"].attrs["convention"]
        assert json.loads(f["sensors/shank_r"].attrs["source_units"])["gyr"] == "deg/s"


def test_overwrite_needs_force_and_keeps_old_file(tmp_path):
    s = make_session(tmp_path)
    path = tmp_path / "s.h5"
    save_session(s, path)
    before = path.read_bytes()
    s.metadata["subject"]["id"] = "P2"
    with pytest.raises(InputError, match="output exists"):
        save_session(s, path)
    assert path.read_bytes() == before
    save_session(s, path, force=True)
    assert load_session(path).metadata["subject"]["id"] == "P2"
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_failed_write_leaves_nothing(tmp_path):
    s = make_session(tmp_path)
    s.results.more["bad"] = {"x": object()}  # not storable
    with pytest.raises(TypeError):
        save_session(s, tmp_path / "s.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["input.txt"]


@pytest.mark.parametrize("content", [b"", b"not hdf5 at all"])
def test_load_rejects_non_sessions(tmp_path, content):
    p = tmp_path / "x.h5"
    p.write_bytes(content)
    with pytest.raises(InputError):
        load_session(p)
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    with pytest.raises(InputError, match="not a motionlab session"):
        load_session(tmp_path / "other.h5")


def test_estimate_rate():
    assert estimate_rate(np.arange(10) / 50.0) == pytest.approx(50.0)
    assert np.isnan(estimate_rate(np.array([1.0])))


def test_a_stage_commands_provenance_reads_as_the_command_a_user_typed(monkeypatch):
    """``python -m motionlab sync …`` (argv[0] the package's __main__.py) and the installed
    executable are recorded as ``motionlab sync …``, as ingest and run record theirs: the report's
    provenance table showed ``/…/motionlab/__main__.py sync`` for every stage command."""
    monkeypatch.setattr(
        "sys.argv",
        ["/site-packages/motionlab/__main__.py", "sync", "my trial.h5", "--protocol", "knee"],
    )
    s = Session()
    s.add_provenance(parameters={"stage": "sync"})
    assert s.provenance[-1]["command"] == "motionlab sync 'my trial.h5' --protocol knee"
    monkeypatch.setattr("sys.argv", ["/usr/local/bin/motionlab", "fuse", "s.h5"])
    s.add_provenance(parameters={"stage": "fuse"})
    assert s.provenance[-1]["command"] == "motionlab fuse s.h5"


def test_a_truncated_session_file_is_called_damaged_not_foreign(tmp_path):
    """``info`` called a truncated session "not an HDF5 file" where ``run`` said "damaged or
    truncated": a file that starts as HDF5 is a damaged one, for every command."""
    from motionlab.errors import InputError

    path = tmp_path / "s.h5"
    save_session(Session(), path)
    cut = tmp_path / "cut.h5"
    cut.write_bytes(path.read_bytes()[:1500])
    with pytest.raises(InputError, match="damaged or truncated"):
        load_session(cut)
    other = tmp_path / "text.h5"
    other.write_text("time,x\n0,1\n")
    with pytest.raises(InputError, match="not an HDF5 file"):
        load_session(other)
