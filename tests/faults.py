"""The fault campaign's machinery, shared by ``tests/test_fault_campaign.py`` (a representative
subset in CI) and ``bench/faults.py`` (hundreds of cases): broken copies of every reader's
fixture, the command that reads them, and the promise each run is checked against.

The promise (issue 16): exit 0, or exit 2 with exactly one line on stderr; never a traceback;
inputs byte-identical; no output or temporary file left by a refusal; bounded time.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from click.testing import CliRunner

from motionlab.cli import main

DATA = Path(__file__).resolve().parent / "data"
#: the fixture of each reader (text formats first)
FIXTURES = {
    "xsens": DATA / "xsens" / "MT46_01-000_00B42D4D.txt",
    "xsens_mat": DATA / "xsens" / "MT2022_ACC_GYRO_ROT_MAT_COMMA_00B42D4B.txt",
    "xio": DATA / "xio" / "sensor_data_excerpt.csv",
    "dot": DATA / "dot" / "RFemur_20210820_202113_840_excerpt.csv",
    "apdm": DATA / "apdm" / "apdm_format7.csv",
    "opensim": DATA / "opensim" / "imuOrientations.sto",
    "trc": DATA / "c3d" / "markers_20frames.trc",
    "broad": DATA / "broad" / "broad_10_excerpt.hdf5",
}
TEXT_READERS = [k for k, p in FIXTURES.items() if p.suffix != ".hdf5"]
NUMBER = re.compile(rb"(?<![\w.])-?\d+\.\d+(?:[eE][-+]?\d+)?")
PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "knee.yaml"


@dataclass
class Case:
    """One run: a name, input files (name → bytes) and the command's arguments."""

    name: str
    files: dict[str, bytes]
    args: list[str]
    output: str = "out.h5"


@dataclass
class Verdict:
    name: str
    verdict: str  # "ok", "refused" or a broken promise
    exit_code: int
    stderr: str
    seconds: float


# ----------------------------------------------------------------------------- mutations


def truncate(data: bytes, at: float) -> bytes:
    """The first ``at`` (0–1) of the file."""
    return data[: int(len(data) * at)]


def flip(data: bytes, offset: int, mask: int = 0xFF) -> bytes:
    """One byte XOR-ed with ``mask`` at ``offset`` (modulo the size)."""
    b = bytearray(data)
    if b:
        b[offset % len(b)] ^= mask
    return bytes(b)


def replace_number(data: bytes, k: int, value: bytes) -> bytes:
    """The ``k``-th decimal number of the file (modulo their count) replaced by ``value``."""
    found = list(NUMBER.finditer(data))
    if not found:
        return data
    m = found[k % len(found)]
    return data[: m.start()] + value + data[m.end() :]


def replace_numbers(data: bytes, value: bytes, every: int = 1) -> bytes:
    """Every ``every``-th decimal number replaced by ``value``."""
    count = 0

    def sub(m: re.Match) -> bytes:
        nonlocal count
        count += 1
        return value if count % every == 0 else m.group()

    return NUMBER.sub(sub, data)


def _delimiter(data: bytes) -> bytes:
    head = data[:4000]
    return max((b"\t", b",", b";", b" "), key=head.count)


def drop_column(data: bytes, j: int) -> bytes:
    """Column ``j`` removed from every line that has it."""
    d = _delimiter(data)
    out = []
    for line in data.split(b"\n"):
        cells = line.split(d)
        if len(cells) > 2:
            del cells[j % len(cells)]
        out.append(d.join(cells))
    return b"\n".join(out)


def extra_column(data: bytes) -> bytes:
    """One more cell at the end of every data line."""
    d = _delimiter(data)
    return b"\n".join(
        line + d + b"1.0" if line[:1].isdigit() else line for line in data.split(b"\n")
    )


def swap_delimiter(data: bytes, new: bytes = b";") -> bytes:
    return data.replace(_delimiter(data), new)


def encode(data: bytes, codec: str) -> bytes:
    return data.decode("utf-8", "replace").encode(codec, "replace")


def h5_mutate(data: bytes, how: str, tmp: Path) -> bytes:
    """A BROAD file with one dataset or attribute changed (``how``)."""
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "h5mut.hdf5"
    path.write_bytes(data)
    with h5py.File(path, "r+") as f:
        if how == "rate_text":
            f.attrs["sampling_rate"] = "fast"
        elif how == "rate_zero":
            f.attrs["sampling_rate"] = 0.0
        elif how == "rate_huge":
            f.attrs["sampling_rate"] = 1e300
        elif how == "rate_array":
            f.attrs["sampling_rate"] = np.arange(3.0)
        elif how.startswith("strings:"):
            name = how.split(":")[1]
            n = f[name].shape
            del f[name]
            f.create_dataset(name, data=np.full(n, "x", dtype=object), dtype=h5py.string_dtype())
        elif how.startswith("shape:"):
            name = how.split(":")[1]
            del f[name]
            f[name] = np.zeros((5, 7))
        elif how.startswith("drop:"):
            del f[how.split(":")[1]]
        elif how.startswith("value:"):
            _, name, value = how.split(":")
            a = f[name][()]
            a[len(a) // 2] = float(value)
            f[name][...] = a
        elif how == "compressed_then_damaged":
            a = f["imu_acc"][()]
            del f["imu_acc"]
            f.create_dataset("imu_acc", data=a, compression="gzip", chunks=(16, 3))
    out = path.read_bytes()
    path.unlink()
    if how == "compressed_then_damaged":  # damage the compressed chunks, not the metadata
        b = bytearray(out)
        for k in range(len(b) // 3, 2 * len(b) // 3, 97):
            b[k] ^= 0x55
        out = bytes(b)
    return out


# ------------------------------------------------------------------------------- running


def sha(files: dict[str, bytes]) -> dict[str, str]:
    return {k: hashlib.sha256(v).hexdigest() for k, v in files.items()}


@contextlib.contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def run_case(case: Case, folder: Path, time_limit: float = 30.0) -> Verdict:
    """Run ``case`` in an empty ``folder`` and judge it against the promise."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in case.files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)  # x-IMU3: folder per device
        (folder / name).write_bytes(data)
    before = {p.name for p in folder.iterdir()}
    t0 = time.perf_counter()
    with _cwd(folder):
        result = CliRunner().invoke(main, case.args, catch_exceptions=True)
    seconds = time.perf_counter() - t0
    after = {p.name for p in folder.iterdir()}
    changed = [n for n, h in sha({n: (folder / n).read_bytes() for n in case.files}).items()
               if h != sha(case.files)[n]]  # fmt: skip
    stderr = result.stderr
    code = result.exit_code
    if code not in (0, 2):
        verdict = f"exit {code}"
    elif "Traceback" in result.output or "Traceback" in stderr:
        verdict = "traceback"
    elif changed:
        verdict = "input changed"
    elif code == 2 and (len(stderr.splitlines()) != 1 or not stderr.startswith("error: ")):
        verdict = "not one line"
    elif code == 2 and after != before:
        verdict = "output left"
    elif code == 0 and case.output and case.output not in after:
        verdict = "no output"
    elif code == 0 and after - before - {case.output}:
        verdict = "temporary left"
    elif seconds > time_limit:
        verdict = "slow"
    else:
        verdict = "ok" if code == 0 else "refused"
    return Verdict(case.name, verdict, code, stderr.strip()[:300], seconds)


# -------------------------------------------------------------------------------- cases


def ingest_case(name: str, reader: str, data: bytes, extra: list[str] | None = None) -> Case:
    fname = "in" + FIXTURES[reader].suffix
    return Case(name, {fname: data}, ["ingest", fname, "-o", "out.h5", *(extra or [])])


def map_case(name: str, text: str) -> Case:
    fname = "in" + FIXTURES["xsens"].suffix
    files = {fname: FIXTURES["xsens"].read_bytes(), "map.yaml": text.encode()}
    return Case(name, files, ["ingest", fname, "--map", "map.yaml", "-o", "out.h5"])


def protocol_case(name: str, text: str) -> Case:
    """``run`` with a broken protocol: refused before any data is read (no output)."""
    fname = "in" + FIXTURES["xsens"].suffix
    files = {fname: FIXTURES["xsens"].read_bytes(), "p.yaml": text.encode()}
    return Case(
        name, files, ["run", fname, "--protocol", "p.yaml", "-o", "res", "--quiet"], output=""
    )


#: YAML values of the wrong type for a key, with the key's path (``a.b``) in the knee protocol
YAML_TYPE_ERRORS = {
    "name": "[knee]",
    "segments.pelvis.side": "[r]",
    "segments.pelvis.sensor_axes": "xyz",
    "segments.pelvis.required": "maybe",
    "segments.pelvis.landmarks": "{a: 1}",
    "calibration.0.duration_s": "five",
    "calibration.0.reference_rho": "high",
    "calibration.0.vertical_axis": "[y]",
    "joints.knee_r.side": "[r]",
    "joints.knee_r.proximal": "7",
    "joints.knee_r.sequence": "ABC",
    "joints.knee_r.distal": "thigh_r",
    "normative": "[1, 2]",
    "thresholds": "three",
    "metrics": "rom",
    "title": "2026-02-30",
    "tasks.0.duration_s": ".nan",
}
MAP_TYPE_ERRORS = {
    "sensors.00B42D4D.side": "[r]",
    "sensors.00B42D4D.segment": "[shank]",
    "sensors.00B42D4D.label": "12",
    "sensors.00B42D4D.sied": "r",
    "subject": "[P017]",
    "session.date": "2026-02-30",
    "reader": "generic",
    "reader.format": "[generic]",
}


def yaml_with(text: str, dotted: str, value: str) -> str:
    """``text`` (YAML) with the key at ``dotted`` set to the YAML ``value`` (round trip)."""
    import yaml

    doc = yaml.safe_load(text)
    node = doc
    keys = dotted.split(".")
    for k in keys[:-1]:
        if isinstance(node, list):
            node = node[int(k)]
        else:
            node = node.setdefault(k, {}) if isinstance(node.get(k, {}), dict) else node[k]
    last = keys[-1]
    marker = "__MARK__"
    if isinstance(node, list):
        node[int(last)] = marker
    else:
        node[last] = marker
    body = yaml.safe_dump(doc, sort_keys=False, default_flow_style=False, allow_unicode=True)
    return body.replace(marker, value)


def _text_mutations(data: bytes, rng: np.random.Generator) -> list[tuple[str, Callable[[], bytes]]]:
    """Every kind of damage to a text file, each a maker of the damaged bytes."""
    return [
        ("truncate", lambda: truncate(data, rng.uniform(0, 1))),
        ("flip", lambda: flip(data, int(rng.integers(len(data))), int(rng.integers(1, 256)))),
        ("nan", lambda: replace_number(data, int(rng.integers(1 << 30)), b"nan")),
        ("inf", lambda: replace_number(data, int(rng.integers(1 << 30)), b"-inf")),
        ("huge", lambda: replace_number(data, int(rng.integers(1 << 30)), b"1e308")),
        ("huge_all", lambda: replace_numbers(data, b"1e308", int(rng.integers(2, 9)))),
        ("text_cell", lambda: replace_number(data, int(rng.integers(1 << 30)), b"\x00abc" * 50)),
        ("drop_column", lambda: drop_column(data, int(rng.integers(20)))),
        ("extra_column", lambda: extra_column(data)),
        ("delimiter", lambda: swap_delimiter(data, [b";", b",", b"|"][int(rng.integers(3))])),
        ("utf16", lambda: encode(data, "utf-16")),
        ("latin1_bom", lambda: b"\xef\xbb\xbf" + data.replace(b"Acc", "Äcc".encode("latin-1"))),
        ("crlf", lambda: data.replace(b"\n", b"\r\n")),
        ("empty", lambda: b""),
        ("head_only", lambda: data[: data.find(b"\n", data.find(b"\n") + 1) + 1]),
        ("binary_tail", lambda: data + b"\x00" * 4096),
    ]


def text_cases(reader: str, rng: np.random.Generator, n: int) -> list[Case]:
    """``n`` broken copies of a text reader's fixture (every mutation kind, random places)."""
    kinds = _text_mutations(FIXTURES[reader].read_bytes(), rng)
    cases = []
    for i in range(n):
        kind, make = kinds[i % len(kinds)]
        cases.append(ingest_case(f"{reader}/{kind}/{i}", reader, make()))
    return cases


def ximu3_cases(rng: np.random.Generator, n: int) -> list[Case]:
    """``n`` x-IMU3 exports (a folder per device, ``tests/ximu3_export.py``) with one of the
    channel files of one device broken, or removed."""
    from ximu3_export import export_files

    good = export_files(seconds=2.0)
    names = [k for k in good if k.endswith((".csv", ".json")) and "Battery" not in k]
    cases = []
    for i in range(n):
        target = names[int(rng.integers(len(names)))]
        files = dict(good)
        if i % 17 == 16:
            kind = "missing"
            del files[target]
        else:
            kinds = _text_mutations(good[target], rng)
            kind, make = kinds[i % len(kinds)]
            files[target] = make()
        short = target.split("/")[-1]
        cases.append(Case(f"ximu3/{kind}:{short}/{i}", files, ["ingest", "imu", "-o", "out.h5"]))
    return cases


H5_MUTATIONS = [
    "rate_text", "rate_zero", "rate_huge", "rate_array", "strings:imu_acc", "strings:movement",
    "shape:imu_gyr", "drop:opt_quat", "drop:imu_mag", "value:imu_acc:1e308",
    "value:imu_gyr:nan", "value:imu_acc:inf", "compressed_then_damaged",
]  # fmt: skip


def broad_cases(rng: np.random.Generator, tmp: Path, n_random: int) -> list[Case]:
    """HDF5: type swaps in attributes and datasets, damaged chunks, truncation, flips."""
    data = FIXTURES["broad"].read_bytes()
    cases = [ingest_case(f"broad/{m}", "broad", h5_mutate(data, m, tmp)) for m in H5_MUTATIONS]
    for i in range(n_random):
        if i % 2:
            mutated = truncate(data, rng.uniform(0, 1))
        else:
            mutated = flip(data, int(rng.integers(len(data))), int(rng.integers(1, 256)))
        cases.append(ingest_case(f"broad/{'truncate' if i % 2 else 'flip'}/{i}", "broad", mutated))
    return cases


def apdm_h5_cases(rng: np.random.Generator, tmp: Path, n_random: int) -> list[Case]:
    """An APDM .h5 export (built as documented, ``tests/test_io_apdm.py``) truncated or with
    one byte flipped, given to ``ingest``."""
    from test_io_apdm import _write_apdm_h5

    tmp.mkdir(parents=True, exist_ok=True)
    _write_apdm_h5(tmp / "apdm.h5")
    data = (tmp / "apdm.h5").read_bytes()
    cases = []
    for i in range(n_random):
        if i % 2:
            mutated = truncate(data, rng.uniform(0, 1))
        else:
            mutated = flip(data, int(rng.integers(len(data))), int(rng.integers(1, 256)))
        name = f"apdm_h5/{'truncate' if i % 2 else 'flip'}/{i}"
        cases.append(Case(name, {"in.h5": mutated}, ["ingest", "in.h5", "-o", "out.h5"]))
    return cases


def session_cases(
    session: bytes, rng: np.random.Generator, n_random: int, flips: bool = True
) -> list[Case]:
    """A session file broken, given to ``info`` (reads every dataset) or ``fuse``.

    Byte flips can make libhdf5 itself crash (a segmentation fault reading a damaged attribute
    heap); the readers probe every HDF5 file in a forked child first
    (:func:`motionlab.isolated.check_hdf5`), so that a crash there is a refusal. ``bench/faults.py``
    still runs each case in a child of its own, so that a crash the probe missed is counted
    instead of ending the run. ``flips=False`` only truncates.
    """
    cases = []
    for i in range(n_random):
        if i % 2 or not flips:
            mutated = truncate(session, rng.uniform(0, 1))
        else:
            mutated = flip(session, int(rng.integers(len(session))), int(rng.integers(1, 256)))
        command = ["info", "s.h5"] if i % 4 < 3 else ["fuse", "s.h5", "-o", "out.h5"]
        output = "" if command[0] == "info" else "out.h5"
        cases.append(Case(f"session/{command[0]}/{i}", {"s.h5": mutated}, command, output))
    return cases


def yaml_cases() -> list[Case]:
    """Every protocol and map key given a value of the wrong type; aliases; bad dates."""
    knee = PROTOCOL.read_text()
    cases = [
        protocol_case(f"protocol/{k}", yaml_with(knee, k, v)) for k, v in YAML_TYPE_ERRORS.items()
    ]
    base_map = "sensors:\n  00B42D4D: {segment: shank, side: r, label: shank_r}\nsession: {}\n"
    for key, value in MAP_TYPE_ERRORS.items():
        cases.append(map_case(f"map/{key}", yaml_with(base_map, key, value)))
    laughs = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n"
        for p, c in zip("abcdefgh", "bcdefghi", strict=True)  # noqa: E501
    )
    cases += [
        protocol_case("protocol/billion_laughs", laughs),
        map_case("map/billion_laughs", laughs),
        protocol_case("protocol/unknown_key", knee.replace("purpose:", "purpos:", 1)),
        protocol_case("protocol/binary", "\x00" * 100),
        map_case("map/recursive_alias", "a: &a [*a]\n"),
    ]
    return cases


def campaign(
    tmp: Path, seed: int, n_text: int, n_h5: int, n_session: int, flips: bool = True
) -> list[Case]:
    """Every kind of case: ``n_text`` per text reader, ``n_h5`` random HDF5 damages and
    ``n_session`` broken sessions besides the fixed ones."""
    rng = np.random.default_rng(seed)
    cases = []
    for reader in TEXT_READERS:
        cases += text_cases(reader, rng, n_text)
    cases += ximu3_cases(rng, n_text)
    cases += broad_cases(rng, tmp, n_h5)
    cases += apdm_h5_cases(rng, tmp / "apdm", n_h5)
    cases += yaml_cases()
    session = tmp / "good" / "s.h5"
    if n_session:
        good = run_case(
            Case("good", {"in.txt": FIXTURES["xsens"].read_bytes()}, ["ingest", "in.txt", "-o",
                 "s.h5"], "s.h5"), tmp / "good")  # fmt: skip
        assert good.verdict == "ok", good
        cases += session_cases(session.read_bytes(), rng, n_session, flips)
    return cases


def table(verdicts: list[Verdict]) -> str:
    """Counts by verdict, and by family (the case name's first part) and verdict."""
    out = io.StringIO()
    by: dict[str, dict[str, int]] = {}
    for v in verdicts:
        fam = v.name.split("/")[0]
        by.setdefault(fam, {}).setdefault(v.verdict, 0)
        by[fam][v.verdict] += 1
    verdicts_seen = sorted({v.verdict for v in verdicts})
    out.write(f"{'family':<12}" + "".join(f"{k:>16}" for k in verdicts_seen) + "\n")
    for fam, counts in by.items():
        out.write(f"{fam:<12}" + "".join(f"{counts.get(k, 0):>16}" for k in verdicts_seen) + "\n")
    total = {k: sum(v.verdict == k for v in verdicts) for k in verdicts_seen}
    out.write(f"{'total':<12}" + "".join(f"{total[k]:>16}" for k in verdicts_seen) + "\n")
    return out.getvalue()
