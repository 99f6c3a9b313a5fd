"""The ``dance3d`` command: ``app`` builds the parser and turns errors into one line."""

from pipeline.cli.app import _parser, main, one_line

__all__ = ["_parser", "main", "one_line"]
