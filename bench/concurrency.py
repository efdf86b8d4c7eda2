"""Concurrency and crash campaign (issue 26): parallel writers on one session, kills at random
moments, and every order of re-running the stages, each case judged against the promise.

Clean means, per case:

- writers: every writer ends (no hang) with exit 0, or exit 2 and one ``error:`` line; every
  writer that said it wrote has its provenance entry in the final file (no lost result); each
  of them ran on inputs that were up to date at its turn, and the final file's stale results
  are the ones a model of the stages' data flow predicts (no stale result used);
- kills: after SIGKILL at a random moment (or while the output is being written), every input
  is byte-identical and every output is the old complete file or the new complete one;
- orders: for every order of re-running ``sync``, ``fuse``, ``calibrate``, ``angles`` and
  ``metrics`` (with ``--force``) on an analysed session, each command runs (exit 0) exactly
  when the model says its inputs are up to date, and otherwise refuses (exit 2, one line);
  afterwards ``info``'s stale results are the model's and ``report`` refuses exactly when one is
  stale.

The model is written here from the stages' data flow (what each stage reads), not taken from
:mod:`motionlab.lineage`, so that the campaign checks the implementation against it.

    python3 bench/concurrency.py                      # ≈ 10 writer trials, 16 kills, 120 orders
    python3 bench/concurrency.py --writers 6 --trials 20 --orders 30 --batch-kills 2
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from integrity_helpers import (  # noqa: E402
    PROTOCOL,
    fork_cli,
    kill_at,
    make_sessions,
    one_error_line,
    sha,
    wait,
)

#: what each stage reads (the model): ``clock`` is the sensors' time stamps, which sync changes
READS = {
    "sync": (),
    "fuse": ("clock",),
    "calibrate": ("clock", "fuse"),
    "angles": ("fuse", "calibrate"),
    "metrics": ("fuse", "calibrate", "angles"),
}
#: the command line of each stage, re-run
COMMAND = {
    "sync": ["sync", "{s}", "--force", "--protocol", PROTOCOL],
    "fuse": ["fuse", "{s}", "--force", "--filter", "madgwick"],
    "calibrate": ["calibrate", "{s}", "--force", "--protocol", PROTOCOL],
    "angles": ["angles", "{s}", "--force"],
    "metrics": ["metrics", "{s}", "--force"],
}
#: the result each stage makes (sync: the clock)
MAKES = {"sync": "clock", "fuse": "fuse", "calibrate": "calibrate", "angles": "angles",
         "metrics": "metrics"}  # fmt: skip
#: motionlab's name of each result
RESULT = {"fuse": "fusion", "calibrate": "calibration", "angles": "angles", "metrics": "metrics"}


@dataclass
class Model:
    """Versions of every result and, per result, the versions of what it was computed from."""

    version: dict[str, int] = field(default_factory=lambda: dict.fromkeys(MAKES.values(), 0))
    read: dict[str, dict[str, int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for stage, made in MAKES.items():  # the analysed session: all up to date
            self.read.setdefault(made, {r: 0 for r in READS[stage]})

    def stale(self) -> set[str]:
        out: set[str] = set()
        for stage in READS:  # in the order of the data flow
            made = MAKES[stage]
            if any(self.version[r] != v or r in out for r, v in self.read[made].items()):
                out.add(made)
        return out

    def allowed(self, stage: str) -> bool:
        return not (set(READS[stage]) & self.stale())

    def run(self, stage: str) -> None:
        made = MAKES[stage]
        self.read[made] = {r: self.version[r] for r in READS[stage]}
        self.version[made] += 1


@dataclass
class Case:
    family: str
    name: str
    clean: bool
    detail: str = ""


def _args(stage: str, session: Path) -> list[str]:
    return [str(session) if a == "{s}" else a for a in COMMAND[stage]]


def _stale_now(path: Path) -> set[str]:
    from motionlab.session import load_session

    ses = load_session(path)
    return {s for s, r in RESULT.items() if r in ses.lineage.stale(ses.results)}


# ----------------------------------------------------------------------------------- writers


def writer_trial(analysed: Path, folder: Path, n: int, rng: random.Random, k: int) -> Case:
    """``n`` stage commands started within 0.5 s of each other on one session."""
    from motionlab.session import load_session

    folder.mkdir(parents=True)
    path = folder / "session.h5"
    shutil.copy(analysed, path)
    before = len(load_session(path).provenance)
    stages = [rng.choice(["fuse", "calibrate", "angles", "metrics", "angles", "metrics"])
              for _ in range(n)]  # fmt: skip
    pids = []
    for i, stage in enumerate(stages):
        pids.append(fork_cli(_args(stage, path), folder / f"w{i}.log"))
        time.sleep(rng.uniform(0.0, 0.5 / n))
    codes = [wait(pid, timeout=300) for pid in pids]
    logs = [(folder / f"w{i}.log").read_text() for i in range(n)]
    name = f"writers/{k}: " + " ".join(stages)
    if None in codes:
        return Case("writers", name, False, "hang")
    for code, log in zip(codes, logs, strict=True):
        if code not in (0, 2) or (code == 2 and not one_error_line(log)):
            return Case("writers", name, False, f"exit {code}: {log[-200:]}")
    ses = load_session(path)
    done = [p["parameters"].get("stage") for p in ses.provenance[before:]]
    said = sorted(s for s, c in zip(stages, codes, strict=True) if c == 0)
    if sorted(done) != said:
        return Case("writers", name, False, f"lost: wrote {said}, file holds {sorted(done)}")
    model = Model()
    for stage in done:  # in the order they wrote
        if not model.allowed(stage):
            return Case("writers", name, False, f"{stage} ran on a stale input")
        model.run(stage)
    stale = _stale_now(path)
    model_stale = {s for s in RESULT if s in model.stale()}
    if stale != model_stale:
        return Case("writers", name, False, f"stale {sorted(stale)}, model {sorted(model_stale)}")
    refused = sum(c == 2 for c in codes)
    return Case("writers", name, True, f"{len(done)} wrote, {refused} refused (stale or waited)")


# ------------------------------------------------------------------------------------- kills


def kill_stage(analysed: Path, folder: Path, rng: random.Random, k: int) -> Case:
    from motionlab.session import load_session

    folder.mkdir(parents=True)
    path = folder / "session.h5"
    shutil.copy(analysed, path)
    old, before = sha(path), len(load_session(path).provenance)
    stage = rng.choice(["fuse", "calibrate", "angles", "metrics"])
    writing = k % 2 == 1
    pid = fork_cli(_args(stage, path), folder / "k.log")
    delay = rng.uniform(0.0, 0.05) if writing else rng.uniform(0.0, 2.0)
    kill_at(pid, delay, folder, after_tmp=writing)
    wait(pid, timeout=300)
    name = f"kill/{stage} {'while writing' if writing else 'at random'} +{1000 * delay:.0f} ms"
    if sha(path) == old:
        return Case("kills", name, True, "old file")
    try:
        ses = load_session(path)
        new = (
            len(ses.provenance) == before + 1
            and ses.provenance[-1]["parameters"].get("stage") == stage
        )
    except Exception as exc:  # noqa: BLE001 - any failure to read is the verdict
        return Case("kills", name, False, f"broken: {exc}")
    return Case("kills", name, new, "new file" if new else "neither old nor new")


def kill_run(raw: Path, analysed: Path, folder: Path, rng: random.Random, k: int) -> Case:
    from motionlab.session import load_session

    out = folder / "out"
    out.mkdir(parents=True)
    shutil.copy(analysed, out / "session.h5")
    (out / "results.json").write_text('{"old": true}')
    data = folder / "raw.h5"
    shutil.copy(raw, data)
    before, old = sha(data), sha(out / "session.h5")
    args = ["run", "--protocol", PROTOCOL, str(data), "-o", str(out), "--force", "--quiet",
            "--no-clock-sync", "--seed", "1"]  # fmt: skip
    writing = k % 2 == 1
    pid = fork_cli(args, folder / "run.log")
    delay = rng.uniform(0.0, 0.05) if writing else rng.uniform(0.2, 4.0)
    kill_at(pid, delay, out, after_tmp=writing)
    wait(pid, timeout=300)
    name = f"kill/run {'while writing' if writing else 'at random'} +{1000 * delay:.0f} ms"
    if sha(data) != before:
        return Case("kills", name, False, "input changed")
    try:
        json.loads((out / "results.json").read_text())
        if sha(out / "session.h5") == old:
            return Case("kills", name, True, "old files")
        ses = load_session(out / "session.h5")
        ok = ses.results.metrics is not None and ses.provenance[-1]["parameters"].get("seed") == 1
    except Exception as exc:  # noqa: BLE001
        return Case("kills", name, False, f"broken: {exc}")
    return Case("kills", name, ok, "new session" if ok else "neither old nor new")


def kill_batch(raw: Path, analysed: Path, folder: Path, rng: random.Random, k: int) -> Case:
    """A real ``motionlab batch`` (its pool of worker processes) killed, all of it, with SIGKILL
    at a random moment; then the session's outputs are old or new."""
    from motionlab.session import load_session

    folder.mkdir(parents=True)
    data = folder / "raw.h5"
    shutil.copy(raw, data)
    (folder / "study.yaml").write_text(
        f"protocol: {PROTOCOL}\nclock_sync: false\nseed: 1\n"
        "sessions:\n  - {subject: S1, visit: V1, files: [raw.h5]}\n"
    )
    out = folder / "study"
    target = out / "S1" / "V1"
    target.mkdir(parents=True)
    shutil.copy(analysed, target / "session.h5")
    before, old = sha(data), sha(target / "session.h5")
    env = os.environ | {"PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "motionlab", "batch", str(folder / "study.yaml"), "-o", str(out),
         "--workers", "1", "--force"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not any(target.glob(".*.tmp")) and proc.poll() is None:
        time.sleep(0.001)
    delay = rng.uniform(0.0, 0.05)
    time.sleep(delay)
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()
    name = f"kill/batch while writing +{1000 * delay:.0f} ms"
    if sha(data) != before:
        return Case("kills", name, False, "input changed")
    if sha(target / "session.h5") == old:
        return Case("kills", name, True, "old file")
    try:
        ses = load_session(target / "session.h5")
        ok = ses.results.metrics is not None and ses.provenance[-1]["parameters"].get("seed") == 1
    except Exception as exc:  # noqa: BLE001
        return Case("kills", name, False, f"broken: {exc}")
    return Case("kills", name, ok, "new file" if ok else "neither old nor new")


# ------------------------------------------------------------------------------------ orders


def orders(analysed: Path, folder: Path, limit: int | None, rng: random.Random) -> list[Case]:
    """Every order of re-running the five stages, sharing the work of common prefixes."""
    from click.testing import CliRunner

    from motionlab.cli import main

    stages = list(READS)
    perms = list(itertools.permutations(stages))
    if limit is not None and limit < len(perms):
        perms = rng.sample(perms, limit)
    folder.mkdir(parents=True)
    done: dict[tuple[str, ...], tuple[Path, Model, str]] = {(): (analysed, Model(), "")}
    runner = CliRunner()
    cases = []
    for perm in perms:
        problem = ""
        for i in range(1, len(perm) + 1):
            prefix = perm[:i]
            if prefix in done:
                problem = done[prefix][2]
                continue
            path0, model0, _ = done[prefix[:-1]]
            path = folder / f"{len(done)}.h5"
            shutil.copy(path0, path)
            model = Model(dict(model0.version), {k: dict(v) for k, v in model0.read.items()})
            stage = prefix[-1]
            expect = model.allowed(stage)
            res = runner.invoke(main, _args(stage, path))
            if expect and res.exit_code == 0:
                model.run(stage)
            elif expect or res.exit_code != 2 or not one_error_line(res.output):
                wanted = "0" if expect else "2 and one line"
                seen = res.output.strip()[-160:]
                problem = problem or f"{stage}: exit {res.exit_code}, expected {wanted} ({seen})"
            done[prefix] = (path, model, problem)
        path, model, problem = done[perm]
        stale = _stale_now(path)
        model_stale = {s for s in RESULT if s in model.stale()}
        if not problem and stale != model_stale:
            problem = f"stale {sorted(stale)}, model {sorted(model_stale)}"
        if not problem and model_stale:  # report refuses (fast); when nothing is stale it runs
            res = runner.invoke(main, ["report", str(path), "-o", str(folder / "r.pdf")])
            if res.exit_code != 2 or "stale" not in res.output:
                problem = f"report on stale results: exit {res.exit_code}"
        cases.append(Case("orders", " → ".join(perm), not problem, problem or
                          f"stale after: {', '.join(sorted(model_stale)) or 'none'}"))  # fmt: skip
    return cases


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=26)
    ap.add_argument("--writers", type=int, default=4, help="parallel writers per trial")
    ap.add_argument("--trials", type=int, default=10, help="trials of parallel writers")
    ap.add_argument("--kills", type=int, default=12, help="stage commands killed")
    ap.add_argument("--run-kills", type=int, default=4, help="'run's killed")
    ap.add_argument("--batch-kills", type=int, default=1, help="'batch'es killed (slow start)")
    ap.add_argument("--orders", type=int, default=None, help="orders tried (default: all 120)")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    t0 = time.perf_counter()
    cases: list[Case] = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        raw, analysed = make_sessions(tmp / "sessions")
        from motionlab import stages
        from motionlab.session import load_session

        stages.fuse(load_session(raw), "madgwick")  # compiled once, before the forks
        for k in range(args.trials):
            cases.append(writer_trial(analysed, tmp / f"w{k}", args.writers, rng, k))
        for k in range(args.kills):
            cases.append(kill_stage(analysed, tmp / f"k{k}", rng, k))
        for k in range(args.run_kills):
            cases.append(kill_run(raw, analysed, tmp / f"r{k}", rng, k))
        for k in range(args.batch_kills):
            cases.append(kill_batch(raw, analysed, tmp / f"b{k}", rng, k))
        cases += orders(analysed, tmp / "orders", args.orders, rng)
    print(f"{len(cases)} cases in {time.perf_counter() - t0:.0f} s (seed {args.seed})")
    print(f"{'family':<10} {'cases':>6} {'clean':>6}  clean means")
    means = {
        "writers": "no hang; exit 0, or 2 with one line; every writer that wrote is in the "
        "file; none ran on a stale input; stale set = model's",
        "kills": "inputs byte-identical; each output the old or the new complete file",
        "orders": "each command runs iff its inputs are up to date (else exit 2, one line); "
        "stale set = model's; report refuses stale results",
    }
    for family in ("writers", "kills", "orders"):
        group = [c for c in cases if c.family == family]
        if group:
            clean = sum(c.clean for c in group)
            print(f"{family:<10} {len(group):>6} {clean:>6}  {means[family]}")
    clean = sum(c.clean for c in cases)
    print(f"{'all':<10} {len(cases):>6} {clean:>6}  {100 * clean / len(cases):.1f} % clean")
    print("cases:")
    for c in cases:
        print(f"  {'clean' if c.clean else 'NOT CLEAN':<9} {c.name:<58} {c.detail}")


if __name__ == "__main__":
    main()
