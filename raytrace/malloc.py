"""The C allocator, set up for rendering: freed pass-sized blocks are reused, not unmapped.

A pass allocates its arrays afresh in every kernel (rays, hits, surfaces, colours: about
1.5 MB each for 65 536 rows of three float64). glibc's ``malloc`` serves blocks above its
mmap threshold (128 KiB, growing up to 32 MiB as such blocks are freed) with a fresh
``mmap``, and gives memory at the top of a heap above its trim threshold back to the kernel,
so each pass pays the kernel again for every page it touches: about 10 000 page faults a
render of the 82k-triangle mesh scene at 1000², 16 000 on 2 threads. :func:`tune` fixes the
mmap threshold at its largest value (32 MiB on 64-bit) and the trim threshold at
:data:`TRIM_BYTES` with ``mallopt(3)`` (``M_MMAP_THRESHOLD``, ``M_TRIM_THRESHOLD``), so
blocks freed by one pass serve the next from the same heap: 3 page faults a render, 3–8 %
less CPU on the mesh scene on one thread (about 1 % on the Whitted scene), 12 % and 5 % less
wall time on two (docs/performance.md, "The allocator").

The price is memory kept after it is freed: each arena (one per rendering thread) keeps at
least :data:`TRIM_BYTES` at its top, and blocks up to 32 MiB freed below a live one stay in
the heap. That is a setting for the whole process, so only the ``raytrace`` command, whose
process is its own, calls :func:`tune`; a script or notebook that renders many frames may
call it too (``raytrace.malloc.tune()``), the library never does on its own.

Only glibc has ``mallopt`` with these parameters; elsewhere (musl, macOS, Windows)
:func:`tune` does nothing. It acts once per process.
"""

from __future__ import annotations

import ctypes
import functools
import sys

#: ``mallopt`` parameters (glibc's ``malloc.h``).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: glibc's largest mmap threshold on 64-bit (``DEFAULT_MMAP_THRESHOLD_MAX``, 4 MiB × 8).
MMAP_BYTES = 32 * 2**20
#: Freed memory a heap keeps before giving its top back: more than a pass's working set.
TRIM_BYTES = 64 * 2**20


@functools.cache
def tune() -> bool:
    """Set glibc's mmap and trim thresholds (module docstring) once per process; True where
    both were set, False where the C library has no such ``mallopt`` (not glibc)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018 (glibc's own symbol: musl has mallopt too)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return (mallopt(M_MMAP_THRESHOLD, MMAP_BYTES) == 1
            and mallopt(M_TRIM_THRESHOLD, TRIM_BYTES) == 1)
