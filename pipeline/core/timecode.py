"""Parsing and formatting of times typed by annotators."""

from __future__ import annotations

import math
import re

_CLOCK = re.compile(r"(?:(\d+):)?(\d{1,2}):(\d{1,2}(?:\.\d+)?)")


def parse_time(text: str) -> float:
    """Seconds from ``12.5``, ``01:02.250`` (MM:SS.mmm) or ``00:01:02.250`` (HH:MM:SS.mmm).

    Raises ValueError with a readable reason for anything else.
    """
    s = text.strip()
    if not s:
        raise ValueError("empty time")
    m = _CLOCK.fullmatch(s)
    if m:
        hours = int(m.group(1) or 0)
        minutes = int(m.group(2))
        seconds = float(m.group(3))
        if minutes >= 60 or seconds >= 60:
            raise ValueError(f"time {s!r} has minutes or seconds >= 60")
        return hours * 3600 + minutes * 60 + seconds
    try:
        value = float(s)
    except ValueError:
        raise ValueError(f"cannot read time {s!r} (use seconds like 12.5 or HH:MM:SS.mmm)") from None
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"time {s!r} must be a finite number of seconds >= 0")
    return value


def format_time(seconds: float) -> str:
    """``HH:MM:SS.mmm``, the timecode burnt into QC videos."""
    ms = int(round(seconds * 1000))
    h, rem = divmod(ms, 3_600_000)
    m, rem = divmod(rem, 60_000)
    s, ms = divmod(rem, 1000)
    return f"{h:02d}:{m:02d}:{s:02d}.{ms:03d}"
