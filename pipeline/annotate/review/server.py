"""The review server: a small JSON API over the track manifests, the QC videos, and the page.

Routes (everything else, including any path that tries to leave the project, is 404):
  GET  /                        the page (segment list); /segment/<id> the same page, one segment
  GET  /static/<file>           the page's script and style, shipped in this package
  GET  /api/segments            every tracked segment with its annotation status
  GET  /api/segments/<id>       tracks, manifest rows (or the proposal), problems, version
  PUT  /api/segments/<id>       save rows: checked like `dance3d manifests check`, written
                                atomically, refused (409) if the file changed since `version`
  GET  /qc/<id>.mp4             the QC video, rendered on first request (HTTP range requests, so the player can seek)

Trim mode (the dance segments of each download, annotations/segments.csv):
  GET  /trim                    the page (video list); /trim/<video_id> the same page, one video
  GET  /api/videos              every downloaded video with its rows and proposals counts
  GET  /api/videos/<id>         its rows (or the proposals), proposals, shots, per-second cues, version
  PUT  /api/videos/<id>         replace its rows: checked like the trim stage, atomic, 409 when stale
  GET  /raw/<id>                the downloaded video (range requests)

Off loopback (or with ``--token``) every route needs the token cookie, and writes the server's own
Origin (``access.py``); ``/?token=…`` sets the cookie. Saves are logged with the annotator's name.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import re
import tempfile
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs

from pipeline.annotate.manifests import (
    INFO,
    Span,
    check_manifest_file,
    parse_manifest,
    recorded_tracks_fingerprint,
    write_manifest,
)
from pipeline.annotate.proposals import ProposalOptions, propose, track_stats
from pipeline.annotate.review.access import (
    SaveLog,
    cookie_header,
    has_token_cookie,
    same_origin,
    unauthorised_page,
)
from pipeline.annotate.review.trimming import TrimModel
from pipeline.core.errors import Dance3dError
from pipeline.core.ids import is_safe_id
from pipeline.core.paths import ANNOTATIONS, TRACK_MANIFESTS, TRACKS
from pipeline.core.storage import item_files
from pipeline.pose.trackfile import read_tracks

log = logging.getLogger(__name__)
STATIC = Path(__file__).parent / "static"
STATIC_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                ".css": "text/css; charset=utf-8"}
VIDEO_TYPES = {".mp4": "video/mp4", ".m4v": "video/mp4", ".mov": "video/mp4", ".webm": "video/webm",
               ".mkv": "video/x-matroska", ".ogv": "video/ogg"}


class ReviewApp:
    """What the handler needs: the project, the proposal options and the checker's settings."""

    def __init__(self, root: Path, proposals: ProposalOptions, min_clip_seconds: float,
                 token: str | None = None) -> None:
        self.root = Path(root).resolve()
        self.token = token  # None: open (loopback); else every request needs it (access.py)
        self.log = SaveLog(self.root)
        self.proposals = proposals
        self.min_clip_seconds = min_clip_seconds
        self.lock = threading.Lock()  # one save at a time
        self.qc_lock = threading.Lock()  # one QC render at a time (the player sends several range requests)
        self.trim = TrimModel(self.root)

    def qc_video(self, seg_id: str) -> Path:
        """The segment's QC video, rendered on first request (and again when its tracks are newer)."""
        from pipeline.pose.qc import qc_video

        with self.qc_lock:
            return qc_video(self.root, seg_id, kp_min_score=self.proposals.kp_min_score)

    def manifest_path(self, seg_id: str) -> Path:
        return self.root / TRACK_MANIFESTS / f"{seg_id}.csv"

    def tracks_path(self, seg_id: str) -> Path:
        return self.root / TRACKS / f"{seg_id}.parquet"

    def segments(self) -> list[str]:
        return [p.stem for p in item_files(self.root / TRACKS)]

    def version(self, seg_id: str) -> str:
        path = self.manifest_path(seg_id)
        return hashlib.sha256(path.read_bytes()).hexdigest()[:16] if path.exists() else ""

    def proposal_text(self, seg_id: str) -> str:
        tracks = read_tracks(self.tracks_path(seg_id))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"{seg_id}.csv"
            write_manifest(path, propose(tracks, self.proposals), tracks.fingerprint)
            return path.read_text()

    def problems(self, seg_id: str, path: Path | None = None) -> list[dict]:
        path = path or self.manifest_path(seg_id)
        _, found = check_manifest_file(path, self.root / TRACKS, self.min_clip_seconds)
        shown = str(self.manifest_path(seg_id).relative_to(self.root))
        return [{"line": p.line, "warning": p.warning, "message": p.message,
                 "text": str(p).replace(str(path), shown)} for p in found]

    def status(self, seg_id: str, problems: list[dict] | None = None) -> dict:
        path = self.manifest_path(seg_id)
        if not path.exists():
            return {"id": seg_id, "status": "unannotated", "errors": 0}
        problems = self.problems(seg_id) if problems is None else problems
        errors = sum(1 for p in problems if not p["warning"])
        if path.read_text() == self.proposal_text(seg_id):
            state = "proposal"
        else:
            state = "checked" if errors == 0 else "edited"
        return {"id": seg_id, "status": state, "errors": errors}

    def segment(self, seg_id: str) -> dict:
        tracks = read_tracks(self.tracks_path(seg_id))
        path = self.manifest_path(seg_id)
        if path.exists():
            spans, _ = parse_manifest(path)
            problems = self.problems(seg_id)
        else:
            spans, problems = propose(tracks, self.proposals), []
        stats = [track_stats(tracks, t) for t in tracks.ids]
        return {
            "id": seg_id, "fps": tracks.fps, "duration": tracks.frames_total / tracks.fps,
            "width": tracks.width, "height": tracks.height, "has_manifest": path.exists(),
            "version": self.version(seg_id), "status": self.status(seg_id, problems)["status"],
            "tracks": [{"id": s.track_id, "start": s.start, "end": s.end, "frames": s.frames} for s in stats],
            "rows": [_row(s) for s in spans], "problems": problems,
        }

    def save(self, seg_id: str, body: dict) -> tuple[int, dict]:
        with self.lock:
            current = self.version(seg_id)
            if body.get("version", "") != current:
                who = self.log.who_changed(self._relative(self.manifest_path(seg_id)), current)
                return HTTPStatus.CONFLICT, {"error": f"the manifest changed on disk since this page loaded{who}: "
                                                      "reload it (your edits here are not saved)", "version": current}
            try:
                spans = [_span(r) for r in body.get("rows", [])]
            except (KeyError, TypeError, ValueError) as exc:
                return HTTPStatus.BAD_REQUEST, {"error": f"malformed rows: {exc}"}
            path = self.manifest_path(seg_id)
            if path.exists() and _same_rows(parse_manifest(path)[0], spans):
                return HTTPStatus.OK, {"version": current, "unchanged": True}  # byte-for-byte untouched
            tracks = read_tracks(self.tracks_path(seg_id))
            fingerprint = recorded_tracks_fingerprint(path) if path.exists() else tracks.fingerprint
            with tempfile.TemporaryDirectory() as tmp:
                candidate = Path(tmp) / f"{seg_id}.csv"
                write_manifest(candidate, spans, fingerprint)
                problems = self.problems(seg_id, candidate)
                if any(not p["warning"] for p in problems):
                    return HTTPStatus.UNPROCESSABLE_ENTITY, {"error": "not saved: the manifest has errors",
                                                             "problems": problems}
                write_manifest(path, spans, fingerprint)
            version = self.version(seg_id)
            self.log.record(self._relative(path), body.get("annotator", ""), version)
            return HTTPStatus.OK, {"version": version, "problems": problems}

    def save_trim(self, video_id: str, body: dict) -> tuple[int, dict]:
        """The trim page's save (``TrimModel.save``), logged with its annotator; a stale one names who saved."""
        status, payload = self.trim.save(video_id, body)
        if status == HTTPStatus.OK and not payload.get("unchanged"):
            self.log.record(str(ANNOTATIONS), body.get("annotator", ""), payload["version"])
        elif status == HTTPStatus.CONFLICT:
            who = self.log.who_changed(str(ANNOTATIONS), payload["version"])
            payload = {**payload, "error": payload["error"].replace(" since this page loaded",
                                                                    f" since this page loaded{who}", 1)}
        return status, payload

    def _relative(self, path: Path) -> str:
        return str(path.relative_to(self.root))


def _row(span: Span) -> dict:
    return {"track_id": span.track_id, "start": round(span.start, 3), "end": round(span.end, 3),
            "keep": span.keep, "note": span.note, "info": {k: span.info.get(k, "") for k in INFO}}


def _span(row: dict) -> Span:
    keep = row["keep"]
    if isinstance(keep, str):
        keep = {"yes": True, "no": False}[keep]
    info = {k: str(v) for k, v in (row.get("info") or {}).items() if k in INFO}
    return Span(int(row["track_id"]), float(row["start"]), float(row["end"]), bool(keep), str(row.get("note", "")),
                info=info)


def _same_rows(a: list[Span], b: list[Span]) -> bool:
    def key(s: Span) -> tuple:
        return (s.track_id, round(s.start, 3), round(s.end, 3), s.keep, s.note)

    return sorted(map(key, a)) == sorted(map(key, b))


_SEGMENT = re.compile(r"/api/segments/([^/]+)")
_VIDEO = re.compile(r"/api/videos/([^/]+)")
_RAW = re.compile(r"/raw/([^/]+)")
_TRIM_PAGE = re.compile(r"/trim/([^/]+)")
_QC = re.compile(r"/qc/([^/]+)\.mp4")
_PAGE = re.compile(r"/segment/([^/]+)")


def make_handler(app: ReviewApp) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        server_version = "dance3d-review"

        def log_message(self, fmt: str, *args) -> None:
            log.debug("%s %s", self.address_string(), fmt % args)

        def _send(self, status: int, body: bytes, content_type: str, extra: dict | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            for key, value in (extra or {}).items():
                self.send_header(key, value)
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        def _json(self, status: int, payload) -> None:
            self._send(status, json.dumps(payload).encode(), "application/json")

        def _not_found(self) -> None:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

        def _segment_id(self, match: re.Match | None) -> str | None:
            if match is None:
                return None
            seg_id = match.group(1)
            return seg_id if is_safe_id(seg_id) and app.tracks_path(seg_id).exists() else None

        def _video_id(self, match: re.Match | None) -> str | None:
            if match is None:
                return None
            video_id = match.group(1)
            return video_id if is_safe_id(video_id) and app.trim.video_file(video_id) else None

        def _admitted(self) -> bool:
            """With a token: the cookie (or ``?token=`` once, answered with the cookie and a redirect),
            and the server's own Origin on writes. False when the refusal has been sent."""
            if app.token is None:
                return True
            path, _, query = self.path.partition("?")
            given = parse_qs(query).get("token")
            if given is not None and self.command in ("GET", "HEAD"):
                if hmac.compare_digest(given[0].encode(), app.token.encode()):
                    self._send(HTTPStatus.SEE_OTHER, b"", "text/plain",
                               {"Location": path or "/", "Set-Cookie": cookie_header(app.token)})
                else:
                    self._send(HTTPStatus.UNAUTHORIZED, unauthorised_page(), STATIC_TYPES[".html"])
                return False
            if not has_token_cookie(self.headers.get("Cookie", ""), app.token):
                self._send(HTTPStatus.UNAUTHORIZED, unauthorised_page(), STATIC_TYPES[".html"])
                return False
            if self.command not in ("GET", "HEAD") and not same_origin(self.headers.get("Origin"),
                                                                      self.headers.get("Host")):
                self._json(HTTPStatus.FORBIDDEN, {"error": "a write must come from this server's own page"})
                return False
            return True

        def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
            if not self._admitted():
                return
            path = self.path.split("?", 1)[0]
            if path == "/" or (path.startswith("/segment/") and self._segment_id(_PAGE.fullmatch(path))):
                return self._send(HTTPStatus.OK, (STATIC / "index.html").read_bytes(), STATIC_TYPES[".html"])
            if path == "/trim" or self._video_id(_TRIM_PAGE.fullmatch(path)):
                return self._send(HTTPStatus.OK, (STATIC / "trim.html").read_bytes(), STATIC_TYPES[".html"])
            if path == "/api/videos":
                return self._json(HTTPStatus.OK, app.trim.videos())
            video_id = self._video_id(_VIDEO.fullmatch(path))
            if video_id:
                return self._json(HTTPStatus.OK, app.trim.video(video_id))
            video_id = self._video_id(_RAW.fullmatch(path))
            if video_id:
                media = app.trim.video_file(video_id)
                return self._video(media, VIDEO_TYPES.get(media.suffix.lower(), "application/octet-stream"))
            if path.startswith("/static/"):
                name = path[len("/static/"):]
                target = STATIC / name
                if "/" in name or target.suffix not in STATIC_TYPES or not target.is_file():
                    return self._not_found()
                return self._send(HTTPStatus.OK, target.read_bytes(), STATIC_TYPES[target.suffix])
            if path == "/api/segments":
                return self._json(HTTPStatus.OK, [app.status(s) for s in app.segments()])
            seg_id = self._segment_id(_SEGMENT.fullmatch(path))
            if seg_id:
                return self._json(HTTPStatus.OK, app.segment(seg_id))
            seg_id = self._segment_id(_QC.fullmatch(path))
            if seg_id:
                try:
                    return self._video(app.qc_video(seg_id))
                except Dance3dError as exc:
                    log.error("%s", exc)
                    return self._send(HTTPStatus.INTERNAL_SERVER_ERROR, f"{exc}\n".encode(), "text/plain")
            return self._not_found()

        do_HEAD = do_GET

        def do_POST(self) -> None:  # noqa: N802 (no route takes POST; refused like any write first)
            if self._admitted():
                self._not_found()

        def do_PUT(self) -> None:  # noqa: N802
            if not self._admitted():
                return
            path = self.path.split("?", 1)[0]
            seg_id = self._segment_id(_SEGMENT.fullmatch(path))
            video_id = None if seg_id else self._video_id(_VIDEO.fullmatch(path))
            if not seg_id and not video_id:
                return self._not_found()
            length = int(self.headers.get("Content-Length") or 0)
            try:
                body = json.loads(self.rfile.read(length) or b"{}")
            except json.JSONDecodeError as exc:
                return self._json(HTTPStatus.BAD_REQUEST, {"error": f"not JSON: {exc}"})
            status, payload = app.save(seg_id, body) if seg_id else app.save_trim(video_id, body)
            self._json(status, payload)

        def _video(self, path: Path, content_type: str = "video/mp4") -> None:
            size = path.stat().st_size
            start, end = 0, size - 1
            match = re.fullmatch(r"bytes=(\d*)-(\d*)", self.headers.get("Range", ""))
            if match:
                if match.group(1):
                    start = int(match.group(1))
                    end = int(match.group(2)) if match.group(2) else end
                elif match.group(2):
                    start = max(0, size - int(match.group(2)))
                end = min(end, size - 1)
                if start > end:
                    return self._send(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE, b"", "text/plain",
                                      {"Content-Range": f"bytes */{size}"})
            with open(path, "rb") as f:
                f.seek(start)
                body = f.read(end - start + 1)
            status = HTTPStatus.PARTIAL_CONTENT if match else HTTPStatus.OK
            extra = {"Accept-Ranges": "bytes"}
            if match:
                extra["Content-Range"] = f"bytes {start}-{end}/{size}"
            self._send(status, body, content_type, extra)

    return Handler


def serve(app: ReviewApp, host: str = "127.0.0.1", port: int = 8765) -> ThreadingHTTPServer:
    """A started server (call ``serve_forever`` or run it in a thread)."""
    return ThreadingHTTPServer((host, port), make_handler(app))
