"""Keep glibc from hoarding freed video frames: a fixed mmap threshold for large blocks.

glibc raises its mmap threshold each time a large mmapped block is freed (up to 32 MiB),
so after the first full-HD frame (6 MiB) every later one comes from the heap instead, and
with frames handed between decoder, detector and pose threads the per-thread heaps
fragment: peak RSS of the 2D stage grew by about 7 MiB per second of video. Setting the
threshold explicitly turns that adaptation off; large buffers are mmapped and returned to
the system when freed (a few microseconds per frame).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_MMAP_THRESHOLD = -3
THRESHOLD = 128 * 1024  # glibc's initial value


def fix_mmap_threshold() -> bool:
    """Set the threshold on glibc Linux; False where there is no glibc ``mallopt``."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, THRESHOLD))
    except (OSError, AttributeError):  # musl and others: no mallopt
        return False
