"""The dataset card (data/corpus/README.md, with Hugging Face metadata), its statistics table and
duration histograms."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from pipeline.core.storage import atomic_path
from pipeline.motion.mocap.skeleton import H36M17


def channel_stats(ledger: list[dict], segments: list[dict], track_ids: dict[str, int], clip_minutes: dict[str, float],
                  windows: list[dict]) -> list[dict]:
    """Rows like the seed paper's Table 2, one per channel plus a total.

    track_ids: video_id -> number of real track ids over its segments;
    clip_minutes: video_id -> minutes of cleaned clips.
    """
    channel_of = {r["video_id"]: r["channel"] or "(unknown)" for r in ledger if r["status"] == "ok"}
    rows: dict[str, dict] = defaultdict(lambda: defaultdict(float))
    for r in ledger:
        if r["status"] == "ok":
            row = rows[channel_of[r["video_id"]]]
            row["videos"] += 1
            row["minutes"] += r["duration"] / 60
            row["track_ids"] += track_ids.get(r["video_id"], 0)
            row["track_minutes"] += clip_minutes.get(r["video_id"], 0.0)
    for s in segments:
        row = rows[channel_of.get(s["video_id"], "(unknown)")]
        row["segments"] += 1
        row["segment_minutes"] += s["frames"] / s["fps"] / 60
    for w in windows:
        rows[channel_of.get(w["video_id"], "(unknown)")][f"windows_{w['split']}"] += 1
    table = []
    for channel in sorted(rows):
        r = rows[channel]
        table.append({"channel": channel, "videos": int(r["videos"]), "minutes": round(r["minutes"], 2),
                      "segments": int(r["segments"]), "segment_minutes": round(r["segment_minutes"], 2),
                      "track_ids_per_video": round(r["track_ids"] / r["videos"], 2) if r["videos"] else 0.0,
                      "track_minutes": round(r["track_minutes"], 2), "windows_train": int(r["windows_train"]),
                      "windows_val": int(r["windows_val"])})
    total = {"channel": "total"}
    for key in table[0] if table else []:
        if key != "channel":
            total[key] = round(sum(t[key] for t in table), 2)
    if table:
        videos = sum(t["videos"] for t in table)
        total["track_ids_per_video"] = round(sum(t["track_ids_per_video"] * t["videos"] for t in table) / videos, 2) \
            if videos else 0.0
    return table + ([total] if table else [])


def histogram_png(path: Path, series: dict[str, list[float]]) -> None:
    """Duration histograms (seconds), one panel per series."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(series), figsize=(4 * len(series), 3), squeeze=False)
    for ax, (name, values) in zip(axes[0], series.items()):
        ax.hist(values or [0], bins=20, color="#4477aa")
        ax.set_title(name)
        ax.set_xlabel("seconds")
        ax.set_ylabel("count")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)


def alignment_png(path: Path, motion: np.ndarray, beat_frames: list[int], motion_beat_frames: list[int],
                  fps: float, title: str) -> None:
    """One window at a glance: mean joint speed over time, music beats (lines) and motion beats (dots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    speed = np.linalg.norm(np.diff(np.asarray(motion, float), axis=0), axis=-1).mean(-1) * fps
    t = np.arange(len(speed)) / fps
    fig, ax = plt.subplots(figsize=(10, 2.6))
    ax.plot(t, speed, color="#4477aa", lw=1.2, label="mean joint speed (m/s)")
    for k, f in enumerate(beat_frames):
        ax.axvline(f / fps, color="#cc6677", lw=0.8, alpha=0.8, label="music beat" if k == 0 else None)
    mb = [f for f in motion_beat_frames if f < len(speed)]
    ax.plot(np.asarray(mb) / fps, speed[mb], "o", color="#117733", ms=4, label="motion beat")
    ax.set_xlabel("seconds into the window")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=7, ncol=3)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)


def durations_csv(path: Path, series: dict[str, list[float]], bin_seconds: float = 5.0) -> None:
    """Histogram counts per 5 s bin, one column per series, for `dvc plots`."""
    top = max([max(v) for v in series.values() if v] or [bin_seconds])
    edges = np.arange(0, top + bin_seconds, bin_seconds)
    counts = {name: np.histogram(values, bins=edges)[0] if values else np.zeros(len(edges) - 1, int)
              for name, values in series.items()}
    lines = ["seconds," + ",".join(series)]
    for i, start in enumerate(edges[:-1]):
        lines.append(f"{start:g}," + ",".join(str(int(counts[n][i])) for n in series))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def _alignment_text(a: dict | None) -> str:
    if not a or not a.get("windows"):
        return "No windows yet, so no alignment figures."
    return (f"Over {a['windows']} windows, motion beats against the window's own music beats and two "
            f"controls: the beats of a window of another video (shuffled, seeded), and the window's own beats "
            f"moved half a beat later (half beat):\n\n"
            f"| score | matched | shuffled | half beat |\n|---|---|---|---|\n"
            f"| beat-align score, Bailando's (each music beat to its nearest motion beat) | "
            f"{a['matched_beat_align_score']} | {a['shuffled_beat_align_score']} | "
            f"{a.get('half_beat_beat_align_score', 'n/a')} |\n"
            f"| beat-align score, AIST++'s (each motion beat to its nearest music beat) | "
            f"{a.get('matched_beat_align_score_aistpp', 'n/a')} | {a.get('shuffled_beat_align_score_aistpp', 'n/a')} | "
            f"{a.get('half_beat_beat_align_score_aistpp', 'n/a')} |\n"
            f"| beat-consistency F-score (2 frames) | {a['matched_beat_f1']} | {a['shuffled_beat_f1']} | "
            f"{a.get('half_beat_beat_f1', 'n/a')} |\n\n"
            "A corpus whose motion follows its music scores clearly higher matched than under either control; no "
            "gap means the motion and the music are out of sync somewhere in the pipeline, or the dancers do "
            "not dance to the beat. The shuffled control fails on covers (videos dancing to one song share "
            "its beats, so shuffled scores like matched); the half-beat control holds for any corpus. "
            "Both beat-align scores use sigma = 0.05 s; Bailando's is lisiyao21/Bailando "
            "utils/beat_align_score.py, AIST++'s google-research/mint tools/calculate_beat_scores.py."
            + _beats_text(a))


def _beats_text(a: dict) -> str:
    """Which tracker labelled the beats, its licence, and the dancers' beat levels."""
    trackers = a.get("beat_trackers") or {}
    levels = a.get("beat_levels") or {}
    if not trackers:
        return ""
    lines = ["\n\n**Beats.** " + " ".join(f"`{name}`: {text}." for name, text in trackers.items())]
    if "rnn" in trackers:
        lines.append("The beats, downbeats and bars of this corpus come from madmom's models, licensed "
                     "CC BY-NC-SA 4.0: use of the labels is non-commercial and shares alike; set "
                     "`audio.beats: librosa` in params.yaml for licence-free labels.")
    if levels:
        lines.append("The beat columns of each window are at the level its dance follows "
                     "(`beat_level`, `beat_level_reason`): " +
                     ", ".join(f"{n} {c}" for n, c in levels.items()) + " windows.")
    return " ".join(lines)


def style_stats(metas: list[dict]) -> list[dict]:
    """Windows per style label (sources.csv's style column; "(none)" when empty), most first."""
    counts: dict[str, dict[str, int]] = {}
    for m in metas:
        row = counts.setdefault(m.get("style") or "(none)", {"train": 0, "val": 0, "videos": set()})
        row[m["split"]] += 1
        row["videos"].add(m["video_id"])
    return [{"style": style, "videos": len(r["videos"]), "windows_train": r["train"], "windows_val": r["val"]}
            for style, r in sorted(counts.items(), key=lambda kv: (-(kv[1]["train"] + kv[1]["val"]), kv[0]))]


# The `smpl` config: what a trainer of EDGE or Bailando reads, with the music and provenance beside it.
SMPL_COLUMNS = ("window_id", "video_id", "clip_id", "start_time", "smpl_poses", "smpl_trans", "smpl_scaling",
                "smpl_hand_poses", "contact", "planted", "mfcc", "beat", "beat_frames", "tempo", "licence")
SMPL_TEXT = """## SMPL skeleton (config `smpl`)

`smpl_poses`, `smpl_trans` and `smpl_scaling` hold each dancer's motion on the SMPL 24-joint
kinematic tree, in AIST++'s layout, so the field's music-to-dance trainers (EDGE, Bailando, FineDance)
read it as they read AIST++ (`dance3d export aistpp` writes their files). Forward kinematics: joint j
sits at its parent's position plus the parent's world rotation times `smpl_scaling` x its rest offset;
the rest offsets are the SMPL neutral body's as published with EDGE (`pipeline/motion/smpl/skeleton.py`
names the source and commit; no SMPL model file is used or shipped). `smpl_trans` is the pelvis joint
itself (EDGE's convention); with an SMPL body model's own forward pass, subtract its rest pelvis joint
from `transl`. Rotations come from inverse kinematics on the world joints (`pipeline/motion/smpl/retarget.py`
states the rule for each joint); joints nothing in a video sees (spine 1-3 split in thirds, toes, and
wrists without hands) follow stated rules. With hands (`pose2d.hands`), `smpl_hand_poses` holds SMPL-H's
30 finger joints (left then right: index, middle, pinky, ring, thumb, three joints each, axis-angle),
so `smpl_poses[:, :66]` followed by it is SMPL-H's 52-joint pose, and the wrists in `smpl_poses` turn
with the palms. Finger rotations are relative to the clip's own rest hand (its palm, fingers straight on
from the knuckles: `pipeline/motion/smpl/hands.py`); `dance3d export finedance --template` re-solves
them onto a template's flat hand, such as the SMPL-X joints FineDance and LODGE use. `datasets.load_dataset(<corpus folder>, "smpl")` loads these columns with the
music and provenance. `dance3d eval smpl` reports how far forward kinematics lands from the world joints."""


def hf_front_matter(splits: list[str], group_splits: list[str] | None = None) -> str:
    """Hugging Face dataset-card metadata: `datasets.load_dataset(<corpus folder>)` finds the
    splits that have shards (val is named `validation`, as the Hub names it); with group windows,
    a second config, `groups` (`load_dataset(<corpus folder>, "groups")`)."""
    def files(folder: str, names: list[str]) -> str:
        return "".join(f"  - split: {'validation' if s == 'val' else s}\n    path: {folder}{s}/*.parquet\n"
                       for s in names)

    groups = f"- config_name: groups\n  data_files:\n{files('groups/', group_splits)}" if group_splits else ""
    smpl = (f"- config_name: smpl\n  data_files:\n{files('', splits)}"
            f"  columns: [{', '.join(SMPL_COLUMNS)}]\n") if splits else ""
    return ("---\npretty_name: dance3d corpus\nlicense: other\nlicense_name: per-source\n"
            "license_details: every window inherits the licence of its source video (columns licence, url)\n"
            "tags:\n- dance\n- motion-capture\n- 3d-human-pose\n- music\n"
            f"configs:\n- config_name: default\n  data_files:\n{files('', splits)}{smpl}{groups}---\n\n")


def _groups_text(groups: dict | None, window: float, hop: float, fps: float) -> str:
    """The group windows: what they hold, and how many there are."""
    frames = round(window * fps)
    count = (f"{groups['train']} training and {groups['val']} validation group windows, "
             f"{groups['dancers']} dancers in all." if groups else "None in this corpus (no segment has two dancers "
             "in one window).")
    return f"""## Group windows (config `groups`)

`groups/train/shard-NNNNN.parquet` and `groups/val/...`: one row per {window:g} s window of a
segment with two or more dancers, every {hop:g} s on the segment clock (frames 0, {round(hop * fps)}, ...),
holding every dancer whose clip covers the whole window, in track-id order. {count}
`datasets.load_dataset(<corpus folder>, "groups")` loads them.

| column | type | meaning |
|---|---|---|
| window_id | string | `<segment_id>_g<start_frame>` |
| split, video_id, url, licence, segment_id, start_frame, start_time, segment_start | | as in the solo windows |
| dancers | int32 | how many dancers the window holds (D) |
| clip_ids, track_ids | list of string, list of int32 | each dancer's clip and track (link to the solo windows) |
| world_joints | D x {frames} x 17 x 3 float32 | each dancer in the segment's scene: y up, one floor at y = 0, x/z in metres about the group's centre over the window (positions relative to each other kept) |
| root | D x {frames} x 3 float32 | each dancer's pelvis: where they stand and travel, in formation |
| world_feet | D x {frames} x 4 x 3 float32 | heels and toe tips, the same frame (NaN without feet) |
| world_hands | D x {frames} x 2 x 21 x 3 float32 | left and right hands, the same frame, as in the solo windows (NaN without hands) |
| contact, planted | D x {frames} x 2 / 4 int8 | as in the solo windows, per dancer |
| camera_pitch, camera_roll | float32 | the scene's camera tilt (degrees), from all its dancers |
| mfcc, chroma, onset, beat, tempo | | the window's music, as in the solo windows |
"""


def _contact_text(contact: dict | None) -> str:
    """How contact is judged, and the contact model's held-out figures (metrics/contact.json)."""
    rule = ("A heel or toe tip is **planted** when the contact model (a small network on 1.2 s of the 2D "
            "keypoints around each frame, trained on motion capture seen by virtual cameras) gives it a "
            "probability above `ground.contact_threshold` (0.4) for at least `ground.min_contact_frames` (3) "
            "frames in a row, and stays planted while the probability stays above `ground.contact_hold` (0.1). "
            "Its labels on the capture: a point within "
            "4 cm of the floor and moving slower than 0.2 m/s. Planted points anchor the root path (no drift "
            "or depth jitter while a foot is planted), set the floor (their median height is y = 0) and stay "
            "where they were planted; the held frames at either end are pinned but do not anchor.")
    if not contact or "heldout" not in contact:
        return rule
    every = contact["heldout"].get("all", {})
    return (rule + f" On held-out motion capture through ten cameras with noisy 2D (a pose model of expected "
            f"OKS 0.80) the model's per-frame F1 at probability 0.5 is **{every.get('f1', float('nan')):.3f}** "
            f"over all four points (heels "
            f"{every.get('f1_left_heel', float('nan')):.3f} / {every.get('f1_right_heel', float('nan')):.3f}, toes "
            f"{every.get('f1_left_toe', float('nan')):.3f} / {every.get('f1_right_toe', float('nan')):.3f}), "
            f"against {every.get('f1_all_planted', float('nan')):.3f} for calling every frame planted "
            "(`dance3d eval world` measures the whole world path on your own capture).")


def render_card(stats: list[dict], ledger: list[dict], params: dict, totals: dict,
                alignment: dict | None = None, styles: list[dict] | None = None, contact: dict | None = None,
                groups: dict | None = None) -> str:
    window, hop = params["window_seconds"], params["hop_seconds"]
    fps = params.get("fps", 24)
    header = ("| channel | videos | minutes | trimmed segments | trimmed minutes | track ids / video | "
              "track minutes | windows train | windows val |\n|---|---|---|---|---|---|---|---|---|\n")
    table = "".join(f"| {r['channel']} | {r['videos']} | {r['minutes']} | {r['segments']} | {r['segment_minutes']} | "
                    f"{r['track_ids_per_video']} | {r['track_minutes']} | {r['windows_train']} | {r['windows_val']} |\n"
                    for r in stats)
    sources = "".join(f"| {r['video_id']} | {r['title'] or '-'} | {r['channel'] or '-'} | {r['licence'] or '-'} | "
                      f"{r['url']} |\n" for r in ledger if r["status"] == "ok")
    joints = ", ".join(f"{i} {n}" for i, n in enumerate(H36M17))
    style_table = "".join(f"| {r['style']} | {r['videos']} | {r['windows_train']} | {r['windows_val']} |\n"
                          for r in styles or [])
    return f"""# dance3d corpus

3D dance motion synchronised with music features, cut into {window} s windows every {hop} s,
made by dance3d from the videos listed below. {totals['windows_train']} training and
{totals['windows_val']} validation windows ({totals['window_minutes']:.1f} minutes of distinct motion).

## Files

`train/shard-NNNNN.parquet` and `val/shard-NNNNN.parquet`, zstd-compressed, one row per
window. Any Parquet reader works (pyarrow, pandas, Hugging Face `datasets`); the thin
PyTorch loader is `pipeline.train.dataset.WindowDataset`. Each file's key-value metadata
(`dance3d`) holds the schema version and the parameters that made it.

| column | type | meaning |
|---|---|---|
| window_id | string | `<clip_id>_w<start_frame>` |
| split | string | train or val (by video: a hash of video_id, so no video is in both) |
| video_id, url, title, channel, style, licence | string | provenance of the source video (style: the sources.csv label) |
| tags | list of string | the site's tags for the video (from its listing or download) |
| segment_id, clip_id, track_id | string, string, int32 | the trimmed segment, the cleaned clip (one dancer), its track |
| group_window_id | string | the group window (config `groups`) that holds this dancer with the others of the segment and overlaps this window most; empty when none |
| start_frame, start_time | int32, float64 | first frame k of the window and k/{fps:g} s, on the segment clock |
| segment_start | float64 | where the segment starts in the source video (s) |
| motion | {round(window * fps)} x 17 x 3 float32 | Human3.6M-17 joints, metres, root-relative, camera frame (x right, y down, z away) |
| world_joints | {round(window * fps)} x 17 x 3 float32 | the same joints in a gravity-aligned world frame: y up, floor at y = 0, x/z in metres from the root at the window's first frame; the root travels and jumps, anchored by the planted feet (see "World motion" below), one skeleton per clip (constant bone lengths), planted feet pinned |
| root | {round(window * fps)} x 3 float32 | the pelvis of world_joints: the root trajectory |
| contact | {round(window * fps)} x 2 int8 | 1 while the left / right foot is on the floor: its heel or toe tip is planted (see "World motion") |
| planted | {round(window * fps)} x 4 int8 | 1 while the left heel, right heel, left toe tip, right toe tip is planted |
| contact_probability | {round(window * fps)} x 4 float32 | the contact model's probability for each of those points (NaN: a corpus built without the contact model, whose contact is the older ankle rule) |
| feet | {round(window * fps)} x 4 x 3 float32 | left heel, right heel, left toe tip, right toe tip, like motion (root-relative, camera frame); NaN when the lifter has no feet |
| world_feet | {round(window * fps)} x 4 x 3 float32 | the same points like world_joints: planted points stand where they were planted, on the floor; the others ride on their ankles |
| world_hands | {round(window * fps)} x 2 x 21 x 3 float32 | the left, then the right hand's 21 points (MediaPipe's order: wrist, then thumb, index, middle, ring and pinky from the palm out) like world_joints: the hand model's metric hand, one skeleton per clip, hung on the wrist; where the model is unsure, drawn between the frames where it is sure (see hand_confidence). NaN for a hand never seen in the clip, and where the corpus was built without `pose2d.hands` |
| hand_confidence | {round(window * fps)} x 2 float32 | the hand model's presence for each hand and frame (0.5 and up: sure, MediaPipe's threshold); NaN without hands |
| rotations_6d | {round(window * fps)} x 23 x 6 float32 | local joint rotations on the clip's skeleton, 6D (first two columns of each 3 x 3 rotation), joints in the order of `dance3d export bvh`'s hierarchy (file metadata `rotation_joints`); T-pose rest, y up, facing +z |
| bone_lengths | 16 float32 | the clip's skeleton (metres; bones in the order of the file metadata `bones`) |
| camera_pitch, camera_roll | float32 | the camera's estimated tilt (degrees; pitch > 0: looking down), from the body's long axis over the clip |
| smpl_poses | {round(window * fps)} x 72 float32 | the same motion on the SMPL 24-joint tree: local rotations, axis-angle (radians), joint-major, AIST++'s `smpl_poses` (see "SMPL skeleton" below) |
| smpl_trans | {round(window * fps)} x 3 float32 | the SMPL pelvis joint, metres, like world_joints (y up, floor 0, x/z from the window's first root) |
| smpl_scaling | float32 | the scale of SMPL's rest offsets for this dancer (AIST++'s `smpl_scaling`, here about 1: metres) |
| smpl_hand_poses | {round(window * fps)} x 90 float32 | SMPL-H's 30 finger joints after its 22 body joints: left then right hand, index, middle, pinky, ring, thumb, three joints each, axis-angle (see "SMPL skeleton" below); NaN without hands |
| mfcc | {round(window * fps)} x 39 float32 | MFCC-13, deltas, delta-deltas |
| chroma | {round(window * fps)} x 12 float32 | chroma (STFT) |
| onset | {round(window * fps)} float32 | onset strength |
| beat | {round(window * fps)} int8 | 1 on the frame nearest to each music beat, at the window's beat level |
| downbeat | {round(window * fps)} int8 | 1 on the frame nearest to each bar start |
| beat_phase | {round(window * fps)} float32 | 0 at a beat, rising towards 1 before the next (NaN: fewer than two beats) |
| bar_phase | {round(window * fps)} float32 | the same over bars |
| tempo | float32 | tempo at the window's beat level (BPM) |
| beat_times, downbeat_times | list of float32 | music beats and bar starts, seconds from the window's start |
| beat_frames | list of int32 | music beats as frame indices in the window (exact times in the audio features) |
| downbeat_frames | list of int32 | bar starts as frame indices (a subset of beat_frames) |
| beat_level | string | tracked, half or double: the level of the music's beats the dance follows |
| beat_level_reason | string | why: each level's F-measure against the motion beats |
| beat_tracker | string | rnn (madmom's models, CC BY-NC-SA 4.0) or librosa |
| motion_beat_frames | list of int32 | kinematic beats: local minima of the smoothed mean joint speed (AIST++) |
| beat_align_score | float32 | Bailando's beat-align score: each music beat to its nearest motion beat (sigma 0.05 s) |
| beat_align_score_aistpp | float32 | AIST++'s: each motion beat to its nearest music beat (sigma 0.05 s) |
| beat_f1 | float32 | beat-consistency F-score of motion beats against music beats, 2-frame tolerance |

Joint order: {joints}.

Frame rate and alignment: exactly {fps:g} fps (`common.fps`). Motion frame k and audio feature
frame k of a window are both centred at k/{fps:g} s on the segment clock (audio resampled to
{round(fps * 512)} Hz, hop 512, centred frames), so there is no drift. Key poses at beats are
`motion[beat_frames]`. Motion was lifted from 2D keypoints (first freed of the pose model's
frame-to-frame noise by a Hodrick-Prescott filter, `lift.denoise_2d`) by a VideoPose3D-style
model, smoothed with a Hodrick-Prescott filter (lambda from params) and resampled with a cubic
spline. Audio was loudness-normalised to EBU R128 before features.

**A dancer's size is the lifter's guess.** One camera does not see how big a dancer is: the
lifter gives everyone whose 2D looks like an adult's an adult's size, so a child dancing alone
comes out too large (`dance3d eval lifter` reports MPJPE beside N-MPJPE, the error once the size
is forgiven, per source). Dancers of one scene are scaled onto its one floor, so their sizes
relative to each other hold.

## World motion

{_contact_text(contact)} All dancers of a segment are grounded in one scene: one gravity, one
floor, each dancer scaled onto it and placed where their planted feet are seen.

{_groups_text(groups, window, hop, fps)}

{SMPL_TEXT}

## Motion–music alignment

{_alignment_text(alignment)}

![one window: speed, music beats, motion beats](alignment.png)

## Statistics

{header}{table}
Windows per style (the `style` column; a style label per video, as the seed's Music2Dance uses):

| style | videos | windows train | windows val |
|---|---|---|---|
{style_table}
![durations](durations.png)

## Sources, licences and attribution

Every window names its source. Respect each source's licence; the corpus inherits them.

| video_id | title | channel | licence | url |
|---|---|---|---|---|
{sources}"""
