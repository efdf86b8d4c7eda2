"""motionlab demo on the bundled examples: the acceptance checks of the report issue.

The PDF has at least 8 pages (counted in the PDF itself), its text (``pdftotext`` where the
machine has it, else the text the writer stores) names every joint and plane, the CSV headers
carry units, no text on any page overlaps or leaves the page, and the shipped data stay small.
"""

import re
import shutil
import subprocess
from pathlib import Path

import matplotlib
import pandas as pd
import pytest
from click.testing import CliRunner

from motionlab.cli import main
from motionlab.cli.demo import DEMO_DIR, EXAMPLES
from motionlab.report import build_document, load_views
from motionlab.report.pdf import RC, layout_problems
from motionlab.session import load_session

UNIT = re.compile(r"_(deg|s|hz|ms|pct|n|ratio|m|m_s|m_s2|ut|per_min)$")
TEXT_COLUMNS = {
    "task",
    "joint",
    "angle",
    "plane",
    "vs_normal",
    "metric",
    "sensor",
    "serial",
    "segment",
    "side",
    "channels",
    "qc_flags",
    "method",
    "step",
    "kind",
    "segment_ok",
    "in_fit",  # calibration.csv: the axis entered the segment's fit
    "movement_axis_verdict",  # and, for an axis found in the movement, its own check's grade
    "grade",
    "reason",
    "column",
    "kept",  # a stride kept or rejected (spatiotemporal.csv), with its reason
    "parameter",  # spatiotemporal_summary.csv: one row per parameter, its unit in its name
    "note",  # and why a number of it is withheld (as spatiotemporal_course.csv's)
}
# in spatiotemporal_summary.csv the unit of mean, sd, se, median and quartiles is the one in
# the row's parameter name
#: a long table whose values' unit is its ``unit`` column (the parameter's name's suffix)
PER_ROW_UNIT = {
    "spatiotemporal_summary.csv": {"unit", "mean", "sd", "se", "median", "q1", "q3", "count_of"}
}
WORDS = {
    "knee": ["Right knee", "Left knee", "flexion", "adduction", "rotation", "varus"],
    "elbow": ["Right elbow", "Left elbow", "flexion", "carrying", "pronation"],
}
PLANES = ["sagittal", "frontal", "transverse"]


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo")
    res = CliRunner().invoke(main, ["demo", "-o", str(out), "--quiet"])
    assert res.exit_code == 0, res.output
    assert "demo done" in res.output
    return out


def _pdf_pages(path: Path) -> int:
    return len(re.findall(rb"/Type\s*/Page[^s]", path.read_bytes()))


def _pdf_text(path: Path) -> str:
    if shutil.which("pdftotext"):
        return subprocess.run(
            ["pdftotext", "-layout", str(path), "-"], capture_output=True, check=True, text=True
        ).stdout
    return path.with_suffix(".txt").read_text()


def test_shipped_examples_are_small():
    sizes = [(DEMO_DIR / f).stat().st_size for f, _ in EXAMPLES.values()]
    assert sum(sizes) < 2_000_000


@pytest.mark.parametrize("name", list(EXAMPLES))
def test_report_pages_and_text(demo, name):
    pdf = demo / name / "report.pdf"
    assert _pdf_pages(pdf) >= 8
    stored = (demo / name / "report.txt").read_text().split("\f")
    assert len(stored) == _pdf_pages(pdf)
    text = _pdf_text(pdf)
    for word in WORDS[name] + PLANES:
        assert word in text, word
    assert "Validation against optical motion capture" in text
    assert "Expected accuracy" in text and "SHA-256" in text


@pytest.mark.parametrize("name", list(EXAMPLES))
def test_csv_headers_carry_units(demo, name):
    csv_dir = demo / name / "csv"
    angles = sorted(csv_dir.glob("*_angles.csv"))
    assert [p.name for p in angles] == [f"{name}_l_angles.csv", f"{name}_r_angles.csv"]
    for path in csv_dir.glob("*.csv"):
        frame = pd.read_csv(path)
        assert len(frame), path.name
        for col in frame.columns:
            allowed = TEXT_COLUMNS | PER_ROW_UNIT.get(path.name, set())
            assert col in allowed or UNIT.search(col), f"{path.name}: {col}"
    table = pd.read_csv(angles[0])
    assert table.columns[0] == "time_s" and all(c.endswith("_deg") for c in table.columns[1:])
    assert table["time_s"].is_monotonic_increasing


def test_normal_simulated_elbow_motion_is_not_flagged(demo):
    """The simulated subject moves its elbows within the task-specific normal ranges."""
    from motionlab.report.model import rom_rows

    view = load_views([load_session(demo / "elbow" / "session.h5")])[0]
    rows = [r for r in rom_rows(view) if r.normal]
    assert {r.task for r in rows} == {"reaching", "hand_to_mouth"}
    assert all(r.status == "within" for r in rows), [
        (r.task, r.column, r.status) for r in rows if r.status != "within"
    ]


def test_no_text_overlaps_or_leaves_any_page(demo):
    views = load_views([load_session(demo / "knee" / "session.h5")])
    with matplotlib.rc_context(RC):
        doc = build_document(views)
        problems = [
            f"page {i}: {p}" for i, fig in enumerate(doc.pages, 1) for p in layout_problems(fig)
        ]
    assert problems == []


def _body(text: str, *folders: Path) -> list[str]:
    """A report's text without the lines that name files (in ``folders``), times and the
    software."""
    noise = (*(str(f) for f in folders), "written", "Written", "seconds", "motionlab 0")
    return [line for line in text.splitlines() if not any(n in line for n in noise)]


def test_a_report_rebuilt_from_the_session_file_says_what_run_said(demo, tmp_path):
    """The session file keeps the order of every result's keys, so a report rebuilt from it
    lists joints, sensors, tasks and flags as ``run``'s report did (one path)."""
    rebuilt = tmp_path / "rebuilt.pdf"
    session = demo / "knee" / "session.h5"
    res = CliRunner().invoke(main, ["report", str(session), "-o", str(rebuilt)])
    assert res.exit_code == 0, res.output
    ran = (demo / "knee" / "report.txt").read_text(encoding="utf-8")
    again = rebuilt.with_suffix(".txt").read_text(encoding="utf-8")
    assert len(_body(ran, demo)) > 500
    assert _body(again, demo, tmp_path) == _body(ran, demo, tmp_path)
