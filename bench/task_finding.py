"""Where the calibration steps and the tasks are found, against the simulator's truth.

For each shipped protocol and seed, ``motionlab.simulate`` records the protocol (its calibration
steps, then its tasks) with every sensor at a random orientation and place on its segment
(``mounting="random"``) and the realistic simulator of ``bench/real_world.py`` (anatomical knee,
``skin`` preset: every IMU on its own clock, skin moving over the bone), and the session goes
through the stages as ``motionlab run`` chains them (clock sync, fusion, calibration, angles,
metrics and gait). Printed per seed: each calibration step's window against its true one (``-``
not found), and each task's window against the true task: the share of the true task the
window covers and the share of the window that is the true task (``cover/purity``, %), and for
a gait task the strides the gait analysis kept. A task the finder could not find is the one
line it raised. The summary counts, per protocol, the tasks whose window covers at least half
of the true task and is at least half that task.

``--finder`` runs the step and task finders only (:func:`motionlab.segments.steps.find_steps`,
:func:`~motionlab.segments.steps.find_tasks`) on the sensors as recorded (no clock sync, no
fusion: seconds instead of minutes; no strides).

Needs no data files. Usage::

    python bench/task_finding.py [--protocols knee,walk,...] [--seeds 0-9] [--workers 2]
                                 [--finder] [--preset skin]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from joint_angles import duration
from pool import worker_pool
from real_world import DURATION_S, simulator_options
from seeds import seeds_arg

from motionlab.errors import InputError
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import PACKAGED, load_protocol
from motionlab.segments.sensors import streams_of
from motionlab.segments.steps import find_steps, find_tasks
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset

GOOD = 0.5  # a task window is right when it covers this share of the task and is this much task


def overlap(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Length (s) of the intersection of two windows."""
    return max(0.0, min(a[1], b[1]) - max(a[0], b[0]))


def run_one(job: tuple[str, int, str, bool]) -> dict:
    """Steps and task windows found in one simulated session, and the truth's."""
    name, seed, preset, finder = job
    protocol = load_protocol(name)
    length = DURATION_S.get(name) or duration(protocol)
    options = simulator_options(preset, False)
    session, truth = simulate(protocol, length, seed, mounting="random", **options)
    true = {s["name"]: (s["start_s"], s["end_s"], s["phase"]) for s in truth.steps}
    out = {"name": name, "seed": seed, "true": true, "steps": {}, "tasks": {}, "strides": None}
    out["task_names"] = [t.name for t in protocol.tasks]  # a protocol without tasks has none
    t0 = time.perf_counter()
    try:
        if finder:
            streams = streams_of(session, protocol)
            steps = find_steps(streams, protocol)
            after = max((v[1] for v in steps.values() if v is not None), default=-np.inf)
            out["steps"] = steps
            out["tasks"] = find_tasks(streams, protocol, after_s=after, suggest=False, steps=steps)
        else:
            prepare_sensors(session)
            analyse(session, PipelineOptions(protocol, progress=False))
            out["steps"] = {k: (tuple(v) if v else None)
                            for k, v in session.results.calibration.steps.items()}  # fmt: skip
            out["tasks"] = session.results.metrics.spans()
            gait = session.results.gait
            if gait is not None:
                n = 0 if gait.strides is None else int(np.sum(gait.strides.kept))
                out["strides"] = (n, gait.status)
    except InputError as exc:
        out["error"] = str(exc).split(";")[0]
    out["seconds"] = time.perf_counter() - t0
    return out


def task_scores(r: dict) -> dict[str, tuple[float, float] | None]:
    """Per true task: (cover, purity) of its window, or None when it has none."""
    out = {}
    for task, (a, b, phase) in r["true"].items():
        if phase != "task" or task not in r["task_names"]:
            continue
        w = r["tasks"].get(task)
        if w is None:
            out[task] = None
            continue
        inter = overlap(w, (a, b))
        out[task] = (inter / (b - a), inter / max(w[1] - w[0], 1e-9))
    return out


def show(r: dict) -> None:
    """One seed: its steps, its tasks."""
    head = f"{r['name']:>20} seed {r['seed']}:"
    if "error" in r:
        print(f"{head} {r['error']}")
    cells = []
    for step, (a, b, phase) in r["true"].items():
        if phase == "task":
            continue
        w = r["steps"].get(step)
        cells.append(f"{step} {a:.0f}-{b:.0f}→" + ("-" if w is None else f"{w[0]:.0f}-{w[1]:.0f}"))
    print(f"{head} steps " + ", ".join(cells))
    cells = []
    for task, score in task_scores(r).items():
        a, b, _ = r["true"][task]
        w = r["tasks"].get(task)
        if w is None:
            cells.append(f"{task} {a:.0f}-{b:.0f}→none")
            continue
        mark = "" if min(score) >= GOOD else " ✗"
        cells.append(
            f"{task} {a:.0f}-{b:.0f}→{w[0]:.0f}-{w[1]:.0f} "
            f"({100 * score[0]:.0f}/{100 * score[1]:.0f}%){mark}"
        )
    kept = r["strides"]
    strides = "" if kept is None else f"; strides kept {kept[0]} ({kept[1]})"
    print(f"{' ' * len(head)} tasks " + ", ".join(cells) + strides)


def summary(results: list[dict]) -> None:
    """Per protocol: tasks right, wrong and not found; the mean cover and purity."""
    print(f"\n{'protocol':>20} {'tasks':>5} {'right':>5} {'wrong':>5} {'none':>5} "
          f"{'cover %':>8} {'purity %':>8} {'no stride':>9}")  # fmt: skip
    for name in dict.fromkeys(r["name"] for r in results):
        mine = [r for r in results if r["name"] == name]
        scores = [s for r in mine for s in task_scores(r).values()]
        right = sum(s is not None and min(s) >= GOOD for s in scores)
        none = sum(s is None for s in scores)
        found = [s for s in scores if s is not None]
        cover = 100 * np.mean([s[0] for s in found]) if found else float("nan")
        purity = 100 * np.mean([s[1] for s in found]) if found else float("nan")
        walks = [r["strides"] for r in mine if r["strides"] is not None]
        none_walk = sum(n == 0 for n, _ in walks)
        print(f"{name:>20} {len(scores):>5} {right:>5} {len(found) - right:>5} {none:>5} "
              f"{cover:>8.0f} {purity:>8.0f} {none_walk:>9}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    names = ",".join(p.stem for p in sorted(PACKAGED.glob("*.yaml")))
    ap.add_argument("--protocols", default=names)
    ap.add_argument("--seeds", type=seeds_arg, default=list(range(10)))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--preset", default="skin")
    ap.add_argument("--finder", action="store_true", help="the finders only (no fusion)")
    args = ap.parse_args()
    get_preset(args.preset)  # an unknown preset fails here, not in every worker
    jobs = [(n, s, args.preset, args.finder) for n in args.protocols.split(",") for s in args.seeds]
    with worker_pool(args.workers) as pool:
        results = pool.map(run_one, jobs, chunksize=1)
    for r in results:
        show(r)
    summary(results)


if __name__ == "__main__":
    main()
