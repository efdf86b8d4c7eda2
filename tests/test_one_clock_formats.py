"""Sensors whose files show one clock keep the gait numbers that compare the legs without a
pelvis sensor.

Only an Xsens DOT export's ``SyncStatus: Synced`` was taken as one clock. An APDM CSV, a generic
CSV and an OpenSense ``.sto`` hold several sensors on one time column, and the MTw files of one
Awinda recording start at the station's one ``PacketCounter``; yet without a pelvis sensor the
sync tried to link the legs by the heel strikes and, where it could not, withheld step time,
double support, lengths, speed and step-time asymmetry. Here the heel strikes are made unable to
link them (``LINK_MAX_SE_S`` tightened, as in tests/test_gait_clocks.py).
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED, needs_shared

from motionlab.clocksync import stage
from motionlab.ingest import ingest
from motionlab.io.clock import SHARED_CLOCK
from motionlab.pipeline import PipelineOptions, analyse
from motionlab.simulate.errors import get_preset

LEGS = ("thigh_r", "thigh_l", "shank_r", "shank_l")


@pytest.fixture(scope="module")
def walk():
    """A 40-s simulated walk at 50 Hz whose four leg sensors share one clock (true time, no lost
    samples: one time column holds them all), its pelvis sensor left out; the truth's step-time
    asymmetry (%)."""
    from motionlab.simulate import simulate

    preset = get_preset("typical")
    timing = dataclasses.replace(preset.timing, clock_offset_sigma_s=0.0, clock_drift_sigma=0.0,
                                 drop_fraction=0.0)  # fmt: skip
    session, truth = simulate("walk", 40.0, 2, dataclasses.replace(preset, timing=timing),
                              rate_hz=50.0, gait="normal")  # fmt: skip
    sensors = {k: session.sensors[k] for k in LEGS}
    assert all(np.array_equal(s.time, sensors["thigh_r"].time) for s in sensors.values())
    g = truth.gait
    return sensors, _asymmetry(g["ic_r"][g["ic_r_steady"]], g["ic_l"][g["ic_l_steady"]])


def _asymmetry(ic_r: np.ndarray, ic_l: np.ndarray) -> float:
    """Symmetry index (%) of the median step times onto each side (contacts, s)."""
    onto_r = [t - ic_l[ic_l < t][-1] for t in ic_r if (ic_l < t).any()]
    onto_l = [t - ic_r[ic_r < t][-1] for t in ic_l if (ic_r < t).any()]
    r, left = np.median(onto_r), np.median(onto_l)
    return float(200 * abs(r - left) / (r + left))


def _map(folder: Path, keys: dict[str, str]) -> Path:
    """A sensor map placing each leg sensor (``{file's key: label}``)."""
    lines = [f"  '{key}': {{segment: {lab[:-2]}, side: {lab[-1]}, label: {lab}}}"
             for key, lab in keys.items()]  # fmt: skip
    path = folder / "map.yaml"
    path.write_text("subject: {height_m: 1.75}\nsensors:\n" + "\n".join(lines) + "\n")
    return path


def _channels(sensors: dict, labels: tuple[str, ...]) -> list[np.ndarray]:
    """Each sensor's accelerometer (m/s²) and gyroscope (rad/s), (N, 6)."""
    return [np.c_[sensors[k].acc, sensors[k].gyr] for k in labels]


def _apdm(sensors: dict, folder: Path, files: tuple[tuple[str, ...], ...] = (LEGS,)) -> tuple:
    """APDM Motion Studio CSVs, one Time column for the sensors of each (``files``)."""
    paths = []
    for i, labels in enumerate(files):
        quantities = [f"{q}/{a}" for q in ("Acceleration", "Angular Velocity") for a in "XYZ"]
        head = ["Time"] + [f"{k}/{q}" for k in labels for q in quantities]
        units = ["s"] + [u for _ in labels for u in ["m/s^2"] * 3 + ["rad/s"] * 3]
        data = np.column_stack([sensors[labels[0]].time, *_channels(sensors, labels)])
        rows = "\n".join(",".join(f"{v:.9g}" for v in row) for row in data)
        path = folder / f"walk_{i}.csv"
        path.write_text("Test Name:,walk\nSample Rate:,50,Hz\n" + ",".join(head) + "\n"
                        + ",".join(units) + "\n" + rows + "\n")  # fmt: skip
        paths.append(path)
    return paths, _map(folder, {k: k for k in LEGS})


def _generic(sensors: dict, folder: Path) -> tuple:
    """One CSV with a time column and every sensor's columns, read through a column map."""
    t = sensors["thigh_r"].time
    names = ["t"] + [f"{k}_{c}{a}" for k in LEGS for c in ("acc", "gyr") for a in "xyz"]
    data = np.column_stack([t, *_channels(sensors, LEGS)])
    path = folder / "walk.csv"
    rows = "\n".join(",".join(f"{v:.9g}" for v in row) for row in data)
    path.write_text(",".join(names) + "\n" + rows + "\n")
    specs = [
        f"    - {{label: {k}, acc: {{columns: [{k}_accx, {k}_accy, {k}_accz], unit: m/s^2}},"
        f" gyr: {{columns: [{k}_gyrx, {k}_gyry, {k}_gyrz], unit: rad/s}}}}"
        for k in LEGS
    ]
    smap = _map(folder, {k: k for k in LEGS})
    smap.write_text(smap.read_text() + "reader:\n  format: generic\n  time: t\n  sensors:\n"
                    + "\n".join(specs) + "\n")  # fmt: skip
    return [path], smap


def _awinda(sensors: dict, folder: Path, late: str = "", product: str = "MTW2-3A7G6",
            name: str = "walk-000_{device}.txt") -> tuple:  # fmt: skip
    """MT Manager 2022 exports of one Awinda recording, one file per MTw: the station's
    PacketCounter (from 51400, wrapping at 2^16) and SampleTimeFine on every file; ``late``:
    a sensor whose file starts one sample later; ``product``: the header's ProductCode;
    ``name``: the file names (``{device}`` the device's id)."""
    paths, keys = [], {}
    t = sensors["thigh_r"].time
    counter = (51400 + np.arange(len(t))) % 65536
    fine = 123_456_789 + np.round(t * 1e4).astype(np.int64)
    for i, k in enumerate(LEGS):
        device = f"00B42D{0x4B + i:02X}"
        keys[device] = k
        head = ("// General information:\n//  MT Manager version: 2022.2.0\n"
                f"// Device information:\n//  DeviceId: {device}\n"
                + (f"//  ProductCode: {product}\n" if product else "")
                + "// Coordinate system: ENU\nPacketCounter\tSampleTimeFine\t"
                "Acc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\n")  # fmt: skip
        values = _channels(sensors, (k,))[0]
        rows = [f"{counter[j]:05d}\t{fine[j]}\t" + "\t".join(f"{v:.6f}" for v in values[j])
                for j in range(int(k == late), len(t))]  # fmt: skip
        path = folder / name.format(device=device)
        path.write_text(head + "\n".join(rows) + "\n")
        paths.append(path)
    return paths, _map(folder, keys)


def _run(paths: list[Path], smap: Path, clock_sync: bool = True):
    """Ingest and analyse as ``motionlab run`` (``clock_sync=False``: ``--no-clock-sync``);
    the session and every sensor's ingested stamps."""
    session = ingest(paths, smap)
    recorded = {k: s.time.copy() for k, s in session.sensors.items()}
    analyse(session, PipelineOptions(protocol="walk", progress=False, clock_sync=clock_sync))
    return session, recorded


#: legacy exports (no ProductCode) named after one recording of master 012005D6, as MT Manager
#: names them (the OpenSense example ``MT_012005D6_031-000_00B421AF.txt``)
LEGACY = {"product": "", "name": "MT_012005D6_031-000_{device}.txt"}


@pytest.mark.parametrize("write", [_apdm, _generic, _awinda,
                                   lambda s, f: _awinda(s, f, **LEGACY)])  # fmt: skip
def test_files_on_one_clock_keep_what_compares_the_legs(write, walk, tmp_path, monkeypatch):
    """An APDM CSV, a generic CSV, the MTw files of one Awinda recording and legacy exports
    named after one recording of one master device (an Awinda station or an Xbus Master; a
    legacy export names no product, and these were timed by the data, every angle weak where
    the fits were refused): every sensor is
    marked as on the file's one clock, the sync fits each clock as a check and moves none, and
    the step-time asymmetry is given (within 2 points of the truth's), the console saying why
    no clock was moved: before, it was withheld as 'the two legs' sensor clocks are not
    linked'."""
    from motionlab.report import ReportOutput, load_view
    from motionlab.report.console import run_summary

    monkeypatch.setattr(stage, "LINK_MAX_SE_S", 1e-6)
    sensors, true = walk
    session, recorded = _run(*write(sensors, tmp_path))
    marks = {s.attrs.get(SHARED_CLOCK) for s in session.sensors.values()}
    assert len(marks) == 1 and None not in marks
    fits = session.results.clock_sync.fits.values()
    assert fits and all(f.status.startswith(stage.VENDOR_KEPT) for f in fits)
    for k, s in session.sensors.items():
        np.testing.assert_array_equal(s.time, recorded[k])
    summ = session.results.gait.summary
    assert "step_time_asymmetry_pct" not in summ.withheld and summ.step_pairs >= 5
    assert summ.step_time_asymmetry_pct == pytest.approx(true, abs=2.0)
    assert np.isfinite(summ.sides["l"]["step_time_s"].mean)
    out = ReportOutput(tmp_path / "report.pdf", tmp_path / "report.txt")
    names = {"session_file": "session.h5", "csv_dir": "csv", "results_json": "results.json"}
    text = run_summary(load_view(session), out, {}, 1.0, **names)
    assert "clock sync: kept as recorded: the files show one clock (3 sensor pairs" in text


@pytest.mark.parametrize(
    ("write", "why"),
    [
        (lambda s, f: _awinda(s, f, late="shank_l"), "shank_l's file starts a sample later"),
        (lambda s, f: _awinda(s, f, product=""), "no ProductCode and no master's recording"),
        (lambda s, f: _awinda(s, f, late="shank_l", **LEGACY), "one recording, one file late"),
        (lambda s, f: _apdm(s, f, (LEGS[::2], LEGS[1::2])), "each leg in its own file"),
    ],
)
def test_files_that_do_not_show_one_clock_still_withhold(write, why, walk, tmp_path,
                                                         monkeypatch):  # fmt: skip
    """Files that do not show one clock are timed by the data: the heel strikes cannot link
    the legs here, so what compares them is withheld with the reason, which names
    ``--no-clock-sync``, in the console; a user who knows better and skips the sync gets the
    numbers."""
    from motionlab.report import load_view
    from motionlab.report.console import _gait_line

    monkeypatch.setattr(stage, "LINK_MAX_SE_S", 1e-6)
    sensors, true = walk
    paths, smap = write(sensors, tmp_path)
    session, _ = _run(paths, smap)
    summ = session.results.gait.summary
    reason = summ.withheld.get("step_time_asymmetry_pct", "")
    assert reason.startswith("not given: the two legs' sensor clocks are not linked"), why
    assert "--no-clock-sync" in reason and np.isnan(summ.step_time_asymmetry_pct)
    assert f"step-time asymmetry {reason}" in _gait_line(load_view(session))
    skipped, _ = _run(paths, smap, clock_sync=False)
    summ = skipped.results.gait.summary
    assert skipped.results.clock_sync is None and not summ.withheld
    assert summ.step_time_asymmetry_pct == pytest.approx(true, abs=2.0)


@pytest.mark.parametrize(
    ("names", "marked"),
    [
        (["MT_012005D6_031-000_00B42D4B.txt", "MT_012005D6_031-000_00B42D4C.txt"], True),
        # two recordings of one station
        (["MT_012005D6_031-000_00B42D4B.txt", "MT_012005D6_032-000_00B42D4C.txt"], False),
        # two stations
        (["MT_012005D6_031-000_00B42D4B.txt", "MT_012005D7_031-000_00B42D4C.txt"], False),
        # the "master" is one of the sensors: devices connected on their own
        (["MT_00B42D4B_031-000_00B42D4B.txt", "MT_00B42D4B_031-000_00B42D4C.txt"], False),
        # a name that gives no master
        (["MT46_01-000_00B42D4B.txt", "MT46_01-000_00B42D4C.txt"], False),
    ],
)
def test_legacy_exports_are_one_clock_only_as_one_recording_of_one_master(names, marked,
                                                                          tmp_path):  # fmt: skip
    """Legacy MT Manager exports (no ProductCode) that start at one PacketCounter: one clock
    only when their names give one recording of one master device that is none of them."""
    head = "// Start Time: Unknown\n// Update Rate: 100.0Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"
    rows = "\n".join(f"{4097 + j:05d}\t0.1\t0.2\t9.8" for j in range(200))
    for n in names:
        (tmp_path / n).write_text(head + rows + "\n")
    session = ingest([tmp_path / n for n in names])
    marks = {s.attrs.get(SHARED_CLOCK) for s in session.sensors.values()}
    assert marks == ({f"Xsens MT Manager: 2 exports of recording {names[0][:19]} of master "
                      "012005D6 starting at PacketCounter 4097"} if marked else {None})  # fmt: skip


def test_an_opensense_sto_is_one_clock(walk, tmp_path):
    """An OpenSense ``.sto`` of the four leg IMUs: marked as one clock, and the sync leaves
    the stamps as written (orientations only: no fit can be made)."""
    from motionlab import stages
    from motionlab.io.opensim import write_sto
    from motionlab.kinematics.segment_types import opensim_imu_name

    sensors, _ = walk
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(sensors["thigh_r"].time), 1))
    path = tmp_path / "walk.sto"
    write_sto(path, sensors["thigh_r"].time, {opensim_imu_name(k): quat for k in LEGS})
    session = ingest([path])
    assert {s.attrs.get(SHARED_CLOCK) for s in session.sensors.values()} == {
        "one time column for 4 IMUs in walk.sto"
    }
    recorded = {k: s.time.copy() for k, s in session.sensors.items()}
    stages.sync(session, "walk")
    for k, s in session.sensors.items():
        np.testing.assert_array_equal(s.time, recorded[k])


@needs_shared
@pytest.mark.parametrize(
    ("files", "mark"),
    [
        (["formats/apdm/apdm_format7.csv"], "one Time column for 6 sensors in apdm_format7.csv"),
        (["formats/apdm/imuData01.csv"], "one Time column for 4 sensors in imuData01.csv"),
        (["formats/opensim/imuOrientations.sto"],
         "one time column for 8 IMUs in imuOrientations.sto"),
        (["datasets/ring/trial1/imu_rigid.csv"],
         "one time base (comment line 1: 40.0 Hz) for 5 sensors in imu_rigid.csv"),
        (["formats/dot/RTibia_20210820_202113_825.csv",
          "formats/dot/RFemur_20210820_202113_840.csv"], "Xsens DOT SyncStatus: Synced"),
        (["formats/xsens/MT2022_ACC_00B42D4B.txt",
          "formats/xsens/MT2022_ACC_GYRO_ROT_EULER_TAB_00B42D4F.txt"],
         "Xsens Awinda: 2 MTw exports starting at PacketCounter 51400"),
        # one start (04097) but a legacy header: nothing says they are MTws
        (["formats/xsens/MT46_01-000_00B42D4D.txt", "formats/xsens/MT46_01-000_00B42D4E.txt"],
         None),
        # two MTws of two recordings (MT Manager 2019 and 2020; PacketCounter 3027 and 1330)
        (["formats/xsens/MT_01200454_000-000_00B40DE4.txt",
          "formats/xsens/MT_01200312-002-000_00B474BA.txt"], None),
        # x-IMU3 devices: each Command.json sets its own device's calendar time (11:44:29 to
        # 12:42:45 on this trial) and says nothing of the others'
        (["datasets/trunk/Aag/pivot_hs/imu"], None),
    ],
)  # fmt: skip
def test_the_real_files_that_show_one_clock(files, mark):
    """The vendor files in ../shared: which say their sensors are on one clock."""
    ring = Path(__file__).parents[1] / "motionlab" / "protocols" / "examples" / "ring_map.yaml"
    session = ingest([SHARED / f for f in files], ring if "ring" in files[0] else None)
    assert len(session.sensors) > 1
    assert {s.attrs.get(SHARED_CLOCK) for s in session.sensors.values()} == {mark}
