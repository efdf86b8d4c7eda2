"""``motionlab demo``: the whole pipeline on the examples shipped inside the package."""

from __future__ import annotations

import time
from pathlib import Path

import click

from motionlab.cli import frozen_imports
from motionlab.cli.paths import FOLDER

DEMO_DIR = Path(__file__).resolve().parent.parent / "data" / "demo"
#: example name → (session file in DEMO_DIR, protocol)
EXAMPLES = {"knee": ("knee.h5", "knee"), "elbow": ("elbow.h5", "elbow")}


@click.command("demo")
@click.option(
    "-o",
    "--output",
    "outdir",
    default="motionlab-demo",
    show_default=True,
    type=FOLDER,
    help="Output folder (one subfolder per example).",
)
@click.option("--only", type=click.Choice(list(EXAMPLES)), help="Run one example only.")
@click.option("--force", is_flag=True, help="Replace existing outputs.")
@click.option("--quiet", is_flag=True, help="No progress on stderr.")
def command(outdir: str, only: str | None, force: bool, quiet: bool) -> None:
    """Run 'motionlab run' on the bundled examples: a simulated bilateral knee session and a
    simulated elbow session, both with optical markers (so the report has its validation
    pages). Writes OUTDIR/<example>/report.pdf, report.txt, session.h5 and csv/.

    \b
    Example:
      motionlab demo -o demo
      motionlab demo --only knee -o demo --force
    """
    from motionlab.pipeline import RUN_IMPORTS, PipelineOptions, run_pipeline

    t0 = time.perf_counter()
    reports = []
    for name, (file, protocol) in EXAMPLES.items():
        if only and name != only:
            continue
        if not quiet:
            click.echo(f"== example '{name}': {DEMO_DIR / file}", err=True)
        options = PipelineOptions(protocol, force=force, progress=not quiet)
        with frozen_imports(*RUN_IMPORTS):
            result = run_pipeline([DEMO_DIR / file], Path(outdir) / name, options)
        click.echo(result.summary)
        click.echo("")
        reports.append(result.report_path)
    click.echo(
        f"demo done in {time.perf_counter() - t0:.0f} s; open "
        + " and ".join(str(p) for p in reports)
    )
