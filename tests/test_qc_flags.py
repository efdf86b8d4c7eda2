"""QC flags for held samples, identical streams and assumed rates (ingest, info)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from conftest import SHARED, generic_reader, needs_shared

from motionlab.cli import main
from motionlab.ingest import ingest
from motionlab.qc import check_stream
from motionlab.session import SensorStream

MAP = {"reader": generic_reader()}


def _held_stream(rate: float = 1000 / 6, real: float = 50.0, seconds: float = 6.0):
    """A ``real`` Hz signal sent on a ``rate`` grid: each row repeats the last real sample."""
    rng = np.random.default_rng(4)
    t = np.arange(int(seconds * rate)) / rate
    fresh = rng.normal(size=(int(seconds * real) + 1, 6)) + [0, 0, 9.81, 0, 0, 0]
    rows = fresh[np.floor(t * real + 1e-9).astype(int)]
    return t, rows


def test_held_samples_flagged_with_the_real_rate():
    t, rows = _held_stream()
    qc = check_stream(SensorStream("s", t, acc=rows[:, :3], gyr=rows[:, 3:]), 0.1)
    assert qc["flags"]["held_samples"]
    assert qc["held_share"] == pytest.approx(0.7, abs=0.01)
    assert qc["effective_rate_hz"] == pytest.approx(50.0, rel=0.02)
    rng = np.random.default_rng(1)
    fresh = SensorStream("f", t, acc=rng.normal(size=(len(t), 3)), gyr=rng.normal(size=(len(t), 3)))
    assert not check_stream(fresh, 0.1)["flags"]["held_samples"]


def test_identical_streams_and_held_samples_in_info(tmp_path):
    t, rows = _held_stream()
    cols = ["t", "ax", "ay", "az", "gx", "gy", "gz"]
    for name in ("a.csv", "b.csv"):
        pd.DataFrame(np.column_stack([t, rows]), columns=cols).to_csv(tmp_path / name, index=False)
    rng = np.random.default_rng(2)
    other = np.column_stack([t, rng.normal(size=(len(t), 6)) + [0, 0, 9.81, 0, 0, 0]])
    pd.DataFrame(other, columns=cols).to_csv(tmp_path / "c.csv", index=False)
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(MAP))
    files = [tmp_path / n for n in ("a.csv", "b.csv", "c.csv")]
    ses = ingest(files, tmp_path / "map.yaml")
    a, b, c = ses.sensors.values()
    assert a.qc["identical_to"] == [b.label] and b.qc["flags"]["identical_stream"]
    assert not c.qc["flags"].get("identical_stream")
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(main, ["ingest", *map(str, files), "--map", str(tmp_path / "map.yaml"),
                                    "-o", str(out)])  # fmt: skip
    assert res.exit_code == 0, res.output
    info = CliRunner().invoke(main, ["info", str(out)]).output
    assert "held_samples" in info and "≈ 50 Hz real" in info
    assert "identical_stream" in info and "identical to: " in info


@needs_shared
def test_xsens_assumed_rate_is_a_qc_flag(tmp_path):
    path = SHARED / "formats" / "xsens" / "MT2022_ACC_00B42D4B.txt"
    out = tmp_path / "x.h5"
    assert CliRunner().invoke(main, ["ingest", str(path), "-o", str(out)]).exit_code == 0
    info = CliRunner().invoke(main, ["info", str(out)]).output
    assert "qc flags: rate_assumed" in info and "100.0 Hz assumed" in info
    js = CliRunner().invoke(main, ["info", str(out), "--json"]).output
    assert '"rate_assumed": true' in js
