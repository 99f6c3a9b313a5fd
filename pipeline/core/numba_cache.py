"""One numba cache folder per live process, so parallel workers never corrupt a cache.

numba's on-disk cache (``cache=True``: librosa's beat tracker, the HP filter) updates one
index file per function by read-modify-write without a lock. Two processes compiling at
once can leave an index entry that names the other process's machine code; every process
that loads it afterwards segfaults, and a cache inside ``site-packages`` stays poisoned
for the whole environment. So every dance3d process claims a *slot*: a folder under the
cache root that it holds an exclusive ``flock`` on for its whole life, and points
``NUMBA_CACHE_DIR`` at it before numba compiles anything. A cache folder therefore only
ever has one writer, slots persist (each compiles once per machine), and a slot whose
owner died is simply taken over by the next process: the lock dies with its holder.

``fresh()`` gives a process a throw-away empty cache instead (the executor's retry of a
crashed item), so even a cache corrupted by something else cannot fail an item twice.
"""

from __future__ import annotations

import atexit
import fcntl
import os
import shutil
import sys
import tempfile
from pathlib import Path

ENV_ROOT = "DANCE3D_CACHE_DIR"   # where slots live; default: $XDG_CACHE_HOME/dance3d
ENV_FRESH = "DANCE3D_NUMBA_FRESH"  # "1": this process uses an empty private cache
MAX_SLOTS = 64

_held: list = []  # the open lock file of this process's slot, kept alive with the process


def cache_root() -> Path:
    if os.environ.get(ENV_ROOT):
        return Path(os.environ[ENV_ROOT])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "dance3d"


def _point_numba_at(folder: Path) -> None:
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    if "numba" in sys.modules:  # numba already imported: its config was read at import time
        sys.modules["numba"].config.CACHE_DIR = str(folder)


def _fresh_dir() -> Path:
    folder = Path(tempfile.mkdtemp(prefix="dance3d-numba-"))
    atexit.register(shutil.rmtree, folder, True)  # a private cache lives as long as its process
    return folder


def claim_slot() -> Path:
    """Give this process its own numba cache folder (idempotent); returns the folder."""
    if _held:
        return Path(_held[0].name).parent
    if os.environ.get(ENV_FRESH) == "1":
        folder = _fresh_dir()
        _point_numba_at(folder)
        return folder
    version = f"py{sys.version_info.major}{sys.version_info.minor}"
    try:
        root = cache_root() / "numba" / version
        root.mkdir(parents=True, exist_ok=True)
        for k in range(MAX_SLOTS):
            folder = root / f"slot-{k:02d}"
            folder.mkdir(exist_ok=True)
            handle = open(folder / ".lock", "a")
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.close()
                continue
            _held.append(handle)
            _point_numba_at(folder)
            return folder
    except OSError:  # read-only home, full disk: a private cache still works, it just compiles again
        pass
    folder = _fresh_dir()
    _point_numba_at(folder)
    return folder
