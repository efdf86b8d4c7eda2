"""CPU time of the report stage alone on stored sessions (e.g. `motionlab demo`'s), and a profile.

    PYTHONPATH=. python3 bench/report_speed.py DEMO/knee/session.h5 DEMO/elbow/session.h5
    PYTHONPATH=. python3 bench/report_speed.py DEMO/knee/session.h5 --profile 30

Per session: `load_views` + `write_report` three times in one process (the first also loads
fonts and caches), CPU s (`time.process_time`) and wall s; the CPU time is the steadier figure on
a shared machine. With ``--profile N`` the last repeat runs under cProfile (CPU clock) and the
N largest cumulative and own times are printed. Outputs go to a temporary folder.
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sessions", nargs="+", type=Path)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", type=int, default=0, help="print the N top profile rows")
    args = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix="report_speed_"))
    for path in args.sessions:
        ses = load_session(path)
        for k in range(args.repeat):
            last = args.profile and k == args.repeat - 1
            prof = cProfile.Profile(time.process_time) if last else None
            t, c = time.perf_counter(), time.process_time()
            if prof:
                prof.enable()
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
            if prof:
                st = pstats.Stats(prof)
                st.sort_stats("cumulative").print_stats(args.profile)
                st.sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()
