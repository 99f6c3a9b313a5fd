"""Readers for the pipeline's catalogue files: the download ledger and the segment index."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

LEDGER = "ledger.parquet"
INDEX = "index.parquet"


def read_ledger(raw_dir: Path) -> dict[str, dict]:
    """The download ledger by url ({} when there is none)."""
    path = Path(raw_dir) / LEDGER
    return {row["url"]: row for row in pq.read_table(path).to_pylist()} if path.exists() else {}


def read_index(seg_dir: Path) -> dict[str, dict]:
    """The segment index by segment id, in index order ({} when there is none)."""
    path = Path(seg_dir) / INDEX
    return {r["segment_id"]: r for r in pq.read_table(path).to_pylist()} if path.exists() else {}
