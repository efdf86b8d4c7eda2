"""Study-scale batch processing: speed-up, Dask byte-identity, resume, failure isolation.

A study of simulated knee sessions (a short version of the packaged knee protocol: standing,
right and left seated knee flexion, walking, 4 s rests; 40 s at 100 Hz, five IMUs, the
``typical`` error preset; four visits per subject, subject heights 1.55-1.95 m) runs through
``motionlab batch``:

1. with 1 and with 2 local workers, in the same run: wall time and speed-up;
2. on a Dask ``LocalCluster`` with 2 worker processes: wall time, and whether its
   ``study_metrics.csv`` has the bytes of the local runs';
3. the finished study again, as the command ``motionlab batch`` (every session skipped);
4. a study with 3 corrupt sessions (truncated HDF5, text garbage, a session lacking sensors)
   during which one worker process is killed (SIGKILL) mid-session: exit code, failures,
   whether every good session finished, and whether any output is left half-written.

The data are simulated (``--data`` is not used); ``--work DIR`` keeps the sessions between runs.

    python3 bench/batch.py                      # 200 sessions; about an hour on 2 cores
    python3 bench/batch.py --sessions 12 --failure-sessions 6   # a quick look
    python3 bench/batch.py --parts speedup --sessions 40         # when the machine is quiet
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import h5py
import yaml

from motionlab.batch import load_manifest, run_study
from motionlab.batch.state import CLAIM, STAMP, FileHashes, is_current, session_key
from motionlab.protocol import PACKAGED

DURATION_S = 40.0
REST_S = 4.0  # still time between steps, so that the pipeline finds them
MOTIONLAB = [sys.executable, "-c", "from motionlab.cli import main; main()"]
VISITS = ("v1", "v2", "v3", "v4")
PARTS = ("speedup", "dask", "rerun", "failure")


def short_knee_protocol(path: Path) -> Path:
    """The packaged knee protocol with a short calibration and one walking task."""
    doc = yaml.safe_load((PACKAGED / "knee.yaml").read_text(encoding="utf-8"))
    steps = {s["name"]: s for s in doc["calibration"]}
    steps["standing"]["duration_s"] = 3
    for name in ("knee_flexion_r", "knee_flexion_l"):
        steps[name].update(duration_s=5, repetitions=3)
    doc |= {
        "name": "knee_short",
        "calibration": [steps[k] for k in ("standing", "knee_flexion_r", "knee_flexion_l")],
        "tasks": [t | {"duration_s": 8} for t in doc["tasks"] if t["name"] == "gait"],
        # the normal ranges of the tasks kept (a range of a task dropped is a protocol error)
        "normative": {k: v for k, v in doc.get("normative", {}).items() if k == "gait"},
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def _simulate_one(protocol: str, path: str, seed: int, height: float) -> str:
    from motionlab.session import save_session
    from motionlab.simulate import simulate

    if not Path(path).is_file():
        session, _ = simulate(protocol, DURATION_S, seed, height=height, rest_s=REST_S)
        save_session(session, path, force=True)
    return path


def make_sessions(work: Path, protocol: Path, n: int) -> list[tuple[str, str, Path]]:
    """``n`` simulated sessions (subject, visit, file), made once and kept in ``work/sim``."""
    (work / "sim").mkdir(parents=True, exist_ok=True)
    specs = []
    for k in range(n):
        subject, visit = f"S{k // len(VISITS) + 1:03d}", VISITS[k % len(VISITS)]
        height = 1.55 + 0.4 * ((k // len(VISITS)) * 0.618 % 1.0)
        specs.append((subject, visit, work / "sim" / f"{subject}_{visit}.h5", 1000 + k, height))
    with ProcessPoolExecutor(2) as pool:
        list(
            pool.map(
                _simulate_one,
                [str(protocol)] * n,
                [str(s[2]) for s in specs],
                [s[3] for s in specs],
                [s[4] for s in specs],
            )
        )
    return [(s, v, f) for s, v, f, _, _ in specs]


def write_manifest(path: Path, protocol: Path, sessions: list[tuple[str, str, Path]]) -> Path:
    lines = [f"protocol: {protocol.name}", "sessions:"]
    lines += [
        f"  - {{subject: {s}, visit: {v}, files: {f.relative_to(path.parent)}}}"
        for s, v, f in sessions
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def corrupt_sessions(work: Path, good: Path) -> list[tuple[str, str, Path]]:
    """Three broken inputs: a truncated session file, text garbage, a session without shanks."""
    bad = work / "bad"
    bad.mkdir(exist_ok=True)
    data = good.read_bytes()
    (bad / "truncated.h5").write_bytes(data[: len(data) // 2])
    (bad / "garbage.txt").write_text("this is not;a recording\n\x00\x01 at all\n")
    shutil.copyfile(good, bad / "no_shanks.h5")
    with h5py.File(bad / "no_shanks.h5", "r+") as f:
        del f["sensors/shank_r"], f["sensors/shank_l"]
    return [
        ("X01", "v1", bad / "truncated.h5"),
        ("X02", "v1", bad / "garbage.txt"),
        ("X03", "v1", bad / "no_shanks.h5"),
    ]


def timed_study(manifest: Path, out: Path, **kw) -> tuple[float, object]:
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    result = run_study(load_manifest(manifest), out, **kw)
    return time.perf_counter() - t0, result


def _killer(out: Path, after: int, killed: list, stop: threading.Event) -> None:
    """Once ``after`` sessions have finished, SIGKILL the worker of a running session;
    ``killed`` gets its pid and the session's folder."""
    while not stop.is_set():
        if sum(1 for _ in out.glob(f"*/*/{STAMP}")) >= after:
            for claim in out.glob(f"*/*/{CLAIM}"):
                try:
                    pid = int(claim.read_text())
                    os.kill(pid, signal.SIGKILL)
                except (OSError, ValueError):
                    continue
                killed += [pid, claim.parent]
                return
        time.sleep(0.2)


def half_written(out: Path) -> list[str]:
    """Outputs that are temporary, unreadable or truncated."""
    problems = [str(p) for p in out.rglob("*") if p.name.endswith(".tmp") or p.name == CLAIM]
    for pdf in out.rglob("*.pdf"):
        if not pdf.read_bytes().rstrip().endswith(b"%%EOF"):
            problems.append(str(pdf))
    for h5 in out.rglob("*.h5"):
        try:
            with h5py.File(h5, "r") as f:
                f.visit(lambda _name: None)
        except OSError:
            problems.append(str(h5))
    for table in out.rglob("*.csv"):
        with open(table, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
        if rows and any(len(r) != len(rows[0]) for r in rows):
            problems.append(str(table))
    return problems


def failure_run(work: Path, protocol: Path, good: list, out: Path) -> dict:
    """The study with 3 corrupt sessions; one worker killed mid-run; via the command line."""
    bad = corrupt_sessions(work, good[0][2])
    sessions = good[: len(good) // 2] + bad[:2] + good[len(good) // 2 :] + bad[2:]
    manifest = write_manifest(work / "study_failures.yaml", protocol, sessions)
    shutil.rmtree(out, ignore_errors=True)
    killed: list = []
    stop = threading.Event()
    killer = threading.Thread(target=_killer, args=(out, max(2, len(good) // 3), killed, stop))
    killer.start()
    t0 = time.perf_counter()
    proc = subprocess.run(
        [*MOTIONLAB, "batch", str(manifest), "-o", str(out), "--workers", "2"],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - t0
    stop.set()
    killer.join()
    with open(out / "study_failures.csv", newline="", encoding="utf-8") as f:
        failures = list(csv.DictReader(f))
    study, hashes = load_manifest(manifest), FileHashes()
    current = {
        out / s.folder: is_current(
            out / s.folder, session_key(list(s.files), study.protocol, None, None, hashes)
        )
        for s in study.sessions
    }
    finished = sum(current[out / s.folder] for s in study.sessions if s.subject.startswith("S"))
    victim = (killed[1].relative_to(out).as_posix(), current[killed[1]]) if killed else None
    return {
        "wall": wall,
        "exit": proc.returncode,
        "killed": killed[:1],
        "victim": victim,
        "failures": failures,
        "finished": finished,
        "good": len(good),
        "half_written": half_written(out),
    }


def _children_cpu_s() -> float:
    """CPU time of the finished child processes (the pool's workers once it has shut down)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def speed_rows(work: Path, manifest: Path, parts: set[str]) -> list[tuple]:
    """(run, sessions run, wall s, CPU s or None) of the 1- and 2-worker and Dask runs."""
    rows = []
    for workers in (1, 2) if "speedup" in parts else ():
        cpu = _children_cpu_s()
        wall, result = timed_study(manifest, work / f"out_local{workers}", workers=workers)
        rows.append(
            (
                f"local pool, {workers} worker(s)",
                result.count("done"),
                wall,
                _children_cpu_s() - cpu,
            )
        )
    if "dask" in parts:
        import dask
        from distributed import LocalCluster

        with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
            cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)
        try:
            wall, result = timed_study(
                manifest, work / "out_dask", scheduler=cluster.scheduler_address
            )
        finally:
            cluster.close()
        rows.append(("Dask LocalCluster, 2 workers", result.count("done"), wall, None))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=200, help="simulated sessions in the study")
    ap.add_argument(
        "--failure-sessions",
        type=int,
        default=40,
        help="good sessions in the failure run (plus 3 corrupt ones)",
    )
    ap.add_argument("--parts", default=",".join(PARTS), help=f"any of {', '.join(PARTS)}")
    ap.add_argument("--work", type=Path, help="working folder (kept); default: a temporary one")
    ap.add_argument("--data", help="not used: the sessions are simulated")
    args = ap.parse_args()
    parts = set(args.parts.split(","))
    work = args.work or Path(tempfile.mkdtemp(prefix="motionlab-batch-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    protocol = short_knee_protocol(work / "knee_short.yaml")
    t0 = time.perf_counter()
    good = make_sessions(work, protocol, args.sessions)
    print(
        f"{args.sessions} simulated sessions of {DURATION_S:g} s in {work} "
        f"({time.perf_counter() - t0:.0f} s to simulate or find)"
    )
    manifest = write_manifest(work / "study.yaml", protocol, good)
    warm = write_manifest(work / "warmup.yaml", protocol, good[:2])
    timed_study(warm, work / "out_warmup", workers=2)  # fills numba's on-disk caches

    load = os.getloadavg()[0]
    rows = speed_rows(work, manifest, parts)
    if rows:
        print(
            f"load average (1 min) before: {load:.1f}, after: {os.getloadavg()[0]:.1f} "
            f"(cores: {os.cpu_count()}); 'cores busy' = workers' CPU time / wall time"
        )
        base = rows[0][2] if rows[0][0].startswith("local pool, 1") else None
        print("\n| run | sessions run | wall (s) | s per session | cores busy | speed-up vs 1 |")
        print("|---|---|---|---|---|---|")
        for name, done, wall, cpu in rows:
            busy = "-" if cpu is None else f"{cpu / wall:.2f}"
            gain = "-" if base is None else f"{base / wall:.2f}"
            print(f"| {name} | {done} | {wall:.1f} | {wall / max(done, 1):.2f} | {busy} | {gain} |")
    metrics = {
        n: (work / n / "study_metrics.csv").read_bytes()
        for n in ("out_local1", "out_local2", "out_dask")
        if (work / n / "study_metrics.csv").is_file()
    }
    if metrics:
        first = next(iter(metrics.values()))
        same = {n: b == first for n, b in metrics.items()}
        rows_n = first.count(b"\n") - 1
        print(
            f"\nstudy_metrics.csv byte-identical to {next(iter(metrics))}'s: {same} "
            f"({len(first)} bytes, {rows_n} rows)"
        )

    if "rerun" in parts:
        t0 = time.perf_counter()
        rerun = subprocess.run(
            [*MOTIONLAB, "batch", str(manifest), "-o", str(work / "out_local2"), "--workers", "2"],
            capture_output=True,
            text=True,
        )
        print(
            f"\nre-run of the finished study, as a command: {time.perf_counter() - t0:.1f} s, "
            f"exit code {rerun.returncode}: {rerun.stdout.strip()}"
        )

    if "failure" in parts:
        f = failure_run(work, protocol, good[: args.failure_sessions], work / "out_failures")
        print(
            f"\nfailure run: {f['good']} good + 3 corrupt sessions, 2 workers, worker pid "
            f"{f['killed'] or 'none'} killed mid-session; {f['wall']:.1f} s, "
            f"exit code {f['exit']}"
        )
        print(f"  good sessions finished: {f['finished']}/{f['good']}")
        if f["victim"]:
            name, ok = f["victim"]
            print(f"  the killed worker's session {name}: {'finished on retry' if ok else 'LOST'}")
        print("  | subject | visit | kind | attempts | error |")
        print("  |---|---|---|---|---|")
        for r in f["failures"]:
            print(
                f"  | {r['subject']} | {r['visit']} | {r['kind']} | {r['attempts']} | "
                f"{r['error']} |"
            )
        print(f"  half-written or temporary files: {f['half_written'] or 'none'}")


if __name__ == "__main__":
    main()
