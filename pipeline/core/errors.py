"""Error types whose message always names the file, the line (when there is one) and the reason."""

from __future__ import annotations

from pathlib import Path


class Dance3dError(Exception):
    """Base class for every error dance3d raises on purpose."""


class InputError(Dance3dError):
    """Bad input a human can fix: ``file:line: reason``."""

    def __init__(self, path: str | Path, reason: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.reason = reason
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {reason}")


class InputErrors(Dance3dError):
    """Several problems in one human-edited file, reported together (one per line)."""

    def __init__(self, errors: list[InputError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))


class MediaError(InputError):
    """A video or audio file that cannot be probed, decoded or cut."""


class ModelMissingError(Dance3dError):
    """A model file that is neither present nor downloadable."""


class RateLimitedError(Dance3dError):
    """The remote site is throttling us; stop politely instead of hammering it."""
