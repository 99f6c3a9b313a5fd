"""The review page's trim mode: dance segments of each downloaded video, edited in annotations/segments.csv.

A save replaces one video's rows and is checked by the trim stage's own planner
(``plan_segments``) before anything is written: errors in the video's rows refuse the save and
come back with their lines; the file is written atomically, and refused (409) when it changed
on disk since the page loaded it.
"""

from __future__ import annotations

import hashlib
import tempfile
import threading
from http import HTTPStatus
from pathlib import Path

from pipeline.core.errors import InputError, InputErrors
from pipeline.core.paths import ANNOTATIONS, RAW, SEGMENT_PROPOSALS
from pipeline.core.storage import atomic_path
from pipeline.core.tables import read_csv
from pipeline.core.timecode import parse_time
from pipeline.ingest.catalog import read_ledger
from pipeline.ingest.segments import OPTIONAL, REQUIRED, plan_segments, replace_video_rows


class TrimModel:
    """What the trim mode reads and writes in one project."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root).resolve()
        self.lock = threading.Lock()  # one save at a time

    @property
    def annotations(self) -> Path:
        return self.root / ANNOTATIONS

    def downloads(self) -> dict[str, dict]:
        return {r["video_id"]: r for r in read_ledger(self.root / RAW).values() if r["status"] == "ok"}

    def video_file(self, video_id: str) -> Path | None:
        row = self.downloads().get(video_id)
        return self.root / RAW / row["path"] if row else None

    def version(self) -> str:
        path = self.annotations
        return hashlib.sha256(path.read_bytes()).hexdigest()[:16] if path.exists() else ""

    def human_rows(self) -> dict[str, list[dict]]:
        """Rows by video, as typed (times parsed; an unparsable time is kept as text for the page to show)."""
        rows: dict[str, list[dict]] = {}
        if not self.annotations.exists():
            return rows
        for row in read_csv(self.annotations, REQUIRED, OPTIONAL):
            def time(text: str):
                try:
                    return parse_time(text)
                except ValueError:
                    return text
            rows.setdefault(row.get("video_id"), []).append(
                {"start": time(row.get("start")), "end": time(row.get("end")), "label": row.get("label"),
                 "note": row.get("note"), "line": row.line})
        return rows

    def proposals(self, video_id: str) -> dict:
        from pipeline.pose.proposed import read_proposals

        path = self.root / SEGMENT_PROPOSALS / f"{video_id}.parquet"
        return read_proposals(path) if path.exists() else {"segments": [], "shots": [], "cuts": [], "seconds": []}

    def videos(self) -> list[dict]:
        human = self.human_rows()
        out = []
        for video_id, row in self.downloads().items():
            proposed = len(self.proposals(video_id)["segments"])
            status = "annotated" if video_id in human else ("proposed" if proposed else "unannotated")
            out.append({"id": video_id, "status": status, "rows": len(human.get(video_id, [])),
                        "proposals": proposed, "duration": row["duration"], "title": row["title"]})
        return out

    def video(self, video_id: str) -> dict:
        row = self.downloads()[video_id]
        human = self.human_rows().get(video_id)
        found = self.proposals(video_id)
        proposals = [{"start": s["start"], "end": s["end"], "label": "", "note": "", "reason": s["reason"]}
                     for s in found["segments"]]
        return {"id": video_id, "title": row["title"], "fps": row["fps"] or 25.0, "duration": row["duration"],
                "version": self.version(), "has_rows": human is not None,
                "rows": human if human is not None else [dict(p) for p in proposals],
                "proposals": proposals, "shots": found["shots"], "cuts": found["cuts"],
                "seconds": [{k: s[k] for k in ("music", "people", "moving", "dance")} for s in found["seconds"]]}

    def save(self, video_id: str, body: dict) -> tuple[int, dict]:
        with self.lock:
            current = self.version()
            if body.get("version", "") != current:
                return HTTPStatus.CONFLICT, {"error": f"{ANNOTATIONS} changed on disk since this page loaded: "
                                                      "reload it (your edits here are not saved)", "version": current}
            try:
                rows = [(float(r["start"]), float(r["end"]), str(r.get("label") or ""), str(r.get("note") or ""))
                        for r in body.get("rows", [])]
            except (KeyError, TypeError, ValueError) as exc:
                return HTTPStatus.BAD_REQUEST, {"error": f"malformed rows: {exc}"}
            text = self.annotations.read_text(encoding="utf-8") if self.annotations.exists() else ""
            new_text, lines = replace_video_rows(text, video_id, rows)
            problems = self.check(new_text, lines)
            if any(p["blocking"] for p in problems):
                return HTTPStatus.UNPROCESSABLE_ENTITY, {"error": "not saved: the segments have errors",
                                                         "problems": problems}
            if new_text == text:
                return HTTPStatus.OK, {"version": current, "unchanged": True, "problems": problems}
            self.annotations.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.annotations) as tmp:
                tmp.write_text(new_text, encoding="utf-8")
            return HTTPStatus.OK, {"version": self.version(), "problems": problems}

    def check(self, text: str, lines: list[int]) -> list[dict]:
        """The trim stage's checks on ``text``. Problems on the video's new ``lines`` name their row
        (0-based) and block the save, as does a problem of the whole file (its header); problems
        on other videos' lines have row None and do not block this save (the trim stage reports them)."""
        ledger = read_ledger(self.root / RAW).values()
        with tempfile.TemporaryDirectory() as tmp:
            candidate = Path(tmp) / "segments.csv"
            candidate.write_text(text, encoding="utf-8")
            try:  # the trim stage's own call (stages/trim.py)
                plan_segments(candidate, {r["video_id"]: r["duration"] for r in ledger if r["status"] == "ok"},
                              known_videos={r["video_id"] for r in ledger if r["video_id"]})
            except InputErrors as exc:
                errors = exc.errors
            except InputError as exc:  # the file as a whole (its header)
                errors = [exc]
            else:
                return []
        out = []
        for e in errors:
            row = lines.index(e.line) if e.line in lines else None
            where = f"{ANNOTATIONS}:{e.line}" if e.line else str(ANNOTATIONS)
            out.append({"line": e.line, "row": row, "blocking": row is not None or e.line is None,
                        "message": e.reason, "text": f"{where}: {e.reason}"})
        return out
