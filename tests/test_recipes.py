"""The recipes of ``docs/architecture.md`` ("Adding a reader / an estimator / a report page"),
each done here the way the recipe says and nothing else: a reader module and its name in
``READER_MODULES``; an estimator module registered with ``@register`` (its name in
``ESTIMATOR_MODULES``); a page function and its call in ``_session_pages``. What the recipe
promises then follows without another edit: ``motionlab ingest`` reads the new format,
``motionlab fuse --list`` and ``--filter`` know the estimator, the report holds the page. (A joint
type, a segment and a run option are one table entry each: ``tests/test_joint_types.py``,
``tests/test_segment_types.py`` and ``tests/test_cli_flags.py`` check those tables, and the
worked examples are in the architecture's recipes.)"""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import motionlab.report as report
from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.fusion import registry
from motionlab.fusion.attitude import tilt_quaternion
from motionlab.io import READER_MODULES, Recording
from motionlab.session import SensorStream, load_session

MAGIC = b"TOYIMU 1\n"


def _toy_reader() -> types.ModuleType:
    """A reader for a made-up format: a magic line, then ``t_ms gx gy gz ax ay az`` rows
    (ms, deg/s, g)."""

    def sniff(path: Path, head: bytes) -> bool:
        return head.startswith(MAGIC)

    def read(path: Path, options: dict | None) -> Recording:
        options = options or {}
        try:
            rows = np.loadtxt(path, skiprows=1, ndmin=2)
        except ValueError as exc:
            raise InputError(f"not a number ({exc})", path, remedy="re-export the file") from None
        stream = SensorStream(
            label=str(options.get("label") or path.stem), time=rows[:, 0] / 1e3,
            gyr=np.deg2rad(rows[:, 1:4]), acc=9.80665 * rows[:, 4:7], vendor="toy",
            source_units={"gyr": "deg/s", "acc": "g"},
        )  # fmt: skip
        return Recording(sensors=[stream], format="toyimu")

    module = types.ModuleType("motionlab.io.toyimu")
    module.FORMAT, module.sniff, module.read = "toyimu", sniff, read
    return module


@pytest.fixture
def toy_file(tmp_path) -> Path:
    """Ten seconds at 100 Hz of a sensor lying still, then turning at 30 °/s about its z axis."""
    t = np.arange(1000) * 10.0
    gyr = np.zeros((1000, 3))
    gyr[500:, 2] = 30.0
    acc = np.tile([0.0, 0.0, 1.0], (1000, 1))
    path = tmp_path / "shank.toy"
    rows = np.column_stack([t, gyr, acc])
    path.write_bytes(MAGIC + "\n".join(" ".join(f"{v:g}" for v in row) for row in rows).encode())
    return path


@pytest.fixture
def with_toy_reader(monkeypatch):
    """The reader recipe: the module, and its name first in ``READER_MODULES``."""
    monkeypatch.setitem(sys.modules, "motionlab.io.toyimu", _toy_reader())
    monkeypatch.setattr("motionlab.io.READER_MODULES", ("toyimu", *READER_MODULES))


def test_a_new_reader_is_a_module_and_its_name(with_toy_reader, toy_file, tmp_path):
    out = CliRunner().invoke(main, ["ingest", str(toy_file), "-o", str(tmp_path / "s.h5")])
    assert out.exit_code == 0, out.output
    stream = load_session(tmp_path / "s.h5").sensors["shank"]
    assert stream.n_samples == 1000 and stream.source_units["gyr"] == "deg/s"
    assert np.allclose(np.rad2deg(stream.gyr[-1]), [0.0, 0.0, 30.0])
    assert np.allclose(stream.acc[0], [0.0, 0.0, 9.80665])
    toy_file.write_bytes(MAGIC + b"0 0 0 zero 0 0 1\n")  # its bad input is one line, exit 2
    out = CliRunner().invoke(main, ["ingest", str(toy_file), "-o", str(tmp_path / "t.h5")])
    assert out.exit_code == 2 and "shank.toy" in out.output and "re-export" in out.output


@dataclass
class GyroOnlyParams:
    """The toy estimator's parameters."""

    tilt_window: float = registry.param(0.5, "s", "accelerometer average that sets the start")


def gyro_only(gyr, acc, mag, rate, params: GyroOnlyParams) -> registry.FusionResult:
    """Strapdown integration from the tilt of the first ``tilt_window`` seconds."""
    n0 = max(1, int(params.tilt_window * rate))
    q0 = tilt_quaternion(acc[:n0].mean(axis=0))
    quat = rot.integrate_gyro(q0, gyr, 1.0 / rate)
    return registry.FusionResult(quat, "gyro_only", {"tilt_window": params.tilt_window})


def test_a_new_estimator_is_a_registered_function(with_toy_reader, toy_file, tmp_path, monkeypatch):
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry.available()))
    registry.register("gyro_only", GyroOnlyParams, "strapdown from the first tilt")(gyro_only)
    runner = CliRunner()
    listed = runner.invoke(main, ["fuse", "--list"])
    assert listed.exit_code == 0 and "gyro_only" in listed.output and "tilt_window" in listed.output
    session = tmp_path / "s.h5"
    assert runner.invoke(main, ["ingest", str(toy_file), "-o", str(session)]).exit_code == 0
    out = runner.invoke(main, ["fuse", str(session), "--filter", "gyro_only"])
    assert out.exit_code == 0, out.output
    entry = load_session(session).results.fusion["shank"]
    assert entry.name == "gyro_only" and entry.params == {"tilt_window": 0.5}
    turned = np.rad2deg(rot.angle_between(entry.quat[0], entry.quat[-1]))
    assert turned == pytest.approx(30.0 * 4.99, abs=0.5)  # 499 intervals of 10 ms at 30 °/s


def test_a_new_report_page_is_a_function_and_its_call(tmp_path, monkeypatch):
    from motionlab.pipeline import PipelineOptions, analyse
    from motionlab.report import load_view, write_report
    from motionlab.simulate import simulate
    from motionlab.simulate.errors import get_preset

    def my_page(doc, view) -> None:
        doc.section("Toy page")
        doc.paragraph(f"{len(view.session.sensors)} sensors on this page.")

    pages = report._session_pages

    def session_pages(doc, view) -> None:  # the one call added at the end of _session_pages
        pages(doc, view)
        my_page(doc, view)

    monkeypatch.setattr(report, "_session_pages", session_pages)
    session, _ = simulate("walk", 30.0, 0, get_preset("clean"), rate_hz=50.0)  # stand and walk
    analyse(session, PipelineOptions(protocol="walk"))
    write_report([load_view(session)], tmp_path / "r.pdf")
    text = (tmp_path / "r.txt").read_text()
    assert "Toy page" in text and f"{len(session.sensors)} sensors on this page." in text


def test_a_new_joint_type_is_one_table_entry(tmp_path, monkeypatch):
    """A "stifle" type (the knee's table entry under another name, its columns named by the
    joint) gives a protocol's knee the knee's angles, with nothing but the entry added."""
    import copy
    import dataclasses

    import yaml

    from motionlab.kinematics.joint_types import JOINT_TYPES
    from motionlab.pipeline import PipelineOptions, analyse
    from motionlab.protocol import PACKAGED
    from motionlab.simulate import simulate
    from motionlab.simulate.errors import get_preset

    stifle = dataclasses.replace(JOINT_TYPES["knee"], name="stifle", clinical=False,
                                 display="stifle", opensim=(), plugin_gait=None)  # fmt: skip
    monkeypatch.setitem(JOINT_TYPES, "stifle", stifle)
    tree = yaml.safe_load((PACKAGED / "knee.yaml").read_text())
    tree["joints"]["knee_r"]["type"] = "stifle"
    protocol = tmp_path / "stifle.yaml"
    protocol.write_text(yaml.safe_dump(tree))
    session, _ = simulate("knee", 190.0, 3, get_preset("clean"), rate_hz=50.0)
    other = copy.deepcopy(session)
    analyse(session, PipelineOptions(protocol="knee", clock_sync=False))  # one radio clock
    analyse(other, PipelineOptions(protocol=protocol, clock_sync=False))
    knee, stifled = session.results.angles, other.results.angles
    for angle in stifle.angle_names:
        a, b = knee.data[f"knee_r_{angle}_deg"], stifled.data[f"knee_r_{angle}_deg"]
        assert np.nanmax(np.abs(a - b)) < 1e-9, angle
    assert stifled.units["knee_r_flexion_deg"] == "deg"
