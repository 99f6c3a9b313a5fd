"""audio stage: data/segments (audio read from data/raw) -> data/audio/<segment_id>.flac (44.1 kHz,
EBU R128, lossless) and data/audio_features/<segment_id>.parquet (24 fps on the segment clock;
see pipeline/music/audio.py).
Segments without an audio track are listed in reports/audio.json and left out downstream."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pipeline.music.audio
import pipeline.music.beats
import pipeline.music.featurefile
from pipeline.core.errors import InputError
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.metrics import write_metrics
from pipeline.core.params import corpus_fps, load_params, stage_params
from pipeline.core.paths import AUDIO, AUDIO_FEATURES, RAW, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta
from pipeline.ingest.catalog import read_index
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.music.audio import AudioJob, LoudnessOptions, audio_segment
from pipeline.music.beats import DEFAULT_TRACKER, TRACKERS
from pipeline.music.featurefile import SCHEMA_VERSION

log = logging.getLogger("dance3d.audio")
CODE = code_fingerprint(pipeline.music.audio, pipeline.music.beats, pipeline.music.featurefile,
                        "pipeline.ingest.segmentvideo")


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    params = {**stage_params(all_params, "audio"), "fps": corpus_fps(all_params)}
    opts = LoudnessOptions(target_lufs=float(params.get("target_lufs", -23.0)),
                           true_peak=float(params.get("true_peak", -2.0)),
                           loudness_range=float(params.get("loudness_range", 7.0)))
    extra_sets = list(params.get("extra_features") or [])
    tracker = str(params.get("beats", DEFAULT_TRACKER))
    if tracker not in TRACKERS:
        raise InputError(root / "params.yaml", f"audio.beats: {tracker!r} is not a tracker: {', '.join(TRACKERS)}")
    items, silent = [], []
    for seg_id, seg in read_index(root / SEGMENTS).items():
        if not seg["has_audio"]:
            silent.append(seg_id)
            continue
        inputs = {"segment": seg["fingerprint"]}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out_audio, out_features = root / AUDIO / f"{seg_id}.flac", root / AUDIO_FEATURES / f"{seg_id}.parquet"
        job = AudioJob(SegmentVideo.from_index(root / RAW, seg), out_audio, out_features, opts, tuple(extra_sets),
                       params["fps"], params, inputs, fp, tracker)
        items.append(WorkItem(seg_id, fp, (out_features, out_audio), job, size=float(seg["end"] - seg["start"])))
    if silent:
        log.info("%d segments have no audio track and are left out downstream: %s", len(silent), ", ".join(silent))
    for old in (root / AUDIO).glob("*.wav") if (root / AUDIO).exists() else ():
        old.unlink()  # before audio was stored as FLAC
    run_item_stage("audio", items, audio_segment, out_dirs=[root / AUDIO_FEATURES, root / AUDIO], params=params)
    loudness = {}
    for path in item_files(root / AUDIO_FEATURES):
        loudness[path.stem] = read_meta(path).get("loudness", {})
    limited = sorted(seg for seg, lo in loudness.items() if lo.get("peak_limited"))
    if limited:
        log.info("true-peak ceiling limited the gain (output quieter than the target, never compressed): %s",
                 ", ".join(limited))
    write_metrics(root, "audio",
                  {"segments_with_audio": len(items), "segments_without_audio": sorted(silent),
                   "loudness_mode": {m: sum(1 for lo in loudness.values() if lo.get("mode") == m)
                                     for m in sorted({lo.get("mode", "") for lo in loudness.values()})},
                   "peak_limited": limited, "loudness": loudness})


def main() -> int:
    setup_logging()
    return run_stage("audio", run)


if __name__ == "__main__":
    sys.exit(main())
