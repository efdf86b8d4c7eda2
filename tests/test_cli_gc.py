"""The command line's garbage-collector handling around the libraries' imports."""

import ast
import gc
import inspect
import sys

from motionlab import pipeline
from motionlab.cli import frozen_imports, paused_gc


def test_frozen_for_the_block_only():
    """Imports the modules, keeps what is alive out of the collections inside the block, and
    leaves the collector as it found it after (nothing frozen, on or off as before)."""
    assert gc.isenabled()
    with frozen_imports("json.decoder"):
        assert "json.decoder" in sys.modules
        assert gc.isenabled() and gc.get_freeze_count() > 0
    assert gc.isenabled() and gc.get_freeze_count() == 0
    gc.disable()
    try:
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()  # it was off: stays off
    finally:
        gc.enable()


def test_run_imports_are_what_run_pipeline_imports():
    """``RUN_IMPORTS``, which ``motionlab run`` loads before the stages, names every module
    ``run_pipeline`` imports in its body."""
    body = ast.parse(inspect.getsource(pipeline.run_pipeline))
    inside = {n.module for n in ast.walk(body) if isinstance(n, ast.ImportFrom)}
    inside |= {a.name for n in ast.walk(body) if isinstance(n, ast.Import) for a in n.names}
    assert inside == set(pipeline.RUN_IMPORTS)
