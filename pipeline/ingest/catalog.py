"""The catalogue files' contract: the discovered videos, the download ledger and the segment index
(schemas, readers, writers)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import pyarrow as pa

from pipeline.core.storage import read_rows, write_rows

DISCOVERED = "videos.parquet"
DISCOVERED_VERSION = 1
LEDGER = "ledger.parquet"
INDEX = "index.parquet"
LEDGER_VERSION = 1
INDEX_VERSION = 2  # 2: segments are views on data/raw (source, audio_stream), no files

DISCOVERED_SCHEMA = pa.schema(
    [
        ("list_url", pa.string()), ("list_line", pa.int32()),  # the sources.csv row of the channel/playlist/feed
        ("position", pa.int32()),  # order of first discovery within the list (stable: new entries are appended)
        ("url", pa.string()), ("video_id", pa.string()), ("title", pa.string()), ("channel", pa.string()),
        ("upload_date", pa.string()), ("duration", pa.float64()), ("tags", pa.list_(pa.string())),
        ("licence", pa.string()), ("style", pa.string()),
        ("selected", pa.bool_()), ("reason", pa.string()),  # the discover filters' verdict, and why not
    ]
)

LEDGER_SCHEMA = pa.schema(
    [
        ("url", pa.string()), ("video_id", pa.string()), ("status", pa.string()),
        ("error_class", pa.string()), ("error_message", pa.string()),
        ("path", pa.string()), ("info_path", pa.string()), ("size", pa.int64()), ("sha256", pa.string()),
        ("fps", pa.float64()), ("duration", pa.float64()), ("width", pa.int32()), ("height", pa.int32()),
        ("has_audio", pa.bool_()), ("title", pa.string()), ("channel", pa.string()), ("uploader", pa.string()),
        ("upload_date", pa.string()), ("licence", pa.string()), ("style", pa.string()),
        ("tags", pa.list_(pa.string())), ("attempts", pa.int32()),
    ]
)

INDEX_SCHEMA = pa.schema(
    [
        ("segment_id", pa.string()), ("video_id", pa.string()), ("start", pa.float64()), ("end", pa.float64()),
        ("fps", pa.float64()), ("fps_fraction", pa.string()), ("frames", pa.int32()),
        ("width", pa.int32()), ("height", pa.int32()), ("has_audio", pa.bool_()), ("audio_stream", pa.int32()),
        ("label", pa.string()),
        ("source", pa.string()),  # the downloaded file in data/raw that the frames and audio are read from
        ("fingerprint", pa.string()),
    ]
)


def read_discovered(catalog_dir: Path) -> dict[str, list[dict]]:
    """The discovered videos by list url, each list in position order ({} when there is none)."""
    path = Path(catalog_dir) / DISCOVERED
    lists: dict[str, list[dict]] = {}
    if path.exists():
        for row in read_rows(path):
            lists.setdefault(row["list_url"], []).append(row)
    return lists


def write_discovered(catalog_dir: Path, rows: list[dict], params: Mapping[str, Any]) -> None:
    """Lists in sources.csv order, entries in position order. No timestamps: an unchanged feed
    gives a byte-identical file, so DVC re-runs nothing downstream."""
    write_rows(rows, DISCOVERED_SCHEMA, Path(catalog_dir) / DISCOVERED, schema_version=DISCOVERED_VERSION,
               params=params)


def read_ledger(raw_dir: Path) -> dict[str, dict]:
    """The download ledger by url ({} when there is none)."""
    path = Path(raw_dir) / LEDGER
    return {row["url"]: row for row in read_rows(path)} if path.exists() else {}


def write_ledger(raw_dir: Path, rows: list[dict], params: Mapping[str, Any]) -> None:
    """One row per source, in sources.csv order."""
    write_rows(rows, LEDGER_SCHEMA, Path(raw_dir) / LEDGER, schema_version=LEDGER_VERSION, params=params)


def read_index(seg_dir: Path) -> dict[str, dict]:
    """The segment index by segment id, in index order ({} when there is none)."""
    path = Path(seg_dir) / INDEX
    return {r["segment_id"]: r for r in read_rows(path)} if path.exists() else {}


def write_index(seg_dir: Path, rows: list[dict], params: Mapping[str, Any]) -> None:
    """One row per segment, in plan order; ``fingerprint`` is each segment's up-to-date key."""
    write_rows(rows, INDEX_SCHEMA, Path(seg_dir) / INDEX, schema_version=INDEX_VERSION, params=params)
