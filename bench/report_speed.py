"""CPU time of the report stage alone on stored sessions (e.g. `motionlab demo`'s), and a profile.

    PYTHONPATH=. python3 bench/report_speed.py DEMO/knee/session.h5 DEMO/elbow/session.h5
    PYTHONPATH=. python3 bench/report_speed.py DEMO/knee/session.h5 --profile 30

Per session: `load_views` + `write_report` three times in one process (the first also loads
fonts and caches), CPU s (`time.process_time`) and wall s; the CPU time is the steadier figure on
a shared machine. With ``--profile N`` the last repeat runs under cProfile (CPU clock) and the
N largest cumulative and own times are printed. With ``--parts`` the last repeat also prints
the CPU time spent inside some of matplotlib's and the report's functions (nested: an axis's
draw is inside its axes' draw; a function missing from this version is left out). Outputs go
to a temporary folder.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import tempfile
import time
from pathlib import Path

from motionlab.report import load_views, write_report
from motionlab.session import load_session

#: label → "module or class path:function", timed by --parts (indented: inside the row above)
PARTS = {
    "building the pages": "motionlab.report:build_document",
    "  creating axes": "matplotlib.axes.Axes:__init__",
    "    clearing them (Axes.clear)": "matplotlib.axes.Axes:clear",
    "      first tick objects": "matplotlib.axis.Axis:_get_tick",
    "      grid settings": "matplotlib.axes.Axes:grid",
    "  creating texts": "matplotlib.text.Text:__init__",
    "  creating lines": "matplotlib.lines.Line2D:__init__",
    "  creating figures": "matplotlib.figure.Figure:__init__",
    "  legends made": "matplotlib.legend.Legend:__init__",
    "  fill_between": "matplotlib.axes.Axes:fill_between",
    "  measuring words (not in the widths cache)": "motionlab.report.widths:_measure",
    "CSV tables": "motionlab.report:write_csvs",
    "long curves to their envelopes (thin_curves)": "motionlab.report.pdf:thin_curves",
    "drawing the pages into the PDF": "matplotlib.backends.backend_pdf.PdfPages:savefig",
    "  axes": "matplotlib.axes.Axes:draw",
    "    axis (ticks, tick labels)": "matplotlib.axis.Axis:draw",
    "    axis, one tick object (stamp_ticks)": "motionlab.report.pdf._StampedTicks:draw",
    "      creating ticks": "matplotlib.axis.Axis:get_major_ticks",
    "      drawing ticks": "matplotlib.axis.Tick:draw",
    "    lines (curves, tick marks)": "matplotlib.lines.Line2D:draw",
    "    collections (bands, scatters)": "matplotlib.collections.Collection:draw",
    "    patches (spines, frames, bars)": "matplotlib.patches.Patch:draw",
    "    legends": "matplotlib.legend.Legend:draw",
    "  the report's plain lines": "motionlab.report.pdf.PlainText:draw",
    "  other texts (tick labels, titles, ...)": "matplotlib.text.Text:draw",
    "the fonts' subsets": "matplotlib.backends.backend_pdf.PdfFile:writeFonts",
    "closing the PDF": "matplotlib.backends.backend_pdf.PdfPages:close",
    "pages' text (page_text)": "motionlab.report.pdf:page_text",
    "finding the texts (Artist.findobj)": "matplotlib.artist.Artist:findobj",
    "garbage collection": "gc:collect",
    "load_views": "motionlab.report:load_views",
}
CPU: dict[str, float] = {}


def _timed(owner, name: str, label: str) -> None:
    real = getattr(owner, name)

    def wrapper(*args, **kwargs):
        c = time.process_time()
        try:
            return real(*args, **kwargs)
        finally:
            CPU[label] = CPU.get(label, 0.0) + time.process_time() - c

    setattr(owner, name, wrapper)


def _patch_parts() -> None:
    import importlib

    for label, target in PARTS.items():
        path, name = target.split(":")
        mod, _, cls = path.rpartition(".")
        try:
            owner = importlib.import_module(path)
        except ImportError:
            owner = getattr(importlib.import_module(mod), cls, None)
        if owner is not None and hasattr(owner, name):
            _timed(owner, name, label)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sessions", nargs="+", type=Path)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", type=int, default=0, help="print the N top profile rows")
    ap.add_argument("--parts", action="store_true", help="CPU time inside some functions")
    args = ap.parse_args()
    if args.parts:
        _patch_parts()
    out = Path(tempfile.mkdtemp(prefix="report_speed_"))
    for path in args.sessions:
        ses = load_session(path)
        for k in range(args.repeat):
            last = args.profile and k == args.repeat - 1
            prof = cProfile.Profile(time.process_time) if last else None
            t, c = time.perf_counter(), time.process_time()
            if prof:
                prof.enable()
            CPU.clear()
            res = write_report(
                load_views([ses], None, [path]), out / "report.pdf", out / "csv", force=True
            )
            if prof:
                prof.disable()
            print(
                f"{path}: {len(res.pages)} pages, {time.process_time() - c:.2f} s CPU, "
                f"{time.perf_counter() - t:.2f} s wall" + (" (profiled)" if prof else ""),
                flush=True,
            )
            if args.parts and k == args.repeat - 1:
                for label in PARTS:
                    if label in CPU:
                        print(f"  {label:45s} {CPU[label]:6.2f} s CPU")
            if prof:
                st = pstats.Stats(prof)
                st.sort_stats("cumulative").print_stats(args.profile)
                st.sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()
