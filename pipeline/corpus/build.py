"""Building the corpus from the 24 fps motion and the audio features: windows, shards, card, metrics.

The shard stage calls these; the window contract (schema, split rule) is ``windows.py``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from pipeline.core.ids import video_id_of_segment
from pipeline.core.paths import AUDIO_FEATURES, CLEAN, CORPUS, METRICS, MOTION24, RAW, SEGMENTS, TRACKS
from pipeline.core.storage import atomic_path, item_files, read_meta, write_json, write_parquet
from pipeline.corpus.card import channel_stats, durations_csv, histogram_png, render_card
from pipeline.corpus.windows import SCHEMA_VERSION, Window, split_of, window_starts, windows_table
from pipeline.ingest.catalog import read_index, read_ledger
from pipeline.motion.motionfile import clip_frame_counts, read_motion
from pipeline.music.featurefile import read_features
from pipeline.pose.trackfile import read_tracks


def collect_windows(root: Path, window: int, hop: int, val_fraction: float) -> tuple[list[Window], dict]:
    ledger = {r["video_id"]: r for r in read_ledger(root / RAW).values() if r["status"] == "ok"}
    segments = read_index(root / SEGMENTS)
    windows: list[Window] = []
    counts = {"clips": 0, "clips_without_audio": 0, "clips_too_short": 0}
    for motion_file in item_files(root / MOTION24):
        seg_id = motion_file.stem
        seg = segments.get(seg_id)
        feature_file = root / AUDIO_FEATURES / f"{seg_id}.parquet"
        clips = read_motion(motion_file).clips
        counts["clips"] += len(clips)
        if seg is None or not feature_file.exists():
            counts["clips_without_audio"] += len(clips)
            continue
        feats = read_features(feature_file)
        video = ledger.get(seg["video_id"], {})
        for clip in clips:
            starts = [k for k in window_starts(int(clip.frame[0]), len(clip.frame), window, hop)
                      if k + window <= feats.frames]
            if not starts:
                counts["clips_too_short"] += 1
            for k in starts:
                i = k - int(clip.frame[0])
                meta = {"window_id": f"{clip.clip_id}_w{k:06d}", "split": split_of(seg["video_id"], val_fraction),
                        "video_id": seg["video_id"], "url": video.get("url", ""), "title": video.get("title", ""),
                        "channel": video.get("channel", ""), "style": video.get("style", ""),
                        "licence": video.get("licence", ""), "segment_id": seg_id, "clip_id": clip.clip_id,
                        "track_id": clip.track_id, "start_frame": k, "start_time": k / 24,
                        "segment_start": seg["start"], "tempo": feats.tempo}
                windows.append(Window(meta, clip.joints[i: i + window], feats.mfcc[k: k + window],
                                      feats.chroma[k: k + window], feats.onset[k: k + window],
                                      feats.beat[k: k + window]))
    return windows, counts


def write_shards(root: Path, windows: list[Window], window: int, per_shard: int, row_group: int,
                 params: dict) -> dict[str, int]:
    written = {}
    for split in ("train", "val"):
        folder = root / CORPUS / split
        shutil.rmtree(folder, ignore_errors=True)  # the corpus is rebuilt whole: no stale shards
        folder.mkdir(parents=True)
        rows = [w for w in windows if w.meta["split"] == split]
        for n, start in enumerate(range(0, len(rows), per_shard)):
            table = windows_table(rows[start: start + per_shard], window)
            write_parquet(table, folder / f"shard-{n:05d}.parquet", schema_version=SCHEMA_VERSION, params=params,
                          extra={"fps": 24, "window_frames": window, "joints": "h36m17", "units": "metres",
                                 "alignment": "motion and audio frame k centred at k/24 s on the segment clock"},
                          row_group_size=row_group)
        written[split] = len(rows)
    return written


def write_card_and_metrics(root: Path, windows: list[Window], counts: dict, params: dict, window: int,
                           hop: int) -> None:
    ledger = list(read_ledger(root / RAW).values())
    index = read_index(root / SEGMENTS)
    segments = list(index.values())

    def video_of(seg_id: str) -> str:
        return index[seg_id]["video_id"] if seg_id in index else video_id_of_segment(seg_id)

    track_ids: dict[str, int] = {}
    for f in item_files(root / TRACKS):
        video = video_of(f.stem)
        track_ids[video] = track_ids.get(video, 0) + len(read_tracks(f).ids)
    clip_minutes: dict[str, float] = {}
    clip_seconds: list[float] = []
    for f in item_files(root / CLEAN):
        fps = read_meta(f)["fps"]
        frames_per_clip = clip_frame_counts(f)
        video = video_of(f.stem)
        clip_minutes[video] = clip_minutes.get(video, 0.0) + sum(frames_per_clip.values()) / fps / 60
        clip_seconds.extend(n / fps for n in frames_per_clip.values())
    metas = [w.meta for w in windows]
    stats = channel_stats(ledger, segments, track_ids, clip_minutes, metas)
    n_train = sum(1 for m in metas if m["split"] == "train")
    covered: dict[str, set] = {}
    for m in metas:  # windows overlap: count each clip frame once
        covered.setdefault(m["clip_id"], set()).update(range(m["start_frame"], m["start_frame"] + window))
    distinct_frames = sum(len(frames) for frames in covered.values())
    totals = {"windows_train": n_train, "windows_val": len(metas) - n_train,
              "window_minutes": distinct_frames / 24 / 60}
    series = {"source videos": [r["duration"] for r in ledger if r["status"] == "ok"],
              "trimmed segments": [s["frames"] / s["fps"] for s in segments], "clips": clip_seconds}
    card_params = {"window_seconds": window / 24, "hop_seconds": hop / 24}
    (root / CORPUS).mkdir(parents=True, exist_ok=True)
    histogram_png(root / CORPUS / "durations.png", series)
    with atomic_path(root / CORPUS / "card.md") as tmp:
        tmp.write_text(render_card(stats, ledger, card_params, totals))
    durations_csv(root / METRICS / "durations.csv", {"videos": series["source videos"],
                                                     "segments": series["trimmed segments"], "clips": clip_seconds})
    total = stats[-1] if stats else {}
    metrics = {"videos": total.get("videos", 0), "video_minutes": total.get("minutes", 0.0),
               "segments": total.get("segments", 0), "segment_minutes": total.get("segment_minutes", 0.0),
               "track_ids_per_video": total.get("track_ids_per_video", 0.0),
               "track_minutes": total.get("track_minutes", 0.0), "windows_train": totals["windows_train"],
               "windows_val": totals["windows_val"], "clips": counts["clips"],
               "clips_without_audio": counts["clips_without_audio"], "clips_too_short": counts["clips_too_short"]}
    write_json(root / METRICS / "corpus.json", metrics)
