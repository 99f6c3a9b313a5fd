"""Propose the dance segments of an untrimmed video: where a shot has music and moving people.

Three cues, each on a one-second grid of the video's clock (from its first frame):
- shots: ffmpeg's ``scdet`` scene-change filter (hard cuts), fed the frames the people cues decode;
- music: sound that is loud enough, mostly harmonic (HPSS) and without the pauses of speech
  (the share of low-energy frames, a classic speech/music cue);
- people moving: RTMDet + the body pose model on a few frames per second; motion is the
  spread over 4 s of each person's joints about their body's centre, in body heights, people
  matched across samples by IoU (``people_cues``).

A second is *dance* when all three hold. Runs of dance seconds inside one shot, with short
gaps filled, become proposals; a run that reaches a shot's edge takes the cut's exact time.
Every shot gets a verdict and a reason, so the review page can show why a part was left out.
These are heuristics: ``dance3d eval segments`` measures them against human segments.
"""

from __future__ import annotations

import logging
import subprocess
import threading
from dataclasses import asdict, dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any, Callable, Iterator

import av
import numpy as np

from pipeline.core.errors import MediaError
from pipeline.core.threads import threaded
from pipeline.ingest.media import VideoInfo, ffmpeg_exe
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.ingest.shots import CutFinder
from pipeline.ingest.trim import output_size
from pipeline.pose.proposed import SCHEMA_VERSION, read_proposals

log = logging.getLogger(__name__)
AUDIO_RATE = 22050
HOP = 512
HPSS_STEP = 2    # HPSS looks at every 2nd STFT frame (hop 1024)
JOINT_QUANTILE = 90  # of the joints' spreads: a dance may move only the arms
WINDOW = 4.0         # seconds of samples a motion spread is taken over
QUEUE = 4            # sampled frames decoded or detected ahead of the pose model


@dataclass(frozen=True)
class ProposeOptions:
    sample_fps: float = 3.0         # frames per second the people cues look at
    cut_threshold: float = 10.0     # scdet score (0-100) of a hard cut
    min_loudness_db: float = -50.0  # quieter seconds are silence
    min_harmonic: float = 0.4       # share of spectral energy that is harmonic (speech and noise: lower)
    max_low_energy: float = 0.4     # share of frames under half the mean energy (speech pauses: higher)
    min_person_height: float = 0.15  # a person is at least this share of the frame's height
    min_motion: float = 0.05        # spread of the joints about the body's centre over 4 s (90th percentile
                                    # of the joints), in body heights, of the most moving person
    min_seconds: float = 4.0        # shorter proposals are dropped
    max_gap: float = 2.0            # seconds of non-dance inside a run that are bridged
    edge_snap: float = 3.0          # a run this close to its shot's cut starts or ends at the cut
    max_side: int = 640             # frames are downscaled to this before the models

    @staticmethod
    def from_params(params: dict) -> "ProposeOptions":
        return ProposeOptions(**{k: type(getattr(ProposeOptions, k))(v) for k, v in params.items()
                                 if k in ProposeOptions.__dataclass_fields__})


@dataclass
class Timeline:
    """The cues of one video, one value per second (second k covers [k, k + 1) s)."""

    duration: float
    cuts: list[float]                # seconds, in order
    loudness_db: np.ndarray
    harmonic: np.ndarray
    low_energy: np.ndarray
    people: np.ndarray               # most people seen in a sample of that second
    motion: np.ndarray               # joint spread in body heights (NaN: nobody to measure)

    def flags(self, opts: ProposeOptions) -> dict[str, np.ndarray]:
        music = ((self.loudness_db >= opts.min_loudness_db) & (self.harmonic >= opts.min_harmonic)
                 & (self.low_energy <= opts.max_low_energy))
        people = self.people >= 1
        moving = people & (np.nan_to_num(self.motion) >= opts.min_motion)
        return {"music": music, "people": people, "moving": moving, "dance": music & moving}


@dataclass(frozen=True)
class Proposal:
    start: float
    end: float
    reason: str


@dataclass(frozen=True)
class Shot:
    start: float
    end: float
    verdict: str                     # "dance", "partly dance" or "no dance"
    reason: str


@dataclass
class Proposals:
    segments: list[Proposal] = field(default_factory=list)
    shots: list[Shot] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"segments": [asdict(s) for s in self.segments], "shots": [asdict(s) for s in self.shots]}


# --- cues --------------------------------------------------------------------------------

def load_audio(path: Path, audio_stream: int | None) -> np.ndarray:
    """Mono float32 at AUDIO_RATE (empty without an audio stream)."""
    if audio_stream is None:
        return np.zeros(0, np.float32)
    cmd = [ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-i", str(path),
           "-map", f"0:{audio_stream}", "-ac", "1", "-ar", str(AUDIO_RATE), "-f", "f32le", "-"]
    proc = subprocess.run(cmd, capture_output=True)
    if proc.returncode != 0:
        raise MediaError(path, "cannot decode the audio: " + proc.stderr.decode(errors="replace").strip()[-200:])
    return np.frombuffer(proc.stdout, np.float32)


def audio_cues(y: np.ndarray, seconds: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per second: loudness (dBFS), harmonic share (HPSS) and low-energy share, each over a 2 s window."""
    import librosa

    loud = np.full(seconds, -120.0)
    harmonic = np.zeros(seconds)
    low = np.ones(seconds)
    if len(y) < HOP * 4:
        return loud, harmonic, low
    spec = np.abs(librosa.stft(y, n_fft=2048, hop_length=HOP))
    rms = librosa.feature.rms(S=spec, frame_length=2048)[0]
    # HPSS (median filters, most of the cue's time) on every HPSS_STEP-th frame, its time kernel
    # shortened to span the same 0.7 s: 3x faster, harmonic shares within 0.02 on the shared clips.
    harm, perc = librosa.decompose.hpss(spec[:, ::HPSS_STEP], kernel_size=(31 // HPSS_STEP + 1, 31))
    h, p = (harm ** 2).sum(0), (perc ** 2).sum(0)
    per = AUDIO_RATE / HOP
    for k in range(seconds):
        a, b = int(max(0.0, k - 0.5) * per), int((k + 1.5) * per)
        r = rms[a:b]
        if len(r) == 0:
            continue
        loud[k] = 20 * np.log10(max(float(np.sqrt(np.mean(r ** 2))), 1e-6))
        ha, pa = h[a // HPSS_STEP: b // HPSS_STEP].sum(), p[a // HPSS_STEP: b // HPSS_STEP].sum()
        harmonic[k] = float(ha / max(ha + pa, 1e-12))
        low[k] = float(np.mean(r < 0.5 * r.mean()))
    return loud, harmonic, low


@dataclass(frozen=True)
class Sample:
    """The people of one sampled frame who are tall enough to count."""

    time: float
    boxes: np.ndarray      # Nx4
    keypoints: np.ndarray  # Nx17x3
    heights: np.ndarray    # N, box heights in pixels


def sample_people(video: SegmentVideo, models, opts: ProposeOptions, pose_opts=None,
                  tap: Callable[[av.VideoFrame], None] | None = None) -> list[Sample]:
    """RTMDet and the body pose model on every frame of ``video`` (the sample view); ``tap`` sees
    every decoded source frame (the cut finder). ``models``: pose2d's PoseModels (the body model
    is enough); ``pose_opts``: pose2d's people rules. Decoding (with the tap), detection and pose
    run in three threads, as in pose2d: one long video keeps both cores busy."""
    from pipeline.pose.models.pose import BodyAndFeet
    from pipeline.pose.pose2d import Pose2dOptions, find_people, lift_dark

    pose_opts = pose_opts or Pose2dOptions()
    body = models.pose.body if isinstance(models.pose, BodyAndFeet) else models.pose

    def decoded() -> Iterator[tuple[float, np.ndarray, Any]]:
        # Every sampled slot kept, so the decoder skips the non-reference frames no sample shows;
        # the cut finder compares the frames decoded (about half of an H.264 stream with B-frames).
        for frame in video.iter_frames(tap=tap, keep=_every, tap_all=False):
            image = lift_dark(frame.image, pose_opts.dark_mean)
            yield frame.time, image, models.detector.preprocess(image)

    def detected(frames: Iterator[tuple[float, np.ndarray, Any]]) -> Iterator[tuple[float, np.ndarray, Any]]:
        for time, image, blob in frames:
            yield time, image, models.detector.infer(blob)

    stop = threading.Event()
    samples = []
    try:
        for time, image, dets in threaded(detected(threaded(decoded(), QUEUE, stop)), QUEUE, stop):
            found, poses = find_people(image, dets, body, pose_opts)
            heights = found.boxes[:, 3] - found.boxes[:, 1]
            tall = heights >= opts.min_person_height * video.height
            samples.append(Sample(time, found.boxes[tall], poses.keypoints[tall], heights[tall]))
    finally:
        stop.set()
    return samples


def _every(index: int) -> bool:
    return True


def people_cues(samples: list[Sample], seconds: int, cuts: list[float] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Per second: the most people in one sample, and the motion of the most moving person.

    Motion is the spread over time (a 2 s window) of each joint relative to the hips, in body
    heights, the JOINT_QUANTILE-th percentile over joints (dance may move only the arms): a spread,
    not a frame difference, so a periodic dance sampled at its own period does not look still.
    People are followed by box overlap within a shot (``cuts`` end every track).
    """
    from pipeline.pose.boxes import iou_matrix

    people = np.zeros(seconds)
    tracks: dict[int, list[tuple[float, np.ndarray, np.ndarray]]] = {}  # track -> (time, joints, confident)
    previous_boxes, previous_ids, next_id = np.zeros((0, 4)), [], 0
    cut_times = sorted(cuts)
    for sample in samples:
        if cut_times and sample.time >= cut_times[0]:  # a new shot: nobody carries over
            cut_times = [c for c in cut_times if c > sample.time]
            previous_boxes, previous_ids = np.zeros((0, 4)), []
        boxes = sample.boxes
        k = min(seconds - 1, int(sample.time))
        people[k] = max(people[k], len(boxes))
        iou = iou_matrix(boxes, previous_boxes)
        ids = []
        for i in range(len(boxes)):  # greedy: each box takes the free previous box it overlaps most
            j = int(np.argmax(iou[i])) if iou.shape[1] else -1
            if j >= 0 and iou[i, j] >= 0.3 and previous_ids[j] not in ids:
                ids.append(previous_ids[j])
            else:
                ids.append(next_id)
                next_id += 1
            tracks.setdefault(ids[-1], []).append((sample.time, _body_frame(sample.keypoints[i], sample.heights[i]),
                                                   sample.keypoints[i, :, 2] >= 0.3))
        previous_boxes, previous_ids = boxes, ids
    motion = np.full(seconds, np.nan)
    for track in tracks.values():
        times = np.array([t for t, _, _ in track])
        joints = np.stack([j for _, j, _ in track])
        seen = np.stack([c for _, _, c in track])
        for k in range(seconds):
            inside = (times >= k + 0.5 - WINDOW / 2) & (times < k + 0.5 + WINDOW / 2)
            if inside.sum() < 3:
                continue
            spreads = [np.linalg.norm(joints[inside & seen[:, n], n].std(0)) for n in range(joints.shape[1])
                       if (inside & seen[:, n]).sum() >= 3]
            if len(spreads) >= 4:
                motion[k] = np.fmax(motion[k], float(np.percentile(spreads, JOINT_QUANTILE)))
    return people, motion


def _body_frame(keypoints: np.ndarray, height: float) -> np.ndarray:
    """Joints relative to the median of all 17 (a centre that does not jump when a joint is hidden),
    in body heights: articulation, not travel or camera motion."""
    return (keypoints[:, :2] - np.median(keypoints[:, :2], axis=0)) / max(float(height), 1.0)


def sample_view(path: Path, info: VideoInfo, opts: ProposeOptions) -> SegmentVideo:
    """The whole video at ``sample_fps``, downscaled: what the people cues look at."""
    rate = Fraction(opts.sample_fps).limit_denominator(1000)
    width, height = output_size(info.width, info.height, opts.max_side)
    return SegmentVideo(Path(path), 0.0, rate, max(1, int(info.duration * float(rate))), width, height)


def timeline(path: Path, info: VideoInfo, models, opts: ProposeOptions, pose_opts=None) -> Timeline:
    seconds = max(1, int(np.ceil(info.duration - 1e-6)))
    loud, harmonic, low = audio_cues(load_audio(path, info.audio_stream if info.has_audio else None), seconds)
    finder = CutFinder(opts.cut_threshold)  # sees every frame the people cues decode: no second decode
    samples = sample_people(sample_view(path, info, opts), models, opts, pose_opts, tap=finder.push)
    cuts = finder.cuts()
    people, motion = people_cues(samples, seconds, cuts)
    return Timeline(info.duration, cuts, loud, harmonic, low, people, motion)


# --- from cues to segments ---------------------------------------------------------------

def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index runs of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def _why_not(flags: dict[str, np.ndarray], a: int, b: int) -> str:
    share = {name: float(np.mean(v[a:b])) if b > a else 0.0 for name, v in flags.items()}
    if share["people"] < 0.5:
        return "nobody seen"
    if share["music"] < 0.5:
        return "no music (silence, speech or noise)"
    return "people static (not dancing)"


def propose(tl: Timeline, opts: ProposeOptions) -> Proposals:
    """Proposals and shot verdicts from the cues."""
    flags = tl.flags(opts)
    dance = flags["dance"]
    seconds = len(dance)
    bounds = [0.0] + [c for c in tl.cuts if 0 < c < tl.duration] + [tl.duration]
    out = Proposals()
    for s0, s1 in zip(bounds, bounds[1:]):
        # The seconds whose middle lies in the shot.
        a, b = int(np.clip(np.ceil(s0 - 0.5), 0, seconds)), int(np.clip(np.ceil(s1 - 0.5), 0, seconds))
        inside = dance[a:b].copy()
        for r0, r1 in _runs(~inside):  # bridge short gaps between dance runs
            if 0 < r0 and r1 < len(inside) and r1 - r0 <= opts.max_gap:
                inside[r0:r1] = True
        kept = []
        for r0, r1 in _runs(inside):
            if r1 - r0 < opts.min_seconds:  # judged before snapping: a snap never makes a run long enough
                continue
            start = s0 if a + r0 - s0 <= opts.edge_snap else float(a + r0)
            end = s1 if s1 - (a + r1) <= opts.edge_snap else float(a + r1)
            i0, i1 = a + r0, a + r1
            people = int(np.max(tl.people[i0:i1]))
            motion = float(np.nanmedian(tl.motion[i0:i1])) if np.isfinite(tl.motion[i0:i1]).any() else 0.0
            kept.append(Proposal(round(start, 3), round(end, 3),
                                 f"music (harmonic {np.median(tl.harmonic[i0:i1]):.2f}), {people} "
                                 f"{'person' if people == 1 else 'people'} moving "
                                 f"(joint spread {motion:.2f} body heights)"))
        out.segments.extend(kept)
        covered = sum(p.end - p.start for p in kept)
        if covered >= 0.9 * (s1 - s0):
            out.shots.append(Shot(round(s0, 3), round(s1, 3), "dance", kept[0].reason))
        elif kept:
            out.shots.append(Shot(round(s0, 3), round(s1, 3), "partly dance",
                                  f"{covered:.1f} of {s1 - s0:.1f} s; elsewhere {_why_not(flags, a, b)}"))
        else:
            reason = _why_not(flags, a, b) if b > a else "shorter than a second"
            if b > a and dance[a:b].any():
                reason = f"dance for less than {opts.min_seconds:g} s"
            out.shots.append(Shot(round(s0, 3), round(s1, 3), "no dance", reason))
    return out


# --- the propose_segments stage's file and worker ------------------------------------------

SUMMARY = "segments.csv"  # every proposal of every video, for people to read (the stage's own file)


def write_proposals(path: Path, video_id: str, tl: Timeline, found: Proposals, opts: ProposeOptions,
                    params: dict, fingerprint: str) -> None:
    """``<video_id>.parquet``: the per-second cues and flags; the proposals, shots and cuts in its metadata."""
    import pyarrow as pa

    from pipeline.core.storage import write_parquet

    flags = tl.flags(opts)
    table = pa.table({
        "second": pa.array(np.arange(len(tl.people)), pa.int32()),
        "loudness_db": pa.array(tl.loudness_db, pa.float32()), "harmonic": pa.array(tl.harmonic, pa.float32()),
        "low_energy": pa.array(tl.low_energy, pa.float32()), "people": pa.array(tl.people, pa.int16()),
        "motion": pa.array(tl.motion, pa.float32()),
        **{name: pa.array(v, pa.bool_()) for name, v in flags.items()},
    })
    write_parquet(table, path, schema_version=SCHEMA_VERSION, params=params,
                  extra={"fingerprint": fingerprint, "video_id": video_id, "duration": tl.duration, "cuts": tl.cuts,
                         **found.as_dict()})


def write_summary(folder: Path, files: list[Path]) -> Path:
    """``segments.csv``: video_id, start, end, reason of every proposal, in video order."""
    import csv
    import io

    from pipeline.core.storage import atomic_path

    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["video_id", "start", "end", "reason"])
    for f in sorted(files):
        found = read_proposals(f)
        for s in found["segments"]:
            writer.writerow([found["video_id"], f"{s['start']:.3f}", f"{s['end']:.3f}", s["reason"]])
    path = Path(folder) / SUMMARY
    with atomic_path(path) as tmp:
        tmp.write_text("# Proposed dance segments (dance3d propose_segments): never edited by hand; accepted by\n"
                       "# trim.unannotated: proposals, or copied into annotations/segments.csv from the review page.\n"
                       + out.getvalue())
    return path


@dataclass(frozen=True)
class ProposeJob:
    video_id: str
    source: Path
    out: Path
    opts: ProposeOptions
    pose_opts: object            # pose2d's Pose2dOptions (who is a person)
    params: dict
    fingerprint: str


def propose_video(models, job: ProposeJob) -> dict:
    """One video: cues, proposals, and the file. Returns a summary for the stage's log."""
    from pipeline.ingest.media import probe

    info = probe(job.source)
    tl = timeline(job.source, info, models, job.opts, job.pose_opts)
    found = propose(tl, job.opts)
    write_proposals(job.out, job.video_id, tl, found, job.opts, job.params, job.fingerprint)
    return {"segments": len(found.segments), "seconds": round(sum(s.end - s.start for s in found.segments), 3),
            "duration": info.duration}


# --- measuring proposals against human segments --------------------------------------------

def boundary_errors(proposed: list[tuple[float, float]], truth: list[tuple[float, float]]) -> dict:
    """Each human segment matched to the proposal it overlaps most (IoU): start and end errors (s),
    and how many human segments are found (IoU >= 0.5) and how many proposals are right."""
    def iou(a: tuple[float, float], b: tuple[float, float]) -> float:
        inter = max(0.0, min(a[1], b[1]) - max(a[0], b[0]))
        return inter / max(max(a[1], b[1]) - min(a[0], b[0]), 1e-9)

    errors, found = [], 0
    for t in truth:
        best = max(proposed, key=lambda p: iou(p, t), default=None)
        if best is None or iou(best, t) == 0:
            continue
        found += iou(best, t) >= 0.5
        errors.append((abs(best[0] - t[0]), abs(best[1] - t[1])))
    right = sum(1 for p in proposed if any(iou(p, t) >= 0.5 for t in truth))
    starts, ends = [e[0] for e in errors], [e[1] for e in errors]
    return {"human_segments": len(truth), "proposals": len(proposed), "found": int(found), "right": right,
            "start_error_s": round(float(np.mean(starts)), 3) if starts else None,
            "end_error_s": round(float(np.mean(ends)), 3) if ends else None}


def evaluate_project(root: Path) -> dict:
    """Proposals against the human rows of annotations/segments.csv, per video that has both, next to the
    baseline of one segment for the whole video (``trim.unannotated: whole``)."""
    from pipeline.core.paths import ANNOTATIONS, SEGMENT_PROPOSALS
    from pipeline.core.storage import item_files
    from pipeline.core.tables import read_csv
    from pipeline.core.timecode import parse_time

    truth: dict[str, list[tuple[float, float]]] = {}
    path = Path(root) / ANNOTATIONS
    for row in read_csv(path, ("video_id", "start", "end"), ("label", "note")) if path.exists() else []:
        truth.setdefault(row.get("video_id"), []).append((parse_time(row.get("start")), parse_time(row.get("end"))))
    videos = []
    for f in item_files(Path(root) / SEGMENT_PROPOSALS):
        found = read_proposals(f)
        if found["video_id"] not in truth:
            continue
        spans = [(s["start"], s["end"]) for s in found["segments"]]
        videos.append({"video_id": found["video_id"], **boundary_errors(spans, truth[found["video_id"]]),
                       "whole_video": boundary_errors([(0.0, found["duration"])], truth[found["video_id"]])})
    return {"protocol": "each human segment matched to the proposal of largest overlap (IoU); found: IoU >= 0.5; "
                        "errors: mean absolute start and end differences (s) of matched pairs; baseline: the whole "
                        "video as one segment", "videos": videos}


def format_table(result: dict) -> str:
    def cell(v) -> str:
        return "-" if v is None else str(v)

    lines = [result["protocol"], "",
             "| video | human | proposed | found | right | start err (s) | end err (s) | whole video: start / end |",
             "|---|---|---|---|---|---|---|---|"]
    for v in result["videos"]:
        w = v["whole_video"]
        lines.append(f"| {v['video_id']} | {v['human_segments']} | {v['proposals']} | {v['found']} | {v['right']} | "
                     f"{cell(v['start_error_s'])} | {cell(v['end_error_s'])} | "
                     f"{cell(w['start_error_s'])} / {cell(w['end_error_s'])} |")
    if not result["videos"]:
        lines.append("(no video has both human rows in annotations/segments.csv and proposals: run "
                     "`dvc repro propose_segments` first)")
    return "\n".join(lines)
