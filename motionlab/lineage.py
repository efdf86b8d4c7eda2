"""What each stage's result was computed from, so that a session never uses a stale result.

Every stage function (:mod:`motionlab.stages`) that stores a result stamps it
(:meth:`Lineage.record`) with a generation number (one counter per session file, never
reused) and the generations of the results it read (:data:`INPUTS`), plus the SHA-256 of the
protocol file it used. Redoing a stage (``sync``, ``fuse --force``, ``calibrate --force``, ...)
gives its result a new generation, so every result computed from the old one no longer
matches its stamp: it is *stale* (:meth:`Lineage.stale`), and so is everything computed from
a stale result. A stage refuses to read a stale result (:func:`refuse_stale`, one line naming
what to re-run), ``report`` refuses to show one, ``info`` lists them.

Generations rather than content hashes: a stamp costs nothing to make or check (hashing the
orientations and angles of a long session would cost a second on every command), and every
result a session holds is written by a stage function, which stamps it. The session file keeps
the stamps as the root attribute ``lineage`` (schema 3); a file of an older schema has none, and
its results are taken as consistent with each other, as they were used before
(:meth:`Lineage.assumed`). ``heading`` is stamped with ``angles`` and ``gait`` with ``metrics``
(one stage makes both).
"""

from __future__ import annotations

import hashlib
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from motionlab.atomic import check_regular
from motionlab.errors import InputError

#: the stages whose results each stage reads, in the order the stages run
INPUTS: dict[str, tuple[str, ...]] = {
    "clock_sync": (),
    "fusion": ("clock_sync",),
    "calibration": ("clock_sync", "fusion"),
    "angles": ("fusion", "calibration"),
    "metrics": ("fusion", "calibration", "angles"),
    "validation": ("fusion", "calibration", "angles"),
}
#: the command that makes each stage's result
COMMANDS = {
    "clock_sync": "sync",
    "fusion": "fuse",
    "calibration": "calibrate",
    "angles": "angles",
    "metrics": "metrics",
    "validation": "validate",
}


def present(results: Any, stage: str) -> bool:
    """Whether ``results`` (:class:`~motionlab.results.Results`) holds the stage's result."""
    return getattr(results, stage) not in (None, {})


@dataclass
class Stamp:
    """One result's origin: its ``generation``; ``inputs`` ``{stage: generation}`` of the results
    it read (``None``: the stage had no result then); ``protocol_sha256`` of the protocol file
    it used (``None``: none); ``assumed``: stamped when a file of an older schema was read (its
    inputs are the generations found then)."""

    generation: int
    inputs: dict[str, int | None] = field(default_factory=dict)
    protocol_sha256: str | None = None
    assumed: bool = False


@dataclass
class Lineage:
    """The stamps of a session's results: ``stamps`` ``{stage: Stamp}`` and ``counter``, the
    last generation given out."""

    counter: int = 0
    stamps: dict[str, Stamp] = field(default_factory=dict)

    def _generation(self, results: Any, stage: str) -> int | None:
        if not present(results, stage):
            return None
        if stage not in self.stamps:  # made before stamps existed: taken as it is
            self.counter += 1
            self.stamps[stage] = Stamp(self.counter, assumed=True)
        return self.stamps[stage].generation

    def record(
        self,
        results: Any,
        stage: str,
        protocol: Any = None,
        inputs: tuple[str, ...] | None = None,
    ) -> Stamp:
        """Stamp the result ``stage`` just stored in ``results``: a new generation, the
        generations of the stages it read (``inputs``, default its :data:`INPUTS`) and the
        SHA-256 of the ``protocol`` file (a path or a loaded protocol)."""
        read = {up: self._generation(results, up) for up in inputs or INPUTS[stage]}
        self.counter += 1
        self.stamps[stage] = Stamp(self.counter, read, protocol_sha256(protocol))
        return self.stamps[stage]

    def stale(self, results: Any) -> dict[str, str]:
        """``{stage: why}`` of every result of ``results`` that is not computed from the results
        the session holds now, in the order the stages run."""
        out: dict[str, str] = {}
        for stage in INPUTS:
            stamp = self.stamps.get(stage)
            if stamp is None or not present(results, stage):
                continue
            for up, then in stamp.inputs.items():
                now = self.stamps[up].generation if up in self.stamps else then
                if not present(results, up):
                    now = None
                if up in out:
                    out[stage] = f"computed from the {up} result, which is stale"
                elif now != then:
                    done = "removed" if now is None else "redone" if then is not None else "run"
                    out[stage] = f"computed before {COMMANDS[up]} was {done}"
                else:
                    continue
                break
        return out

    @classmethod
    def assumed(cls, results: Any) -> Lineage:
        """Stamps for the results of a file written before stamps existed: each consistent with
        the others (what the older motionlab took them to be)."""
        lineage = cls()
        for stage in INPUTS:
            if present(results, stage):
                inputs = {up: lineage._generation(results, up) for up in INPUTS[stage]}
                lineage.counter += 1
                lineage.stamps[stage] = Stamp(lineage.counter, inputs, assumed=True)
        return lineage

    def to_tree(self) -> dict[str, Any]:
        """The JSON-able form stored in the session file."""
        return {
            "counter": self.counter,
            "stamps": {
                k: {"generation": s.generation, "inputs": s.inputs}
                | ({"protocol_sha256": s.protocol_sha256} if s.protocol_sha256 else {})
                | ({"assumed": True} if s.assumed else {})
                for k, s in self.stamps.items()
            },
        }

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> Lineage:
        """The lineage of :meth:`to_tree`'s form (``ValueError``/``TypeError``/``KeyError`` for
        a damaged one)."""
        stamps = {}
        for stage, s in tree["stamps"].items():
            inputs = {str(k): None if v is None else int(v) for k, v in s["inputs"].items()}
            sha = s.get("protocol_sha256")
            stamps[str(stage)] = Stamp(int(s["generation"]), inputs,
                                       None if sha is None else str(sha),
                                       bool(s.get("assumed", False)))  # fmt: skip
        return cls(int(tree["counter"]), stamps)


def sha256_file(path: str | Path) -> str:
    """SHA-256 hex digest of a file's bytes."""
    check_regular(path)
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def protocol_sha256(protocol: Any) -> str | None:
    """SHA-256 of the protocol's file (a path, or a loaded protocol's ``path``), if it has one."""
    path = getattr(protocol, "path", protocol)
    if path is None or not Path(path).is_file():
        return None
    return sha256_file(path)


def rerun(stale: dict[str, str], needed: tuple[str, ...] | list[str]) -> list[str]:
    """The stages to redo, in the order they run, to bring the ``needed`` stages' results up to
    date (each stale one and the stale results it reads)."""
    wanted: set[str] = set()
    todo = [s for s in needed if s in stale]
    while todo:
        stage = todo.pop()
        wanted.add(stage)
        todo += [u for u in INPUTS[stage] if u in stale and u not in wanted]
    return [s for s in INPUTS if s in wanted]


#: the stages whose command needs the protocol named (the others take the calibration's)
NEEDS_PROTOCOL = ("clock_sync", "calibration")
#: where the shipped protocols lie: one of them is named by its name in a command
_PACKAGED = Path(__file__).resolve().parent / "protocols"


def rerun_commands(session: Any, stale: dict[str, str], needed: Any, path: Any = None) -> str:
    """The commands to run, in order, to bring the ``needed`` stages' results of ``session`` up
    to date, as they can be run: ``motionlab calibrate session.h5 protocol=knee force=True,
    then motionlab angles session.h5 force=True`` (the session file ``path``; the protocol the
    calibration used, by its name where it is a shipped one; library spelling, the CLI turns
    ``name=value`` into its flags, :class:`~motionlab.errors.InputError` ``argument``)."""
    cal = getattr(session.results, "calibration", None)
    protocol = None
    if cal is not None:
        file = Path(cal.protocol_path) if cal.protocol_path else None
        shipped = file is None or file.resolve() == _PACKAGED / f"{cal.protocol}.yaml"
        protocol = cal.protocol if shipped else str(file)
    where = f" {shlex.quote(str(path))}" if path is not None else ""
    commands = []
    for stage in rerun(stale, needed):
        words = f"motionlab {COMMANDS[stage]}{where}"
        if stage in NEEDS_PROTOCOL:
            words += f" protocol={shlex.quote(protocol)}" if protocol else " protocol=<protocol>"
        commands.append(f"{words} force=True")
    return ", then ".join(commands)


def refuse_stale(session: Any, needed: tuple[str, ...] | list[str], path: Any = None) -> None:
    """Raise :class:`InputError` when a result among ``needed`` is stale: one line naming the
    first and the commands to re-run (:func:`rerun_commands`)."""
    stale = session.lineage.stale(session.results)
    bad = [s for s in needed if s in stale]
    if not bad:
        return
    raise InputError(
        f"the {bad[0]} result is stale ({stale[bad[0]]})",
        path,
        f"results/{bad[0]}",
        f"re-run {rerun_commands(session, stale, bad, path)} first",
        argument=("force", "protocol"),
    )
