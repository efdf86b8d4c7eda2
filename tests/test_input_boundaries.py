"""One regression test per class of bad input of issue 16: refused at the boundary where it
enters (exit 2, one line naming file and place) or accepted and flagged."""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path

import ezc3d
import h5py
import numpy as np
from click.testing import CliRunner

from motionlab.cli import main
from motionlab.io import read_any
from motionlab.session import load_session

DATA = Path(__file__).resolve().parent / "data"
XSENS = DATA / "xsens" / "MT46_01-000_00B42D4D.txt"
MAT = DATA / "xsens" / "MT2022_ACC_GYRO_ROT_MAT_COMMA_00B42D4B.txt"


def cli(folder: Path, *args: str):
    old = os.getcwd()
    os.chdir(folder)
    try:
        return CliRunner().invoke(main, list(args))
    finally:
        os.chdir(old)


def refused(result, *expect: str) -> str:
    assert result.exit_code == 2, (result.exit_code, result.output)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    for text in expect:
        assert text in lines[0], lines[0]
    return lines[0]


def session(tmp_path: Path, name: str = "s.h5") -> Path:
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    assert cli(tmp_path, "ingest", "in.txt", "-o", name).exit_code == 0
    return tmp_path / name


def test_output_equal_to_an_input_is_refused_even_with_force(tmp_path):
    (tmp_path / "s.txt").write_bytes(XSENS.read_bytes())
    refused(cli(tmp_path, "ingest", "s.txt", "-o", "s.txt", "--force"), "also an input")
    assert (tmp_path / "s.txt").read_bytes() == XSENS.read_bytes()
    s = session(tmp_path)
    refused(cli(tmp_path, "fuse", "s.h5", "-o", "s.h5", "--force"), "also an input")
    refused(cli(tmp_path, "angles", "s.h5", "--csv", "s.h5", "--force"), "also an input")
    refused(cli(tmp_path, "report", "s.h5", "-o", "s.h5", "--force"), "also an input")
    assert load_session(s).sensors


def test_session_with_non_json_metadata_or_text_channels(tmp_path):
    s = session(tmp_path)
    with h5py.File(s, "r+") as f:
        f.attrs["metadata"] = "{not json"
    refused(cli(tmp_path, "info", "s.h5"), "s.h5 key /@metadata", "not JSON")
    s = session(tmp_path, "t.h5")
    with h5py.File(s, "r+") as f:
        g = f["sensors"][next(iter(f["sensors"]))]
        n = g["acc"].shape
        del g["acc"]
        g.create_dataset("acc", data=np.full(n, "x", dtype=object), dtype=h5py.string_dtype())
    for command in ("info", "fuse"):
        refused(cli(tmp_path, command, "t.h5"), "/acc", "expected numbers")


def test_session_with_damaged_compressed_data(tmp_path):
    s = session(tmp_path)
    with h5py.File(s, "r+") as f:
        g = f["sensors"][next(iter(f["sensors"]))]
        acc = g["acc"][()]
        del g["acc"]
        g.create_dataset("acc", data=acc, compression="gzip", chunks=(2, 3))
    data = bytearray(s.read_bytes())
    with h5py.File(s, "r") as f:
        g = f["sensors"][next(iter(f["sensors"]))]
        offsets = [g["acc"].id.get_chunk_info(k).byte_offset for k in range(2)]
    for off in offsets:
        data[off + 4 : off + 12] = b"\xff" * 8
    s.write_bytes(bytes(data))
    refused(cli(tmp_path, "info", "s.h5"), "s.h5 key /sensors/", "damaged")


def test_broad_rate_as_text(tmp_path):
    path = tmp_path / "b.hdf5"
    path.write_bytes((DATA / "broad" / "broad_10_excerpt.hdf5").read_bytes())
    with h5py.File(path, "r+") as f:
        f.attrs["sampling_rate"] = "fast"
    refused(cli(tmp_path, "ingest", "b.hdf5", "-o", "o.h5"), "key /sampling_rate")


def test_xsens_zero_rotation_matrix_is_missing_not_a_crash(tmp_path):
    lines = MAT.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if "Mat[1][1]" in ln)
    names = lines[header].split(",")
    cells = lines[header + 2].split(",")
    for j, name in enumerate(names):
        if name.startswith("Mat["):
            cells[j] = "0"
    lines[header + 2] = ",".join(cells)
    (tmp_path / "m.txt").write_text("\n".join(lines) + "\n")
    rec = read_any(tmp_path / "m.txt")
    assert np.isnan(rec.sensors[0].quat[1]).all() and np.isfinite(rec.sensors[0].quat[0]).all()


def test_rate_far_beyond_the_native_rate_is_refused_before_allocating(tmp_path):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    for rate in ("1e9", "1e6"):
        t0 = time.perf_counter()
        refused(cli(tmp_path, "ingest", "in.txt", "--rate", rate, "-o", "o.h5"), "native rate")
        assert time.perf_counter() - t0 < 5
    assert cli(tmp_path, "ingest", "in.txt", "--rate", "200", "-o", "o.h5").exit_code == 0


def test_time_stamps_near_1e300_are_refused(tmp_path):
    rows = "".join(f"{k * 1e298:.6e},0.1,0.2,0.3,0.0,0.0,1.0\n" for k in range(1, 50))
    head = "Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
    head += "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)\n"
    (tmp_path / "in.csv").write_text(head + rows)
    refused(cli(tmp_path, "ingest", "in.csv", "-o", "o.h5"), "in.csv", "sensor")


def test_all_zero_quaternions_are_not_stored_as_orientations(tmp_path):
    text = XSENS.read_text().splitlines()
    header = next(i for i, ln in enumerate(text) if ln.startswith("PacketCounter"))
    names = text[header].split("\t")
    qcols = [j for j, n in enumerate(names) if n.startswith("Quat_")]
    for i in range(header + 1, len(text)):
        cells = text[i].split("\t")
        for j in qcols:
            cells[j] = "0"
        text[i] = "\t".join(cells)
    (tmp_path / "in.txt").write_text("\n".join(text) + "\n")
    r = cli(tmp_path, "ingest", "in.txt", "-o", "o.h5")
    if r.exit_code == 2:  # refused: the channel holds no orientation
        refused(r, "in.txt", "quat")
        return
    assert r.exit_code == 0, r.output
    s = next(iter(load_session(tmp_path / "o.h5").sensors.values()))
    assert s.quat is None or not np.isfinite(s.quat).any()


def test_accelerometer_spike_is_flagged_and_fusion_without_result_exits_2(tmp_path):
    text = XSENS.read_text().splitlines()
    header = next(i for i, ln in enumerate(text) if ln.startswith("PacketCounter"))
    j = text[header].split("\t").index("Acc_X")
    for i in range(header + 1, len(text), 3):
        cells = text[i].split("\t")
        cells[j] = "1e308"
        text[i] = "\t".join(cells)
    (tmp_path / "in.txt").write_text("\n".join(text) + "\n")
    r = cli(tmp_path, "ingest", "in.txt", "-o", "o.h5")
    assert r.exit_code == 0, r.output  # the ingest says so in one line, info lists the flag
    assert (
        r.stderr == "warning: in: values beyond what a sensor measures (1e308, ±inf) in acc 40 %"
        " of the rows: damaged? — check the file, or export it again\n"
    )
    s = next(iter(load_session(tmp_path / "o.h5").sensors.values()))
    assert s.qc["flags"]["implausible_values"] and s.qc["implausible_share"]["acc"] > 0.3
    r = cli(tmp_path, "fuse", "o.h5")
    assert r.exit_code in (0, 2)
    if r.exit_code == 2:  # never NaN orientations with exit 0 (tests/test_fusion_nonfinite.py)
        refused(r, "no finite orientation")
    else:
        fused = load_session(tmp_path / "o.h5").results.fusion
        assert all(np.isfinite(e.quat).all() for e in fused.values())


def test_folders_and_unreadable_paths_give_one_line(tmp_path):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    (tmp_path / "d").mkdir()
    refused(cli(tmp_path, "ingest", "d", "-o", "o.h5"), "d: is a folder")
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "d", "-o", "o.h5"), "d: is a folder")
    refused(cli(tmp_path, "ingest", "in.txt", "-o", "d"), "output is a folder")
    refused(cli(tmp_path, "run", "in.txt", "--protocol", "d", "-o", "r"), "d: ")


def test_run_into_an_unwritable_folder_is_refused_before_any_work(tmp_path):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    t0 = time.perf_counter()
    refused(cli(tmp_path, "run", "in.txt", "--protocol", "knee", "-o", "/proc/motionlab-out"),
            "not writable")  # fmt: skip
    assert time.perf_counter() - t0 < 5


def test_sparse_text_file_is_refused_without_reading_it(tmp_path):
    path = tmp_path / "big.txt"
    with open(path, "wb") as f:
        f.write(XSENS.read_bytes()[:300])
        f.truncate(1 << 30)  # sparse: 1 GiB of NUL bytes after an Xsens header
    t0 = time.perf_counter()
    refused(cli(tmp_path, "ingest", "big.txt", "-o", "o.h5"), "binary")
    assert time.perf_counter() - t0 < 5


def test_echoed_cell_is_cut_and_escaped(tmp_path):
    head = "Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
    head += "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)\n"
    rows = [f"{k * 0.01:.2f},0.1,0.2,0.3,0.0,0.0,1.0" for k in range(50)]
    rows[20] = "0.20,0.1," + "x\x01" * 3000 + ",0.3,0.0,0.0,1.0"
    (tmp_path / "in.csv").write_text(head + "\n".join(rows) + "\n")
    line = refused(cli(tmp_path, "ingest", "in.csv", "-o", "o.h5"), "line 22", "\\x01")
    assert len(line) < 400
    # an OpenSim .sto quaternion cell full of NUL bytes was echoed whole (1.1 KB)
    sto = (DATA / "opensim" / "imuOrientations.sto").read_text().splitlines()
    first = next(i for i, ln in enumerate(sto) if ln.lower().startswith("time")) + 1
    cells = sto[first].split("\t")
    cells[1] = "0" + "\x00" * 1000 + ",0,0,0"
    sto[first] = "\t".join(cells)
    (tmp_path / "in.sto").write_text("\n".join(sto) + "\n")
    line = refused(cli(tmp_path, "ingest", "in.sto", "-o", "s.h5"), "is not a number", "\\x00")
    assert len(line) < 400


def _c3d(path: Path, frames: int = 40) -> None:
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = ["a", "b", "c"]
    points = np.ones((4, 3, frames))
    points[:3] = np.random.default_rng(1).uniform(-500, 500, (3, 3, frames))
    f["data"]["points"] = points
    f.write(str(path))


def test_c3d_stale_header_is_read_and_bloated_point_count_refused_fast(tmp_path):
    _c3d(tmp_path / "full.c3d")
    data = bytearray((tmp_path / "full.c3d").read_bytes())
    stale = bytearray(data)
    stale[8:10] = np.array([79], "<u2").tobytes()  # header: last frame 80, file holds 40
    (tmp_path / "stale.c3d").write_bytes(bytes(stale))
    assert read_any(tmp_path / "stale.c3d").markers[0].time.size == 40
    from motionlab.io.c3d import _parameters

    start = (data[0] - 1) * 512
    used = _parameters(bytes(data[start : start + 1024]), "<")[("POINT", "USED")]
    assert used == [3.0]
    at = bytes(data).find(b"USED", start) + 4 + 2 + 2  # name, offset, type and dims
    assert data[at : at + 2] == b"\x03\x00"
    data[at : at + 2] = np.array([30000], "<i2").tobytes()
    (tmp_path / "bloated.c3d").write_bytes(bytes(data))
    t0 = time.perf_counter()
    refused(cli(tmp_path, "ingest", "bloated.c3d", "-o", "o.h5"), "POINT:USED")
    assert time.perf_counter() - t0 < 5


def test_yaml_map_problems(tmp_path):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    (tmp_path / "m.yaml").write_text("session: {date: 2026-02-30}\n")
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "m.yaml", "-o", "o.h5"), "line 1", "date")
    (tmp_path / "m.yaml").write_text("sensors:\n  00B42D4D: {segment: shank, sied: r}\n")
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "m.yaml", "-o", "o.h5"),
            "did you mean 'side'")  # fmt: skip
    assert json.dumps({"ok": True})


def test_simulate_never_writes_over_its_protocol_or_one_output_over_another(tmp_path):
    from click.testing import CliRunner

    from motionlab.cli import main
    from motionlab.protocol import PACKAGED

    proto = tmp_path / "walk.yaml"
    proto.write_bytes((PACKAGED / "walk.yaml").read_bytes())
    before = proto.read_bytes()
    res = CliRunner().invoke(
        main, ["simulate", "--protocol", str(proto), "--duration", "5", "-o", str(proto), "--force"]
    )
    assert res.exit_code == 2 and "also an input" in res.output
    assert proto.read_bytes() == before
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(
        main, ["simulate", "--protocol", "walk", "--duration", "5", "-o", str(out),
               "--truth", str(out)],
    )  # fmt: skip
    assert res.exit_code == 2 and not out.exists()


def test_stages_on_an_unfused_session_say_to_fuse_it_first(tmp_path):
    """A session with raw acc and gyr but no fusion result: the calibration and the angles
    refuse it in one line naming the sensor and the remedy (nothing is fused behind the user's
    back, issue 24); once fused it calibrates."""
    from motionlab.protocol import load_protocol
    from motionlab.session import save_session
    from motionlab.simulate import simulate

    session, _ = simulate(load_protocol("walk"), 30.0, 1, "clean")
    save_session(session, tmp_path / "s.h5")
    before = (tmp_path / "s.h5").read_bytes()
    remedy = "run 'motionlab fuse' (or motionlab.fuse(session)) first"
    line = refused(cli(tmp_path, "calibrate", "s.h5", "--protocol", "walk"), remedy)
    named = line.split("sensor '")[1].split("'")[0]  # the first the calibration reads
    assert named in session.sensors and f"sensor '{named}' has no fusion result" in line
    assert f"results/fusion/{named}" in line
    refused(cli(tmp_path, "angles", "s.h5", "--protocol", "walk", "--no-calibration"), remedy)
    assert (tmp_path / "s.h5").read_bytes() == before
    assert cli(tmp_path, "fuse", "s.h5").exit_code == 0
    assert cli(tmp_path, "calibrate", "s.h5", "--protocol", "walk").exit_code == 0


def test_ingest_warns_of_a_truncated_line_and_refuses_an_accelerometer_in_g(tmp_path):
    """A plausible file ingests silently; a last line cut short is said in one warning line.
    An accelerometer in g labelled m/s² was a warning too, and the run went on to angles graded
    `determined` (the hostile-input audit): gravity cannot be 0.99 m/s², so it is refused."""
    xio = (DATA / "xio" / "sensor_data_excerpt.csv").read_text()
    (tmp_path / "ok.csv").write_text(xio)
    r = cli(tmp_path, "ingest", "ok.csv", "-o", "ok.h5")
    assert r.exit_code == 0 and r.stderr == "", r.output
    (tmp_path / "in.csv").write_text(xio[:-30])
    r = cli(tmp_path, "ingest", "in.csv", "-o", "o.h5")
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines() == [
        "warning: in: line 301: truncated last line (7 of 10 columns) dropped",
    ]
    (tmp_path / "g.csv").write_text(xio.replace("(g)", "(m/s^2)"))
    refused(cli(tmp_path, "ingest", "g.csv", "-o", "g.h5"),
            "error: g.csv sensor g: |a| at rest is 0.99 m/s² (read as m/s^2), where 1 g is "
            "9.81: the accelerometer is in g — check the export's accelerometer unit")  # fmt: skip
    (tmp_path / "ms2.csv").write_text(xio.replace("(g)", "(mg)"))
    refused(cli(tmp_path, "ingest", "ms2.csv", "-o", "m.h5"), "not ≈ 9.81: a wrong unit")
    assert not (tmp_path / "g.h5").exists() and not (tmp_path / "m.h5").exists()


def test_symlink_loop_is_one_line(tmp_path):
    """A link that leads back to itself crashed the input-is-output check (RuntimeError from
    Path.resolve, exit 1) for an input, a map and an output alike."""
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    os.symlink(tmp_path / "b.txt", tmp_path / "a.txt")
    os.symlink(tmp_path / "a.txt", tmp_path / "b.txt")
    loop = "a.txt: is a symbolic link that leads back to itself (a loop) — give the file's own path"
    refused(cli(tmp_path, "ingest", "a.txt", "-o", "o.h5"), loop)
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "a.txt", "-o", "o.h5"), loop)
    refused(cli(tmp_path, "run", "a.txt", "--protocol", "knee", "-o", "r"), loop)
    refused(cli(tmp_path, "ingest", "in.txt", "-o", "a.txt"), "a.txt in .: output exists")
    refused(cli(tmp_path, "run", "in.txt", "--protocol", "a.txt", "-o", "r"),
            "a.txt: is a symbolic link that leads nowhere (or back to itself)")  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "in.txt"]


def test_ingest_warns_of_orientations_dropped(tmp_path):
    """Quaternions far from unit norm were set missing, or the channel dropped (a sensor left
    with no data at all), with exit 0 and not a word: the ingest now warns."""
    from motionlab.io.opensim import write_sto

    t = np.arange(5) / 100
    good = np.tile([1.0, 0.0, 0.0, 0.0], (5, 1))
    one = good.copy()
    one[2] *= 1e5
    write_sto(tmp_path / "q.sto", t, {"a": good * 1e5, "b": one, "c": good})
    r = cli(tmp_path, "ingest", "q.sto", "-o", "o.h5")
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines() == [
        "warning: a: orientation dropped: no quaternion has unit norm (e.g. all zero); no "
        "channel left — check the file, or export it again",
        "warning: b: 1 orientations with a norm far from 1 set missing — check the file, or "
        "export it again",
    ]


def test_yaml_key_written_twice_is_refused(tmp_path):
    """YAML keeps the last of two equal keys silently: a sensor mapped twice lost its first
    segment, exit 0. A key written twice is refused (sensor maps, protocols, manifests); a
    merged key (<<: *base) that the mapping redefines is YAML's override, and kept."""
    from motionlab.yamlsafe import LineLoader, load_yaml

    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    (tmp_path / "m.yaml").write_text("sensors:\n  a: {segment: shank}\n  a: {segment: thigh}\n")
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "m.yaml", "-o", "o.h5"),
            "m.yaml line 3: not valid YAML (key 'a' is written twice (lines 2 and 3))")  # fmt: skip
    assert not (tmp_path / "o.h5").exists()
    doc = load_yaml("b: &b {x: 1, y: 2}\nc: {<<: *b, y: 3}\n", LineLoader, tmp_path / "p", "")
    assert doc["c"] == {"x": 1, "y": 3}


def test_ingest_warns_of_a_truncated_apdm_file(tmp_path):
    """APDM keeps its repairs with the file (one file, many sensors): a truncated last line
    was dropped without a word."""
    text = (DATA / "apdm" / "imuData01_1s.csv").read_bytes()
    (tmp_path / "in.csv").write_bytes(text.rstrip(b"\r\n")[:-200])
    r = cli(tmp_path, "ingest", "in.csv", "-o", "o.h5")
    assert r.exit_code == 0, r.output
    warnings = r.stderr.splitlines()
    assert len(warnings) == 1 and warnings[0].startswith("warning: in.csv: line 132: truncated")


def test_outputs_into_an_input_folder_are_refused_even_with_force(tmp_path):
    """``motionlab run <trial>/imu -o <trial>/imu`` wrote the session, report and CSVs into the
    x-IMU3 export it read (also into a device folder below it, and with ``--force``): the next
    read of that folder would meet them. Refused before any work; the folder is unchanged."""
    from tests import ximu3_export as xe

    imu = xe.write(tmp_path, xe.export_files())
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    device = next(imu.iterdir()).name
    for out in ("imu", f"imu/{device}/out"):
        for force in ((), ("--force",)):
            res = cli(tmp_path, "run", "--quiet", "--protocol", "lumbar_seated", "imu", "-o",
                      out, *force)  # fmt: skip
            refused(res, "input folder imu", "inputs are never modified")
    refused(cli(tmp_path, "ingest", "imu", "-o", "imu/s.h5"), "input folder imu")
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_an_optical_file_of_one_frame_says_so(tmp_path):
    """A TRC file with its header and one frame was refused as 'frame times are not strictly
    increasing', which does not say what is wrong."""
    trc = (DATA / "c3d" / "markers_20frames.trc").read_text().splitlines()
    (tmp_path / "one.trc").write_text("\n".join(trc[:7]) + "\n")
    refused(cli(tmp_path, "ingest", "one.trc", "-o", "o.h5"), "1 frame: too few to follow a marker")


def test_accelerometer_and_gyroscope_columns_swapped_are_refused(tmp_path):
    """The hostile-input audit swapped an x-io export's accelerometer and gyroscope columns: it
    ingested with no word (its gyroscope then read a constant 1 °/s, its 'accelerometer' the
    rates ×9.81). Where the gyroscope reads the sensor still for 0.5 s, ‖a‖ must be steady
    (real recordings: interquartile range ≤ 1.8 % of the median, simulated ≤ 5.7 %)."""
    from motionlab import qc
    from motionlab.simulate import simulate

    session, _ = simulate("knee", duration=170.0, seed=0, rate_hz=50.0)
    s = session.sensors["shank_r"]
    (tmp_path / "in.csv").write_text(
        "t,ax,ay,az,gx,gy,gz\n"
        + "\n".join(
            f"{t:.4f}," + ",".join(f"{v:.6f}" for v in (*np.degrees(g), *a / 9.80665))
            for t, a, g in zip(s.time, s.acc, s.gyr, strict=True)
        )  # fmt: skip
    )
    reader = {"format": "generic", "label": "shank", "time": "t",
              "acc": {"columns": ["ax", "ay", "az"], "unit": "g"},
              "gyr": {"columns": ["gx", "gy", "gz"], "unit": "deg/s"}}  # fmt: skip
    (tmp_path / "map.yaml").write_text(json.dumps({"reader": reader}))
    line = refused(cli(tmp_path, "ingest", "in.csv", "--map", "map.yaml", "-o", "s.h5"))
    assert "columns swapped?" in line or "another channel's (the gyroscope's)" in line, line
    assert not (tmp_path / "s.h5").exists()
    found = qc.check_stream(s, 0.1)["acc_rest_spread"]  # the same sensor as recorded
    assert found < 0.1 and qc.swapped_problem(replace(s, qc={"acc_rest_spread": found})) is None
    # the audit's case: the rates, read as g, happen to give ‖a‖ ≈ 9.81 at the median, so only
    # their spread where the (swapped) gyroscope reads still tells
    rates = np.degrees(s.gyr)
    rates *= 1.0 / np.median(np.linalg.norm(rates, axis=1))
    swapped = replace(s, acc=rates * 9.80665, gyr=np.radians(s.acc / 9.80665))
    swapped = replace(swapped, qc=qc.check_stream(swapped, 0.1))
    assert 9.0 < swapped.qc["acc_rest_norm"] < 11.0 and qc.acc_unit_problem(swapped) is None
    assert "columns swapped?" in qc.swapped_problem(swapped)[0]


def test_a_device_given_as_a_map_or_protocol_is_called_what_it_should_be(tmp_path):
    """'--map /dev/zero' was told to 'give a recording saved as a file'."""
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    refused(cli(tmp_path, "ingest", "in.txt", "--map", "/dev/zero", "-o", "o.h5"),
            "give a sensor map saved as a file")  # fmt: skip
    refused(cli(tmp_path, "run", "in.txt", "--protocol", "/dev/zero", "-o", "r"),
            "give a protocol saved as a file")  # fmt: skip
