"""Fault campaign (issue 16): hundreds of broken, odd and real inputs through the CLI, each
judged against the promise (exit 0, or exit 2 with one stderr line; no traceback; inputs
byte-identical; nothing left behind by a refusal), with the counts by verdict.

Cases come from ``tests/faults.py`` (every reader's fixture mutated, HDF5 type swaps, YAML type
errors, broken sessions); ``--c3d DIR`` adds truncated and byte-flipped copies of every C3D
file in DIR (e.g. the c3d.org samples). HDF5, session and C3D cases run in a forked child
each, so that a crash inside libhdf5 or ezc3d that the readers' own guards
(:mod:`motionlab.isolated`) missed counts as a verdict instead of ending the run. The peak
memory of ``ingest`` (growth of the peak RSS over the imports, in a fresh interpreter) is
measured for every fixture, every C3D file and a synthetic C3D of
``--big-c3d-mb`` MB (float storage, and the same points as int16 words: half the file, the
same result, the worst ratio), and compared with 4× the input size + 300 MB.

    python3 bench/faults.py                       # ≈ 440 cases
    python3 bench/faults.py --c3d ../shared/formats/c3d --seed 2
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import c3d_variants  # noqa: E402
import faults  # noqa: E402


def run_isolated(case: faults.Case, folder: Path, timeout: float = 120.0) -> faults.Verdict:
    """``case`` in a forked child (motionlab already imported): a crash (signal) is the verdict
    ``crash``; ``peak`` is the growth of the peak resident memory during the run, of the child
    or of the readers' own children (ezc3d and the HDF5 probe run in one,
    :mod:`motionlab.isolated`), whichever is larger."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: run, report, and leave without cleanup
        os.close(read)
        code = 1
        try:
            base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
            v = faults.run_case(case, folder, timeout)
            peak = (
                1024
                * max(
                    resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                    resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
                )
                - base
            )
            os.write(write, json.dumps(v.__dict__ | {"peak": peak}).encode())
            code = 0
        finally:
            os._exit(code)
    os.close(write)
    t0 = time.perf_counter()
    chunks = []
    while chunk := os.read(read, 65536):
        chunks.append(chunk)
    os.close(read)
    _, status = os.waitpid(pid, 0)
    seconds = time.perf_counter() - t0
    if os.WIFSIGNALED(status) or not chunks:
        return faults.Verdict(case.name, "crash", -os.WTERMSIG(status) if os.WIFSIGNALED(status)
                              else 1, "", seconds)  # fmt: skip
    res = json.loads(b"".join(chunks))
    peak = res.pop("peak")
    v = faults.Verdict(**res)
    v.peak = peak  # type: ignore[attr-defined]
    return v


#: a fresh interpreter that imports the readers and ingest, then runs the CLI and writes its
#: peak resident memory after the imports and the growth of its peak (or its children's, as
#: ezc3d's child was) over it (bytes) to the file named first (Linux: /proc/self/status)
_FRESH = """
import atexit, importlib, pkgutil, resource, sys
import h5py, motionlab.io, motionlab.ingest
for m in pkgutil.iter_modules(motionlab.io.__path__, "motionlab.io."):
    importlib.import_module(m.name)
from motionlab.cli import main
def hwm():  # kB; this process's own (ru_maxrss would carry the spawning process's peak)
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmHWM"))
base, out = hwm(), sys.argv[1]
def report():
    peak = max(hwm(), resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    with open(out, "w") as f:
        f.write(f"{1024 * base} {1024 * (peak - base)}")
atexit.register(report)
sys.argv = ["motionlab", *sys.argv[2:]]
main()
"""


def peak_memory(case: faults.Case, folder: Path) -> tuple[int, int]:
    """(exit code, growth of the peak RSS over the imports in bytes) of ``case`` run in a fresh
    interpreter: a forked child inherits the parent's peak (the parent may have built a big
    file with ezc3d), which would hide the child's own."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in case.files.items():
        (folder / name).write_bytes(data)
    report = folder / "peak.txt"
    env = os.environ | {"PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", _FRESH, str(report), *case.args], cwd=folder,
                          env=env, capture_output=True, timeout=600)  # fmt: skip
    return done.returncode, int(report.read_text().split()[1]) if report.exists() else 0


def c3d_cases(folder: Path, rng: np.random.Generator, per_file: int) -> list[faults.Case]:
    cases = []
    for path in sorted(folder.glob("*.c3d")):
        data = path.read_bytes()
        cases.append(faults.Case(f"c3d/original/{path.stem}", {"in.c3d": data},
                                 ["ingest", "in.c3d", "-o", "out.h5"]))  # fmt: skip
        for i in range(per_file):
            if i % 2:
                mutated = faults.truncate(data, rng.uniform(0, 1))
            else:  # flips in the header and parameter section, where counts live
                mutated = faults.flip(data, int(rng.integers(min(len(data), 4096))),
                                      int(rng.integers(1, 256)))  # fmt: skip
            name = f"c3d/{'cut' if i % 2 else 'flip'}/{path.stem}/{i}"
            args = ["ingest", "in.c3d", "-o", "out.h5"]
            cases.append(faults.Case(name, {"in.c3d": mutated}, args))
    return cases


def big_c3d(path: Path, megabytes: float) -> bytes:
    """A C3D file of about ``megabytes`` MB: 60 markers as float32 at 200 Hz (ezc3d writes it)."""
    import ezc3d

    markers = 60
    frames = int(megabytes * 1e6 / (16 * markers))
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [200.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = [f"M{k:02d}" for k in range(markers)]
    points = np.ones((4, markers, frames))
    points[:3] = np.random.default_rng(0).uniform(-500, 500, (3, markers, frames))
    f["data"]["points"] = points
    f.write(str(path))
    data = path.read_bytes()
    path.unlink()
    return data


def guard_cost(session: Path, c3d_files: list[Path], repeat: int = 10) -> list[str]:
    """Milliseconds of a normal read with and without the child-process guards: a session
    (``load_session``, HDF5 probe) and each C3D file (``c3d.read``: no native code, no guard
    any more; the rows show its read time)."""
    from motionlab import isolated
    from motionlab.io import c3d
    from motionlab.session import load_session

    def ms(fn, path: Path) -> float:
        best = []
        for _ in range(repeat):
            isolated._PROBED.clear()
            t0 = time.perf_counter()
            fn(path)
            best.append(time.perf_counter() - t0)
        return 1000 * float(np.median(best))

    rows = []
    for fn, paths in ((load_session, [session]), (c3d.read, c3d_files)):
        for path in paths:
            guarded = ms(fn, path)
            real = isolated.can_isolate
            isolated.can_isolate = lambda: False
            try:
                plain = ms(fn, path)
            finally:
                isolated.can_isolate = real
            rows.append(f"  {fn.__module__.split('.')[-1] + '.' + fn.__name__:<22} "
                        f"{path.name:<36} {path.stat().st_size / 1e6:7.2f} MB  "
                        f"{plain:7.1f} ms in-process  {guarded:7.1f} ms guarded  "
                        f"(+{guarded - plain:.1f} ms)")  # fmt: skip
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--per-reader", type=int, default=40, help="cases per text reader")
    ap.add_argument("--c3d", type=Path, help="folder of C3D files to break")
    ap.add_argument("--per-c3d", type=int, default=12)
    ap.add_argument("--big-c3d-mb", type=float, default=48.0,
                    help="size of a synthetic C3D for the memory table (0: none)")  # fmt: skip
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cases = faults.campaign(tmp / "make", args.seed, args.per_reader, 20, 0)
        native = [c for c in cases if c.name.startswith(("broad/", "apdm_h5/"))]  # libhdf5
        cases = [c for c in cases if c not in native]
        verdicts = [faults.run_case(c, tmp / f"c{i}") for i, c in enumerate(cases)]
        files = {"in.txt": faults.FIXTURES["xsens"].read_bytes()}
        good_case = faults.Case("good", files, ["ingest", "in.txt", "-o", "s.h5"], "s.h5")
        good = faults.run_case(good_case, tmp / "good")
        isolated = native + faults.session_cases((tmp / "good" / "s.h5").read_bytes(), rng, 80)
        if args.c3d:
            isolated += c3d_cases(args.c3d, rng, args.per_c3d)
        verdicts += [run_isolated(c, tmp / f"i{i}") for i, c in enumerate(isolated)]
        memory = []
        originals = [
            faults.ingest_case(f"memory/{k}", k, p.read_bytes()) for k, p in faults.FIXTURES.items()
        ]
        originals += [c for c in isolated if c.name.startswith("c3d/original")]
        if args.big_c3d_mb > 0:  # float storage, and the same points as int16 words
            data = big_c3d(tmp / "big.c3d", args.big_c3d_mb)
            args_ = ["ingest", "in.c3d", "-o", "out.h5"]
            originals.append(faults.Case("memory/c3d_synthetic", {"in.c3d": data}, args_))
            int16 = {"in.c3d": c3d_variants.to_int16(data, 0.1)}
            originals.append(faults.Case("memory/c3d_synthetic_int16", int16, args_))
            del data, int16
        for i, c in enumerate(originals):
            code, peak = peak_memory(c, tmp / f"m{i}")
            size = sum(len(d) for d in c.files.values())
            memory.append((c.name, size, peak, 4 * size + 300e6, code))
        big = tmp / "big.h5"
        simulate = ["simulate", "--protocol", "walk", "--duration", "600", "-o", str(big)]
        faults.run_case(faults.Case("big", {}, simulate, ""), tmp / "big")  # a 10-min session
        sessions = [tmp / "good" / "s.h5"] + ([big] if big.exists() else [])
        costs = [r for s in sessions for r in guard_cost(s, [])]
        costs += guard_cost(sessions[0], sorted(args.c3d.glob("*.c3d")) if args.c3d else [])[1:]
    broken = [v for v in verdicts if v.verdict not in ("ok", "refused")]
    print(f"{len(verdicts)} cases in {time.perf_counter() - t0:.0f} s (seed {args.seed}); "
          f"{100 * (1 - len(broken) / len(verdicts)):.1f} % clean")  # fmt: skip
    print(faults.table(verdicts))
    for v in broken:
        print(f"  {v.verdict:<14} {v.name}: {v.stderr[:160]}")
    net = [v for v in verdicts if "crashed reading it" in v.stderr]
    print(f"refused by the child-process safety net (a native crash in a child): {len(net)}")
    for v in net:
        print(f"  {v.name}: {v.stderr[:160]}")
    print("peak memory of ingest (growth of the peak RSS of a fresh process over the imports):")
    for name, size, peak, limit, code in memory:
        state = "ok" if peak <= limit else "OVER"
        print(f"  {name:<44} {size / 1e6:8.2f} MB in  {peak / 1e6:8.0f} MB peak  "
              f"(limit {limit / 1e6:.0f} MB) {state}  exit {code}")  # fmt: skip
    print("cost of the guards on normal reads (median of 10):")
    print("\n".join(costs))
    assert good.verdict == "ok"


if __name__ == "__main__":
    main()
