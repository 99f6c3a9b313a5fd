"""audio stage: data/segments -> data/audio/<segment_id>.wav (44.1 kHz, EBU R128) and
data/audio_features/<segment_id>.parquet (24 fps on the segment clock; see pipeline/music/audio.py).
Segments without an audio track are listed in metrics/audio.json and left out downstream."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa

import pipeline.music.audio
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import AUDIO, AUDIO_FEATURES, METRICS, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta, write_json, write_parquet
from pipeline.ingest.catalog import read_index
from pipeline.music.audio import FPS, LoudnessOptions, compute_features, load_for_features, normalise_loudness

log = logging.getLogger("dance3d.audio")
SCHEMA_VERSION = 1
CODE = code_fingerprint(pipeline.music.audio)


def _fixed(values: np.ndarray) -> pa.Array:
    return pa.FixedSizeListArray.from_arrays(pa.array(values.astype(np.float32).ravel(), pa.float32()),
                                             values.shape[1])


def features_table(f) -> pa.Table:
    frame = np.arange(f.frames, dtype=np.int32)
    columns = {"frame": pa.array(frame), "time": pa.array(frame / FPS, pa.float64()), "mfcc": _fixed(f.mfcc),
               "chroma": _fixed(f.chroma), "onset": pa.array(f.onset, pa.float32()),
               "beat": pa.array(f.beat, pa.int8())}
    for name, values in sorted(f.extra.items()):
        columns[name] = _fixed(values)
    return pa.table(columns)


def audio_segment(job: tuple) -> dict:
    wav, out_wav, out_features, opts, extra_sets, params, inputs, fp = job
    loudness = normalise_loudness(wav, out_wav, opts)
    features = compute_features(load_for_features(out_wav), tuple(extra_sets))
    extra = {"fingerprint": fp, "segment_id": out_features.stem, "fps": FPS, "tempo": features.tempo,
             "loudness": loudness.as_dict(),
             "beat_times": [round(t, 6) for t in features.beat_times],
             "alignment": "frame k is centred at k/24 s: audio resampled to 12288 Hz, hop 512, centred frames"}
    write_parquet(features_table(features), out_features, schema_version=SCHEMA_VERSION, params=params,
                  inputs=inputs, extra=extra)
    return {"frames": features.frames, "tempo": features.tempo, "loudness": loudness.as_dict()}


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "audio")
    opts = LoudnessOptions(target_lufs=float(params.get("target_lufs", -23.0)),
                           true_peak=float(params.get("true_peak", -2.0)),
                           loudness_range=float(params.get("loudness_range", 7.0)))
    extra_sets = list(params.get("extra_features") or [])
    items, silent = [], []
    for seg_id, seg in read_index(root / SEGMENTS).items():
        if not seg["has_audio"] or not seg["wav_path"]:
            silent.append(seg_id)
            continue
        inputs = {"segment": seg["fingerprint"]}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out_wav, out_features = root / AUDIO / f"{seg_id}.wav", root / AUDIO_FEATURES / f"{seg_id}.parquet"
        job = (root / SEGMENTS / seg["wav_path"], out_wav, out_features, opts, extra_sets, params, inputs, fp)
        items.append(WorkItem(seg_id, fp, (out_features, out_wav), job))
    if silent:
        log.info("%d segments have no audio track and are left out downstream: %s", len(silent), ", ".join(silent))
    run_item_stage("audio", items, audio_segment, out_dirs=[root / AUDIO_FEATURES, root / AUDIO], params=params)
    loudness = {}
    for path in item_files(root / AUDIO_FEATURES):
        loudness[path.stem] = read_meta(path).get("loudness", {})
    limited = sorted(seg for seg, lo in loudness.items() if lo.get("peak_limited"))
    if limited:
        log.info("true-peak ceiling limited the gain (output quieter than the target, never compressed): %s",
                 ", ".join(limited))
    write_json(root / METRICS / "audio.json",
               {"segments_with_audio": len(items), "segments_without_audio": sorted(silent),
                "loudness_mode": {m: sum(1 for lo in loudness.values() if lo.get("mode") == m)
                                  for m in sorted({lo.get("mode", "") for lo in loudness.values()})},
                "peak_limited": limited, "loudness": loudness})


def main() -> int:
    setup_logging()
    return run_stage("audio", run)


if __name__ == "__main__":
    sys.exit(main())
