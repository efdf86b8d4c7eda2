"""The gyroscope's unit against the accelerometer's tilt (``qc.gyr_scale``): a slowly moving
gyroscope in °/s read as rad/s stays under the 35 rad/s check, and is refused by ``motionlab
ingest`` because its rotation does not match how the accelerometer sees gravity turn."""

import dataclasses
import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import DATA, SHARED, generic_reader, needs_shared

from motionlab import qc
from motionlab.cli import main
from motionlab.protocol import load_protocol
from motionlab.simulate import simulate

DEG = math.pi / 180


@pytest.fixture(scope="module")
def seated():
    """A slow trunk session at 50 Hz (the ``lumbar_seated`` protocol's steps done standing:
    still, then flexion, lateral bending and rotation in slow cycles, everyday movement; the
    seated block's quick leans reach 150°/s, where linear acceleration blurs the tilt the check
    reads): ``label -> (t, acc m/s², gyr rad/s)``."""
    protocol = load_protocol("lumbar_seated")
    standing = [dataclasses.replace(step, pose="standing", instructions="standing")
                for step in protocol.calibration]  # fmt: skip
    session, _ = simulate(dataclasses.replace(protocol, calibration=standing), duration=40.0,
                          seed=0, rate_hz=50.0)  # fmt: skip
    return {k: (s.time, s.acc, s.gyr) for k, s in session.sensors.items()}


def write_recording(folder, name, t, acc, gyr, gyr_unit):
    """``name.csv`` (columns t, ax..az m/s², gx..gz as given) and a map that reads the
    gyroscope in ``gyr_unit``; returns the ingest's arguments."""
    csv = folder / f"{name}.csv"
    np.savetxt(csv, np.column_stack([t, acc, gyr]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz")  # fmt: skip
    reader = generic_reader()
    reader["gyr"]["unit"] = gyr_unit
    reader["label"] = name
    (folder / "map.yaml").write_text(yaml.safe_dump({"reader": reader}))
    return [str(csv), "--map", str(folder / "map.yaml"), "-o", str(folder / "s.h5")]


def ingest(args):
    return CliRunner().invoke(main, ["ingest", *args])


def assert_refused(result, folder, *words):
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert not (folder / "s.h5").exists()


def test_slow_deg_s_read_as_rad_s_is_refused(tmp_path, seated):
    t, acc, gyr = seated["pelvis"]
    deg = np.degrees(gyr)
    assert np.linalg.norm(deg, axis=1).max() < qc.GYR_MAX_PLAUSIBLE  # the old check is silent
    result = ingest(write_recording(tmp_path, "pelvis", t, acc, deg, "rad/s"))
    assert_refused(result, tmp_path, "error: pelvis.csv sensor pelvis: the gyroscope (read as "
                   "rad/s) turns", "is it in °/s? — check the export's gyroscope unit",
                   "gyr: {unit: deg/s}")  # fmt: skip


def test_slow_deg_s_read_as_deg_s_passes(tmp_path, seated):
    t, acc, gyr = seated["pelvis"]
    result = ingest(write_recording(tmp_path, "pelvis", t, acc, np.degrees(gyr), "deg/s"))
    assert result.exit_code == 0, result.output
    assert "gyroscope" not in result.stderr


@pytest.mark.parametrize("label", ["pelvis", "thorax"])
def test_rad_s_passes_with_its_scale_near_one(tmp_path, seated, label):
    t, acc, gyr = seated[label]
    result = ingest(write_recording(tmp_path, label, t, acc, gyr, "rad/s"))
    assert result.exit_code == 0, result.output
    assert "gyroscope" not in result.stderr
    found = qc.gyr_scale(t, acc, gyr)
    assert 0.9 < found["scale"] < 1.1 and 0.9 < found["axes_free_scale"] < 1.1
    misread = qc.gyr_scale(t, acc, gyr / DEG)  # the scale that explains the tilt: π/180
    assert 0.9 * DEG < misread["scale"] < 1.1 * DEG and misread["deg_s_fit"] > 1000


def test_rad_s_read_as_deg_s_is_refused(tmp_path, seated):
    t, acc, gyr = seated["thorax"]
    result = ingest(write_recording(tmp_path, "thorax", t, acc, gyr, "deg/s"))
    assert_refused(result, tmp_path, "(read as deg/s) turns", "is it in rad/s?",
                   "gyr: {unit: rad/s}")  # fmt: skip


def test_a_gyroscope_turns_at_least_as_far_as_its_sensor_tilts():
    """``turn_ratio``: a simulated knee session's thigh turns about as far as it tilts (more:
    it also turns about the vertical), and 57 times less with a rad/s gyroscope read as °/s,
    which is then refused whatever the fit says."""
    session, _ = simulate("knee", duration=120.0, seed=1, rate_hz=50.0)
    s = session.sensors["thigh_r"]
    as_read = qc.gyr_scale(s.time, s.acc, s.gyr)
    assert as_read["tilt_deg"] >= qc.SCALE_TURN_TILT_DEG and 1.0 < as_read["turn_ratio"] < 1.5
    misread = qc.gyr_scale(s.time, s.acc, s.gyr * DEG)
    assert misread["turn_ratio"] == pytest.approx(as_read["turn_ratio"] * DEG, rel=1e-6)
    misread["rad_s_fit"] = 1.0  # as a moving limb's linear acceleration leaves it
    assert qc.gyr_unit_finding(misread) == "rad_s"


@needs_shared
def test_real_knee_recording_with_its_gyroscope_57_times_too_small_is_refused(tmp_path):
    """The hostile-input audit: a DOT thigh recording whose gyroscope was written in rad/s under
    its °/s header went through the ingest with no flag (the fit: 3.7 times better in rad/s,
    under the 4 of a doubt)."""
    from motionlab.io import read_any

    s = read_any(SHARED / "datasets/human/imt_dot/knee_tracking1/femur.csv").sensors[0]
    t, acc = s.time - s.time[0], s.acc
    result = ingest(write_recording(tmp_path, "femur", t, acc, s.gyr, "deg/s"))
    assert_refused(result, tmp_path, "turns", "× less than the tilt")
    result = ingest(write_recording(tmp_path, "femur", t, acc, np.degrees(s.gyr), "deg/s"))
    assert result.exit_code == 0 and "gyroscope" not in result.stderr, result.output


def test_accelerometer_axes_in_another_order_are_not_a_unit(seated):
    """The axes-free scale (a free 3×3 map) does not move when the accelerometer's columns are
    permuted, and no unit is blamed; the same with the gyroscope in °/s is still °/s."""
    t, acc, gyr = seated["pelvis"]
    plain = qc.gyr_scale(t, acc, gyr)
    for swapped in (acc[:, [1, 2, 0]], acc[:, [1, 0, 2]], acc * [-1, 1, 1]):
        found = qc.gyr_scale(t, swapped, gyr)
        assert found["axes_free_scale"] == pytest.approx(plain["axes_free_scale"], rel=1e-6)
        assert found["scale"] < 0.5 and qc.gyr_unit_finding(found) == ""
        assert qc.gyr_unit_finding(qc.gyr_scale(t, swapped, gyr / DEG)) == "deg_s"


def test_still_sensor_with_a_drifting_bias_is_not_deg_s():
    """A still sensor, bias drifting by 1°/s over 5 minutes: π/180 explains the (absent) tilt
    about 4.5 times better than rad/s, because it claims less, but rad/s misses it by a tenth
    of a degree: no finding. Without the miss guard this would be a doubt."""
    rng = np.random.default_rng(1)
    t = np.arange(30000) / 100.0
    acc = np.array([0.3, -0.2, 9.8]) + rng.normal(0, 0.02, (len(t), 3))
    bias = np.radians([0.5, -0.3, 0.2]) + np.outer(t / t[-1], np.radians([1.0, -1.0, 1.0]))
    gyr = bias + rng.normal(0, 0.002, (len(t), 3))
    found = qc.gyr_scale(t, acc, gyr)
    assert found["deg_s_fit"] > qc.SCALE_DOUBT and found["miss_deg"]["as_read"] < 0.5
    assert qc.gyr_unit_finding(found) == ""


def test_too_short_or_damaged_gives_no_verdict():
    t = np.arange(6) / 50.0
    assert qc.gyr_scale(t, np.tile([0, 0, 9.81], (6, 1)), np.zeros((6, 3))) is None
    t = np.arange(500) / 50.0
    acc = np.tile([0, 0, 9.81], (500, 1))
    assert qc.gyr_scale(t, acc, np.full((500, 3), np.nan)) is None
    assert qc.gyr_unit_finding(None) == ""


TRUNK_CHAIR = "datasets/trunk/Aag/trunkmovement_ls/imu/x-IMU3 93E8-5410-EC7B-D38B (UDP)"
QMT = "datasets/human/qmt_full_body/full_body_example_data.mat"


def real_excerpts() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Slow real stretches, gyroscope in °/s: a person's lower back as they sit down (qmt full
    body, 100 Hz, 13-21 s from its start, under 14 °/s) and the x-IMU3 on the wheelchair of a trunk
    trial (50 Hz, 8 s, under 27 °/s): ``name -> (t s, acc m/s², gyr °/s)``."""
    import scipy.io as sio

    from motionlab.io import read_any

    m = sio.loadmat(SHARED / QMT, squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float) - m["t"][0]
    keep = (t >= 13.0) & (t < 21.0)
    back = m["lower_back"]
    out = {"lower_back": (t[keep], np.asarray(back.acc)[keep], np.degrees(back.gyr[keep]))}
    s = read_any(SHARED / TRUNK_CHAIR).sensors[0]
    keep = (s.time >= 3686.0) & (s.time < 3694.0)
    out["wheelchair"] = (s.time[keep], s.acc[keep], np.degrees(s.gyr[keep]))
    return out


@needs_shared
def test_real_slow_excerpts_deg_s_read_as_rad_s_are_refused(tmp_path):
    for name, (t, acc, deg) in real_excerpts().items():
        assert np.linalg.norm(deg, axis=1).max() < qc.GYR_MAX_PLAUSIBLE
        folder = tmp_path / name
        folder.mkdir()
        assert_refused(ingest(write_recording(folder, name, t, acc, deg, "rad/s")), folder,
                       f"sensor {name}", "is it in °/s?")  # fmt: skip
        result = ingest(write_recording(folder, name, t, acc, deg, "deg/s"))
        assert result.exit_code == 0 and "gyroscope" not in result.stderr, result.output


def found(deg_s_fit=1.0, rad_s_fit=1.0, free=1.0, miss=20.0):
    """A hand-made ``qc["gyr_scale"]``: the fits, the axes-free scale, the miss as read (°)."""
    return {"scale": free, "axes_free_scale": free, "deg_s_fit": deg_s_fit,
            "rad_s_fit": rad_s_fit, "tilt_deg": 100.0, "windows": 50,
            "miss_deg": {"as_read": miss, "deg_s": miss / math.sqrt(deg_s_fit),
                         "rad_s": miss / math.sqrt(rad_s_fit), "none": miss}}  # fmt: skip


@pytest.mark.parametrize(
    "kwargs, finding",
    [
        ({"deg_s_fit": 12.0, "free": 0.02}, "deg_s"),
        ({"deg_s_fit": 6.0, "free": 0.02}, "deg_s?"),
        ({"deg_s_fit": 3.9, "free": 0.02}, ""),  # under 4: no doubt
        ({"deg_s_fit": 12.0, "free": 0.5}, "axes?"),  # fits on the same axes only
        ({"deg_s_fit": 12.0, "free": 0.02, "miss": 4.0}, ""),  # misses by < 5°: no evidence
        ({"deg_s_fit": 0.01, "rad_s_fit": 12.0, "free": 60.0, "miss": 4.0}, "rad_s"),
        ({"deg_s_fit": 0.01, "rad_s_fit": 12.0, "free": 3.0}, "axes?"),
        ({"turn": 0.02}, "rad_s"),  # turned 50 times less than it tilted, whatever the fit
        ({"turn": 0.02, "tilt": 60.0}, ""),  # too little tilt to tell
        ({"turn": 0.02, "tilt": 60.0, "moved": 40.0}, "rad_s"),  # but 40° in pairs that moved
        ({"turn": 0.02, "tilt": 60.0, "moved": 20.0}, ""),
        ({"turn": 0.3}, ""),
    ],
)
def test_verdict_thresholds(kwargs, finding):
    f = found(**{k: v for k, v in kwargs.items() if k not in ("turn", "tilt", "moved")})
    f["turn_ratio"], f["tilt_deg"] = kwargs.get("turn", 1.2), kwargs.get("tilt", 100.0)
    if "moved" in kwargs:  # absent from checks stored before it existed
        f["moving_tilt_deg"] = kwargs["moved"]
    assert qc.gyr_unit_finding(f) == finding


def test_doubt_is_one_warning_line():
    from motionlab.session import SensorStream

    s = SensorStream(label="x", time=np.arange(3.0), source_units={"gyr": "rad/s"})
    s.qc = {"flags": {}, "gyr_scale": found(deg_s_fit=6.0, free=0.02)}
    (line,) = qc.doubts(s)
    assert line.startswith("the gyroscope (read as rad/s) turns 50× more than the tilt")
    assert "by 20° per 0.5 s (RMS), by 8.2° in °/s: is it in °/s? — check the export's" in line
    s.qc["gyr_scale"] = found(deg_s_fit=12.0, free=0.5)
    assert "its unit, or axes that are not the accelerometer's?" in qc.doubts(s)[0]


@pytest.mark.parametrize(("scale", "unit"), [(1 / DEG, "deg/s"), (DEG, "rad/s")])
def test_a_gyroscope_57_times_off_its_own_unit_is_not_asked_if_it_is_in_that_unit(
    tmp_path, seated, scale, unit
):
    """Degrees per second read as °/s that still turn 57× too far (converted twice) were told
    '(a gyroscope in °/s read as °/s turns 57.3×) ... is it in °/s?', which they were."""
    t, acc, gyr = seated["thorax"]
    gyr = gyr * scale * (1 / DEG if unit == "deg/s" else 1.0)
    result = ingest(write_recording(tmp_path, "thorax", t, acc, gyr, unit))
    assert_refused(result, tmp_path, f"(read as {unit}) turns", "57.3× is the step between "
                   "rad/s and °/s", "converted between °/s and rad/s twice, or not at all? — "
                   f"check the gyroscope's values against its unit ({unit})")  # fmt: skip
    assert "is it in" not in result.stderr


DOT_HEADER = (
    "sep=,\nDeviceTag:,Femur\nFirmwareVersion:,3.0.0\nSyncStatus:,Synced\nOutputRate:,60Hz\n"
    "Measurement Mode:,Inertial data Mode - Rate Quantities(with mag)\n\n"
    "PacketCounter,SampleTimeFine,Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z\n"
)


def write_dot(path, t, acc, gyr_values):
    """A DOT "rate quantities" export (its gyroscope columns are °/s by the format) holding
    ``gyr_values`` as given in them: ``np.degrees(gyr)`` is a good file, ``gyr`` (rad/s) the
    audit's."""
    ticks = 1_000_000 + np.round(np.asarray(t) * 1e6).astype(np.int64)
    rows = [f"{k + 1},{tick}," + ",".join(f"{v:.6f}" for v in (*a, *g))
            for k, (tick, a, g) in enumerate(zip(ticks, acc, gyr_values, strict=True))]  # fmt: skip
    path.write_text(DOT_HEADER + "\n".join(rows) + "\n")
    return path


def swing(seconds=3.0, rate=60.0, amplitude_deg=20.0, hz=0.5, lever=0.4, yaw_rad_s=0.0):
    """A sensor ``lever`` m below a pivot swinging about its x axis (``amplitude_deg`` at
    ``hz``: a shank), turning about the vertical at ``yaw_rad_s``, with noise: ``(t, acc m/s²,
    gyr rad/s)``. At θ, gravity is ``g (0, sin θ, cos θ)`` in the sensor, and the swing adds
    ``(0, θ'' r, θ'² r)``: linear acceleration, as a limb's, which leaves every unit a large
    residual in the tilt fit. A turn about the vertical adds ``ω ∥ u``, unseen by the
    accelerometer."""
    rng = np.random.default_rng(0)
    t = np.arange(round(seconds * rate)) / rate
    w0, amp = 2 * np.pi * hz, np.radians(amplitude_deg)
    theta, rate_x = amp * np.sin(w0 * t), amp * w0 * np.cos(w0 * t)
    u = np.column_stack((np.zeros_like(t), np.sin(theta), np.cos(theta)))
    swinging = np.column_stack((np.zeros_like(t), -w0 * w0 * theta, rate_x**2)) * lever
    acc = 9.81 * u + swinging + rng.normal(0, 0.02, (len(t), 3))
    gyr = rate_x[:, None] * [1.0, 0.0, 0.0] + yaw_rad_s * u + rng.normal(0, 0.005, (len(t), 3))
    return t, acc, gyr


def dot_ingest(path, folder):
    return ingest([str(path), "-o", str(folder / "s.h5"), "--force"])


def test_a_short_dot_file_swinging_with_its_gyroscope_in_rad_s_is_refused(tmp_path):
    """The audit's file: 3 s of a DOT export whose gyroscope columns hold rad/s under the
    format's °/s passed the ingest without a word. The swing's linear acceleration left the
    fit only 2.1 times better in rad/s (a doubt needs 4), and the turn budget asked for 90° of
    tilt over the slow block pairs, which the 3 s add up to (50°) only on longer recordings.
    Now the tilt of the block pairs that moved (≥ 1° each) counts from 30°."""
    t, acc, gyr = swing()
    result = dot_ingest(write_dot(tmp_path / "femur.csv", t, acc, gyr), tmp_path)
    assert_refused(result, tmp_path, "error: femur.csv sensor Femur: the gyroscope (read as "
                   "deg/s) turns", "× less than the tilt", "is it in rad/s?")  # fmt: skip
    found = qc.gyr_scale(t, acc, gyr * DEG)
    assert found["tilt_deg"] < qc.SCALE_TURN_TILT_DEG and found["rad_s_fit"] < qc.SCALE_DOUBT
    assert found["moving_tilt_deg"] >= qc.SCALE_TURN_MOVED_DEG
    result = dot_ingest(write_dot(tmp_path / "femur.csv", t, acc, np.degrees(gyr)), tmp_path)
    assert result.exit_code == 0 and result.stderr == "", result.output


def test_a_short_dot_file_the_tilt_cannot_check_is_one_warning_naming_it(tmp_path):
    """A sensor that only turns about the vertical (a chair pivoting, 1 rad/s) shows the
    accelerometer no tilt: 3 s of it with rad/s under the °/s header read at 1 °/s, which a
    gyroscope in °/s may give as well. Nothing tells the units apart: one warning line names
    the file, and the ingest goes on. In °/s its 57 °/s are beyond what a gyroscope in rad/s
    read as °/s gives (35 °/s: a ±2000 °/s range): no warning."""
    t, acc, gyr = swing(amplitude_deg=0.0, lever=0.0, yaw_rad_s=1.0)
    result = dot_ingest(write_dot(tmp_path / "femur.csv", t, acc, gyr), tmp_path)
    assert result.exit_code == 0, result.output
    (line,) = result.stderr.splitlines()
    assert line.startswith(
        "warning: Femur: femur.csv: the gyroscope's unit cannot be "
        "checked in 2.98 s: read as deg/s, it never turns faster "
    ), line
    assert line.endswith("too little to compare — check the export's gyroscope unit"), line
    result = dot_ingest(write_dot(tmp_path / "femur.csv", t, acc, np.degrees(gyr)), tmp_path)
    assert result.exit_code == 0 and result.stderr == "", result.output


def test_a_dot_excerpt_in_rad_s_is_warned_and_as_recorded_passes(tmp_path):
    """The real DOT fixture (3.3 s of a seated thigh, 25° of slow tilt, never above 28 °/s):
    as recorded, °/s explains the tilt far better than rad/s would (no warning); with its
    gyroscope columns rewritten in rad/s nothing tells, and it is said in one line."""
    fixture = DATA / "dot" / "femur_rate_quantities_excerpt.csv"
    lines = fixture.read_text().splitlines()
    head = next(i for i, x in enumerate(lines) if x.startswith("PacketCounter"))
    gyr_at = [lines[head].split(",").index(f"Gyr_{a}") for a in "XYZ"]
    rows = [x.split(",") for x in lines[head + 1 :]]
    for r in rows:
        r[gyr_at[0] : gyr_at[-1] + 1] = [f"{math.radians(float(r[i])):.6f}" for i in gyr_at]
    moved = tmp_path / "femur.csv"
    moved.write_text("\n".join(lines[: head + 1] + [",".join(r) for r in rows]) + "\n")
    result = dot_ingest(moved, tmp_path)
    assert result.exit_code == 0, result.output
    (line,) = result.stderr.splitlines()
    assert line.startswith("warning: Femur: femur.csv: the gyroscope's unit cannot be checked")
    result = dot_ingest(fixture, tmp_path)
    assert result.exit_code == 0 and result.stderr == "", result.output


def test_at_rest_in_either_unit_or_fast_gives_no_unchecked_warning():
    """A gyroscope that reads zeros, or at most 0.2 °/s (at rest were it rad/s too), is not
    warned of: its unit changes nothing. One that turns faster than 35 °/s is no rad/s one."""
    t, acc, gyr = swing(amplitude_deg=0.0, lever=0.0)
    from motionlab.session import SensorStream

    def flags(w):
        s = SensorStream(label="x", time=t, acc=acc, gyr=w, source_units={"gyr": "deg/s"})
        return qc.check_stream(s, 0.1)["flags"]

    assert not flags(np.zeros_like(gyr))["gyr_unit_unchecked"]
    assert not flags(gyr * 0.02)["gyr_unit_unchecked"]  # ≤ 0.2 °/s
    assert flags(gyr * 0.02 + [0.0, 0.0, 2 * DEG])["gyr_unit_unchecked"]  # 2 °/s about z
    assert not flags(gyr + [0.0, 0.0, 40 * DEG])["gyr_unit_unchecked"]  # 40 °/s
    s = SensorStream(label="x", time=t, acc=acc, gyr=gyr * 0.02 + [0, 0, 2 * DEG])
    assert "gyr_unit_unchecked" not in qc.check_stream(s, 0.1)["flags"]  # read as rad/s


@needs_shared
def test_real_dot_excerpts_of_3_s_are_never_refused_as_recorded_nor_silent_in_rad_s():
    """Every 3-s excerpt of the six real DOT files (116): as recorded, none is refused or
    warned that its unit cannot be checked (one, a shank at heel strike, keeps the "axes?"
    doubt it had before); with the gyroscope in rad/s under the °/s header, each is refused or
    warned. Before, 107 of them passed without a word (3 refused, 6 warned)."""
    from motionlab import timebase
    from motionlab.io import read_any

    counts = {"refused": 0, "warned": 0, "doubt as recorded": 0}
    for path in sorted((SHARED / "datasets/human/imt_dot").glob("*/*.csv")):
        whole = read_any(path).sensors[0]
        t = whole.time - whole.time[0]
        for start in np.arange(0.0, t[-1] - 3.0, 3.0):
            keep = (t >= start) & (t < start + 3.0)
            piece = dataclasses.replace(whole, time=whole.time[keep], acc=whole.acc[keep],
                                        gyr=whole.gyr[keep], mag=None, extra={})  # fmt: skip
            for gyr in (piece.gyr, piece.gyr * DEG):
                s, _ = timebase.repair_clock(dataclasses.replace(piece, gyr=gyr))
                s.qc = qc.check_stream(s, 0.1)
                flags, says = s.qc["flags"], " ".join(qc.doubts(s))
                if gyr is piece.gyr:
                    assert not flags.get("gyr_unit_mismatch"), (path, start)
                    assert not flags["gyr_unit_unchecked"], (path, start)
                    counts["doubt as recorded"] += "gyroscope" in says
                elif flags.get("gyr_unit_mismatch"):
                    counts["refused"] += 1
                else:
                    assert "gyroscope" in says, (path, start)
                    counts["warned"] += 1
    assert counts["refused"] + counts["warned"] == 116 and counts["refused"] >= 20, counts
    assert counts["doubt as recorded"] <= 1, counts
