"""The numba set-up shared by every compiled kernel.

Kernels are compiled with ``cache=True`` (the first run after installing compiles them once,
later starts load the machine code from the cache), ``nogil=True`` (so they can run in the
integrator's thread pool) and without ``fastmath`` (IEEE results, reproducible across runs).
Parallel kernels use ``numba.prange`` over rays: every ray writes only its own rows, so
results do not depend on the number of threads.
"""

from __future__ import annotations

import os

# numba's OpenMP threading layer otherwise leaves its workers spinning after every parallel
# kernel; where the other cores are busy (another process, or this one's other threads) the
# spinning workers take the CPU from the threads with work to do. Whitted at 1280×960 with one
# of 2 cores kept busy by another process: 0.90 s on 1 thread, 1.76 s on 2 spinning, 0.94 s on
# 2 passive (best of 2, /tmp A/B script). A user's own setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402

#: Decorator for serial kernels.
kernel = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")
#: Decorator for kernels parallel over rays (``numba.prange``).
parallel_kernel = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy",
                             parallel=True)
prange = numba.prange


def set_threads(n: int) -> None:
    """Use ``n`` threads (at most the number numba started with) in parallel kernels."""
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
