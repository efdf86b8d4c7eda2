"""A fast stand-in for ``motionlab.pipeline.run_pipeline`` and small studies for the batch tests.

A fake "recording" is a text file. Numbers: the session's knee angles (deg); its metrics are
their range, minimum and maximum, computed here by hand. A first word changes the behaviour:
``corrupt`` raises InputError, ``bug`` raises ValueError, ``crash`` kills the worker process the
first time (a ``.crashed`` flag file beside the input remembers it), ``crash-always`` every time,
``sleep S`` waits S seconds before the numbers, ``walk`` gives a gait summary too (its cadence
the first number; its step-time asymmetry withheld with a note). Each start appends a line to
``<input>.runs``.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from types import SimpleNamespace

import pandas as pd

from motionlab.atomic import atomic_path
from motionlab.errors import InputError


def fake_pipeline(inputs, outdir, options):
    source = Path(inputs[0])
    with open(source.with_suffix(".runs"), "a") as log:  # one line per start
        log.write(f"{os.getpid()}\n")
    words = source.read_text().split()
    if words[0] == "corrupt":
        raise InputError("7 columns, expected 10", source, "line 3", "is the delimiter ';'?")
    if words[0] == "bug":
        raise ValueError("something\nwent wrong")
    if words[0].startswith("crash"):
        flag = source.with_suffix(".crashed")
        if words[0] == "crash-always" or not flag.exists():
            flag.touch()
            os.kill(os.getpid(), signal.SIGKILL)
        words = words[1:]
    if words[0] == "sleep":
        time.sleep(float(words[1]))
        words = words[2:]
    gait = None
    if words[0] == "walk":
        words = words[1:]
        gait = pd.DataFrame({
            "parameter": ["cadence_steps_per_min", "step_time_asymmetry_pct"], "side": "both",
            "unit": ["steps/min", "%"], "mean": [float(words[0]), float("nan")],
            "note": ["", "not given: the two legs' sensor clocks are not linked"],
        })  # fmt: skip
    values = [float(w) for w in words]
    rows = []
    for angle, v in (("flexion", values), ("adduction", [x / 4 for x in values])):
        for metric, value in (("rom_deg", max(v) - min(v)), ("min_deg", min(v)),
                              ("max_deg", max(v))):  # fmt: skip
            rows.append(("gait", "knee_r", angle, metric, value, "deg"))
    metrics = pd.DataFrame(rows, columns=["block", "joint", "angle", "metric", "value", "unit"])
    report = Path(outdir) / "report.txt"
    with atomic_path(report, force=True) as tmp:
        tmp.write_text(
            f"{len(inputs)} inputs, protocol {Path(options.protocol).name}, seed {options.seed}, "
            f"magnetometer {options.magnetometer}, filter {options.estimator}\n"
        )
    return SimpleNamespace(
        session_path=None, report_path=report, csv_dir=None, metrics=metrics, summary="",
        gait=gait,
    )  # fmt: skip


def make_study(root: Path, sessions: dict[tuple[str, str], str], protocol: str = "knee") -> Path:
    """Write one fake recording per ``(subject, visit)`` and the manifest; return its path."""
    root.mkdir(parents=True, exist_ok=True)
    lines = [f"protocol: {protocol}", "sessions:"]
    for (subject, visit), text in sessions.items():
        raw = root / "raw" / subject / visit
        raw.mkdir(parents=True, exist_ok=True)
        (raw / "rec.txt").write_text(text)
        lines.append(
            f"  - {{subject: {subject}, visit: {visit}, files: raw/{subject}/{visit}/*.txt}}"
        )
    (root / "study.yaml").write_text("\n".join(lines) + "\n")
    return root / "study.yaml"


def good_sessions(n_subjects: int = 3, visits: tuple[str, ...] = ("v1", "v2")) -> dict:
    """Sessions whose flexion range grows by 5 deg per visit and 10 deg per subject."""
    return {
        (f"S{s}", v): " ".join(str(x) for x in (0, 20 + 10 * s + 5 * k, 5, 1))
        for s in range(1, n_subjects + 1)
        for k, v in enumerate(visits)
    }
