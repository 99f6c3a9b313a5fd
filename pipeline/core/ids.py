"""Identifiers: safe tokens only, so an id can never escape a data folder."""

from __future__ import annotations

import re
from pathlib import Path

SAFE_ID = re.compile(r"[A-Za-z0-9_-]{1,100}")


def is_safe_id(value: str) -> bool:
    return bool(SAFE_ID.fullmatch(value))


def check_id(value: str, what: str = "id") -> str:
    """Return ``value`` if it is a safe token, else raise ValueError saying why."""
    if not is_safe_id(value):
        shown = value if len(value) <= 60 else value[:57] + "..."
        raise ValueError(
            f"{what} {shown!r} is not a safe identifier "
            "(1-100 characters of A-Z, a-z, 0-9, '_' or '-')"
        )
    return value


def slug_id(text: str) -> str:
    """A safe id derived from free text (e.g. a yt-dlp id or a file stem)."""
    slug = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_")[:100]
    return slug or "video"


def segment_id(video_id: str, k: int) -> str:
    return f"{video_id}_{k:03d}"


def video_id_of_segment(seg_id: str) -> str:
    return seg_id.rsplit("_", 1)[0]


def id_path(folder: Path, item_id: str, suffix: str) -> Path:
    """The path of an item's file inside ``folder``; refuses unsafe ids."""
    check_id(item_id)
    return folder / f"{item_id}{suffix}"
