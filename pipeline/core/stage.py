"""What every stage entry point shares: logging, paths, and turning errors into exit codes."""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import Callable

from pipeline.core.errors import Dance3dError, RateLimitedError
from pipeline.core.failures import StageFailed

EXIT_BAD_INPUT = 2
EXIT_RATE_LIMITED = 3
EXIT_TOO_MANY_FAILURES = 4


def setup_logging(verbose: bool = False) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )


def run_stage(name: str, fn: Callable[[Path], None], root: Path | None = None) -> int:
    """Run ``fn(project_root)`` and map dance3d errors to one clear line and an exit code."""
    root = Path(root or Path.cwd())
    try:
        fn(root)
    except RateLimitedError as exc:
        print(f"{name}: stopped politely: {exc}", file=sys.stderr)
        return EXIT_RATE_LIMITED
    except StageFailed as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return EXIT_TOO_MANY_FAILURES
    except Dance3dError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0
