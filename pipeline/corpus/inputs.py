"""What the corpus is built from, as one fingerprint, so the shard stage rebuilds it only when that
changed: DVC re-runs the stage when any of its dependencies changes (a failure report, a file of an
earlier stage written again with the same content), and rebuilding the corpus, its card and plots
costs seconds for nothing.

The fingerprint covers every item file the corpus reads (by the fingerprint in its metadata: the
item's inputs, params and code; a file without one by its bytes), the download ledger and segment
index, the contact and failure reports the card sums, the shard params and the source of the whole
``pipeline`` package (any code change rebuilds: safe over clever). It is stamped into
``data/corpus/.inputs`` last, after every output is written, and removed before a rebuild starts, so
a stage stopped half-way never leaves a stamp on a half-built corpus.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from pipeline.core.paths import AUDIO_FEATURES, CLEAN, CORPUS, METRICS, MOTION24, RAW, REPORTS, SEGMENTS, TRACKS, WORLD
from pipeline.core.storage import atomic_path, read_meta, sha256_file

ITEM_FOLDERS = (MOTION24, WORLD, AUDIO_FEATURES, CLEAN, TRACKS)
STAMP = CORPUS / ".inputs"
# What a finished shard stage has written; without any of them the corpus is built again.
OUTPUTS = (CORPUS / "README.md", CORPUS / "train", REPORTS / "corpus.json", METRICS / "corpus.json",
           METRICS / "durations.csv")


def corpus_fingerprint(root: Path, params: dict[str, Any], stage_file: Path | None = None) -> str:
    """One hash of everything the corpus of ``root`` is made from, with ``params`` and the code."""
    root = Path(root)
    h = hashlib.sha256()

    def add(name: str, value: str) -> None:
        h.update(f"{name}\0{value}\n".encode())

    for folder in ITEM_FOLDERS:
        for path in sorted((root / folder).glob("*.parquet")):
            add(str(folder / path.name), str(read_meta(path).get("fingerprint") or sha256_file(path)))
    small = [root / SEGMENTS / "index.parquet", root / RAW / "ledger.parquet", root / REPORTS / "contact.json",
             *sorted((root / REPORTS).glob("failures_*.json"))]
    for path in small:
        add(str(path.relative_to(root)), sha256_file(path) if path.is_file() else "missing")
    add("params", json.dumps(params, sort_keys=True, default=str))
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*.py")) + ([Path(stage_file)] if stage_file else []):
        add(str(path.relative_to(package.parent) if path.is_relative_to(package.parent) else path.name),
            hashlib.sha256(path.read_bytes()).hexdigest())
    return h.hexdigest()


def corpus_up_to_date(root: Path, fingerprint: str) -> bool:
    """Whether the corpus of ``root`` was built, whole, from what ``fingerprint`` says."""
    stamp = Path(root) / STAMP
    return (stamp.is_file() and stamp.read_text().strip() == fingerprint
            and all((Path(root) / out).exists() for out in OUTPUTS))


def forget_built(root: Path) -> None:
    """Before a rebuild: the stamp goes first."""
    (Path(root) / STAMP).unlink(missing_ok=True)


def mark_built(root: Path, fingerprint: str) -> None:
    """After every output of the corpus is written."""
    with atomic_path(Path(root) / STAMP) as tmp:
        tmp.write_text(fingerprint + "\n")
