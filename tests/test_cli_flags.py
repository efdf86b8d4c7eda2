"""Library errors name arguments; the CLI turns them into its flags through one table."""

import ast
import re
from pathlib import Path

import pytest

from motionlab.batch.manifest import manifest_spelling
from motionlab.cli.flags import FLAGS, NEGATIVE, cli_error, to_flags
from motionlab.errors import InputError
from motionlab.session import Session, save_session

PACKAGE = Path(__file__).resolve().parents[1] / "motionlab"
FLAG = re.compile(r"(?<![\w-])--?[a-z][a-z-]*")


def _library_errors():
    """``(file:line, call)`` of every ``InputError(...)`` outside ``motionlab/cli``."""
    for path in sorted(PACKAGE.rglob("*.py")):
        if "cli" in path.relative_to(PACKAGE).parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "InputError":
                yield f"{path.relative_to(PACKAGE)}:{node.lineno}", node


def _texts(node: ast.AST) -> list[str]:
    return [
        n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)
    ]


def test_no_library_error_names_a_command_line_flag():
    found = [
        (where, text)
        for where, call in _library_errors()
        for text in _texts(call)
        if FLAG.search(text) and not text.startswith("-")  # "-" alone: a negative number
    ]
    assert not found, found


def test_every_argument_an_error_names_has_a_flag():
    named = set()
    for _, call in _library_errors():
        for kw in call.keywords:
            if kw.arg == "argument":
                named.update(_texts(kw.value))
    assert named, "no library error names an argument"
    assert sorted(named - set(FLAGS) - set(NEGATIVE)) == []


@pytest.mark.parametrize(
    ("library", "cli"),
    [
        ("add force=True to redo it", "add --force to redo it"),
        ("rate=500 Hz is too high", "--rate 500 Hz is too high"),
        ("give rate=100 or less", "give --rate 100 or less"),
        ("calibrate first, or pass calibrated=False", "calibrate first, or pass --no-calibration"),
        ("use method='imu'", "use --method imu"),
        ("argument soft_tissue", "--soft-tissue"),
        ("use estimator=vqf or mekf", "use --filter vqf or mekf"),
    ],
)  # fmt: skip
def test_arguments_become_flags(library, cli):
    names = ("force", "rate", "calibrated", "method", "soft_tissue", "estimator")
    assert to_flags(library, names) == cli


def test_the_cli_line_of_a_library_error(tmp_path):
    path = tmp_path / "s.h5"
    save_session(Session(), path)
    with pytest.raises(InputError) as err:
        save_session(Session(), path)
    assert err.value.arguments == ("force",)
    assert "force=True" in err.value.line() and "--force" not in err.value.line()
    line = cli_error(err.value).line()  # the folder named: which s.h5 is meant
    assert line == f"s.h5 in {tmp_path}: output exists — use --force to replace it"


def test_batch_names_manifest_keys_not_flags_or_arguments():
    err = InputError(
        "sensor 'A1' has no segment",
        "s.txt",
        remedy="map each sensor to a segment with a sensor map, map_path=map.yaml",
        argument=("map_path", "force"),
    )
    line = err.respelled(manifest_spelling).line()
    assert line == ("s.txt: sensor 'A1' has no segment — map each sensor to a segment with a "
                    "sensor map, 'map: map.yaml'")  # fmt: skip
    off = InputError("no sync", remedy="pass clock_sync=False", argument="clock_sync")
    assert off.respelled(manifest_spelling).remedy == "pass 'clock_sync: false'"
    # an argument with no manifest key keeps the library's spelling
    kept = InputError("exists", remedy="pass force=True", argument="force")
    assert kept.respelled(manifest_spelling).remedy == "pass force=True"


def _flags(command) -> set[str]:
    return {o for p in command.params for o in (*p.opts, *p.secondary_opts)}


def test_every_run_option_is_in_batch_the_manifest_and_its_stage_commands():
    """The run options' table (pipeline.RUN_OPTIONS) makes run's and batch's click options, the
    flag table and the manifest keys: each option is a flag of run, of batch and a manifest key
    when the study can set it, and a flag of the stage commands it names."""
    from motionlab.batch.manifest import OPTION_KEYS, SESSION_KEYS, TOP_KEYS
    from motionlab.cli import main
    from motionlab.pipeline import RUN_OPTIONS

    def command(name: str):
        return main.get_command(None, name)  # the command's module, imported on first use

    run, batch = _flags(command("run")), _flags(command("batch"))
    for name, option in RUN_OPTIONS.items():
        flags = set(option.flag.split("/"))
        assert flags <= run, name
        spelled = FLAGS.get(name) or NEGATIVE.get(name)
        assert spelled in flags, name  # an error naming the argument names the run flag
        if option.batch:
            assert flags <= batch, name
            assert OPTION_KEYS[option.manifest] == name
            assert option.manifest in TOP_KEYS and option.manifest in SESSION_KEYS
        for stage in option.stages:
            assert flags <= _flags(command(stage)), (name, stage)
    assert "--orientation" in batch and OPTION_KEYS["orientation"] == "orientation"


def test_a_stage_command_defaults_as_run_does():
    """One path: a stage command's flag that is also a run option has run's default (the angles'
    low-pass is spelled out in ``motionlab angles`` so that its ``--help`` stays light)."""
    import dataclasses

    from motionlab.cli import main
    from motionlab.pipeline import RUN_OPTIONS, PipelineOptions

    defaults = {f.name: f.default for f in dataclasses.fields(PipelineOptions)}
    checked = 0
    for name, option in RUN_OPTIONS.items():
        if option.kind not in ("int", "choice", "text") or defaults[name] is dataclasses.MISSING:
            continue
        for stage in option.stages:
            params = main.get_command(None, stage).params
            param = next(p for p in params if option.flag in p.opts)
            given = None if "UNSET" in repr(param.default) else param.default  # click 8.2: unset
            assert given == defaults[name], (name, stage)
            checked += 1
    assert checked >= 4  # --angle-lowpass (None: the protocol's), --filter, --orientation, --seed


def test_run_and_batch_help_keep_their_examples_and_options():
    """The generated options leave the help readable: examples, every flag, defaults."""
    from click.testing import CliRunner

    from motionlab.cli import main

    shown = {
        "run": ["--filter", "--orientation", "--no-clock-sync", "--quiet"],
        "batch": ["--filter", "--orientation", "manifest key 'filter'"],
    }
    for name, flags in shown.items():
        out = CliRunner().invoke(main, [name, "--help"], terminal_width=100).output
        assert "Example:\n" in out and f"\n    motionlab {name} " in out, out
        assert all(f in out for f in flags), out
    out = CliRunner().invoke(main, ["run", "--help"], terminal_width=100).output
    assert "[default: default]" in out  # the estimator's default shown
