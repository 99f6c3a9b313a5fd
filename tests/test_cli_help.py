"""`dance3d --help` and every command's `--help` print what they printed before the command line was
split into one module per command group (tests/golden/cli_help.txt, written from the one-file
pipeline/cli.py). A deliberate change of wording updates the golden file:
``python -m tests.test_cli_help > tests/golden/cli_help.txt``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from pipeline.cli import build_parser
from pipeline.reference import commands

GOLDEN = Path(__file__).parent / "golden" / "cli_help.txt"


def every_help(width: int = 100) -> str:
    """The top-level help and every command's and subcommand's, depth first, at a fixed width."""
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)  # argparse wraps to the terminal's width
    try:
        parser = build_parser()
        pages = [("dance3d", parser)] + commands(parser)
        return "".join(f"==== {line} --help\n{sub.format_help()}" for line, sub in pages)
    finally:
        if previous is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = previous


@pytest.mark.skipif(sys.version_info[:2] != (3, 11),
                    reason="the golden text is Python 3.11's argparse (the lock's and CI's); other versions word help "
                           "differently")
def test_every_help_text_is_the_same_as_before_the_split() -> None:
    assert every_help() == GOLDEN.read_text()


def test_the_golden_file_covers_every_command() -> None:
    assert GOLDEN.read_text().count("==== dance3d") == len(commands(build_parser())) + 1 > 25


def test_no_help_shows_a_doubled_percent_sign() -> None:
    """argparse %-formats an option's help but prints a description as written: '%%' belongs only in the former."""
    assert [line for line in every_help().splitlines() if "%%" in line] == []


def test_each_module_of_the_command_line_is_small_enough_to_read_whole() -> None:
    """One module per command group (the one-file cli.py was 927 lines)."""
    modules = (Path(__file__).parents[1] / "pipeline" / "cli").glob("*.py")
    assert {p.name: n for p in modules if (n := len(p.read_text().splitlines())) > 300} == {}


if __name__ == "__main__":
    print(every_help(), end="")
