"""No traceback reaches a user: every command of `dance3d`, found by walking its argparse tree (a new
command is covered without editing this file), is run three ways -- in an empty folder, with a file
of random bytes wherever it takes a path, and with a path that does not exist -- and must either do
its job or exit non-zero with one line that names what is wrong."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

from pipeline.cli import build_parser, main, one_line
from pipeline.core.errors import InputError


def leaf_commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple]:
    """(command words, the parser that takes their arguments) for every runnable command."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [(prefix, parser)]
    return [leaf for name, child in subs[0].choices.items() for leaf in leaf_commands(child, (*prefix, name))]


def arguments(parser: argparse.ArgumentParser, path: str) -> list[str]:
    """Values for the parser's positionals and required options: ``path`` wherever a value is free,
    the first choice where there are choices, 1 where a number is asked for."""
    out: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or not (action.required or not action.option_strings):
            continue
        if action.choices:
            value = str(next(iter(action.choices)))
        elif action.type in (int, float):
            value = "1"
        else:
            value = path
        # one value, whatever nargs: "+" and "*" take one too
        out += ([action.option_strings[0]] if action.option_strings else []) + [value]
    return out


COMMANDS = leaf_commands(build_parser())


def test_the_walk_finds_every_command_group() -> None:
    names = {words[0] for words, _ in COMMANDS}
    assert {"run", "eval", "export", "models", "manifests", "render", "qc", "status", "retry", "review"} <= names
    assert len(COMMANDS) > 20


@pytest.mark.parametrize("how", ["empty folder", "random bytes", "no such path"])
@pytest.mark.parametrize("words,parser", COMMANDS, ids=[" ".join(w) for w, _ in COMMANDS])
def test_every_command_fails_in_one_line_without_a_traceback(words: tuple, parser, how: str, tmp_path: Path,
                                                             monkeypatch, capsys) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.chdir(empty)
    monkeypatch.delenv("DANCE3D_DEBUG", raising=False)
    if how == "random bytes":
        target = tmp_path / "input.bin"
        target.write_bytes(os.urandom(3000))
    else:
        target = empty / "missing" if how == "empty folder" else tmp_path / "no" / "such" / "file"
    argv = ["--root", str(empty), *words, *arguments(parser, str(target))]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refusing the arguments: its usage and one line, no traceback
        code = exc.code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err, argv
    if code == 0:
        return  # it did its job with what it was given
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines, f"{argv}: exit {code} with nothing said"
    last = lines[-1]
    if str(target) not in argv:
        assert len(lines) == 1 or "usage:" in err, argv  # nothing to name: one line saying what to give
        return
    named = (str(target) in last or target.name in last or "params.yaml" in last or str(empty) in last
             or "usage:" in err)
    assert named, f"{argv}: {last!r} names neither the input nor the project"
    if how == "no such path" and f"{target}:" in last:  # a path named as the thing that is wrong
        assert "no such" in last and "Errno" not in last, f"{argv}: {last!r} does not say the path is missing"


def test_a_library_error_is_one_line_naming_its_file_and_debug_shows_the_traceback(tmp_path: Path, capsys,
                                                                                   monkeypatch) -> None:
    bad = tmp_path / "world.parquet"
    bad.write_bytes(b"not parquet" * 50)
    assert main(["eval", "sync", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and "not a Parquet file" in err
    monkeypatch.setenv("DANCE3D_DEBUG", "1")
    with pytest.raises(InputError):
        main(["eval", "sync", str(bad)])
    assert one_line(FileNotFoundError(2, "No such file or directory", "x.csv")) == "x.csv: no such file or folder"


def test_an_eval_given_all_its_inputs_runs_outside_a_project_with_the_packages_parameters(
        tmp_path: Path, monkeypatch, capsys, mocap_dir: Path) -> None:
    from pipeline.core.params import DEFAULT_PARAMS, load_params, project_or_default_params
    from tests.conftest import PROJECT

    # The package's defaults are the project's params.yaml as it ships, so figures agree.
    assert project_or_default_params(tmp_path) == load_params(DEFAULT_PARAMS) == load_params(PROJECT / "params.yaml")
    monkeypatch.chdir(tmp_path)
    assert main(["eval", "lifter", "--mocap", str(mocap_dir / "perfume"), "--seconds", "2"]) == 0
    assert "P-MPJPE" in capsys.readouterr().out


@pytest.mark.parametrize("what", ["pose2d", "hands"])
def test_an_evaluation_names_its_missing_annotations_before_it_looks_for_any_model(what: str, tmp_path: Path,
                                                                                   capsys) -> None:
    missing = tmp_path / "annotations.json"
    code = main(["--root", str(tmp_path), "eval", what, "--annotations", str(missing), "--images", str(tmp_path)])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and str(missing) in err, err


def test_eval_smpl_with_no_world_files_says_where_it_looked_and_what_makes_them(tmp_path: Path, capsys) -> None:
    assert main(["--root", str(tmp_path), "eval", "smpl"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tmp_path / "data" / "world") in err and "--mocap" in err
