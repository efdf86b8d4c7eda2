"""Metrics and out-of-plane metrics on hand-made angle curves and orientations."""

from dataclasses import replace

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics import gait_events as ge
from motionlab.kinematics import out_of_plane as oop
from motionlab.kinematics.cycles import Cycles
from motionlab.kinematics.joint_angles import compose
from motionlab.kinematics.metrics import (
    angle_metrics,
    compute_metrics,
    metrics_table,
    single_plane_blocks,
)
from motionlab.protocol import Joint, load_protocol

RATE = 100.0
Z = np.array([0.0, 0.0, 1.0])
KNEE_R = Joint("knee_r", "knee", "thigh_r", "shank_r", "r")


def test_angle_metrics_rom_peaks_and_curve():
    t = np.arange(0, 12, 1 / RATE)
    x = 40 * (1 - np.cos(2 * np.pi * t / 4)) / 2 + 5  # 3 cycles 5 → 45 → 5
    c = Cycles(np.array([0, 400, 800]), np.array([200, 600, 1000]), np.array([400, 800, 1199]))
    m = angle_metrics(x, c)
    assert m.rom_deg == pytest.approx(40, abs=1e-6)
    assert m.repetitions == 3
    assert np.allclose(m.cycle_max_deg, 45, atol=1e-3)
    assert m.cycle_min_mean_deg == pytest.approx(5, abs=1e-3)
    assert m.curve_mean_deg[50] == pytest.approx(45, abs=0.01)
    assert m.curve_sd_deg.max() < 0.2  # the last cycle is one sample short


def test_cross_talk_against_nominal():
    n = 500
    flex = np.linspace(0, 80, n)
    table = {
        "knee_r_flexion_deg": flex,
        "knee_r_adduction_deg": 0.05 * flex,  # 4° off-axis
        "knee_r_rotation_deg": 0.1 * flex,  # 8°
    }
    nominal = {
        "knee_r_flexion_deg": flex,
        "knee_r_adduction_deg": 0.2 * flex,  # 16°
        "knee_r_rotation_deg": 0.1 * flex,
    }
    m = oop.cross_talk(table, nominal, KNEE_R, 0, slice(None))
    assert m.on_axis == "flexion" and m.on_axis_rom_deg == pytest.approx(80)
    assert list(m.off_axis) == ["adduction", "rotation"]
    assert m.off_axis["adduction"].rom_deg == pytest.approx(4)
    assert m.off_axis["adduction"].ratio_pct == pytest.approx(5)
    assert m.off_axis["adduction"].change_pct == pytest.approx(-75)
    assert m.off_axis["rotation"].change_pct == pytest.approx(0)
    bare = oop.cross_talk(table, None, KNEE_R, 0, slice(None)).off_axis["adduction"]
    assert bare.nominal_rom_deg is None and "change_pct" not in bare.to_tree()


def test_axis_angles_and_out_of_plane_offset():
    theta = np.radians(np.linspace(0, 30, 200))
    pelvis = np.tile(rot.IDENTITY, (200, 1))
    # lateral bending about x only: the y and z axes turn by the same angle, x stays
    thorax = rot.from_axis_angle(np.array([1.0, 0, 0]), theta)
    ang = oop.axis_angles(pelvis, thorax)
    assert np.allclose(ang[:, 0], 0, atol=1e-6)
    assert np.allclose(ang[:, 1], np.degrees(theta)) and np.allclose(ang[:, 2], np.degrees(theta))
    c = Cycles(np.array([0]), np.array([199]), np.array([199]))
    m = oop.out_of_plane_offset(ang, np.zeros(3), 1, slice(None), c, 5.0)
    assert m.axes == ["y", "z"] and m.peak_deg < 1e-6
    # add 8° of axial rotation: the y axis stays closer, the offset is out-of-plane motion
    twist = rot.from_axis_angle(np.array([0, 1.0, 0]), np.radians(np.linspace(0, 8, 200)))
    ang = oop.axis_angles(pelvis, rot.mul(thorax, twist))
    m = oop.out_of_plane_offset(ang, np.zeros(3), 1, slice(None), c, 0.5)
    z_angle = ang[-1, 2]
    assert m.peak_deg == pytest.approx(abs(30 - z_angle), abs=1e-6)
    assert z_angle > 30 and 0 < m.above_pct < 100


def test_trunk_compensation_relative_to_neutral():
    t = np.arange(0, 10, 1 / RATE)
    lean = np.where(t > 2, 15 * np.sin(np.pi * (t - 2) / 8) ** 2, 0.0)  # peaks at 15° forward
    angles = np.radians(np.column_stack([lean, 0 * t, 0.5 * lean]))
    neutral = rot.from_axis_angle(Z, 0.7)  # any heading: the neutral posture is the reference
    q = rot.mul(np.tile(neutral, (len(t), 1)), compose(angles, "lumbar"))
    m = oop.trunk_compensation(t, q, slice(200, None), {"flexion": 10.0, "axial_rotation": 10.0})
    assert m.per_angle["flexion"].max_deg == pytest.approx(15, abs=0.05)
    assert m.per_angle["axial_rotation"].peak_abs_deg == pytest.approx(7.5, abs=0.05)
    assert m.per_angle["axial_rotation"].above_pct == 0.0
    # time above 10° of a 15 sin² bump: 1 - 2 asin(sqrt(2/3)) / π of the 8 s
    expect = 100 * (1 - 2 * np.arcsin(np.sqrt(2 / 3)) / np.pi)
    assert m.per_angle["flexion"].above_pct == pytest.approx(expect, abs=1.0)
    assert m.compensated is True


def test_stance_metrics_varus_thrust():
    t = np.arange(0, 4.4, 1 / RATE)
    phase = t % 1.1
    add = 2 + 4 * np.exp(-0.5 * ((phase - 0.15) / 0.05) ** 2)  # +4° early in each stance
    rotation = 3 * np.sin(2 * np.pi * t / 1.1)
    # the loading-response flexion peak at 0.18 s, pre-swing flexion rising to toe-off (0.66 s)
    flexion = 15 * np.exp(-0.5 * ((phase - 0.18) / 0.06) ** 2) + 40 * np.clip(phase - 0.45, 0, 1)
    hs = np.array([0, 110, 220, 330])
    c = Cycles(hs[:-1], hs[:-1] + 66, hs[1:])
    m = oop.stance_metrics(add, rotation, flexion, c, 3.0)
    assert m.strides == 3
    assert np.allclose(m.varus_thrust_deg, 4 * (1 - np.exp(-0.5 * 9)), atol=0.05)
    assert m.varus_thrust_above_pct == 100.0
    # stance = the first 60 % of the stride: from the sine's maximum 3 down to 3 sin(216°)
    expect = 3 - 3 * np.sin(2 * np.pi * 0.6)
    assert m.stance_rotation_range_mean_deg == pytest.approx(expect, abs=0.05)


def test_varus_thrust_is_weight_acceptance_not_late_stance():
    """Adduction that rises with the knee's flexion before toe-off (a healthy knee's coupling) is
    not thrust; only the rise up to the loading-response flexion peak counts."""
    t = np.arange(0, 4.4, 1 / RATE)
    phase = t % 1.1
    flexion = 15 * np.exp(-0.5 * ((phase - 0.18) / 0.06) ** 2) + 40 * np.clip(phase - 0.45, 0, 1)
    add = 2 + 0.1 * flexion  # 1.5° at the loading peak, 3.4° at toe-off
    hs = np.array([0, 110, 220, 330])
    c = Cycles(hs[:-1], hs[:-1] + 66, hs[1:])
    m = oop.stance_metrics(add, np.zeros_like(t), flexion, c, 3.0)
    at_peak = 0.1 * 15 * (1 - np.exp(-0.5 * 9))  # flexion at heel strike is 15 e^-4.5
    assert np.allclose(m.varus_thrust_deg, at_peak, atol=0.02)
    assert m.varus_thrust_above_pct == 0.0
    # a knee that does not flex on loading: the first sixth of stance is weight acceptance
    assert oop.weight_acceptance(np.linspace(5, 0, 67)) == 11
    assert oop.weight_acceptance(flexion[:67]) == 18


def test_compute_metrics_on_a_lumbar_table_and_csv():
    protocol = load_protocol("lumbar")
    t = np.arange(0, 60, 1 / RATE)
    bend = np.where((t > 10) & (t < 40), 20 * np.sin(2 * np.pi * (t - 10) / 10), 0.0)
    angles = np.radians(np.column_stack([0 * t, bend, 0 * t]))
    pelvis = np.tile(rot.from_axis_angle(Z, 0.3), (len(t), 1))
    thorax = rot.mul(pelvis, compose(angles, "lumbar"))
    table = {
        "time_s": t,
        "lumbar_flexion_deg": 0 * t,
        "lumbar_lateral_bending_deg": bend,
        "lumbar_axial_rotation_deg": 0 * t,
    }
    seg_q = {"pelvis": (t, pelvis), "thorax": (t, thorax)}
    blocks = {"lateral_bending": (8.0, 42.0)}
    steps = {"standing": (1.0, 7.0)}
    m = compute_metrics(protocol, table, seg_q, blocks, steps, nominal_table=table)
    lat = m.joints["lateral_bending"]["lumbar_lateral_bending_deg"]
    assert lat.repetitions == 3 and lat.rom_deg == pytest.approx(40, abs=0.01)
    off = m.out_of_plane_offset["lateral_bending"]["lumbar"]
    assert off.axes == ["y", "z"] and off.peak_deg < 1e-6
    ct = m.cross_talk["lateral_bending"]["lumbar"]
    assert ct.on_axis == "lateral_bending" and ct.off_axis["flexion"].rom_deg == 0
    blocks_found = single_plane_blocks(protocol, blocks, steps)
    assert [(b, j.name, i) for b, j, i, _ in blocks_found] == [("lateral_bending", "lumbar", 1)]
    df = metrics_table(m)
    assert list(df.columns) == [
        "block",
        "joint",
        "angle",
        "column",
        "metric",
        "percent",
        "value",
        "unit",
    ]
    row = df[(df.metric == "rom_deg") & (df.angle == "lateral_bending")]
    assert row.value.item() == pytest.approx(40, abs=0.01) and row.joint.item() == "lumbar"
    assert (df[df.metric == "curve_mean_deg"].percent.dropna().max()) == 100
    assert "out_of_plane_peak_deg" in set(df.metric)


def test_a_walks_rom_is_over_the_strides_of_the_joints_leg():
    """The real full-body walk's one task held sitting down and a seated rest between its
    walking bouts: its 'Full ROM' read 119° for a knee that flexed 77-79° per stride and 90° for
    a hip. A walk's ROM and extremes are now taken over the strides of the joint's leg (the
    knee's own, the hip's from the knee below it); the typical range is the strides' anyway.
    The strides are the ones the gait analysis keeps: the real full-body walk's joint pages
    counted 45 cycles (turns and gait initiation among them) where its gait page kept 41."""

    protocol = load_protocol("walk")
    t = np.arange(0, 20, 1 / RATE)
    walking = t < 10  # ten 1-s strides, then sitting down in 0.5 s (knee 95°, hip 85°)
    phase = np.sin(np.pi * (t % 1.0)) ** 2
    down = np.sin(np.pi / 2 * np.clip((t - 10) / 0.5, 0, 1)) ** 2
    knee = np.where(walking, 60 * phase, 95.0 * down)
    hip = np.where(walking, -10 + 45 * phase, -10 + 95 * down)
    table = {"time_s": t}
    for s in "rl":
        table |= {f"knee_{s}_flexion_deg": knee, f"knee_{s}_adduction_deg": 0 * t,
                  f"knee_{s}_rotation_deg": 0 * t, f"hip_{s}_flexion_deg": hip,
                  f"hip_{s}_adduction_deg": 0 * t, f"hip_{s}_rotation_deg": 0 * t}  # fmt: skip
    ic = np.arange(0.0, 9.0)  # the strides' initial contacts, s
    walked = ge.Strides("r", ic, ic + 0.6, ic + 1.0, np.ones(9, bool), ["kept"] * 9)
    strides = {f"shank_{s}": walked for s in "rl"}
    m = compute_metrics(protocol, table, {}, {"walk": (0.0, 19.99)}, {}, strides=strides)
    knee_m, hip_m = m.joints["walk"]["knee_r_flexion_deg"], m.joints["walk"]["hip_l_flexion_deg"]
    # within 0.3°: the metrics' 6 Hz low-pass moves the first sample's minimum by 0.14°
    assert knee_m.rom_deg == pytest.approx(60, abs=0.3) and knee_m.max_deg < 61
    assert hip_m.rom_deg == pytest.approx(45, abs=0.3) and hip_m.max_deg < 36
    assert knee_m.repetitions == 9 and knee_m.cycle_max_mean_deg == pytest.approx(60, abs=0.1)
    assert hip_m.repetitions == 9  # the hip's cycles are its leg's strides
    # the strides the gait analysis rejects (a turn) are not the joints' cycles either
    turned = replace(walked, kept=np.arange(9) < 6)
    m = compute_metrics(protocol, table, {}, {"walk": (0.0, 19.99)}, {},
                        strides={f"shank_{s}": turned for s in "rl"})  # fmt: skip
    assert m.joints["walk"]["knee_r_flexion_deg"].repetitions == 6
    assert m.joints["walk"]["hip_r_flexion_deg"].repetitions == 6
    seated = {"knee_r_flexion_deg": 95.0}  # the same angles without strides: the whole block
    none = replace(walked, kept=np.zeros(9, bool))
    m = compute_metrics(protocol, table, {}, {"walk": (0.0, 19.99)}, {},
                        strides={f"shank_{s}": none for s in "rl"})  # fmt: skip
    assert m.joints["walk"]["knee_r_flexion_deg"].repetitions == 0
    seated_max = m.joints["walk"]["knee_r_flexion_deg"].max_deg
    assert seated_max == pytest.approx(seated["knee_r_flexion_deg"], abs=0.3)  # 6 Hz low-pass


def test_a_sensors_wobble_at_heel_strike_is_not_a_peak():
    """A real walk's knee flexion dipped 8-10° for about 40 ms at each heel strike (the sensors
    wobbling on the skin after the impact, not the knee): the strides' minimum read -3.9° where
    the movement around it reached about 8°. The metrics take the angles low-passed at 6 Hz:
    more than half of such a dip goes, and a walking knee's own curve stays within 0.2°."""
    from motionlab.kinematics.angle_filter import smoothed

    t = np.arange(0, 10, 1 / RATE)
    knee = 5 + 30 * (1 - np.cos(2 * np.pi * t))  # 5-65°, one stride a second
    dip = -8.0 * np.exp(-0.5 * ((t % 1.0 - 0.5) / 0.015) ** 2)  # 8°, ~35 ms wide
    raw = knee + np.roll(dip, 50)  # at each stride's start (the knee's minimum)
    starts = np.arange(100, 900, 100)  # away from the recording's ends
    strides = Cycles(starts, starts + 60, starts + 100)
    assert angle_metrics(raw, strides).cycle_min_mean_deg == pytest.approx(-3.0, abs=0.05)
    m = angle_metrics(smoothed(raw, RATE), strides)
    assert m.cycle_min_mean_deg > 5.0 - 8.0 / 2  # less than half the dip left
    assert m.cycle_max_mean_deg == pytest.approx(65.0, abs=0.2)  # the swing peak kept
    clean = angle_metrics(smoothed(knee, RATE), strides)
    assert clean.cycle_min_mean_deg == pytest.approx(5.0, abs=0.2)
    assert clean.cycle_max_mean_deg == pytest.approx(65.0, abs=0.2)


def test_smoothing_keeps_gaps_and_short_runs():
    """NaN stays NaN; a run of finite samples too short to filter is kept as it is."""
    from motionlab.kinematics.angle_filter import smoothed

    v = np.sin(np.arange(200) / 40.0) * 40  # 0.4 Hz
    v[50:60] = np.nan
    v[100:105] = [1.0, 50.0, -3.0, 7.0, 2.0]
    v[95:100] = v[105:110] = np.nan
    out = smoothed(v, RATE)
    assert np.array_equal(np.isnan(out), np.isnan(v))
    assert np.array_equal(out[100:105], v[100:105])
    assert not np.array_equal(out[:50], v[:50])
    assert np.abs(out[10:40] - v[10:40]).max() < 0.1  # a slow movement passes
    assert smoothed(np.array([3.0]), float("nan"))[0] == 3.0  # one instant: no rate, no filter


def test_cross_talk_is_taken_over_the_repetitions_not_getting_into_posture():
    """The demo elbow's pronation step began with the elbow flexing to 90° (the step is found
    from where the arm starts moving): its "cross-talk" read 90° of flexion, 61 % of the
    pronation. It is taken from the first repetition of the moving angle to the end of its
    last."""
    from motionlab.kinematics.metrics import _repeated

    t = np.arange(0, 14, 1 / RATE)
    posture = 90 * np.clip(t / 2.0, 0, 1)  # 0 → 90° in the first 2 s, then held
    turning = t >= 3
    pronation = np.where(turning, 70 * np.sin(2 * np.pi * 0.5 * (t - 3)) ** 2, 0.0)
    win = _repeated(pronation, slice(0, len(t)), RATE)
    assert t[win.start] >= 2.9 and np.ptp(posture[win]) < 1.0
    assert _repeated(np.zeros(len(t)), slice(5, 50), RATE) == slice(5, 50)  # none: as it was


def test_a_task_time_range_outside_the_angles_names_the_protocol_key_and_the_data_span():
    """A protocol's time_range beyond the recording said 'task sitting: ... is outside the
    angle data — check the task times', naming neither the file nor the key to fix."""
    protocol = load_protocol("lumbar")
    protocol = replace(protocol, tasks=[replace(protocol.tasks[1], time_range=(100.0, 120.0))])
    t = np.arange(0, 60, 1 / RATE)
    table = {"time_s": t} | {c: 0 * t for c in ("lumbar_flexion_deg",
             "lumbar_lateral_bending_deg", "lumbar_axial_rotation_deg")}  # fmt: skip
    name = protocol.tasks[0].name
    with pytest.raises(InputError) as err:
        compute_metrics(protocol, table, {}, {name: (100.0, 120.0)}, {})
    assert str(err.value).startswith(f"lumbar.yaml key tasks[0].time_range: task '{name}' "
                                     "(100.0 to 120.0 s) is outside the angle data (0.0 to "
                                     "60.0 s) — give a time_range inside")  # fmt: skip
    with pytest.raises(InputError, match=r"^task \w+: .* — check the task times"):
        compute_metrics(load_protocol("lumbar"), table, {}, {name: (100.0, 120.0)}, {})


def test_a_cycle_through_a_gap_leaves_no_hole_in_the_mean_curve():
    """One stride through a 0.4-s gap of the thigh sensor broke the hip's and the knee's mean
    cycle curves at 82-94 % (the gait page drew the same strides whole)."""
    t = np.arange(1200) / 100.0
    v = 30 * np.sin(np.pi * t)  # one period per 2-s cycle
    v[350:362] = np.nan  # inside the second cycle
    c = Cycles(np.array([0, 200, 400]), np.array([60, 260, 460]), np.array([200, 400, 600]))
    m = angle_metrics(v, c)
    assert np.isfinite(m.curve_mean_deg).all() and m.repetitions == 3
    assert np.max(np.abs(m.curve_mean_deg - 30 * np.sin(np.linspace(0, 2 * np.pi, 101)))) < 0.5


def test_a_stride_through_a_gap_leaves_the_others_means():
    """A sensor's gap inside one stance made that stride's rotation range NaN, and with it the
    mean the report printed ('- ± -' for a healthy walker's 25 strides)."""
    t = np.arange(0, 4.4, 1 / RATE)
    phase = t % 1.1
    add = 2 + 4 * np.exp(-0.5 * ((phase - 0.15) / 0.05) ** 2)
    rotation = 3 * np.sin(2 * np.pi * t / 1.1)
    flexion = 15 * np.exp(-0.5 * ((phase - 0.18) / 0.06) ** 2)
    rotation[140:150] = np.nan  # inside the second stance (110-176)
    add[140:150] = np.nan
    hs = np.array([0, 110, 220, 330])
    c = Cycles(hs[:-1], hs[:-1] + 66, hs[1:])
    m = oop.stance_metrics(add, rotation, flexion, c, 3.0)
    assert np.isnan(m.stance_rotation_range_deg[1]) and m.strides == 3
    expect = 3 - 3 * np.sin(2 * np.pi * 0.6)
    assert m.stance_rotation_range_mean_deg == pytest.approx(expect, abs=0.05)
    assert m.varus_thrust_mean_deg == pytest.approx(4 * (1 - np.exp(-0.5 * 9)), abs=0.05)
    assert m.varus_thrust_above_pct == 100.0
