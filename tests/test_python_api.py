"""The Python API: ``import motionlab`` stays light, its names are the stage functions, and the
example script runs on the bundled demo."""

import importlib.util
import json
import subprocess
import sys

import numpy as np
from conftest import ROOT

import motionlab


def test_import_is_light_and_names_resolve():
    code = ("import sys, motionlab; heavy = {'numpy', 'h5py', 'numba', 'matplotlib', 'scipy'};"
            "print(sorted(heavy & set(sys.modules)))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    from motionlab import stages

    assert motionlab.fuse is stages.fuse and motionlab.validate is stages.validate
    assert {"load_session", "run_pipeline", "read_any", "export_session"} <= set(motionlab.__all__)
    assert all(getattr(motionlab, name) is not None for name in motionlab.__all__)
    assert motionlab.__version__


def test_example_runs_on_the_demo(tmp_path):
    spec = importlib.util.spec_from_file_location(
        "example", ROOT / "examples" / "knee_from_python.py"
    )
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    doc = example.main(tmp_path)
    flexion = np.array(doc["angles"]["joints"]["knee_r"]["columns"]["knee_r_flexion_deg"], float)
    assert 60 < np.nanmax(flexion) < 120
    saved = json.loads((tmp_path / "knee_results.json").read_text())
    assert saved["validation"]["sync"]["grade"] in ("good", "fair")
    assert saved["validation"]["angles"]["knee_r_flexion_deg"]["rmse_deg"] < 3.0
    assert (tmp_path / "knee_angles.mot").read_text().count("knee_angle_r") == 1
    # the stages as the README chains them compute what 'motionlab run' computes (the
    # example had left out the clock sync: RMSE 0.76° and an offset of 150 ms, not 0.92°)
    ran = motionlab.load_session(example.DEMO)
    motionlab.analyse(ran, motionlab.PipelineOptions("knee", progress=False))
    np.testing.assert_allclose(
        ran.results.angles.columns()["knee_r_flexion_deg"], flexion, atol=5e-5, equal_nan=True
    )
    assert saved["validation"]["sync"]["time_offset_s"] == ran.results.validation.sync.time_offset_s
    # each stage called from Python leaves its provenance entry (none did: the report's
    # provenance table listed no step after ingest); analyse leaves one
    staged = motionlab.load_session(example.DEMO)
    before = len(staged.provenance)
    motionlab.sync(staged, "knee")
    motionlab.fuse(staged)
    motionlab.calibrate(staged, "knee")
    motionlab.angles(staged)
    motionlab.metrics(staged)
    motionlab.validate(staged)
    entries = [p["parameters"] for p in staged.provenance[before:]]
    assert [e["stage"] for e in entries] == [
        "sync", "fuse", "calibrate", "angles", "metrics", "validate"
    ]  # fmt: skip
    assert entries[1]["filter"] == "default" and entries[1]["magnetometer"] is False
    assert ran.provenance[-1]["parameters"]["stage"] == "analyse"
    assert [p["parameters"].get("stage") for p in ran.provenance].count("fuse") == 0


def test_natural_mistakes_in_python_are_input_errors(tmp_path):
    """What a script writer tries first: a path where the session goes, a sensor the session
    lacks, a typo in an option, a reference file's path. They raised AttributeError,
    KeyError, or were taken silently; now each is an InputError naming the argument, and a
    reference path is read as the CLI reads it."""
    import pytest

    from motionlab.errors import InputError

    demo = ROOT / "motionlab" / "data" / "demo" / "knee.h5"
    with pytest.raises(InputError, match="got a path where a Session goes"):
        motionlab.fuse(str(demo))
    session = motionlab.load_session(demo)
    with pytest.raises(InputError, match="no sensor 'nope' in the session"):
        motionlab.fuse(session, sensors=["nope"])
    assert list(motionlab.fuse(session, sensors="shank_r")) == ["shank_r"]  # one label, whole
    with pytest.raises(InputError, match="frames='bogus' is unknown"):
        motionlab.validate(session, frames="bogus")
    with pytest.raises(InputError, match="reference_kind='marker' is unknown"):
        motionlab.validate(session, reference_kind="marker")
    with pytest.raises(InputError, match="no such reference file"):
        motionlab.validate(session, reference=str(tmp_path / "none.c3d"))
    for cutoff in (-1, float("nan"), True, "6"):  # the stage's own check, before any work
        with pytest.raises(InputError, match="is not a cut-off"):
            motionlab.angles(session, angle_lowpass_hz=cutoff)
    # a protocol whose every joint lacks a sensor (the knee recording given the arm protocol)
    # stopped in the angles with a bare StopIteration; analyse refuses it as run does
    with pytest.raises(InputError, match="no joint of the 'arm' protocol has sensors on both"):
        motionlab.analyse(motionlab.load_session(demo), motionlab.PipelineOptions("arm"))


def test_the_csv_tables_are_pandas_frames_from_python(tmp_path):
    """The metrics table could be had only through a private path of the report's; it is
    ``session_tables`` now, the same frames ``write_report`` writes."""
    from motionlab.session import load_session

    session = load_session(ROOT / "motionlab" / "data" / "demo" / "knee.h5")
    motionlab.analyse(session, motionlab.PipelineOptions("knee", progress=False))
    frames = motionlab.session_tables(session)
    metrics = frames["metrics.csv"]
    assert {"task", "joint", "angle", "rom_deg", "vs_normal", "grade"} <= set(metrics.columns)
    flexion = metrics[(metrics.joint == "knee_r") & (metrics.angle == "flexion")]
    assert len(flexion) >= 1 and (flexion.rom_deg > 30).all()
    out = motionlab.write_report(motionlab.load_views([session]), tmp_path / "r.pdf", tmp_path)
    assert {p.name for p in out.csv_paths} == set(frames)


def test_pipeline_options_of_the_wrong_kind_are_refused():
    """``clock_sync="no"`` is truthy and ran the sync; ``frames="bogus"`` was taken as
    ``body``; ``seed="x"`` failed deep inside the validation."""
    import pytest

    from motionlab.errors import InputError

    for kw, what in (({"clock_sync": "no"}, "expected True or False"),
                     ({"frames": "bogus"}, "expected one of anatomical, body"),
                     ({"seed": "x"}, "expected an integer"),
                     ({"map_path": 123}, "expected a path"),
                     ({"angle_lowpass_hz": -6}, r"expected 0 or more \(0 keeps the angles"),
                     ({"angle_lowpass_hz": 6.5}, "expected an integer")):  # fmt: skip
        with pytest.raises(InputError, match=what):
            motionlab.PipelineOptions("knee", **kw)
    assert motionlab.PipelineOptions("knee", seed=3, clock_sync=False).seed == 3


def test_a_stage_imported_first_leaves_ingest_and_simulate_the_functions():
    """After any stage (``motionlab.sync``) the import system had bound the submodule
    ``motionlab.ingest`` over the function of that name: ``ml.ingest(paths)`` then raised
    "'module' object is not callable", as did ``ml.simulate`` after a bench imported its
    package."""
    code = (
        "import motionlab as ml, motionlab.stages, motionlab.ingest, motionlab.simulate.truth;"
        "print(callable(ml.ingest), callable(ml.simulate), ml.ingest.__module__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "True", "motionlab.ingest"]
