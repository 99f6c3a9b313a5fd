"""``annotations/segments.csv``: the dance segments of each video.

Columns: ``video_id, start, end`` and optional ``label, note``. Times are seconds on the
source video's clock (``12.5`` or ``HH:MM:SS.mmm``); ``end`` is exclusive. Segments of a
video are numbered by start time: ``<video_id>_000``, ``<video_id>_001``, ...
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from pipeline.core.errors import InputError, InputErrors
from pipeline.core.ids import check_id, segment_id
from pipeline.core.tables import read_csv
from pipeline.core.timecode import parse_time

REQUIRED = ("video_id", "start", "end")
OPTIONAL = ("label", "note")
UNANNOTATED_POLICIES = ("skip", "whole", "proposals")
END_TOLERANCE = 0.05  # seconds an end may pass the video's end (container rounding); it is clamped


@dataclass(frozen=True)
class SegmentSpec:
    segment_id: str
    video_id: str
    start: float
    end: float
    label: str = ""
    note: str = ""
    line: int | None = None  # annotation line; None for whole-video segments


def plan_segments(
    path: Path,
    durations: Mapping[str, float],
    *,
    known_videos: set[str] | None = None,
    unannotated: str = "skip",
    proposed: Mapping[str, list[tuple[float, float, str]]] | None = None,
) -> list[SegmentSpec]:
    """Validate segments.csv against the downloaded videos and list the segments to cut.

    ``durations`` maps each *available* video to its duration; ``known_videos`` are all
    ids in the sources (a row for a known video whose download failed is skipped, not an
    error). ``proposed``: video -> (start, end, reason) proposals, the segments of a video
    without human rows when ``unannotated`` is "proposals" (human rows always win).
    Every problem in the file is reported at once as InputErrors.
    """
    if unannotated not in UNANNOTATED_POLICIES:
        raise ValueError(f"trim.unannotated must be one of {UNANNOTATED_POLICIES}, not {unannotated!r}")
    known = set(known_videos or ()) | set(durations)
    rows = read_csv(path, REQUIRED, OPTIONAL) if Path(path).exists() else []
    errors: list[InputError] = []
    by_video: dict[str, list[tuple[float, float, object]]] = defaultdict(list)
    for row in rows:
        video_id = row.get("video_id")
        try:
            check_id(video_id, "video_id")
        except ValueError as exc:
            errors.append(InputError(path, str(exc), row.line))
            continue
        if video_id not in known:
            errors.append(InputError(path, f"unknown video {video_id!r} (not in manifests/sources.csv)", row.line))
            continue
        try:
            start, end = parse_time(row.get("start")), parse_time(row.get("end"))
        except ValueError as exc:
            errors.append(InputError(path, str(exc), row.line))
            continue
        if end <= start:
            errors.append(InputError(path, f"end {end:.3f} s is not after start {start:.3f} s", row.line))
            continue
        if video_id not in durations:
            continue  # its download failed: the ledger already says why
        duration = durations[video_id]
        if start >= duration or end > duration + END_TOLERANCE:
            errors.append(InputError(path, f"segment {start:.3f}-{end:.3f} s passes the end of {video_id} "
                                           f"({duration:.3f} s)", row.line))
            continue
        by_video[video_id].append((start, min(end, duration), row))
    plan: list[SegmentSpec] = []
    for video_id in sorted(durations):
        spans = sorted(by_video.get(video_id, []), key=lambda s: s[0])
        for (s0, e0, r0), (s1, e1, r1) in zip(spans, spans[1:]):
            if s1 < e0:
                errors.append(InputError(path, f"segment {s1:.3f}-{e1:.3f} s overlaps line {r0.line} "
                                               f"({s0:.3f}-{e0:.3f} s) of the same video", r1.line))
        if not spans and unannotated == "whole" and video_id not in by_video:
            plan.append(SegmentSpec(segment_id(video_id, 0), video_id, 0.0, durations[video_id], "", "whole video"))
        if not spans and unannotated == "proposals" and video_id not in by_video:
            for k, (start, end, reason) in enumerate(sorted((proposed or {}).get(video_id, []))):
                plan.append(SegmentSpec(segment_id(video_id, k), video_id, start, min(end, durations[video_id]),
                                        "proposed", reason))
        for k, (start, end, row) in enumerate(spans):
            plan.append(SegmentSpec(segment_id(video_id, k), video_id, start, end,
                                    row.get("label"), row.get("note"), row.line))
    if errors:
        raise InputErrors(sorted(errors, key=lambda e: e.line or 0))
    return plan


def replace_video_rows(text: str, video_id: str, rows: list[tuple[float, float, str, str]]) -> tuple[str, list[int]]:
    """``text`` of a segments.csv with the rows of ``video_id`` replaced by ``rows`` (start, end, label, note).

    Every other line (comments, other videos, their formatting) is kept as it is; the new rows
    take the place of the video's first old row (or go at the end), in start order. Returns the
    new text and the 1-based lines of the new rows, so a checker's messages can be shown beside them.
    A header without label or note gains them when a row needs them.
    """
    import csv
    import io

    from pipeline.core.tables import neutralise_cell

    lines = text.splitlines(keepends=True) if text.strip() else ["video_id,start,end,label,note\n"]
    lines = [ln if ln.endswith("\n") else ln + "\n" for ln in lines]
    header_at = next(i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#"))
    header = [h.strip() for h in next(csv.reader([lines[header_at]]))]
    wanted = [c for c in OPTIONAL if c not in header and any(r[2 + OPTIONAL.index(c)] for r in rows)]
    out, insert_at = [], None
    for i, line in enumerate(lines):
        if i <= header_at or not line.strip() or line.lstrip().startswith("#"):
            out.append(line)
            continue
        cells = next(csv.reader([line]))
        if cells and cells[header.index("video_id")].strip() == video_id:
            insert_at = len(out) if insert_at is None else insert_at
            continue
        out.append(line.rstrip("\n") + "," * len(wanted) + "\n" if wanted else line)
    if wanted:
        header = header + wanted
        out[header_at] = ",".join(header) + "\n"
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    for start, end, label, note in sorted(rows):
        values = {"video_id": video_id, "start": f"{start:.3f}", "end": f"{end:.3f}",
                  "label": neutralise_cell(label), "note": neutralise_cell(note)}
        writer.writerow([values.get(c, "") for c in header])
    new = buf.getvalue().splitlines(keepends=True)
    at = len(out) if insert_at is None else insert_at
    out[at:at] = new
    return "".join(out), [at + 1 + k for k in range(len(new))]


def remove_segment_copies(seg_dir: Path) -> int:
    """Index version 1 wrote an mp4 and a wav per segment; views need neither. How many went."""
    copies = [p for pattern in ("*.mp4", "*.wav") for p in seg_dir.glob(pattern)] if seg_dir.exists() else []
    for path in copies:
        path.unlink()
    return len(copies)
