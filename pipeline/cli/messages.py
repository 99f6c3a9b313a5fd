"""How a command says what went wrong: one line, never a traceback (unless --debug)."""

from __future__ import annotations

import os
import sys

from pipeline.core.errors import Dance3dError


def one_line(exc: BaseException) -> str:
    """An error as one line: dance3d's own say the file, line and reason; a library's are named by
    the file they were about, where they say it, with a pointer to --debug."""
    if isinstance(exc, Dance3dError):
        return " ".join(str(exc).split())
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file or folder"
    if isinstance(exc, (IsADirectoryError, NotADirectoryError, PermissionError)) and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{text} ({type(exc).__name__}; --debug shows where)"


def say(exc: Dance3dError) -> None:
    """A handler that goes on after an error (the next segment, the next model) says it in one line;
    under --debug it stops there with the traceback."""
    if os.environ.get("DANCE3D_DEBUG") == "1":
        raise exc
    print(f"dance3d: {one_line(exc)}", file=sys.stderr)


def complain(text: str) -> int:
    """A command's own one-line refusal (missing arguments, nothing to do) on stderr; exit code 2."""
    print(text, file=sys.stderr)
    return 2
