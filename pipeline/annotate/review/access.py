"""Who may use the review server, and who saved what.

Off loopback the server asks for a token, as Jupyter does: it is printed once in the start-up URL
(``http://host:port/?token=…``), exchanged on first use for an HTTP-only, SameSite=Strict cookie,
and every request without that cookie gets 401, static files included. A write (PUT, POST) must
also come from the server's own origin, so a page on another site cannot post with an annotator's
cookie. Saves are attributed to the name the page asks for, in ``manifests/review_log.csv``.
"""

from __future__ import annotations

import csv
import hmac
import io
import ipaddress
import os
import re
import secrets
import threading
from datetime import datetime, timezone
from http.cookies import CookieError, SimpleCookie
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.tables import neutralise_cell

COOKIE = "dance3d_review"
TOKEN_ENV = "DANCE3D_REVIEW_TOKEN"
REVIEW_LOG = Path("manifests/review_log.csv")
_TOKEN = re.compile(r"[A-Za-z0-9_-]{16,128}")


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def choose_token(host: str, asked: bool) -> str | None:
    """The token the server will require: None on loopback unless ``asked``; else
    ``$DANCE3D_REVIEW_TOKEN`` (checked) or a fresh random one."""
    if is_loopback(host) and not asked:
        return None
    given = os.environ.get(TOKEN_ENV, "")
    if given:
        if not _TOKEN.fullmatch(given):
            raise InputError(TOKEN_ENV, "must be 16-128 characters of A-Z, a-z, 0-9, '_' and '-'")
        return given
    return secrets.token_urlsafe(24)


def cookie_header(token: str) -> str:
    return f"{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"


def has_token_cookie(cookie_text: str, token: str) -> bool:
    """True when the request's Cookie header carries the token (a malformed header: False)."""
    try:
        cookies = SimpleCookie(cookie_text or "")
    except CookieError:
        return False
    morsel = cookies.get(COOKIE)
    return morsel is not None and hmac.compare_digest(morsel.value.encode(), token.encode())


def same_origin(origin: str | None, host: str | None) -> bool:
    """A write's Origin header names this server (the Host the browser addressed)."""
    return bool(origin and host) and origin in (f"http://{host}", f"https://{host}")


def unauthorised_page() -> bytes:
    return (b"<!doctype html><meta charset=utf-8><title>dance3d review: token needed</title>"
            b"<h1>This review server needs a token</h1>"
            b"<p>Open the address printed when the server started (<code>http://host:port/?token=...</code>) "
            b"once in this browser; ask whoever started it for that address. From the server's own "
            b"machine (or an SSH tunnel to it), a server on 127.0.0.1 needs no token.</p>\n")


def clean_name(name) -> str:
    """An annotator's name as recorded: one line, at most 60 characters ('anonymous' when none)."""
    text = " ".join(str(name or "").split())[:60]
    return text or "anonymous"


class SaveLog:
    """``manifests/review_log.csv``: time (UTC), file, annotator, version, one row per save."""

    def __init__(self, root: Path) -> None:
        self.path = Path(root) / REVIEW_LOG
        self.lock = threading.Lock()

    def record(self, file: str, annotator: str, version: str) -> None:
        row = [datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"), file, clean_name(annotator), version]
        line = io.StringIO()
        csv.writer(line, lineterminator="\n").writerow([neutralise_cell(v) for v in row])
        with self.lock:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            new = not self.path.exists()
            with open(self.path, "a", encoding="utf-8", newline="") as f:  # one short line: appended whole
                f.write(("time,file,annotator,version\n" if new else "") + line.getvalue())

    def last(self, file: str) -> dict | None:
        """The latest save of ``file`` through the page (None: never)."""
        if not self.path.exists():
            return None
        with open(self.path, encoding="utf-8", newline="") as f:
            rows = [r for r in csv.DictReader(f) if r.get("file") == file]
        return rows[-1] if rows else None

    def who_changed(self, file: str, version: str) -> str:
        """A clause for a stale-save message: who last saved ``file`` at ``version``."""
        last = self.last(file)
        if last and last.get("version") == version:
            return f" (saved by {last['annotator']} at {last['time']})"
        return " (not through this page)"
