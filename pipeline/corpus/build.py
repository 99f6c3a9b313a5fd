"""Building the corpus from the 24 fps motion and the audio features: windows, shards, card, metrics.

The shard stage calls these; the window contract (schema, split rule) is ``windows.py``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from pipeline.core.failures import failure_totals
from pipeline.core.ids import video_id_of_segment
from pipeline.core.metrics import read_report, write_metrics
from pipeline.core.paths import AUDIO_FEATURES, CLEAN, CORPUS, METRICS, MOTION24, RAW, SEGMENTS, TRACKS, WORLD
from pipeline.core.storage import atomic_path, item_files, read_meta, write_parquet
from pipeline.corpus.card import (
    alignment_png,
    channel_stats,
    durations_csv,
    hf_front_matter,
    histogram_png,
    render_card,
    style_stats,
)
from pipeline.corpus.windows import FPS, SCHEMA_VERSION, Window, split_of, window_starts, windows_table
from pipeline.ingest.catalog import read_index, read_ledger
from pipeline.motion.mocap.skeleton import H36M17, H36M_BONES
from pipeline.motion.motionfile import clip_frame_counts, read_motion
from pipeline.motion.world.worldfile import ROTATION_JOINTS, read_world
from pipeline.music.alignment import (
    beat_align_score,
    beat_align_score_aistpp,
    beat_f1,
    half_beat_later,
    kinematic_beats,
    shuffled_pairs,
)
from pipeline.music.beats import beat_flags, describe
from pipeline.music.featurefile import FeatureFile, read_features
from pipeline.music.levels import FACTORS, candidate_levels, choose_level, phase
from pipeline.pose.trackfile import read_tracks


def _in_window(times: np.ndarray, k: int, window: int, fps: float) -> list[int]:
    """Beat times (s, segment clock) as frame indices inside the window starting at frame k."""
    frames = np.rint(np.asarray(times) * fps).astype(int) - k
    return [int(f) for f in frames if 0 <= f < window]


def segment_levels(feats: FeatureFile) -> dict[str, np.ndarray]:
    """The beat levels a segment's music allows (``levels.candidate_levels``), segment clock."""
    return candidate_levels(feats.beat_times, np.asarray(feats.meta.get("downbeat_times", [])),
                            int(feats.meta.get("beats_per_bar", 4)))


def window_beats(feats: FeatureFile, levels: dict[str, np.ndarray], motion: np.ndarray, k: int, window: int,
                 fps: float) -> tuple[dict, dict]:
    """The beat columns of one window at the level its dance follows: the scalar and list columns,
    and the per-frame ones (beat and downbeat flags, beat and bar phase)."""
    start, end = k / fps, (k + window) / fps
    motion_beats = kinematic_beats(motion, fps)
    level = choose_level(levels, start + motion_beats / fps, start, end, fps)
    beats, downbeats = levels[level.name], np.asarray(feats.meta.get("downbeat_times", []), float)
    music = beats[(beats >= start) & (beats < end)] - start
    grid = (k + np.arange(window)) / fps
    columns = {"beat_frames": _in_window(beats, k, window, fps),
               "downbeat_frames": _in_window(downbeats, k, window, fps),
               "beat_times": [float(t) for t in music],
               "downbeat_times": [float(t - start) for t in downbeats if start <= t < end],
               "beat_level": level.name, "beat_level_reason": level.reason,
               "beat_tracker": str(feats.meta.get("beat_tracker", "librosa")),
               "tempo": feats.tempo * FACTORS[level.name],
               "motion_beat_frames": [int(f) for f in motion_beats],
               "beat_align_score": beat_align_score(music, motion_beats / fps),
               "beat_align_score_aistpp": beat_align_score_aistpp(music, motion_beats / fps),
               "beat_f1": beat_f1(music, motion_beats / fps, fps)}
    frames = {"beat": beat_flags(beats - start, window, fps), "downbeat": beat_flags(downbeats - start, window, fps),
              "beat_phase": phase(beats, grid), "bar_phase": phase(downbeats, grid)}
    return columns, frames


def collect_windows(root: Path, window: int, hop: int, val_fraction: float,
                    fps: float = FPS) -> tuple[list[Window], dict]:
    ledger = {r["video_id"]: r for r in read_ledger(root / RAW).values() if r["status"] == "ok"}
    segments = read_index(root / SEGMENTS)
    windows: list[Window] = []
    counts = {"clips": 0, "clips_without_audio": 0, "clips_without_world": 0, "clips_too_short": 0}
    for motion_file in item_files(root / MOTION24):
        seg_id = motion_file.stem
        seg = segments.get(seg_id)
        feature_file = root / AUDIO_FEATURES / f"{seg_id}.parquet"
        world_file = root / WORLD / f"{seg_id}.parquet"
        motion = read_motion(motion_file)
        clips = motion.clips
        counts["clips"] += len(clips)
        if seg is None or not feature_file.exists():
            counts["clips_without_audio"] += len(clips)
            continue
        if not world_file.exists():  # the ground stage failed on it (its _failures.parquet says why)
            counts["clips_without_world"] += len(clips)
            continue
        grounded_clips = {c.clip_id: c for c in read_world(world_file)}
        feats = read_features(feature_file)
        levels = segment_levels(feats)
        for name, rate in (("motion", motion.fps), ("audio features", float(feats.meta.get("fps", FPS)))):
            if abs(rate - fps) > 1e-9:
                raise ValueError(f"{seg_id}: {name} at {rate:g} fps, the corpus at {fps:g}: re-run resample and audio")
        video = ledger.get(seg["video_id"], {})
        for clip in clips:
            starts = [k for k in window_starts(int(clip.frame[0]), len(clip.frame), window, hop)
                      if k + window <= feats.frames]
            grounded = grounded_clips.get(clip.clip_id)
            if grounded is None or len(grounded.frame) != len(clip.frame):
                raise ValueError(f"{world_file}: clip {clip.clip_id} does not match {motion_file}: re-run ground")
            if not starts:
                counts["clips_too_short"] += 1
                continue
            counts.setdefault("grounding", []).append({"clip_id": clip.clip_id, **grounded.facts})
            for k in starts:
                i = k - int(clip.frame[0])
                joints = clip.joints[i: i + window]
                meta = {"window_id": f"{clip.clip_id}_w{k:06d}", "split": split_of(seg["video_id"], val_fraction),
                        "video_id": seg["video_id"], "url": video.get("url", ""), "title": video.get("title", ""),
                        "channel": video.get("channel", ""), "style": video.get("style", ""),
                        "tags": list(video.get("tags") or []),
                        "licence": video.get("licence", ""), "segment_id": seg_id, "clip_id": clip.clip_id,
                        "track_id": clip.track_id, "start_frame": k, "start_time": k / fps,
                        "segment_start": seg["start"],
                        "bone_lengths": np.asarray(grounded.facts["bone_lengths"]),
                        "camera_pitch": grounded.facts["pitch_deg"], "camera_roll": grounded.facts["roll_deg"],
                        "smpl_scaling": grounded.facts.get("smpl_scaling", float("nan"))}
                beat_columns, beat_frames = window_beats(feats, levels, joints, k, window, fps)
                meta.update(beat_columns)
                world = grounded.joints[i: i + window].copy()
                start = world[0, 0, [0, 2]].copy()
                world[..., [0, 2]] -= start  # x/z from the window's first root position
                feet = None if clip.feet is None else clip.feet[i: i + window]
                world_feet = None if grounded.feet is None else grounded.feet[i: i + window].copy()
                if world_feet is not None:
                    world_feet[..., [0, 2]] -= start
                planted = None if grounded.planted is None else grounded.planted[i: i + window]
                probability = (None if grounded.contact_probability is None
                               else grounded.contact_probability[i: i + window])
                smpl_trans = None
                if grounded.smpl_trans is not None:
                    smpl_trans = grounded.smpl_trans[i: i + window].astype(np.float64)
                    smpl_trans[:, [0, 2]] -= start
                smpl_poses = None if grounded.smpl_poses is None else grounded.smpl_poses[i: i + window]
                hands = confidence = hand_poses = None
                if grounded.hands is not None:
                    hands = grounded.hands[i: i + window].astype(np.float64)
                    hands[..., [0, 2]] -= start
                    confidence = grounded.hand_presence[i: i + window]
                    hand_poses = grounded.smpl_hand_poses[i: i + window]
                windows.append(Window(meta, joints, feats.mfcc[k: k + window], feats.chroma[k: k + window],
                                      feats.onset[k: k + window], beat_frames["beat"], world,
                                      grounded.contact[i: i + window], grounded.rotations_6d[i: i + window],
                                      feet, world_feet, planted, probability, smpl_poses, smpl_trans,
                                      beat_frames["downbeat"], beat_frames["beat_phase"], beat_frames["bar_phase"],
                                      hands, confidence, hand_poses))
    return windows, counts


def collect_group_windows(root: Path, window: int, hop: int, val_fraction: float, fps: float = FPS) -> list:
    """Every segment's group windows (``groups.segment_group_windows``): its world clips in one scene."""
    from pipeline.corpus.groups import segment_group_windows

    ledger = {r["video_id"]: r for r in read_ledger(root / RAW).values() if r["status"] == "ok"}
    segments = read_index(root / SEGMENTS)
    out = []
    for world_file in item_files(root / WORLD):
        seg = segments.get(world_file.stem)
        feature_file = root / AUDIO_FEATURES / f"{world_file.stem}.parquet"
        if seg is None or not feature_file.exists():
            continue
        world_meta = read_meta(world_file)
        scene = world_meta.get("scene") or {}
        video = ledger.get(seg["video_id"], {})
        feats = read_features(feature_file)
        meta = {"segment_id": world_file.stem, "split": split_of(seg["video_id"], val_fraction),
                "video_id": seg["video_id"], "url": video.get("url", ""), "licence": video.get("licence", ""),
                "segment_start": seg["start"], "fps": fps, "tempo": feats.tempo,
                "camera_pitch": scene.get("pitch_deg", float("nan")),
                "camera_roll": scene.get("roll_deg", float("nan"))}
        out.extend(segment_group_windows(read_world(world_file), feats, window, hop, meta))
    return out


def write_group_shards(root: Path, groups: list, window: int, per_shard: int, row_group: int, params: dict,
                       fps: float = FPS) -> dict[str, int]:
    """``data/corpus/groups/{train,val}/shard-NNNNN.parquet`` (the ``groups`` config of the card)."""
    from pipeline.corpus.groups import GROUP_SCHEMA_VERSION, group_table

    extra = {"fps": fps, "window_frames": window, "joints": "h36m17", "units": "metres",
             "frame": "the segment's scene: y up, floor y = 0, x/z about the group's centre"}
    written = {}
    for split in ("train", "val"):
        folder = root / CORPUS / "groups" / split
        rows = [g for g in groups if g.meta["split"] == split]
        if not rows:  # no empty group folders in a corpus of solo dancers
            shutil.rmtree(folder, ignore_errors=True)
        written[split] = _write_split(folder, rows, lambda chunk: group_table(chunk, window), per_shard, row_group,
                                      GROUP_SCHEMA_VERSION, params, extra) if rows else 0
    return written


def _write_split(folder: Path, rows: list, to_table, per_shard: int, row_group: int, schema_version: int,
                 params: dict, extra: dict) -> int:
    """``folder``/shard-NNNNN.parquet of ``per_shard`` rows each, the folder made anew (the corpus is
    rebuilt whole: no stale shards); how many rows."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for n, start in enumerate(range(0, len(rows), per_shard)):
        write_parquet(to_table(rows[start: start + per_shard]), folder / f"shard-{n:05d}.parquet",
                      schema_version=schema_version, params=params, extra=extra, row_group_size=row_group)
    return len(rows)


def grounding_summary(clips: list[dict]) -> dict:
    """Medians over the clips of the world grounding: camera tilt, bone-length CV before the one
    skeleton (0 after), contact share and foot skating before and after pinning."""
    keys = ("pitch_deg", "roll_deg", "bone_cv_before", "fit_moved_mm", "contact_share", "skate_before_m_s",
            "skate_after_m_s")
    medians = {k: round(float(np.nanmedian([c[k] for c in clips])), 4) if clips else float("nan") for k in keys}
    return {"clips": len(clips), "clips_with_learned_contact": sum(bool(c.get("contact_learned")) for c in clips),
            **medians}


def alignment_summary(windows: list[Window], fps: float, seed: int = 0) -> dict:
    """Beat alignment of every window with its own music and with two controls: another video's
    music (shuffled) and its own music half a beat late (which holds for covers of one song too)."""
    if not windows:
        return {"windows": 0}
    partners = shuffled_pairs([w.meta["video_id"] for w in windows], seed)
    scores = {name: {"bas": [], "bas_aistpp": [], "f1": []} for name in ("matched", "shuffled", "half_beat")}
    for w, j in zip(windows, partners):
        # All from frame indices (not the windows' exact-time scores), so matched and control
        # music beats have the same precision and only the pairing differs.
        motion = np.asarray(w.meta["motion_beat_frames"], float) / fps
        own = np.asarray(w.meta["beat_frames"], float)
        for name, music in (("matched", own), ("shuffled", np.asarray(windows[j].meta["beat_frames"], float)),
                            ("half_beat", half_beat_later(own))):
            scores[name]["bas"].append(beat_align_score(music / fps, motion))
            scores[name]["bas_aistpp"].append(beat_align_score_aistpp(music / fps, motion))
            scores[name]["f1"].append(beat_f1(music / fps, motion, fps))

    def mean(values: list[float]) -> float:
        good = [v for v in values if v == v]
        return round(float(np.mean(good)), 4) if good else float("nan")

    figures = {f"{name}_{key}": mean(scores[name][short]) for name in scores
               for key, short in (("beat_align_score", "bas"), ("beat_align_score_aistpp", "bas_aistpp"),
                                  ("beat_f1", "f1"))}
    levels = [w.meta.get("beat_level") or "tracked" for w in windows]
    trackers = sorted({w.meta.get("beat_tracker") or "librosa" for w in windows})
    return {"windows": len(windows), **figures, "beat_levels": {n: levels.count(n) for n in FACTORS},
            "beat_trackers": {t: describe(t) for t in trackers},
            "shuffle": "each window's motion beats against the music beats of a window of another video (seeded)",
            "half_beat": "each window's motion beats against its own music beats moved half a beat later"}


def write_shards(root: Path, windows: list[Window], window: int, per_shard: int, row_group: int,
                 params: dict, fps: float = FPS) -> dict[str, int]:
    extra = {"fps": fps, "window_frames": window, "joints": "h36m17", "units": "metres",
             "rotation_joints": ",".join(ROTATION_JOINTS),
             "bones": ",".join(f"{H36M17[a]}-{H36M17[b]}" for a, b in H36M_BONES),
             "alignment": f"motion and audio frame k centred at k/{fps:g} s on the segment clock"}
    return {split: _write_split(root / CORPUS / split, [w for w in windows if w.meta["split"] == split],
                                lambda chunk: windows_table(chunk, window), per_shard, row_group, SCHEMA_VERSION,
                                params, extra)
            for split in ("train", "val")}


def write_card_and_metrics(root: Path, windows: list[Window], counts: dict, params: dict, window: int,
                           hop: int, fps: float = FPS, groups: list | None = None) -> None:
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
        source_fps = read_meta(f)["fps"]  # the clean file's own (source) rate, not the corpus's
        frames_per_clip = clip_frame_counts(f)
        video = video_of(f.stem)
        clip_minutes[video] = clip_minutes.get(video, 0.0) + sum(frames_per_clip.values()) / source_fps / 60
        clip_seconds.extend(n / source_fps for n in frames_per_clip.values())
    metas = [w.meta for w in windows]
    stats = channel_stats(ledger, segments, track_ids, clip_minutes, metas)
    n_train = sum(1 for m in metas if m["split"] == "train")
    covered: dict[str, set] = {}
    for m in metas:  # windows overlap: count each clip frame once
        covered.setdefault(m["clip_id"], set()).update(range(m["start_frame"], m["start_frame"] + window))
    distinct_frames = sum(len(frames) for frames in covered.values())
    totals = {"windows_train": n_train, "windows_val": len(metas) - n_train,
              "window_minutes": distinct_frames / fps / 60}
    series = {"source videos": [r["duration"] for r in ledger if r["status"] == "ok"],
              "trimmed segments": [s["frames"] / s["fps"] for s in segments], "clips": clip_seconds}
    card_params = {"window_seconds": window / fps, "hop_seconds": hop / fps, "fps": fps}
    alignment = alignment_summary(windows, fps)
    (root / CORPUS).mkdir(parents=True, exist_ok=True)
    histogram_png(root / CORPUS / "durations.png", series)
    if windows:  # the window whose beat-align score is the median: a typical one
        scores = [w.meta["beat_align_score"] for w in windows]
        typical = windows[int(np.argsort(np.nan_to_num(scores, nan=-1))[len(windows) // 2])]
        alignment_png(root / CORPUS / "alignment.png", typical.motion, typical.meta["beat_frames"],
                      typical.meta["motion_beat_frames"], fps,
                      f"{typical.meta['window_id']}: beat-align score {typical.meta['beat_align_score']:.2f}")
    group_counts = {s: sum(g.meta["split"] == s for g in groups or []) for s in ("train", "val")}
    group_counts["dancers"] = len({c for g in groups or [] for c in g.meta["clip_ids"]})
    with atomic_path(root / CORPUS / "README.md") as tmp:
        splits = [s for s, n in (("train", totals["windows_train"]), ("val", totals["windows_val"])) if n]
        contact = read_report(root, "contact")
        tmp.write_text(hf_front_matter(splits, [s for s in ("train", "val") if group_counts[s]])
                       + render_card(stats, ledger, card_params, totals, alignment, style_stats(metas), contact,
                                     group_counts if groups else None))
    (root / CORPUS / "card.md").unlink(missing_ok=True)  # the card's name before schema 4
    durations_csv(root / METRICS / "durations.csv", {"videos": series["source videos"],
                                                     "segments": series["trimmed segments"], "clips": clip_seconds})
    total = stats[-1] if stats else {}
    metrics = {"videos": total.get("videos", 0), "video_minutes": total.get("minutes", 0.0),
               "segments": total.get("segments", 0), "segment_minutes": total.get("segment_minutes", 0.0),
               "track_ids_per_video": total.get("track_ids_per_video", 0.0),
               "track_minutes": total.get("track_minutes", 0.0), "windows_train": totals["windows_train"],
               "windows_val": totals["windows_val"], "clips": counts["clips"],
               "clips_without_audio": counts["clips_without_audio"],
               "clips_without_world": counts.get("clips_without_world", 0),
               "clips_too_short": counts["clips_too_short"],
               "beat_alignment": alignment, "grounding": grounding_summary(counts.get("grounding", [])),
               "group_windows": {"train": group_counts["train"], "val": group_counts["val"],
                                 "dancers_median": float(np.median([g.meta["dancers"] for g in groups]))
                                 if groups else 0.0},
               "failures": failure_totals(root)}
    write_metrics(root, "corpus", metrics)
