"""The CSV tables' row-at-a-time writer writes the bytes pandas writes (``report/csv.py``)."""

import numpy as np
import pandas as pd

from motionlab.report.csv import FLOAT_FORMAT, write_frame


def _both(frame: pd.DataFrame, tmp_path) -> tuple[bytes, bytes]:
    ours, theirs = tmp_path / "ours.csv", tmp_path / "pandas.csv"
    write_frame(frame, ours)
    frame.to_csv(theirs, index=False, float_format=FLOAT_FORMAT)
    return ours.read_bytes(), theirs.read_bytes()


def test_float_tables_are_written_as_pandas_writes_them(tmp_path):
    rng = np.random.default_rng(3)
    values = rng.normal(scale=100.0, size=(500, 3))
    values[10, 1] = np.nan  # a gap in one column
    values[11, :] = np.nan  # a row of gaps
    values[12] = [-0.0, -1e-7, 123456789.123456]  # rounds to -0.0000, big numbers
    values[13] = [np.inf, -np.inf, 0.00005]
    frame = pd.DataFrame(values, columns=["time_s", "knee_r_flexion_deg", "a, quoted name"])
    ours, theirs = _both(frame, tmp_path)
    assert ours == theirs
    assert b",," in ours and b"-0.0000" in ours  # the cases above were written


def test_other_tables_go_to_pandas(tmp_path):
    frame = pd.DataFrame({"joint": ["knee_r", "knee_l"], "n": [3, 4], "rom_deg": [60.0, np.nan]})
    ours, theirs = _both(frame, tmp_path)
    assert ours == theirs
    empty = pd.DataFrame({"time_s": np.array([], dtype=float)})
    assert _both(empty, tmp_path)[0] == _both(empty, tmp_path)[1]


def test_a_length_not_measured_says_why_in_the_gait_summary_table():
    """The real 16-IMU walk (no subject height in its session) left step length, stride length
    and speed empty in spatiotemporal_summary.csv with an empty note, the reason only in the
    report's footnote; a table read alone (or a study's gait table) had blanks without a word.
    A withheld number's own reason (the legs' clocks not linked) is kept."""
    from types import SimpleNamespace as NS

    from motionlab.kinematics import spatiotemporal as sp
    from motionlab.report.csv import LENGTH_PARAMETERS, gait_summary_frame
    from motionlab.results import Gait

    n = 8
    table = pd.DataFrame({"side": ["r"] * n + ["l"] * n, "start_s": np.arange(2 * n, dtype=float),
                          "kept": True, "reason": ""})  # fmt: skip
    for c in sp.STRIDE_COLUMNS:
        table[c] = np.nan if c in LENGTH_PARAMETERS else 1.0 + 0.01 * np.arange(2 * n)
    why = "not measured: no subject height_m (or thigh_m and shank_m) in the sensor map"
    for not_linked, expect in (("", why), ("not given: clocks", "not given: clocks")):
        g = Gait(status="ok", summary=sp.summary(table, not_linked), walking_speed=why)
        rows = gait_summary_frame(NS(session=NS(results=NS(gait=g)))).set_index(
            ["parameter", "side"]
        )
        assert rows.loc[("step_length_m", "r"), "note"] == expect
        assert rows.loc[("walking_speed_m_s", "both"), "note"] == expect
        assert rows.loc[("walking_speed_m_s", "both"), "count_n"] == 0  # was every kept stride
        assert rows.loc[("cadence_steps_per_min", "both"), "count_n"] == 2 * n
        assert rows.loc[("stride_time_s", "r"), "note"] == ""  # given: no note
        assert np.isnan(rows.loc[("stride_length_m", "l"), "mean"])


def test_a_mean_of_too_few_strides_says_so_in_the_gait_summary_table():
    """A short walk (the batch bench's 8-s walks: one stride a side) left stride time, stance,
    ... empty with count 1 and no note; the note now says the mean needs 3 strides."""
    from types import SimpleNamespace as NS

    from motionlab.kinematics import spatiotemporal as sp
    from motionlab.report.csv import gait_summary_frame
    from motionlab.results import Gait

    table = pd.DataFrame({"side": ["r", "l", "l", "l"], "start_s": [0.0, 0.5, 1.5, 2.5],
                          "kept": True, "reason": ""})  # fmt: skip
    for c in sp.STRIDE_COLUMNS:
        table[c] = 1.0
    g = Gait(status="ok", summary=sp.summary(table), walking_speed="model")
    rows = gait_summary_frame(NS(session=NS(results=NS(gait=g)))).set_index(["parameter", "side"])
    assert rows.loc[("stride_time_s", "r"), "note"] == "not enough steady strides (1 of 3 needed)"
    assert rows.loc[("stride_time_s", "l"), "note"] == "" and rows.loc[("stride_time_s", "l"),
                                                                    "mean"] == 1.0  # fmt: skip


def test_a_one_leg_walk_says_why_the_other_legs_rows_are_empty():
    """A walk of the right leg's sensors only left every left-leg row of the gait summary, and
    the right leg's step time, double support and lengths, empty with no note."""
    from types import SimpleNamespace as NS

    from motionlab.kinematics import spatiotemporal as sp
    from motionlab.report.csv import gait_summary_frame
    from motionlab.results import Gait, StrideTable

    n = 8
    table = pd.DataFrame({"side": "r", "start_s": np.arange(n, dtype=float), "kept": True,
                          "reason": ""})  # fmt: skip
    for c in sp.STRIDE_COLUMNS:
        table[c] = np.nan if c in sp.BOTH_LEGS else 1.0 + 0.01 * np.arange(n)
    columns = {c: table[c].to_numpy() for c in table.columns if c not in ("side", "reason")}
    strides = StrideTable(**columns, side=table["side"].to_numpy(str),
                          reason=table["reason"].to_numpy(str))  # fmt: skip
    g = Gait(status="ok", summary=sp.summary(table), strides=strides,
             walking_speed="not measured: needs both legs")  # fmt: skip
    rows = gait_summary_frame(NS(session=NS(results=NS(gait=g)))).set_index(["parameter", "side"])
    left = rows.xs("l", level="side")
    assert left["mean"].isna().all() and (left["count_n"] == 0).all()
    assert set(left["note"]) == {"not measured: only the right leg measured"}
    for c in ("step_time_s", "double_support_pct", "step_length_m", "walking_speed_m_s"):
        assert rows.loc[(c, "r"), "note"] == "only the right leg measured: needs both legs"
    assert rows.loc[("stride_time_s", "r"), "note"] == "" and rows.loc[("stride_time_s", "r"),
                                                                    "count_n"] == n  # fmt: skip
