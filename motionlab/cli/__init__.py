"""The ``motionlab`` command: a click group whose subcommands live one per module here.

Each command only parses, calls the library, prints, and maps errors to exit codes:
:class:`~motionlab.errors.InputError` → one line on stderr and exit 2; any other exception is a
bug → exit 1 (``motionlab --debug ...`` shows the traceback).

A command's module is imported when the command is looked up (:data:`COMMANDS`), so that
``import motionlab.cli`` and ``motionlab --help`` import neither the pipeline nor numba, scipy or
matplotlib; ``motionlab --help`` lists the commands with their one-line help from that table
(``tests/test_cli_lazy.py`` holds it equal to each command's own).
"""

from __future__ import annotations

import contextlib
import errno
import gc
import os
import sys
import traceback
import warnings
from collections.abc import Iterator
from importlib import import_module

import click
from click.utils import make_default_short_help

from motionlab import __version__
from motionlab.errors import InputError

EXIT_BAD_INPUT = 2
EXIT_BUG = 1
#: the reader of our output stopped reading (a pipe into head): 128 + SIGPIPE, as a shell reports it
EXIT_BROKEN_PIPE = 141
#: errors of a device that takes no more: no space, over quota
FULL_DEVICE = (errno.ENOSPC, errno.EDQUOT)


#: One BLAS/OpenMP thread: a threaded BLAS splits a product's sums by the machine's core count,
#: so the same session gave numbers differing in the seventh digit on two machines, and between
#: ``run`` and ``batch`` (whose workers have one thread); the matrices here are small (3 × 3 to a
#: few hundred rows), and idle OpenBLAS threads spin for 2**28 cycles after each call (a third of
#: the validate stage's CPU time, docs/performance.md). Set before numpy loads OpenBLAS (a
#: command's module imports it); a value the user set is kept.
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
for _name, _value in BLAS_THREADS.items():
    os.environ.setdefault(_name, _value)


#: command → its one-line help (the first sentence of its docstring) for ``motionlab --help``;
#: the command is ``motionlab.cli.<command>.command``
COMMANDS = {
    "angles": "Compute joint angles (degrees) and store them in the session.",
    "batch": "Process every session of the study MANIFEST (study.yaml) as 'motionlab run' does.",
    "calibrate": "Find the protocol's calibration steps, fit each segment's mounting, report "
    "quality.",
    "demo": "Run 'motionlab run' on the bundled examples: a simulated bilateral knee session and "
    "a simulated elbow session, both with optical markers (so the report has its validation "
    "pages).",
    "export": "Write SESSION's results in another tool's format.",
    "fuse": "Estimate each sensor's orientation (sensor → ENU earth) and store it in the session.",
    "info": "Summarise a session file: sensors, rates, gaps, QC flags, markers, results.",
    "ingest": "Read recording FILES into one session file.",
    "metrics": "Per task, joint and plane: range of motion, peaks, repetitions, mean ± SD cycle "
    "curve; and the protocol's out-of-plane metrics (cross-talk, lumbar out-of-plane offset, "
    "trunk compensation, knee varus thrust and stance rotation).",
    "report": "Write the report of analysed SESSIONS (from motionlab run, or calibrate + angles "
    "+ metrics).",
    "run": "Analyse recording FILES (or one session file) from raw data to the report.",
    "sensorcal": "Calibrate each sensor of SOURCE (a session or a vendor file) and file it by "
    "serial.",
    "simulate": "Simulate a recording of PROTOCOL: IMU signals, optical markers and the exact "
    "truth.",
    "sync": "Estimate each IMU's clock offset and drift against its neighbour's and correct the "
    "stamps.",
    "validate": "Compare SESSION with an optical reference: clock sync, frame alignment, "
    "orientation errors and joint-angle agreement; results go into the session for the report.",
}


@contextlib.contextmanager
def frozen_imports(*modules: str) -> Iterator[None]:
    """Import ``modules`` with Python's cyclic garbage collector paused, then keep everything
    alive at that point out of its collections (``gc.freeze``) for the block.

    A command's libraries (numpy, scipy, numba, pandas, matplotlib) leave some 340 000 objects
    that live as long as the process; the collector's full passes walked them all again and
    again, during the imports (0.2-0.3 s of a ``run``'s CPU) and whenever a stage's allocations
    set one off (0.15 s each). Frozen, they are left alone; after the block they are unfrozen
    (``gc.unfreeze``), so that a process running several commands (the tests, through click's
    runner) frees their garbage as before. docs/performance.md, sixth round.
    """
    with paused_gc():
        for name in modules:
            import_module(name)
        gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextlib.contextmanager
def paused_gc() -> Iterator[None]:
    """Python's cyclic garbage collector off in the block (on after it if it was before)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


class MotionlabGroup(click.Group):
    """Click group that imports a command's module when the command is used, and turns
    exceptions into one clear line and an exit code."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        with paused_gc():  # its module imports the library (frozen_imports)
            return import_module(f"motionlab.cli.{cmd_name}").command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The commands and their one-line help, from :data:`COMMANDS` (no module imported)."""
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = [(n, make_default_short_help(COMMANDS[n], limit)) for n in names]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def invoke(self, ctx: click.Context):
        try:
            with warnings.catch_warnings():  # main() silences numpy's warnings in here
                return super().invoke(ctx)
        except InputError as exc:
            from motionlab.cli.flags import cli_error  # reads the run options' table

            if ctx.obj and ctx.obj.get("debug"):
                traceback.print_exc()
            click.echo(f"error: {cli_error(exc).line()}", err=True)
            sys.exit(EXIT_BAD_INPUT)
        except click.UsageError as exc:  # one line, as every other refusal
            where = exc.ctx.command_path if exc.ctx is not None else "motionlab"
            what = exc.format_message().rstrip(".")
            click.echo(f"error: {what} — see '{where} --help'", err=True)
            sys.exit(exc.exit_code)
        except (click.exceptions.Exit, click.ClickException, click.Abort, SystemExit):
            raise
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)
        except BrokenPipeError:  # the reader stopped reading (| head): stop quietly, as
            # a Unix tool does on SIGPIPE (outputs written before stay as written)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            sys.exit(EXIT_BROKEN_PIPE)
        except Exception as exc:  # a bug: say so, in one line unless --debug
            if isinstance(exc, OSError) and exc.errno in FULL_DEVICE:  # no bug: a full disk
                click.echo(f"error: cannot write ({exc.strerror}) — free some space", err=True)
                sys.exit(EXIT_BAD_INPUT)
            if ctx.obj and ctx.obj.get("debug"):
                traceback.print_exc()
            click.echo(
                f"internal error ({type(exc).__name__}: {exc}) — please report it; "
                "rerun with 'motionlab --debug ...' for the traceback",
                err=True,
            )
            sys.exit(EXIT_BUG)


@click.group(cls=MotionlabGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--debug", is_flag=True, help="Show the full traceback on errors.")
@click.version_option(__version__, prog_name="motionlab")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """motionlab: clinical motion analysis with wearable inertial sensors.

    \b
    Example:
      motionlab ingest shank.txt thigh.txt --map map.yaml -o session.h5
      motionlab info session.h5
    """
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    if not debug:  # numpy's RuntimeWarnings are no message for the user: QC flags and errors are
        warnings.simplefilter("ignore", RuntimeWarning)


def entry() -> None:
    """The ``motionlab`` executable and ``python -m motionlab``: :func:`main` in a process of its
    own, whose shutdown skips the garbage collector's last passes.

    The interpreter's shutdown collects over every object the command and its imports left
    (some 340 000 after a ``run``): about 1 s of wall time after the knee demo's last line. At
    the command's end everything is frozen (:func:`gc.freeze`): nothing left there is garbage
    anyone waits for. :func:`main` called in-process (a test, a notebook) keeps its collector
    (docs/performance.md, "The garbage collector in the command's own process").
    """
    try:
        main()
    finally:
        gc.freeze()
