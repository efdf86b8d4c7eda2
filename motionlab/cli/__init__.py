"""The ``motionlab`` command: a click group whose subcommands live one per module here.

Each command only parses, calls the library, prints, and maps errors to exit codes:
:class:`~motionlab.errors.InputError` → one line on stderr and exit 2; any other exception is a
bug → exit 1 (``motionlab --debug ...`` shows the traceback).
"""

from __future__ import annotations

import sys
import traceback
import warnings

import click

from motionlab import __version__
from motionlab.cli.flags import cli_error
from motionlab.errors import InputError

EXIT_BAD_INPUT = 2
EXIT_BUG = 1


class MotionlabGroup(click.Group):
    """Click group that turns exceptions into one clear line and an exit code."""

    def invoke(self, ctx: click.Context):
        try:
            with warnings.catch_warnings():  # main() silences numpy's warnings in here
                return super().invoke(ctx)
        except InputError as exc:
            if ctx.obj and ctx.obj.get("debug"):
                traceback.print_exc()
            click.echo(f"error: {cli_error(exc).line()}", err=True)
            sys.exit(EXIT_BAD_INPUT)
        except (click.exceptions.Exit, click.ClickException, click.Abort, SystemExit):
            raise
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)
        except Exception as exc:  # a bug: say so, in one line unless --debug
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


def _register() -> None:
    from motionlab.cli import (
        angles,
        calibrate,
        demo,
        fuse,
        info,
        ingest,
        metrics,
        report,
        run,
        sensorcal,
        simulate,
        sync,
    )

    for module in (info, ingest, sync, sensorcal, calibrate, angles, metrics, fuse, simulate, run,
                   report, demo):  # fmt: skip
        main.add_command(module.command)
    from motionlab.cli import validate

    main.add_command(validate.command)
    from motionlab.cli import batch

    main.add_command(batch.command)
    from motionlab.cli import export

    main.add_command(export.command)


_register()
