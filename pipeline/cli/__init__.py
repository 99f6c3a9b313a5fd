"""The ``dance3d`` command: ``app`` builds the parser from one module per command group (running,
review, render, manifests, export, sample, evaluate, models) and turns errors into one line."""

from pipeline.cli.app import build_parser, main
from pipeline.cli.messages import one_line

__all__ = ["build_parser", "main", "one_line"]
