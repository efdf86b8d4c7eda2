"""The study tables of real (simulated) sessions, as a researcher merging them reads them: a
joint with no sensor keeps its rows and says why, each metric row carries its angle's normal
range and comparison as the session's own metrics.csv does, and a gait number withheld has no
count of strides it was not computed from."""

import csv

import pytest

from motionlab.batch import load_manifest, run_study
from motionlab.session import save_session
from motionlab.simulate import simulate


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A walk without a pelvis sensor and without the subject's height, through the real
    pipeline as ``motionlab batch`` runs it."""
    root = tmp_path_factory.mktemp("study")
    session, _ = simulate("walk", 30.0, 0, "clean", rate_hz=50.0)
    del session.sensors["pelvis"]
    session.metadata["subject"] = {}
    save_session(session, root / "walk.h5")
    (root / "study.yaml").write_text(
        "protocol: walk\nclock_sync: false\n"  # the recorded clocks taken as one
        "sessions:\n  - {subject: S01, visit: v1, files: walk.h5}\n"
    )
    result = run_study(load_manifest(root / "study.yaml"), root / "out", workers=1)
    assert result.ok, result.outcomes
    return root / "out"


def test_a_joint_without_a_sensor_says_so_in_the_study_metrics(study):
    """Without a pelvis sensor the hips were left out of study_metrics.csv, and nothing told
    why; they keep their rows, empty, graded 'not measured' with the reason."""
    rows = _rows(study / "study_metrics.csv")
    hips = [r for r in rows if r["joint"] in ("hip_r", "hip_l")]
    knees = [r for r in rows if r["joint"] == "knee_r" and r["column"]]
    assert {(r["angle"], r["metric"]) for r in hips if r["joint"] == "hip_r"} >= {
        (a, m) for a in ("flexion", "adduction", "rotation") for m in ("rom_deg", "min_deg")
    }
    assert {(r["value"], r["grade"], r["note"]) for r in hips} == {
        ("", "not measured", "not measured: no pelvis sensor")
    }
    assert knees and all(r["grade"] != "not measured" for r in knees)
    grades = _rows(study / "S01" / "v1" / "csv" / "grades.csv")
    assert {(r["grade"], r["reason"]) for r in grades if r["joint"].startswith("hip")} == {
        ("not measured", "not measured: no pelvis sensor")
    }


def test_the_study_metrics_carry_the_sessions_normal_ranges_and_flags(study):
    """study_metrics.csv had no normal range or comparison, which the session's metrics.csv
    has: each angle's rows now carry them, the same text; the session's own metrics.csv has the
    hips' rows too, empty and 'not measured', with their normal range."""
    rows = _rows(study / "study_metrics.csv")
    own = {(r["task"], r["joint"], r["angle"]): r
           for r in _rows(study / "S01" / "v1" / "csv" / "metrics.csv")}  # fmt: skip
    rom = [r for r in rows if r["metric"] == "rom_deg"]
    assert len(rom) == len(own) == 12
    assert sum(r["grade"] == "not measured" for r in own.values()) == 6
    for r in rom:
        trial = own[r["block"], r["joint"], r["angle"]]
        assert r["grade"] == trial["grade"] and r["vs_normal"] == trial["vs_normal"]
        for c in ("normal_min_deg", "normal_max_deg"):
            assert float(r[c]) == float(trial[c])
        assert bool(r["note"]) == (r["grade"] != "determined")
    knee = next(r for r in rom if r["joint"] == "knee_r" and r["angle"] == "flexion")
    assert (knee["normal_min_deg"], knee["normal_max_deg"]) == ("0.0", "65.0")  # walk.yaml


def test_a_withheld_walking_speed_counts_no_strides(study):
    """Without the subject's height no stride has a length, yet the bilateral walking speed,
    withheld, counted every kept stride (15 on this walk) in study_gait.csv."""
    rows = {(r["parameter"], r["side"]): r for r in _rows(study / "study_gait.csv")}
    speed = rows["walking_speed_m_s", "both"]
    assert speed["mean"] == "" and speed["count_n"] == "0"
    assert speed["note"].startswith("not measured: no subject height")
    assert (
        int(rows["cadence_steps_per_min", "both"]["count_n"])
        == sum(int(rows["stride_time_s", side]["count_n"]) for side in ("r", "l"))
        > 10
    )
