"""The command line imports what a command needs when it runs: ``import motionlab.cli`` and
``motionlab --help`` import neither the pipeline nor numba, scipy or matplotlib, and the light
commands' ``--help`` neither; ``import motionlab.pipeline`` (``run --help``, ``batch --help``)
leaves scipy's signal, stats and spatial packages, pandas and matplotlib to the stages that use
them (checked in a fresh interpreter through ``sys.modules``; no timing).
``motionlab --help`` lists each command with the one-line help of ``cli.COMMANDS``, which must be
the command's own."""

from __future__ import annotations

import os
import subprocess
import sys

import click
import pytest
from click.utils import make_default_short_help
from conftest import ROOT

from motionlab.cli import COMMANDS, main

HEAVY = ("numba", "scipy", "matplotlib", "pandas", "h5py", "motionlab.pipeline", "motionlab.report")
#: commands whose options need no library table (run and batch read the pipeline's options,
#: fuse, ingest, simulate, validate, export and sensorcal their choices and defaults from
#: library modules that import numpy and scipy)
LIGHT = ("info", "angles", "calibrate", "metrics", "sync", "report", "demo")
#: what importing the pipeline must not load: a stage imports them where it uses them
#: (scipy.signal alone loads scipy.stats, ~1 s of start-up, and the run never uses scipy.stats)
PIPELINE_LAZY = ("scipy.signal", "scipy.stats", "scipy.spatial", "pandas", "matplotlib")


def _imported_after(code: str, heavy: tuple[str, ...] = HEAVY) -> list[str]:
    probe = f"{code}\nimport sys\nprint(' '.join(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return out.stdout.split()


def test_import_cli_imports_nothing_heavy():
    assert _imported_after("import motionlab.cli") == []


@pytest.mark.parametrize("args", [["--help"], *[[c, "--help"] for c in LIGHT]])
def test_help_imports_nothing_heavy(args):
    code = (
        "from click.testing import CliRunner\nfrom motionlab.cli import main\n"
        f"r = CliRunner().invoke(main, {args!r})\nassert r.exit_code == 0, r.output\n"
    )
    assert _imported_after(code) == []


def test_import_pipeline_leaves_scipy_signal_spatial_and_pandas_to_the_stages():
    assert _imported_after("import motionlab.pipeline", PIPELINE_LAZY) == []
    for command in ("run", "batch"):
        code = (
            "from click.testing import CliRunner\nfrom motionlab.cli import main\n"
            f"r = CliRunner().invoke(main, [{command!r}, '--help'])\nassert r.exit_code == 0\n"
        )
        assert _imported_after(code, PIPELINE_LAZY) == [], command


def test_no_module_of_a_session_run_imports_scipy_signal():
    """Only the simulator (and its command) uses scipy.signal; the stages use motionlab.dsp, so
    a run never pays its import (SciPy 1.17: scipy.stats and the array-API docstrings,
    0.6-1.3 s)."""
    modules = sorted(
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for p in (ROOT / "motionlab").rglob("*.py")
        if "simulate" not in p.parts and p.name not in ("simulate.py", "__main__.py")
    )
    code = f"import importlib\nfor m in {modules!r}:\n    importlib.import_module(m)\n"
    assert _imported_after(code, ("scipy.signal", "scipy.stats")) == []


def test_one_line_help_is_each_commands_own():
    ctx = click.Context(main)
    assert main.list_commands(ctx) == sorted(COMMANDS)
    for name, short in COMMANDS.items():
        command = main.get_command(ctx, name)
        assert command.name == name
        for limit in (30, 45, 60, 80, 400):
            assert make_default_short_help(short, limit) == command.get_short_help_str(limit)
    assert main.get_command(ctx, "no-such-command") is None


def test_the_listing_names_every_command():
    text = subprocess.run(
        [sys.executable, "-m", "motionlab", "--help"], cwd=ROOT, capture_output=True, text=True
    ).stdout
    for name in COMMANDS:
        assert f"\n  {name} " in text, name


def test_cli_sets_one_blas_thread_before_numpy_unless_the_user_did():
    probe = (
        "import os, sys\nimport motionlab.cli\n"
        "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['OMP_NUM_THREADS'],"
        " 'numpy' in sys.modules)"
    )
    env = {
        k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")
    }
    for preset, expected in ((None, "1 1 False"), ("4", "4 1 False")):
        run_env = env if preset is None else {**env, "OPENBLAS_NUM_THREADS": preset}
        out = subprocess.run(
            [sys.executable, "-c", probe], cwd=ROOT, env=run_env, capture_output=True, text=True,
            check=True,
        )  # fmt: skip
        assert out.stdout.strip() == expected


def test_the_commands_own_process_ends_frozen_and_a_caller_keeps_its_collector():
    """``entry`` (the executable, ``python -m motionlab``) freezes the garbage collector's
    objects when the command ends (the shutdown walks none of them); ``main`` called in-process
    (a test, a notebook) leaves the caller's collector as it was."""
    import gc

    from click.testing import CliRunner

    probe = (
        "import atexit, gc, sys\n"
        "atexit.register(lambda: print('frozen', gc.get_freeze_count()))\n"
        "sys.argv = ['motionlab', 'info', '--help']\n"
        "from motionlab.cli import entry\n"
        "entry()\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0 and "Usage:" in out.stdout
    assert int(out.stdout.split("frozen")[-1]) > 1000
    before = gc.get_freeze_count()
    assert CliRunner().invoke(main, ["info", "--help"]).exit_code == 0
    assert gc.get_freeze_count() == before
