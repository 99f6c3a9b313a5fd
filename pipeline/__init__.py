"""dance3d: turn dance videos into a 3D dance-motion corpus synced to music.

Every piece of logic lives in this package and is testable alone; the modules in
``stages/`` are thin DVC entry points around it.
"""

from pipeline.core.malloc import fix_mmap_threshold
from pipeline.core.numba_cache import claim_slot

__version__ = "0.1.0"

# Before anything imports numba (librosa, the HP filter): a numba cache of this process's own.
claim_slot()
# Freed video frames go back to the system, so memory stays flat over a long video.
fix_mmap_threshold()
