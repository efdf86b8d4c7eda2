"""Scaling: ``motionlab run`` on long simulated sessions, time and peak memory per stage.

A simulated walk session (the packaged ``walk`` protocol: 5 s stand, then walking with turns;
``typical`` error preset, 100 Hz, five sensors on pelvis, thighs and shanks, each on its own
clock) is made 8 sensors long by three more sensors, copies of the thighs' and the pelvis's
signals under labels on no protocol segment: ``run`` fuses every sensor, while clock sync,
calibration, angles and metrics use the protocol's five. Each duration runs ``motionlab run``
(:func:`motionlab.pipeline.run_pipeline`, default options: 6-D smoother, clock sync on) on the
saved session in a fresh process, after a warm-up run on a 1-minute session in the same process
(numba's compiled code loaded, as in a second ``run``). Per stage: wall time, CPU time
(``time.process_time``: the measure that holds on a shared machine) and the peak resident
memory above the process's resident memory when the stage began (``/proc`` sampled every 5 ms,
so a peak shorter than that can be missed); and the whole process's peak. The slope is the
growth per hour of recording between the two longest durations measured.

Usage::

    python bench/scaling.py [--minutes 10,30,120] [--work DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

EXTRA = {"extra_1": "thigh_r", "extra_2": "thigh_l", "extra_3": "pelvis"}
PAGE = os.sysconf("SC_PAGE_SIZE")


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE / 2**20


def make_session(minutes: float, path: Path, seed: int = 1) -> None:
    """Simulate the walk session of ``minutes`` and save it with the three extra sensors."""
    from motionlab.protocol import load_protocol
    from motionlab.session import save_session
    from motionlab.simulate import simulate

    session, truth = simulate(load_protocol("walk"), 60.0 * minutes, seed, "typical", gait="normal")
    for label, source in EXTRA.items():
        s = session.sensors[source]
        session.sensors[label] = dataclasses.replace(s, label=label, segment="", side="")
    save_session(session, path, force=True)
    spans = [[st["start_s"], st["end_s"]] for st in truth.steps]  # the stand, then the walk
    path.with_suffix(".json").write_text(json.dumps(spans))


def _protocol(session_path: Path):
    """The walk protocol with its stand and walk at their simulated times (the step finder
    took a whole 10-minute simulated walk, seed 1, for one movement: noted in
    docs/performance.md)."""
    from motionlab.protocol import load_protocol

    proto = load_protocol("walk")
    (a, b), (c, d) = json.loads(session_path.with_suffix(".json").read_text())
    stand = dataclasses.replace(proto.calibration[0], time_range=(a + 0.5, b - 0.5))
    walk = dataclasses.replace(proto.tasks[0], time_range=(c, d))
    return dataclasses.replace(proto, calibration=[stand], tasks=[walk])


def measure(session_path: Path, warm_path: Path, outdir: Path) -> dict:
    """Run the pipeline on ``warm_path`` then on ``session_path`` in this process; stage times
    (wall and CPU s) and peak extra resident memory (MB) of the second run."""
    from motionlab import pipeline

    rows: dict[str, dict[str, float]] = {}
    state = {"peak": 0.0, "stop": False}

    def sample() -> None:
        while not state["stop"]:
            state["peak"] = max(state["peak"], _rss_mb())
            time.sleep(0.005)

    class Stages(pipeline._Stages):
        @contextlib.contextmanager
        def __call__(self, name: str):
            base, cpu = _rss_mb(), time.process_time()
            state["peak"] = base
            with super().__call__(name):
                yield
            rows[name] = {
                "seconds": self.times[name],
                "cpu_s": time.process_time() - cpu,
                "peak_mb": state["peak"] - base,
            }

    options = pipeline.PipelineOptions(_protocol(warm_path), force=True, progress=False)
    pipeline.run_pipeline([warm_path], outdir / "warm", options)
    options = dataclasses.replace(options, protocol=_protocol(session_path))
    rows.clear()
    pipeline._Stages = Stages
    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    t0, cpu = time.perf_counter(), time.process_time()
    pipeline.run_pipeline([session_path], outdir / "run", options)
    total, total_cpu = time.perf_counter() - t0, time.process_time() - cpu
    state["stop"] = True
    with open("/proc/self/status") as f:
        hwm = next(int(line.split()[1]) for line in f if line.startswith("VmHWM")) / 1024
    return {"stages": rows, "total_s": total, "total_cpu_s": total_cpu, "process_peak_mb": hwm}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", default="10,30,120", help="comma-separated session lengths")
    ap.add_argument("--work", type=Path, help="keep the sessions and outputs here")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        out = measure(Path(args.child[0]), Path(args.child[1]), Path(args.child[2]))
        print(json.dumps(out))
        return
    minutes = [float(m) for m in args.minutes.split(",") if m]
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        warm = work / "warm_1min.h5"
        if not warm.exists():
            make_session(1.0, warm)
        results = {}
        for m in minutes:
            path = work / f"walk_{m:g}min.h5"
            if not path.exists():
                t0 = time.perf_counter()
                make_session(m, path)
                print(f"simulated {m:g} min in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
            out = subprocess.run(
                [sys.executable, __file__, "--child", str(path), str(warm), str(work / f"{m:g}")],
                capture_output=True, text=True,
            )  # fmt: skip
            if out.returncode:
                sys.exit(f"run on {m:g} min failed:\n{out.stderr}")
            results[m] = json.loads(out.stdout.strip().splitlines()[-1])
            print(f"ran {m:g} min: {results[m]['total_s']:.1f} s", file=sys.stderr)
    print(table(results))


def table(results: dict[float, dict]) -> str:
    """Markdown table: per stage, seconds and peak MB per duration, and the slope per hour."""
    minutes = sorted(results)
    stages = list(next(iter(results.values()))["stages"])
    head = " | ".join(f"{m:g} min: s / CPU s / MB" for m in minutes)
    lines = [
        f"| stage | {head} | slope (s, CPU s, MB per hour) |",
        "|---|" + "---:|" * (len(minutes) + 1),
    ]
    a, b = minutes[-2:] if len(minutes) > 1 else (minutes[0], minutes[0])
    hours = (b - a) / 60.0

    def slope(get) -> str:
        if hours <= 0:
            return "–"
        return f"{(get(results[b]) - get(results[a])) / hours:.1f}"

    for st in stages:
        row = {m: results[m]["stages"][st] for m in minutes}
        cells = " | ".join(
            f"{r['seconds']:.2f} / {r['cpu_s']:.2f} / {r['peak_mb']:.0f}" for r in row.values()
        )
        s = slope(lambda r, st=st: r["stages"][st]["seconds"])
        cpu = slope(lambda r, st=st: r["stages"][st]["cpu_s"])
        mb = slope(lambda r, st=st: r["stages"][st]["peak_mb"])
        lines.append(f"| {st} | {cells} | {s}; {cpu}; {mb} |")
    cells = " | ".join(
        f"{r['total_s']:.2f} / {r['total_cpu_s']:.2f} / {r['process_peak_mb']:.0f}"
        for r in (results[m] for m in minutes)
    )
    s = slope(lambda r: r["total_s"])
    cpu = slope(lambda r: r["total_cpu_s"])
    mb = slope(lambda r: r["process_peak_mb"])
    lines.append(f"| whole run (MB: process peak) | {cells} | {s}; {cpu}; {mb} |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
