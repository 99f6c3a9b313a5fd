"""Track manifests: ``manifests/tracks/<segment_id>.csv``, one per segment, edited by annotators.

One row per span of a track id that is kept or rejected::

    track_id,start,end,keep,note,frames,mean_score,box_height,motion,reason

``start`` and ``end`` are QC-video timecodes in seconds (3 decimals): the times of the
*first and last frame to keep, both included*. ``keep`` is ``yes`` or ``no``. Several
rows for one id keep several spans; a track id with no row is dropped. ``frames`` ...
``reason`` are filled by ``dance3d manifests seed`` to help the annotator and are not
read back (editing them changes nothing).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.tables import read_csv, write_csv
from pipeline.core.timecode import parse_time
from pipeline.pose.trackfile import SegmentTracks

EDITABLE = ("track_id", "start", "end", "keep", "note")
INFO = ("frames", "mean_score", "box_height", "motion", "reason")
HEADER = EDITABLE + INFO
KEEP_VALUES = {"yes": True, "no": False}


@dataclass(frozen=True)
class Span:
    track_id: int
    start: float
    end: float
    keep: bool
    note: str = ""
    line: int | None = None
    info: dict = field(default_factory=dict, compare=False)


@dataclass(frozen=True)
class Problem:
    path: str
    line: int | None
    message: str
    warning: bool = False

    def __str__(self) -> str:
        where = f"{self.path}:{self.line}" if self.line is not None else self.path
        return f"{where}: {'warning: ' if self.warning else ''}{self.message}"


def parse_manifest(path: Path) -> tuple[list[Span], list[Problem]]:
    """Read a manifest; cell-level problems are returned, not raised."""
    problems: list[Problem] = []
    try:
        rows = read_csv(path, HEADER)
    except InputError as exc:
        return [], [Problem(str(path), exc.line, exc.reason)]
    spans: list[Span] = []
    seen: dict[tuple, int] = {}
    for row in rows:
        errors = []
        raw_id = row.get("track_id")
        try:
            track_id = int(raw_id)
            if track_id < 0:
                raise ValueError
        except ValueError:
            errors.append(f"track_id {raw_id!r} is not a whole number >= 0")
            track_id = -1
        times = []
        for column in ("start", "end"):
            try:
                times.append(parse_time(row.get(column)))
            except ValueError as exc:
                errors.append(f"{column}: {exc}")
        keep_text = row.get("keep").lower()
        if keep_text not in KEEP_VALUES:
            errors.append(f"keep must be yes or no, not {row.get('keep')!r}")
        if errors:
            problems.extend(Problem(str(path), row.line, e) for e in errors)
            continue
        start, end = times
        key = (track_id, round(start, 3), round(end, 3), keep_text)
        if key in seen:
            problems.append(Problem(str(path), row.line, f"duplicate of line {seen[key]}"))
            continue
        seen[key] = row.line
        if start >= end:
            problems.append(Problem(str(path), row.line, f"start {start:.3f} s is not before end {end:.3f} s"))
            continue
        info = {c: row.get(c) for c in INFO}
        spans.append(Span(track_id, start, end, KEEP_VALUES[keep_text], row.get("note"), row.line, info))
    return spans, problems


def check_spans(path: Path, spans: list[Span], tracks: SegmentTracks, min_clip_seconds: float) -> list[Problem]:
    """Problems of parsed spans against the segment's tracks (errors and warnings)."""
    problems: list[Problem] = []
    tolerance = 0.5 / tracks.fps
    ids = tracks.ids
    by_id: dict[int, list[Span]] = {}
    for span in spans:
        if span.track_id not in ids:
            shown = ", ".join(map(str, ids)) or "none"
            problems.append(Problem(str(path), span.line, f"unknown track id {span.track_id} "
                                                          f"(tracks in {tracks.segment_id}: {shown})"))
            continue
        rows = tracks.of(span.track_id)
        first, last = tracks.time[rows[0]], tracks.time[rows[-1]]
        if span.start < first - tolerance or span.end > last + tolerance:
            problems.append(Problem(str(path), span.line, f"span {span.start:.3f}-{span.end:.3f} s is outside "
                                                          f"track {span.track_id} ({first:.3f}-{last:.3f} s)"))
            continue
        by_id.setdefault(span.track_id, []).append(span)
        if span.keep and span.end - span.start + 1 / tracks.fps < min_clip_seconds:
            problems.append(Problem(str(path), span.line, f"kept span is {span.end - span.start:.2f} s, shorter "
                                                          f"than clean.min_clip_seconds ({min_clip_seconds} s): "
                                                          "it will be dropped", warning=True))
    for track_id, group in by_id.items():
        group.sort(key=lambda s: s.start)
        for a, b in zip(group, group[1:]):
            if b.start <= a.end:
                problems.append(Problem(str(path), b.line, f"span {b.start:.3f}-{b.end:.3f} s of track {track_id} "
                                                           f"overlaps line {a.line} ({a.start:.3f}-{a.end:.3f} s)"))
    for track_id in ids:
        if track_id not in {s.track_id for s in spans}:
            problems.append(Problem(str(path), None, f"track {track_id} has no row: it will be dropped", warning=True))
    if spans and not any(s.keep for s in spans):
        problems.append(Problem(str(path), None, "every span is rejected: this segment gives no clips", warning=True))
    return problems


def format_seconds(value: float) -> str:
    return f"{value:.3f}"


TRACKS_COMMENT = "tracks fingerprint: "


def write_manifest(path: Path, spans: list[Span], tracks_fingerprint: str = "") -> None:
    """Write spans (sorted by track and start) in the manifest format, atomically.

    A leading comment records which tracking result the spans refer to, so the checker
    can warn when the tracks were redone since (their ids may have changed).
    """
    rows = []
    for s in sorted(spans, key=lambda s: (s.track_id, s.start)):
        rows.append([s.track_id, format_seconds(s.start), format_seconds(s.end), "yes" if s.keep else "no", s.note,
                     *(s.info.get(c, "") for c in INFO)])
    comments = [f"{TRACKS_COMMENT}{tracks_fingerprint}"] if tracks_fingerprint else []
    comments.append("start/end: QC timecodes (s) of the first and last frame to keep; keep: yes/no. "
                    "See docs/tutorials/annotating.md")
    write_csv(path, HEADER, rows, comments)


def recorded_tracks_fingerprint(path: Path) -> str:
    for line in Path(path).read_text(encoding="utf-8-sig").splitlines():
        if not line.startswith("#"):
            break
        if TRACKS_COMMENT in line:
            return line.split(TRACKS_COMMENT, 1)[1].strip()
    return ""


def check_manifest_file(path: Path, tracks_dir: Path, min_clip_seconds: float) -> tuple[list[Span], list[Problem]]:
    """Parse and check one manifest against ``tracks_dir/<segment_id>.parquet``."""
    from pipeline.pose.trackfile import read_tracks

    path = Path(path)
    tracks_file = Path(tracks_dir) / f"{path.stem}.parquet"
    if not tracks_file.exists():
        return [], [Problem(str(path), None, f"manifest for an unknown segment: no {tracks_file} "
                                             "(is the file name a tracked segment id?)")]
    spans, problems = parse_manifest(path)
    if any(p.line is not None and "column" in p.message for p in problems):
        return spans, problems
    tracks = read_tracks(tracks_file)
    recorded = recorded_tracks_fingerprint(path)
    if recorded and recorded != tracks.fingerprint:
        problems.append(Problem(str(path), None, "the tracks were redone since this manifest was seeded: "
                                                 "check that the track ids still match the QC video", warning=True))
    return spans, problems + check_spans(path, spans, tracks, min_clip_seconds)
