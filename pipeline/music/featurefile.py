"""The audio-features table (``data/audio_features/<segment_id>.parquet``), on the motion clock.

One row per feature frame k, centred at k / fps s on the segment clock: mfcc (MFCC-13,
delta, delta-delta), chroma (12), onset strength, beat (1 where a beat falls in the frame),
and any optional sets (``mel80``, ``beat_mfcc40``). Metadata: fps, tempo, exact beat
times, the loudness report and the alignment rule.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, fixed_list, read_meta, write_parquet

SCHEMA_VERSION = 1
BASE_COLUMNS = ("frame", "time", "mfcc", "chroma", "onset", "beat")


@dataclass(frozen=True)
class FeatureFile:
    frames: int
    mfcc: np.ndarray       # frames x 39
    chroma: np.ndarray     # frames x 12
    onset: np.ndarray      # frames
    beat: np.ndarray       # frames int8
    tempo: float
    beat_times: np.ndarray  # seconds
    meta: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # optional sets: name -> frames x d


def features_table(frames: int, fps: float, mfcc: np.ndarray, chroma: np.ndarray, onset: np.ndarray,
                   beat: np.ndarray, extra: Mapping[str, np.ndarray]) -> pa.Table:
    frame = np.arange(frames, dtype=np.int32)
    columns = {"frame": pa.array(frame), "time": pa.array(frame / fps, pa.float64()), "mfcc": fixed_list(mfcc),
               "chroma": fixed_list(chroma), "onset": pa.array(onset, pa.float32()), "beat": pa.array(beat, pa.int8())}
    for name, values in sorted(extra.items()):
        columns[name] = fixed_list(values)
    return pa.table(columns)


def write_features(path: Path, table: pa.Table, meta: Mapping[str, Any], *, fingerprint: str,
                   params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    write_parquet(table, path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, **meta})


def read_features(path: Path) -> FeatureFile:
    table = pq.read_table(path)
    meta = read_meta(path)
    n = table.num_rows
    extra = {name: column_array(table, name, (-1,)) for name in table.column_names if name not in BASE_COLUMNS}
    return FeatureFile(frames=n, mfcc=column_array(table, "mfcc", (-1,)), chroma=column_array(table, "chroma", (-1,)),
                       onset=column_array(table, "onset"), beat=column_array(table, "beat"),
                       tempo=float(meta.get("tempo", 0.0)), beat_times=np.asarray(meta.get("beat_times", []), float),
                       meta=meta, extra=extra)
