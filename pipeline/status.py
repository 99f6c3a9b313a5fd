"""``dance3d status``: a readable summary of what the pipeline has produced so far."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

from pipeline.core.failures import FAILURES_FILE, read_failures
from pipeline.core.metrics import headline_figures
from pipeline.core.paths import (
    AUDIO_FEATURES,
    CATALOG,
    CLEAN,
    CORPUS,
    MOTION24,
    POSE2D,
    POSE3D,
    RAW,
    SEGMENT_PROPOSALS,
    SEGMENTS,
    SMOOTH,
    TRACKS,
    WORLD,
)
from pipeline.core.storage import item_files
from pipeline.ingest.catalog import read_discovered, read_index, read_ledger


def summarise(root: Path) -> str:
    lines: list[str] = []
    lists = read_discovered(root / CATALOG)
    if lists:
        videos = [r for rows in lists.values() for r in rows]
        lines.append(f"discover: {len(lists)} channels/playlists/feeds, {len(videos)} videos listed, "
                     f"{sum(r['selected'] for r in videos)} selected by the filters")
    rows = list(read_ledger(root / RAW).values())
    if rows:
        counts: dict[str, int] = {}
        for r in rows:
            counts[r["status"]] = counts.get(r["status"], 0) + 1
        minutes = sum(r["duration"] for r in rows if r["status"] == "ok") / 60
        lines.append(f"download: {len(rows)} sources, " + ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
                     + f"; {minutes:.1f} min of video")
        for r in rows:
            if r["status"] != "ok":
                lines.append(f"  {r['status']:9} {r['video_id'] or '-':20} {r['error_class']}: {r['error_message']}")
    else:
        lines.append("download: not run yet (dance3d run download, or dvc repro)")
    proposed = item_files(root / SEGMENT_PROPOSALS)
    if proposed:
        from pipeline.pose.proposed import read_proposals

        found = [read_proposals(f) for f in proposed]
        seconds = sum(s["end"] - s["start"] for f in found for s in f["segments"])
        lines.append(f"propose_segments: {sum(len(f['segments']) for f in found)} proposed dance segments "
                     f"({seconds / 60:.1f} min) in {len(found)} videos; review them at /trim (dance3d review)")
    segs = list(read_index(root / SEGMENTS).values())
    if segs:
        minutes = sum(s["frames"] / s["fps"] for s in segs) / 60
        videos = len({s["video_id"] for s in segs})
        silent = sum(1 for s in segs if not s["has_audio"])
        lines.append(f"trim: {len(segs)} segments from {videos} videos, {minutes:.1f} min; {silent} without audio")
    else:
        lines.append("trim: not run yet")
    for stage, folder in (("pose2d", POSE2D), ("track", TRACKS), ("clean", CLEAN), ("lift", POSE3D),
                          ("smooth", SMOOTH), ("resample", MOTION24), ("ground", WORLD), ("audio", AUDIO_FEATURES)):
        files = item_files(root / folder)
        if files:
            lines.append(f"{stage}: {len(files)} segments in {folder}")
    for split in ("train", "val"):
        shards = sorted((root / CORPUS / split).glob("shard-*.parquet"))
        if shards:
            windows = sum(pq.read_metadata(p).num_rows for p in shards)
            lines.append(f"corpus {split}: {windows} windows in {len(shards)} shard{'s' * (len(shards) != 1)}")
    for failures in sorted((root / "data").glob(f"*/{FAILURES_FILE}")) if (root / "data").exists() else []:
        rows = read_failures(failures.parent)
        if rows:
            lines.append(f"failures in {failures.parent.name} ({len(rows)}):")
            lines.extend(f"  {r.item}: {r.error_class}: {r.message}" for r in rows)
    figures = headline_figures(root)
    if figures:  # what `dvc metrics show` shows, for those who do not use DVC
        lines.append("headline metrics (metrics/*.json; the breakdowns in reports/):")
        lines.extend(f"  {name:28s} {value}" for name, value in figures.items())
    return "\n".join(lines)
