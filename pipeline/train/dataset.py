"""A streaming PyTorch dataset over the corpus shards.

The unit of work is a block of consecutive row groups of one shard (read in one call, so
pyarrow decodes them in parallel). Units are spread over DataLoader workers
round-robin (after a seeded shuffle per epoch), so across workers every window is read
exactly once per epoch; inside a worker a shuffle buffer mixes windows from several
row groups. Memory is bounded by the buffer, not by the corpus.
"""

from __future__ import annotations

import random
import warnings
from pathlib import Path
from typing import Iterator

import numpy as np
import pyarrow.parquet as pq
import torch
from torch.utils.data import IterableDataset, get_worker_info

from pipeline.corpus.windows import check_schema

AUDIO_DIMS = 27  # MFCC-13 + deltas (26, as the seed model uses) + the beat flag
# Rows are read-only views of Arrow buffers; collation copies them, so torch's warning is noise here.
warnings.filterwarnings("ignore", message="The given NumPy array is not writable")


def shard_files(folder: Path) -> list[Path]:
    return sorted(Path(folder).glob("shard-*.parquet"))


def decode_batch(table, motion_column: str = "motion") -> list[dict]:
    """Rows of a corpus table as numpy arrays: motion (W x 51, from ``motion_column``), audio (W x 27)."""
    n = table.num_rows
    # Rows are zero-copy views of the Arrow buffers (read-only; the DataLoader's collation copies them).
    motion = np.asarray(table.column(motion_column).combine_chunks().flatten().flatten().flatten(), np.float32)
    motion = motion.reshape(n, -1, 51)
    frames = motion.shape[1]
    mfcc = np.asarray(table.column("mfcc").combine_chunks().flatten().flatten(), np.float32).reshape(n, frames, -1)
    beat = np.asarray(table.column("beat").combine_chunks().flatten(), np.float32).reshape(n, frames, 1)
    audio = np.concatenate([mfcc[:, :, :26], beat], -1)
    ids = table.column("window_id").to_pylist()
    return [{"window_id": ids[i], "motion": motion[i], "audio": audio[i]} for i in range(n)]


class WindowDataset(IterableDataset):
    """``motion="camera"``: root-relative camera-frame joints (the ``motion`` column); ``"world"``:
    y-up world joints with the root's path and the floor at 0 (``world_joints``, schema 4)."""

    def __init__(self, folder: Path, *, shuffle_buffer: int = 256, seed: int = 0, shuffle: bool = True,
                 groups_per_unit: int = 8, motion: str = "camera") -> None:
        if motion not in ("camera", "world"):
            raise ValueError(f"motion must be 'camera' or 'world', not {motion!r}")
        self.motion_column = "motion" if motion == "camera" else "world_joints"
        self.files = shard_files(folder)
        for f in self.files:
            check_schema(f)
        self.units = []
        for f in self.files:
            groups = list(range(pq.ParquetFile(f).num_row_groups))
            blocks = range(0, len(groups), groups_per_unit)
            self.units.extend((f, tuple(groups[i: i + groups_per_unit])) for i in blocks)
        self.shuffle_buffer = shuffle_buffer
        self.seed = seed
        self.shuffle = shuffle
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def _my_units(self) -> list[tuple[Path, tuple[int, ...]]]:
        units = list(self.units)
        if self.shuffle:
            random.Random(self.seed + self.epoch).shuffle(units)
        info = get_worker_info()
        if info is None:
            return units
        return units[info.id:: info.num_workers]

    def __iter__(self) -> Iterator[dict]:
        rng = random.Random(self.seed * 1000 + self.epoch * 7 + (get_worker_info().id if get_worker_info() else 0))
        buffer: list[dict] = []
        columns = ["window_id", self.motion_column, "mfcc", "beat"]
        files: dict[Path, pq.ParquetFile] = {}
        for path, groups in self._my_units():
            if path not in files:
                files[path] = pq.ParquetFile(path)
            rows = decode_batch(files[path].read_row_groups(list(groups), columns=columns), self.motion_column)
            for row in rows:
                if not self.shuffle:
                    yield _tensors(row)
                    continue
                buffer.append(row)
                if len(buffer) >= self.shuffle_buffer:
                    yield _tensors(buffer.pop(rng.randrange(len(buffer))))
        rng.shuffle(buffer)
        for row in buffer:
            yield _tensors(row)


def _tensors(row: dict) -> dict:
    return {"window_id": row["window_id"], "motion": torch.from_numpy(row["motion"]),
            "audio": torch.from_numpy(row["audio"])}
